"""Per-stream adaptive entropy model of ``mcb-rot``: parametric token distributions chosen by the encoder.

No training: every quantized value is coded by ANS (:mod:`mocapbench.entropy.ans`) with the token distribution of
one of :data:`NUM_CLASSES` classes, class ``i`` being a dead-zone-quantized Laplace mixture of scale
``2^((i - 16) / 4)`` quantization steps (quarter octaves from 1/16 to ~3000 steps). The mixture (95 % of scale σ,
5 % of 4σ) gives the tails that real coefficients have. The class of a DCT coefficient of channel ``c`` in frequency
band ``b`` is ``A[c] + B[b]`` (clipped): a channel scale and a spectral tilt, both chosen by the encoder to minimize
the ideal code length of the stream and written into it (one byte each). This adapts to any skeleton and any motion
for ~100 bytes of side information, where a table per (channel, band) would cost ten times more.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from mocapbench.entropy.ans import TOKEN_COUNT, ClassTables, laplace_token_probabilities, tokenize

__all__ = ["NUM_CLASSES", "NUM_BANDS", "tables", "band_of", "fit_offsets", "fit_single", "classes_of"]

NUM_CLASSES = 64
NUM_BANDS = 12
_OFFSET_RANGE = 2 * NUM_CLASSES  # A in [0, 128), B in [-64, 64): one byte each
_TAIL_SHARE, _TAIL_SCALE = 0.05, 4.0


@lru_cache(maxsize=8)
def tables(rounding: float) -> ClassTables:
    """The class token distributions for quantizer rounding offset ``rounding`` (integer counts, cached)."""
    rows = []
    for klass in range(NUM_CLASSES):
        scale = 2.0 ** ((klass - 16) / 4)
        mixture = (1 - _TAIL_SHARE) * laplace_token_probabilities(scale, rounding) + _TAIL_SHARE * (
            laplace_token_probabilities(_TAIL_SCALE * scale, rounding)
        )
        rows.append(np.maximum(1, np.round(mixture * (1 << 22))).astype(np.int64))
    return ClassTables(np.stack(rows))


def band_of(frequency: np.ndarray, length: int, nominal: int) -> np.ndarray:
    """Band (1..NUM_BANDS-1) of DCT frequencies ``k >= 1`` of a segment of ``length`` frames, on the scale of
    ``nominal`` frames: half-octaves of ``k nominal / length``, ``1 + floor(2 log2(max(1, k nominal / length)))``.

    Computed in integers (``1 + `` the largest ``m`` with ``(k nominal)^2 >= length^2 2^m``), so that a decoder in
    another language finds the same class whatever its ``log2``: the same bands as the float formula (a rational
    ``k nominal / length`` is never a power of sqrt(2) with an odd exponent; a test compares both).
    """
    scaled = np.asarray(frequency, dtype=np.int64) * int(nominal)
    square, unit = scaled * scaled, int(length) * int(length)
    band = np.ones(scaled.shape, dtype=np.int64)
    for m in range(1, NUM_BANDS - 1):
        band += square >= unit << m
    return band


def _costs(values: np.ndarray, groups: np.ndarray, num_groups: int, rounding: float) -> np.ndarray:
    """Ideal bits (tokens only) of each group's values under every class: (num_groups, NUM_CLASSES)."""
    tokens, _, _ = tokenize(values)
    histogram = np.bincount(groups * TOKEN_COUNT + tokens, minlength=num_groups * TOKEN_COUNT).astype(np.float64)
    return -histogram.reshape(num_groups, TOKEN_COUNT) @ tables(rounding).log2_probabilities.T


def fit_offsets(
    values: np.ndarray, channels: np.ndarray, bands: np.ndarray, num_channels: int, rounding: float
) -> tuple[np.ndarray, np.ndarray]:
    """Channel scales ``A`` (C,) in [0, 128) and band tilts ``B`` (NUM_BANDS,) in [-64, 64) minimizing the ideal bits.

    Coordinate descent on the separable class ``clip(A[c] + B[b], 0, NUM_CLASSES - 1)``, from the (channel, band)
    histogram: three rounds, each exact for one of A and B given the other.
    """
    cells = channels * NUM_BANDS + bands
    cost = _costs(values, cells, num_channels * NUM_BANDS, rounding).reshape(num_channels, NUM_BANDS, NUM_CLASSES)
    a_candidates = np.arange(_OFFSET_RANGE)
    b_candidates = np.arange(-NUM_CLASSES, NUM_CLASSES)
    tilt = np.zeros(NUM_BANDS, dtype=np.int64)
    scale = np.zeros(num_channels, dtype=np.int64)
    band_index = np.arange(NUM_BANDS)
    channel_index = np.arange(num_channels)
    for _ in range(3):
        klass = np.clip(a_candidates[:, None] + tilt[None, :], 0, NUM_CLASSES - 1)  # (A, B)
        totals = cost[:, band_index[None, :], klass].sum(axis=2)  # (C, A)
        scale = a_candidates[np.argmin(totals, axis=1)]
        klass = np.clip(scale[:, None] + b_candidates[None, :], 0, NUM_CLASSES - 1)  # (C, Bc)
        totals = cost[channel_index[:, None], :, klass].sum(axis=0)  # (Bc, NUM_BANDS)
        tilt = b_candidates[np.argmin(totals, axis=0)]
    return scale, tilt


def fit_single(values: np.ndarray, rounding: float) -> int:
    """The one class that codes ``values`` in the fewest bits."""
    if values.size == 0:
        return 0
    return int(np.argmin(_costs(values, np.zeros(values.size, dtype=np.int64), 1, rounding)[0]))


def classes_of(channels: np.ndarray, bands: np.ndarray, scale: np.ndarray, tilt: np.ndarray) -> np.ndarray:
    """Class of every coefficient from its channel and band (uint8)."""
    return np.clip(scale[channels] + tilt[bands], 0, NUM_CLASSES - 1).astype(np.uint8)


def fit_tilt(values: np.ndarray, channels: np.ndarray, scale: np.ndarray, rounding: float) -> int:
    """The one offset ``t`` in [-64, 64) for which classes ``clip(scale[channel] + t)`` code ``values`` best."""
    if values.size == 0:
        return 0
    cost = _costs(values, channels, len(scale), rounding)  # (C, K)
    candidates = np.arange(-NUM_CLASSES, NUM_CLASSES)
    klass = np.clip(scale[:, None] + candidates[None, :], 0, NUM_CLASSES - 1)
    return int(candidates[np.argmin(np.take_along_axis(cost, klass, axis=1).sum(axis=0))])
