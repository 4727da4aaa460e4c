"""Benchmarks: tracking accuracy/speed on rendered sequences and on natural imagery (bench/natural.py), and servo convergence."""
