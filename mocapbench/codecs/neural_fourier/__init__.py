"""Tojo, Chen & Umetani, "Neural Motion Compression with Frequency-adaptive Fourier Feature Network"
(Eurographics 2022 short paper): the Fourier-feature MLP codecs and the paper's SVD baseline.

Modules
-------
codec
    ``fourier-mlp-int`` and ``fourier-mlp-dct`` (Algorithm 1): the network, Algorithm 1 and the stream.
training
    Training the networks of many clips side by side (stacked weights, batched products, gradients and Adam by
    hand); torch, imported only when a codec trains.
svd
    ``svd``: low-rank approximation of the pose matrix (§4.1).
pose_params
    The pose matrix Y of §3 (root translation, root quaternion, axis-angles) and its inverse.
"""

from mocapbench.codecs.neural_fourier.codec import FourierMlpDctCodec, FourierMlpIntCodec
from mocapbench.codecs.neural_fourier.svd import SvdCodec

__all__ = ["FourierMlpDctCodec", "FourierMlpIntCodec", "SvdCodec"]
