"""The input door: every file, number and XML document a user or a peer supplies enters here,
and leaves as a value or one `DkError` (bounded reads, locked edits, exact bounded numbers,
XML without entity expansion)."""
