"""Benchmarks of the PGA codec (``pga-ik``): :mod:`.paper` reproduces the paper's tables, :mod:`.long` long captures."""
