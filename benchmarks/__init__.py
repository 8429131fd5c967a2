"""Benchmarks: print figures from fixed inputs; never assert timings (see README)."""
