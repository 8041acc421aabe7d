"""Benchmarks of ``mcb-linf``: :mod:`.rd` beside every codec at equal error, :mod:`.train` fits the shipped model."""
