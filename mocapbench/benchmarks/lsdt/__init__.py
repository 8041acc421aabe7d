"""Benchmarks of the LSDT codecs: :mod:`.paper` reproduces the paper's figures, :mod:`.train` trains the bases."""
