"""A live federation over Zenoh: platform nodes (`dkreason serve`) and monitors that find them
(`dkreason monitor --live`).  The key expressions are in wire.py."""
