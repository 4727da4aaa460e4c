"""Benchmarks: tracking accuracy/speed on rendered sequences and on natural imagery (bench/natural/), and servo convergence."""
