"""Benchmarks of ``mcb-rot``: :mod:`.rd` beside ACL and every other codec (rate-distortion, speed, ablation)."""
