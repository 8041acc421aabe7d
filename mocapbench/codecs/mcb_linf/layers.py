"""The signal layers of ``mcb-linf``: representations, the clip DCT and its coefficient layout, steps, lattice.

Pure functions shared by the encoder, the decoder and the model fit (:mod:`.model`); the design is in
:mod:`.codec`. Shapes: positions ``(F, J, 3)`` cm; a signal ``(F, C)`` with ``C = 3 J`` channels; its temporal
DCT on windows of L frames (split at the motion's cuts, :mod:`mocapbench.codecs.segments`) is flattened as
``[full windows (k, c, window) ..., each shorter window (k, c) ...]`` (one int per
coefficient in :class:`CoefficientLayout`).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property, lru_cache

import numpy as np
import scipy  # scipy.fft loads on first use (see mocapbench.lazy_imports)

from mocapbench.codecs.segments import window_lengths

__all__ = [
    "BAND_EDGES",
    "CHANNEL_GROUP_STARTS",
    "CoefficientLayout",
    "LayoutSlices",
    "REPRESENTATIONS",
    "band_of",
    "band_order",
    "base_positions",
    "base_positions_into",
    "bcc_quantize",
    "channel_group",
    "coefficient_channels",
    "coefficient_frequencies",
    "coefficient_windows",
    "dead_zone_quantize",
    "forward_dct",
    "from_signal",
    "inverse_dct",
    "lattice_points",
    "lattice_symbols",
    "quantization_steps",
    "root_relative",
    "to_signal",
]

REPRESENTATIONS = ("absolute", "bone", "pca")  # stream codes 0, 1, 2: append only


# Lower edges of the frequency bands (DCT index on the scale of a full clip); the context of a coefficient.
BAND_EDGES = np.array([0, 1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64, 96, 128, 192, 256, 384, 512, 768, 1024])


_BAND_OF_FREQUENCY = np.searchsorted(BAND_EDGES, np.arange(4096), side="right") - 1  # a lookup: frequency → band


# First channel of each channel group (root xyz, then PCA components 0-2, 3-8, 9-20, 21-44, 45-...).
CHANNEL_GROUP_STARTS = np.array([0, 3, 6, 12, 24, 48])


# Refinement lattice points with every |coordinate| <= this (in half cells) have an index of their own; the
# others are coded as an escape index followed by their coordinates.
_LATTICE_REACH = 15



def bcc_quantize(residual: np.ndarray, radius: float) -> tuple[np.ndarray, float]:
    """Nearest point of the body-centred cubic lattice whose covering radius is ``radius``.

    The lattice is ``a Z^3 ∪ a (Z^3 + 1/2)`` with ``a = 4 radius / sqrt(5)`` (covering radius ``a sqrt(5) / 4``),
    so every point lies within ``radius`` of its nearest lattice point.

    Parameters
    ----------
    residual : ndarray, shape (N, 3), float, cm
    radius : float, cm, > 0

    Returns
    -------
    coords : ndarray, shape (N, 3), int64
        Lattice point in half-cell units: ``point = coords * a / 2``; all-even (Z^3) or all-odd (Z^3 + 1/2).
    half_cell : float
        ``a / 2`` in cm.
    """
    cell = 4.0 * radius / np.sqrt(5.0)
    even = np.rint(residual / cell)
    odd = np.floor(residual / cell) + 0.5
    use_even = np.sum((residual - cell * even) ** 2, axis=-1) <= np.sum((residual - cell * odd) ** 2, axis=-1)
    coords = np.where(use_even[:, None], 2 * even, 2 * odd).astype(np.int64)
    return coords, cell / 2.0


@lru_cache(maxsize=1)
def lattice_points() -> tuple[np.ndarray, np.ndarray]:
    """The BCC points within reach, by distance from the origin, and a lookup from coordinates to index.

    Returns
    -------
    points : ndarray, shape (P, 3), int64, half-cell units (all coordinates even, or all odd), sorted by norm
        then coordinates: index 0-7 are the (±1, ±1, ±1), 8-13 the (±2, 0, 0), ...
    lookup : ndarray, shape (2R + 1,) * 3, int64: index of point ``c`` at ``lookup[c + R]`` (-1 off the lattice)
    """
    reach = _LATTICE_REACH
    axis = np.arange(-reach, reach + 1)
    grid = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), axis=-1).reshape(-1, 3)
    parity = grid & 1
    points = grid[(parity[:, 0] == parity[:, 1]) & (parity[:, 1] == parity[:, 2]) & np.any(grid != 0, axis=1)]
    points = points[np.lexsort((points[:, 2], points[:, 1], points[:, 0], np.sum(points**2, axis=1)))]
    lookup = np.full((2 * reach + 1,) * 3, -1, dtype=np.int64)
    lookup[tuple((points + reach).T)] = np.arange(len(points))
    return points, lookup


def lattice_symbols(lattice: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Index of each lattice point (escape index ``P`` when out of reach) and the out-of-reach points (M, 3)."""
    points, lookup = lattice_points()
    inside = np.all(np.abs(lattice) <= _LATTICE_REACH, axis=1)
    symbols = np.full(len(lattice), len(points), dtype=np.int64)
    symbols[inside] = lookup[tuple((lattice[inside] + _LATTICE_REACH).T)]
    return symbols, lattice[~inside]


