"""Benchmarks: one script per figure the README quotes. Run ``python -m benchmarks NAME``."""
