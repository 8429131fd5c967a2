"""The shipped matching policy (rule files), package data of dkreason."""
