"""Interpolating lifting scheme for trajectories in R^c and in SO(3) (Tournier et al. 2008, §3.5; Rahman et al.
2005; Sweldens 1998).

One analysis step splits a sequence into its even and odd samples, **predicts** every odd sample from the
nearby even ones and keeps the **details** (actual minus prediction); it is then iterated on the even samples
until one sample is left. In SO(3) the prediction is the paper's tangent-space spline: the neighbours
``r_-1, r_0, r_1, r_2`` are mapped to the tangent space at ``r_0`` by the logarithm, interpolated there by the
cubic at ``t = 1/2`` and mapped back by the exponential; the detail is ``d = log(r~^-1 · r)`` and
``r = r~ · exp(d)`` (§3.5). In R^c the same cubic weights apply to the samples themselves.

Conventions
-----------
* Any length N >= 1. The number of detail levels is ``L = ceil(log2 N)``; the paper's "#LOD" total is
  ``L + 1`` (e.g. 9 for the 141 frames of 09_06). Level 0 is the single coarse sample (frame 0); detail level
  ``l = 1..L`` refines ``ceil(N / 2^(L-l+1))`` samples into ``ceil(N / 2^(L-l))``; level L is the finest.
* Interior odd samples use the 4-point cubic (weights -1/16, 9/16, 9/16, -1/16). Near the ends the stencil
  shrinks to the available even samples (quadratic, 3 points), and an odd sample with no even sample on its
  right (the last one when the level has an even length) is extrapolated linearly from the two last even
  samples (constant if only one exists): a cubic extrapolation would overshoot when its detail is dropped.
  These boundary rules are ours; the paper does not give them.
* Closed loop: :func:`lifting_decompose` predicts from the *reconstructed* (quantized) coarser samples, so
  quantization errors do not accumulate across levels, and the same function :func:`lifting_reconstruct`
  runs in the encoder and the decoder. With no dropped level and no quantization the reconstruction is
  exact (perfect reconstruction), for any N, for rotations across ±π and for any quaternion signs.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from mocapbench.lazy_imports import Rotation

__all__ = [
    "EUCLIDEAN",
    "ROTATIONS",
    "LiftingSpace",
    "level_sizes",
    "num_lifting_levels",
    "lifting_decompose",
    "lifting_reconstruct",
]


def num_lifting_levels(num_samples: int) -> int:
    """L = ceil(log2 N), the number of detail levels of an N-sample sequence (the paper's #LOD is L + 1)."""
    if num_samples < 1:
        raise ValueError(f"A trajectory needs at least one sample, got {num_samples}.")
    return int(num_samples - 1).bit_length()


def level_sizes(num_samples: int) -> list[int]:
    """Samples at each level from the coarse one to the full sequence: ``[1, ..., N]`` (length L + 1)."""
    levels = num_lifting_levels(num_samples)
    return [-(-num_samples // (1 << (levels - level))) for level in range(levels + 1)]


@lru_cache(maxsize=512)
def _stencil(num_evens: int, num_odds: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Prediction stencils of one level: even indices ``(m, 4)``, Lagrange weights ``(m, 4)``, base index ``(m,)``.

    Odd sample i sits at position i + 1/2 between even samples i and i + 1 (positions in even-sample units).
    """
    indices = np.zeros((num_odds, 4), dtype=np.int64)
    weights = np.zeros((num_odds, 4))
    for i in range(num_odds):
        if i + 1 < num_evens:
            nodes = [m for m in (i - 1, i, i + 1, i + 2) if 0 <= m < num_evens]
        else:  # nothing on the right: linear (or constant) extrapolation
            nodes = [m for m in (i - 1, i) if m >= 0]
        t = i + 0.5
        for slot, m in enumerate(nodes):
            others = [o for o in nodes if o != m]
            weights[i, slot] = np.prod([(t - o) / (m - o) for o in others]) if others else 1.0
            indices[i, slot] = m
        indices[i, len(nodes) :] = i
    for array in (indices, weights):
        array.setflags(write=False)
    base = np.arange(num_odds)
    base.setflags(write=False)
    return indices, weights, base


@dataclass(frozen=True)
class LiftingSpace:
    """The operations the lifting scheme needs from the space its samples live in.

    Samples are arrays ``(N, s)`` (R^c: ``s = c``; SO(3): scalar-last quaternions, ``s = 4``); details and the
    coarse sample's coded form are vectors ``(m, c)`` (SO(3): rotation vectors, rad).
    """

    name: str
    predict: Callable[[np.ndarray, np.ndarray, np.ndarray, np.ndarray], np.ndarray]
    detail: Callable[[np.ndarray, np.ndarray], np.ndarray]
    apply: Callable[[np.ndarray, np.ndarray], np.ndarray]
    to_vector: Callable[[np.ndarray], np.ndarray]
    from_vector: Callable[[np.ndarray], np.ndarray]


def _euclid_predict(evens, indices, weights, base):
    return np.einsum("ms,msc->mc", weights, evens[indices])


EUCLIDEAN = LiftingSpace(
    name="euclidean",
    predict=_euclid_predict,
    detail=lambda predicted, actual: actual - predicted,
    apply=lambda predicted, detail: predicted + detail,
    to_vector=lambda samples: np.asarray(samples, dtype=np.float64),
    from_vector=lambda vectors: np.asarray(vectors, dtype=np.float64),
)


def _rotation_predict(evens, indices, weights, base):
    # Tangent-space spline (§3.5): log at r0, cubic at t = 1/2, exp back.
    r0 = Rotation.from_quat(evens[base][:, None, :])  # (m, 1)
    tangent = (r0.inv() * Rotation.from_quat(evens[indices])).as_rotvec()  # (m, 4, 3)
    step = np.einsum("ms,msc->mc", weights, tangent)
    return (Rotation.from_quat(evens[base]) * Rotation.from_rotvec(step)).as_quat()


def _rotation_detail(predicted, actual):
    return (Rotation.from_quat(predicted).inv() * Rotation.from_quat(actual)).as_rotvec()  # d = log(r~^-1 r)


def _rotation_apply(predicted, detail):
    return (Rotation.from_quat(predicted) * Rotation.from_rotvec(detail)).as_quat()  # r = r~ exp(d)


ROTATIONS = LiftingSpace(
    name="so3",
    predict=_rotation_predict,
    detail=_rotation_detail,
    apply=_rotation_apply,
    to_vector=lambda samples: Rotation.from_quat(samples).as_rotvec(),
    from_vector=lambda vectors: Rotation.from_rotvec(vectors).as_quat(),
)

#: ``details(level, predicted_odd_samples) -> dequantized detail vectors (m, c), or None for a dropped level``
DetailSource = Callable[[int, np.ndarray], "np.ndarray | None"]


def lifting_reconstruct(num_samples: int, coarse: np.ndarray, details: DetailSource, space: LiftingSpace) -> np.ndarray:
    """Synthesis: rebuild N samples from the coarse sample and the details of each level, coarse to fine.

    Parameters
    ----------
    num_samples : int
        N >= 1.
    coarse : ndarray, shape (1, c)
        The coarse sample in its vector form (R^c: the sample; SO(3): a rotation vector, rad).
    details : callable ``(level, predicted) -> ndarray (m, c) or None``
        Detail vectors of level ``1..L`` for the ``m`` odd samples whose predictions are given (``(m, s)``);
        ``None`` means the level was dropped and the predictions are kept as they are.
    space : LiftingSpace
        :data:`EUCLIDEAN` or :data:`ROTATIONS`.

    Returns
    -------
    ndarray, shape (N, s)
        Samples (SO(3): unit quaternions, signs arbitrary).
    """
    current = space.from_vector(np.asarray(coarse, dtype=np.float64).reshape(1, -1))
    sizes = level_sizes(num_samples)
    for level in range(1, len(sizes)):
        num_evens = current.shape[0]
        num_odds = sizes[level] - num_evens
        predicted = space.predict(current, *_stencil(num_evens, num_odds))
        vectors = details(level, predicted)
        odds = predicted if vectors is None else space.apply(predicted, vectors)
        merged = np.empty((sizes[level], current.shape[1]))
        merged[0::2] = current
        merged[1::2] = odds
        current = merged
    return current


def lifting_decompose(
    samples: np.ndarray,
    space: LiftingSpace,
    levels_dropped: int = 0,
    quantize: Callable[[int, np.ndarray], np.ndarray] | None = None,
) -> tuple[np.ndarray, list[np.ndarray | None], np.ndarray]:
    """Analysis, closed loop: coarse sample and details of every kept level, and what the decoder will rebuild.

    Parameters
    ----------
    samples : ndarray, shape (N, s)
        The trajectory (R^c: values; SO(3): quaternions, any signs).
    space : LiftingSpace
    levels_dropped : int
        How many of the finest detail levels are omitted (their details are taken as zero), >= 0.
    quantize : callable ``(level, vectors (m, c)) -> vectors (m, c)``, optional
        Quantize-and-dequantize of the coarse sample (level 0) and of each kept detail level; the details are
        computed against predictions made from already quantized samples. Default: no quantization.

    Returns
    -------
    coarse : ndarray, shape (1, c)
        The (quantized) coarse vector.
    details : list of length L, entry ``l - 1`` for level ``l``
        The (quantized) detail vectors ``(m, c)`` of each kept level, ``None`` for a dropped one.
    reconstruction : ndarray, shape (N, s)
        The decoder's output for these coarse/details.
    """
    samples = np.asarray(samples, dtype=np.float64)
    if samples.ndim != 2 or samples.shape[0] < 1:
        raise ValueError(f"Expected `samples` of shape (N, s) with N >= 1, got {samples.shape}.")
    if levels_dropped < 0:
        raise ValueError(f"`levels_dropped` must be >= 0, got {levels_dropped}.")
    identity = lambda level, vectors: vectors  # noqa: E731
    quantize = quantize or identity
    num_samples = samples.shape[0]
    num_levels = num_lifting_levels(num_samples)
    coarse = quantize(0, space.to_vector(samples[:1]))
    kept: list[np.ndarray | None] = [None] * num_levels

    def encoder_details(level: int, predicted: np.ndarray):
        if level > num_levels - levels_dropped:
            return None
        stride = 1 << (num_levels - level)  # odd samples of this level sit at odd multiples of the stride
        actual = samples[stride :: 2 * stride]
        kept[level - 1] = quantize(level, space.detail(predicted, actual))
        return kept[level - 1]

    reconstruction = lifting_reconstruct(num_samples, coarse, encoder_details, space)
    return coarse, kept, reconstruction
