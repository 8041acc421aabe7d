"""Generic baselines: what a user would do with off-the-shelf tools (quantize, predict, zstd).

Modules
-------
codecs
    ``raw-zstd``, ``quant-delta-zstd``, ``quant-pred-zstd`` and ``quant-rot-zstd``.
"""

from mocapbench.codecs.baselines.codecs import (
    QuantDeltaZstdCodec,
    QuantPredZstdCodec,
    QuantRotZstdCodec,
    RawZstdCodec,
)

__all__ = ["QuantDeltaZstdCodec", "QuantPredZstdCodec", "QuantRotZstdCodec", "RawZstdCodec"]