def band_of(frequencies: np.ndarray) -> np.ndarray:
    """Band index of (full-clip-scale) DCT frequencies (below 4096)."""
    return _BAND_OF_FREQUENCY[frequencies]


def _windows(num_frames: int, clip_frames: int, cuts=()) -> tuple[np.ndarray, list[tuple[int, int]]]:
    """Starts of the full windows (L frames), and ``(start, length)`` of the shorter ones, both in time order.

    Without cuts: ``F // L`` full windows then one partial of ``F mod L`` frames; with cuts, every segment
    between cuts (:mod:`mocapbench.codecs.segments`) has its own full windows and its own remainder.
    """
    full, partial = [], []
    start = 0
    for length in window_lengths(num_frames, clip_frames, cuts):
        (full.append(start) if length == clip_frames else partial.append((start, length)))
        start += length
    return np.asarray(full, dtype=np.int64), partial


def coefficient_frequencies(num_frames: int, clip_frames: int, channels: int, cuts=()) -> np.ndarray:
    """DCT frequency of every flattened coefficient, on the scale of a full clip of L frames.

    The coefficients are flattened as ``[full windows (k, c, window) ..., each shorter window (k, c) ...]``; a
    window's frequency k of ``p`` frames is reported as ``k L / p`` (rounded down). Depends only on (F, L, C, cuts).
    """
    full, partial = _windows(num_frames, clip_frames, cuts)
    parts = [np.repeat(np.arange(clip_frames), channels * len(full))]
    parts += [np.repeat((np.arange(length) * clip_frames) // length, channels) for _, length in partial]
    return np.concatenate(parts)


def band_order(frequencies: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A permutation sorting the flattened coefficients by band (stable), and the sorted bands."""
    bands = band_of(frequencies)
    order = np.argsort(bands, kind="stable")
    return order, bands[order]


def coefficient_channels(num_frames: int, clip_frames: int, channels: int, cuts=()) -> np.ndarray:
    """Channel of every flattened coefficient (same layout as :func:`coefficient_frequencies`)."""
    full, partial = _windows(num_frames, clip_frames, cuts)
    parts = [np.tile(np.repeat(np.arange(channels), len(full)), clip_frames)]
    parts += [np.tile(np.arange(channels), length) for _, length in partial]
    return np.concatenate(parts)


def coefficient_windows(num_frames: int, clip_frames: int, channels: int, cuts=()) -> np.ndarray:
    """Window (full windows 0, 1, ..., then the shorter ones) of every flattened coefficient (same layout)."""
    full, partial = _windows(num_frames, clip_frames, cuts)
    parts = [np.tile(np.arange(len(full)), clip_frames * channels)]
    parts += [np.full(length * channels, len(full) + index) for index, (_, length) in enumerate(partial)]
    return np.concatenate(parts)


def channel_group(channels: np.ndarray) -> np.ndarray:
    """Channel group of each channel: root, then PCA components in groups (see ``CHANNEL_GROUP_STARTS``)."""
    return np.searchsorted(CHANNEL_GROUP_STARTS, np.arange(channels.max() + 1 if channels.size else 0), side="right")[
        channels
    ] - 1


def quantization_steps(frequencies, channels, step: float, slope: float, root_step_rel: float, clip_frames: int):
    """Quantization step of every coefficient, cm: ``step (1 + slope k / L)``, times ``root_step_rel`` on the root.

    Only correctly rounded IEEE operations: encoder and decoder compute bit-identical steps on any machine.
    """
    steps = step * (1.0 + slope * frequencies / clip_frames)
    return np.where(channels < 3, steps * root_step_rel, steps)


def forward_dct(signal: np.ndarray, clip_frames: int, cuts=()) -> np.ndarray:
    """Temporal DCT-II (orthonormal) of (F, C) on windows of L frames split at ``cuts``, flattened in layout order."""
    num_frames, channels = signal.shape
    full, partial = _windows(num_frames, clip_frames, cuts)
    parts = []
    if len(full):
        clips = signal[full[:, None] + np.arange(clip_frames)]  # (n, L, C)
        parts.append(scipy.fft.dct(clips, axis=1, norm="ortho").transpose(1, 2, 0).ravel())  # (k, c, window)
    for start, length in partial:
        parts.append(scipy.fft.dct(signal[start : start + length], axis=0, norm="ortho").ravel())  # (k, c)
    return np.concatenate(parts)


def inverse_dct(coefficients: np.ndarray, num_frames: int, clip_frames: int, channels: int, cuts=()) -> np.ndarray:
    """Inverse of :func:`forward_dct`: (F, C)."""
    full, partial = _windows(num_frames, clip_frames, cuts)
    out = np.empty((num_frames, channels))
    split = len(full) * clip_frames * channels
    if len(full):
        clips = coefficients[:split].reshape(clip_frames, channels, len(full)).transpose(2, 0, 1)
        out[full[:, None] + np.arange(clip_frames)] = scipy.fft.idct(clips, axis=1, norm="ortho")
    for start, length in partial:
        tail = coefficients[split : split + length * channels].reshape(length, channels)
        out[start : start + length] = scipy.fft.idct(tail, axis=0, norm="ortho")
        split += length * channels
    return out


def dead_zone_quantize(values: np.ndarray, steps: np.ndarray, rounding: float) -> np.ndarray:
    """``sign(v) floor(|v| / step + rounding)``: rounding 0.5 is nearest, less widens the zero bin (int64)."""
    scaled = values / steps
    return (np.sign(scaled) * np.floor(np.abs(scaled) + rounding)).astype(np.int64)


def root_relative(positions: np.ndarray) -> np.ndarray:
    """(F, J, 3) → (F, 3 (J - 1)): joints 1..J-1 relative to the root."""
    return (positions[:, 1:] - positions[:, :1]).reshape(len(positions), -1)


def to_signal(positions: np.ndarray, parents: np.ndarray, representation: str, spatial):
    """(F, J, 3) positions → (F, 3J) signal of the chosen representation."""
    num_frames = len(positions)
    if representation == "absolute":
        return positions.reshape(num_frames, -1)
    if representation == "bone":
        return _to_bones(positions, parents).reshape(num_frames, -1)
    projected = (root_relative(positions) - spatial.mean) @ spatial.basis.T
    return np.concatenate([positions[:, 0], projected], axis=1)


def from_signal(signal: np.ndarray, parents: np.ndarray, representation: str, spatial):
    """Inverse of :func:`to_signal`: (F, J, 3)."""
    num_frames = len(signal)
    if representation == "absolute":
        return signal.reshape(num_frames, -1, 3)
    if representation == "bone":
        return _from_bones(signal.reshape(num_frames, -1, 3), parents)
    relative = (signal[:, 3:] @ spatial.basis + spatial.mean).reshape(num_frames, -1, 3)
    root = signal[:, None, :3]
    return np.concatenate([root, relative + root], axis=1)


def _to_bones(positions: np.ndarray, parents: np.ndarray) -> np.ndarray:
    """(F, J, 3) absolute positions → root position and child − parent vectors."""
    bones = positions.copy()
    bones[:, 1:] -= positions[:, parents[1:]]
    return bones


def _from_bones(bones: np.ndarray, parents: np.ndarray) -> np.ndarray:
    """Inverse of :func:`_to_bones` (parents come before children)."""
    positions = bones.copy()
    for joint in range(1, len(parents)):
        positions[:, joint] += positions[:, parents[joint]]
    return positions


def base_positions(
    coefficients, steps, num_frames, parents, clip_frames, representation, spatial, cuts=()
) -> np.ndarray:
    """Base-layer positions (F, J, 3) cm from the quantized coefficients; shared by encoder and decoder."""
    signal = inverse_dct(coefficients * steps, num_frames, clip_frames, 3 * len(parents), cuts)
    return from_signal(signal, parents, representation, spatial)


@dataclass(frozen=True, eq=False)
class CoefficientLayout:
    """Frequency and channel of every flattened coefficient of an (F frames, C channels) signal."""

    frequencies: np.ndarray
    channels: np.ndarray
    windows: np.ndarray

    @classmethod
    def of(cls, num_frames: int, clip_frames: int, channels: int, cuts=()) -> "CoefficientLayout":
        return cls(
            coefficient_frequencies(num_frames, clip_frames, channels, cuts),
            coefficient_channels(num_frames, clip_frames, channels, cuts),
            coefficient_windows(num_frames, clip_frames, channels, cuts),
        )

    @property
    def num_shift_groups(self) -> int:
        windows = int(self.windows.max()) + 1 if self.windows.size else 0
        return windows * len(CHANNEL_GROUP_STARTS)

    @cached_property
    def shift_groups(self) -> np.ndarray:
        """Shift group of every coefficient: its clip window and channel group."""
        return self.windows * len(CHANNEL_GROUP_STARTS) + channel_group(self.channels)

    @cached_property
    def _bands(self) -> tuple[np.ndarray, np.ndarray]:
        return band_order(self.frequencies)

    @property
    def band_order(self) -> np.ndarray:
        """A permutation sorting the coefficients by band (only the ``"bands"`` coder needs it)."""
        return self._bands[0]

    @property
    def sorted_bands(self) -> np.ndarray:
        return self._bands[1]


#: Coefficients per slice when the decoder computes the layout piece by piece (:class:`LayoutSlices`).
SLICE_COEFFICIENTS = 1 << 16


@dataclass(frozen=True, eq=False)
class LayoutSlices:
    """The layout of :class:`CoefficientLayout` computed for ranges of flattened coefficients on demand.

    The decoder's view of the layout: ``slice(start, stop)`` gives the frequency, channel and window of
    coefficients ``start:stop`` (exactly the entries of :class:`CoefficientLayout`'s arrays there), so that the
    decoder never holds the three F·C int64 arrays, only one slice of them; :meth:`windows_in_order` walks the DCT
    windows for the inverse transform one window at a time.
    """

    num_frames: int
    clip_frames: int
    channels: int
    full: np.ndarray  # start frame of each full window
    partial: tuple[tuple[int, int], ...]  # (start frame, length) of each shorter window
    partial_offsets: np.ndarray  # flattened index of each shorter window's first coefficient, then the end

    @classmethod
    def of(cls, num_frames: int, clip_frames: int, channels: int, cuts=()) -> "LayoutSlices":
        full, partial = _windows(num_frames, clip_frames, cuts)
        split = len(full) * clip_frames * channels
        lengths = np.array([length for _, length in partial], dtype=np.int64)
        offsets = split + np.concatenate([[0], np.cumsum(lengths * channels)]).astype(np.int64)
        return cls(num_frames, clip_frames, channels, full, tuple(partial), offsets)

    @property
    def size(self) -> int:
        """Number of coefficients, F·C."""
        return self.num_frames * self.channels

    @property
    def num_windows(self) -> int:
        return len(self.full) + len(self.partial)

    @property
    def num_shift_groups(self) -> int:
        """As :attr:`CoefficientLayout.num_shift_groups`."""
        return self.num_windows * len(CHANNEL_GROUP_STARTS) if self.size else 0

    def ranges(self):
        """``(start, stop)`` of consecutive slices of at most :data:`SLICE_COEFFICIENTS` covering every coefficient."""
        for start in range(0, self.size, SLICE_COEFFICIENTS):
            yield start, min(self.size, start + SLICE_COEFFICIENTS)

    def slice(self, start: int, stop: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Frequencies, channels and windows (int64) of the flattened coefficients ``start:stop``."""
        index = np.arange(start, stop, dtype=np.int64)
        frequencies, channels, windows = np.empty_like(index), np.empty_like(index), np.empty_like(index)
        n, length, count = len(self.full), self.clip_frames, self.channels
        head = int(np.clip(self.partial_offsets[0] - start, 0, len(index)))  # the full windows' part
        if head:
            full = index[:head]
            frequencies[:head] = full // (count * n)
            channels[:head] = (full // n) % count
            windows[:head] = full % n
        first = max(int(np.searchsorted(self.partial_offsets, start, side="right")) - 1, 0)
        for p in range(first, len(self.partial)):
            begin, end = int(self.partial_offsets[p]), int(self.partial_offsets[p + 1])
            if begin >= stop:
                break
            lo, hi = max(begin, start) - start, min(end, stop) - start
            if lo >= hi:
                continue
            local = index[lo:hi] - begin
            frequencies[lo:hi] = ((local // count) * length) // self.partial[p][1]
            channels[lo:hi] = local % count
            windows[lo:hi] = n + p
        return frequencies, channels, windows

    def windows_in_order(self, coefficients: np.ndarray):
        """``(first frame, frames, frequencies (frames, 1) int64, values (frames, C))`` of every DCT window, full
        windows first then the shorter ones (the flattened order); ``values`` is a view of ``coefficients`` (F·C,)."""
        count, length, n = self.channels, self.clip_frames, len(self.full)
        split = int(self.partial_offsets[0])
        if n:
            full = coefficients[:split].reshape(length, count, n)
            k = np.arange(length, dtype=np.int64)[:, None]
            for w, start in enumerate(self.full):
                yield int(start), length, k, full[:, :, w]
        for p, (start, frames) in enumerate(self.partial):
            offset = int(self.partial_offsets[p])
            k = ((np.arange(frames, dtype=np.int64) * length) // frames)[:, None]
            yield start, frames, k, coefficients[offset : offset + frames * count].reshape(frames, count)


def base_positions_into(
    out, coefficients, layout: LayoutSlices, step, slope, root_step_rel, parents, representation, spatial
) -> np.ndarray:
    """:func:`base_positions` written into ``out`` (F, J, 3) one DCT window at a time (the decoder's version).

    The same arithmetic on every element as :func:`base_positions` (steps, product, inverse DCT of each window,
    the representation's inverse), but its temporaries are one window of L frames, never F·C.
    """
    channels = np.arange(layout.channels, dtype=np.int64)[None, :]
    for start, frames, frequencies, values in layout.windows_in_order(coefficients):
        steps = quantization_steps(frequencies, channels, step, slope, root_step_rel, layout.clip_frames)
        signal = scipy.fft.idct(values * steps, axis=0, norm="ortho")
        out[start : start + frames] = from_signal(signal, parents, representation, spatial)
    return out
