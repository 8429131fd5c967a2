"""Optional rule files a config may add (rules = [...])."""
