"""Benchmarks of the neural Fourier codecs and ``svd``: :mod:`.paper` reproduces the paper's results."""
