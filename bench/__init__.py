"""Benchmarks of fem_grasp (``make bench``); see :mod:`bench.bench`."""
