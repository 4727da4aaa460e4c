"""Benchmarks: tracking accuracy/speed on rendered sequences, and servo convergence."""
