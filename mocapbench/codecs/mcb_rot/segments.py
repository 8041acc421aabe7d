"""Segments of ``mcb-rot``: where they start (a fixed grid, restarted at every cut) and their DCTs.

A segment is the unit of the temporal transform; consecutive segments are grouped into chunks, the unit of random
access. A *cut* (found by the shared :func:`mocapbench.codecs.segments.find_cuts`: the T-pose reference frame at
the start of the CMU BVH files, the seam between two takes joined into one file) starts a new segment, so that no
transform straddles the jump and the two sides cost what they would cost coded apart.
"""

from __future__ import annotations

import functools

import numpy as np
import scipy  # scipy.fft loads on first use (see mocapbench.lazy_imports)

from mocapbench.codecs.segments import window_lengths

__all__ = ["segment_starts", "SegmentLayout", "forward", "inverse"]

def segment_starts(num_frames: int, cuts: np.ndarray, segment_frames: int) -> np.ndarray:
    """First frame of every segment, (S,) int64: a grid of ``segment_frames`` restarted at every cut."""
    lengths = window_lengths(num_frames, segment_frames, cuts)
    return np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(np.int64)


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
        chunk_starts, held = [0], 0
        for segment, length in enumerate(self.lengths[:-1]):
            held += int(length)
            if held >= chunk_frames:
                chunk_starts.append(segment + 1)
                held = 0
        self.chunk_starts = np.array(chunk_starts + [len(self.starts)], dtype=np.int64)

    @functools.cached_property
    def groups(self) -> dict[int, np.ndarray]:
        """Segment length -> the segments of that length (transformed in one call)."""
        return {int(n): np.flatnonzero(self.lengths == n) for n in np.unique(self.lengths)}

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


def inverse(spectra: np.ndarray) -> np.ndarray:
    """Inverse of :func:`forward` along the last axis of ``spectra`` (..., n): the signals (..., n), in place."""
    return scipy.fft.idct(spectra, axis=-1, norm="ortho", overwrite_x=True)
