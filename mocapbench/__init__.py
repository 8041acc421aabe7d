"""mocapbench: compress skeletal motion capture with the codecs from the literature and measure them honestly.

The package itself imports nothing, so ``mocapbench --version`` and ``--help`` start at once. Entry points:
:mod:`mocapbench.cli` (the ``mocapbench`` command), :mod:`mocapbench.codecs` (``create``, ``CODECS``),
:mod:`mocapbench.io` (``read_bvh``, ``read_amc``), :func:`mocapbench.experiments.evaluate.evaluate`.
"""

__version__ = "0.1.0"
"""The package version; ``pyproject.toml`` reads it from here (``[tool.setuptools.dynamic]``)."""
