"""Spatial-transform codecs of joint positions: Hou, Chau, Magnenat-Thalmann & He, "Low-latency compression of mocap
data using learned spatial decorrelation transform" (CAGD 43, 2016), and the spatial DCT / DWT baselines it compares
against.

Modules
-------
codecs
    The six registered codecs (``lsdt-frame``, ``lsdt-clip``, ``dct-spatial-*``, ``dwt-spatial-*``).
pipeline
    The transform-agnostic pipeline shared by the six (stream layout, windows, cuts) and their configs.
frame
    The frame scheme (§3.1): causal closed-loop encoder.
clip
    The clip scheme (§3.2): temporal DCT, then the spatial transform.
vectors
    Quantization and entropy coding of coefficient vectors.
bases
    The committed learned bases (package data) and their fingerprint.
training
    LSDT training (Algorithm 1).
spatial
    The fixed spatial transforms (DCT, Haar DWT).
"""

from mocapbench.codecs.lsdt.codecs import (
    DctSpatialClipCodec,
    DctSpatialFrameCodec,
    DwtSpatialClipCodec,
    DwtSpatialFrameCodec,
    LsdtClipCodec,
    LsdtFrameCodec,
)

__all__ = [
    "DctSpatialClipCodec",
    "DctSpatialFrameCodec",
    "DwtSpatialClipCodec",
    "DwtSpatialFrameCodec",
    "LsdtClipCodec",
    "LsdtFrameCodec",
]
