"""Segments of ``mcb-rot``: where they start (a fixed grid, restarted at every detected cut) and their DCTs.

A segment is the unit of the temporal transform and of random access: its coefficients are coded on their own, so
any frame range is decoded from the segments that hold it. A *cut* is a jump between two frames far larger than the
motion around it (the T-pose reference frame at the start of the CMU BVH files, or the seam between two takes
joined into one file). A transform across a cut spends most of its rate on the jump; starting a new segment there
makes the two sides cost what they would cost coded apart.
"""

from __future__ import annotations

import numpy as np
import scipy  # scipy.fft loads on first use (see mocapbench.lazy_imports)

__all__ = ["detect_cuts", "segment_starts", "SegmentLayout", "forward", "inverse"]

_CUT_WINDOW = 8  # frames on each side whose median motion a jump is compared with


def detect_cuts(positions: np.ndarray, ratio: float, min_jump_cm: float) -> np.ndarray:
    """Frames ``t`` where a new take starts: the largest joint move from ``t - 1`` to ``t`` is a jump.

    Parameters
    ----------
    positions : ndarray, shape (F, J, 3), cm
    ratio : float
        A move is a jump when it exceeds ``ratio`` times the median largest move of the ``_CUT_WINDOW`` frames on
        each side (and ``min_jump_cm``); 0 disables cut detection.
    min_jump_cm : float

    Returns
    -------
    ndarray, shape (N,), int64, ascending, in [1, F)
    """
    if ratio <= 0 or len(positions) < 2:
        return np.zeros(0, dtype=np.int64)
    moves = np.sqrt(np.sum(np.diff(positions, axis=0) ** 2, axis=-1)).max(axis=1)  # moves[t - 1]: t-1 -> t
    padded = np.pad(moves, _CUT_WINDOW, constant_values=np.nan)
    windows = np.lib.stride_tricks.sliding_window_view(padded, 2 * _CUT_WINDOW + 1)
    # The median of the neighbours, the move itself left out (it sits in the middle of its window).
    neighbours = np.delete(windows, _CUT_WINDOW, axis=1)
    valid = ~np.all(np.isnan(neighbours), axis=1)
    typical = np.full(len(moves), np.inf)
    typical[valid] = np.nanmedian(neighbours[valid], axis=1)
    jumps = (moves > ratio * typical) & (moves > min_jump_cm)
    return (np.flatnonzero(jumps) + 1).astype(np.int64)


def segment_starts(num_frames: int, cuts: np.ndarray, segment_frames: int) -> np.ndarray:
    """First frame of every segment, (S,) int64: a grid of ``segment_frames`` restarted at every cut."""
    bounds = np.concatenate([[0], np.asarray(cuts, dtype=np.int64), [num_frames]])
    starts = [np.arange(low, high, segment_frames) for low, high in zip(bounds[:-1], bounds[1:]) if high > low]
    return np.concatenate(starts).astype(np.int64)


class SegmentLayout:
    """Segments of a motion of F frames and the chunks (random-access units) that group them.

    Attributes
    ----------
    starts, lengths : ndarray, shape (S,), int64
        First frame and frame count of every segment.
    chunk_starts : ndarray, shape (K + 1,), int64
        First segment of every chunk, then S: consecutive segments are grouped until a chunk holds at least
        ``chunk_frames`` frames. A chunk's coefficients are one entropy-coded stream, so the decoder makes one
        coder call per class and chunk instead of per class and segment.
    """

    def __init__(self, num_frames: int, starts: np.ndarray, chunk_frames: int = 1) -> None:
        self.num_frames = num_frames
        self.starts = np.asarray(starts, dtype=np.int64)
        self.lengths = np.diff(np.append(self.starts, num_frames))
        # Segments of one length are transformed in one call.
        self.groups = {int(n): np.flatnonzero(self.lengths == n) for n in np.unique(self.lengths)}
        chunk_starts, held = [0], 0
        for segment, length in enumerate(self.lengths[:-1]):
            held += int(length)
            if held >= chunk_frames:
                chunk_starts.append(segment + 1)
                held = 0
        self.chunk_starts = np.array(chunk_starts + [len(self.starts)], dtype=np.int64)

    @property
    def num_segments(self) -> int:
        return len(self.starts)

    @property
    def num_chunks(self) -> int:
        return len(self.chunk_starts) - 1

    def chunk_segments(self, chunk: int) -> np.ndarray:
        """Segments of ``chunk``."""
        return np.arange(self.chunk_starts[chunk], self.chunk_starts[chunk + 1])

    def chunks_of_frames(self, start: int, stop: int) -> np.ndarray:
        """Indices of the chunks holding frames ``start:stop``."""
        first = int(np.searchsorted(self.starts, start, side="right")) - 1
        last = int(np.searchsorted(self.starts, stop - 1, side="right")) - 1
        chunk_first = int(np.searchsorted(self.chunk_starts, first, side="right")) - 1
        chunk_last = int(np.searchsorted(self.chunk_starts, last, side="right")) - 1
        return np.arange(chunk_first, chunk_last + 1)


def forward(signal: np.ndarray, layout: SegmentLayout) -> list[np.ndarray]:
    """Orthonormal DCT-II along time of each segment of ``signal`` (F, C): a list of (n_s, C) arrays."""
    out: list[np.ndarray] = [None] * layout.num_segments  # type: ignore[list-item]
    for length, segments in layout.groups.items():
        index = layout.starts[segments, None] + np.arange(length)
        spectra = scipy.fft.dct(signal[index], axis=1, norm="ortho")
        for i, segment in enumerate(segments):
            out[segment] = spectra[i]
    return out


def inverse(spectra: dict[int, np.ndarray], layout: SegmentLayout, channels: int) -> dict[int, np.ndarray]:
    """Inverse of :func:`forward` for the segments in ``spectra`` (segment -> (n_s, C)): segment -> (n_s, C)."""
    out: dict[int, np.ndarray] = {}
    by_length: dict[int, list[int]] = {}
    for segment in spectra:
        by_length.setdefault(int(layout.lengths[segment]), []).append(segment)
    for length, segments in by_length.items():
        stacked = np.stack([spectra[s] for s in segments]) if len(segments) > 1 else spectra[segments[0]][None]
        signals = scipy.fft.idct(stacked, axis=1, norm="ortho")
        for i, segment in enumerate(segments):
            out[segment] = signals[i]
    return out
