"""Benchmarks behind ``smokyslam bench``: functions that return plain numbers."""
