"""Benchmarks of ``mcb-rot``: :mod:`.rd` beside ACL and every other codec (rate-distortion, speed, ablation),
:mod:`.scales` (scale tracks), :mod:`.encode_cpu` (encoder CPU and bytes per dataset, eps and shell)."""
