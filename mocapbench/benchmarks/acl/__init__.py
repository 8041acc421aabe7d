"""Benchmarks of ``acl``: :mod:`.rd` rate-distortion and speed, :mod:`.reference` why two reference points differ."""
