"""Discontinuities in a motion (a reference/T-pose frame, a cut between takes, a teleport) and the windows around them.

A transform along time (the DCT of a clip codec) spreads a jump over every frequency: one T-pose frame at the
start of a CMU BVH file costs ``mcb-linf`` two thirds of its ratio. Clip codecs therefore split the motion at its
cuts and never let a transform window straddle one; an isolated frame (a cut before and after it) becomes a window
of one frame, coded on its own.

Detection (:func:`find_cuts`): the jump before frame ``i`` is the root-mean-square over joints of
``||P_i - P_{i-1}||`` (cm). Frame ``i`` starts a new segment when its jump exceeds both ``ratio`` times the median
jump of the motion (so the test adapts to the frame rate and the speed of the motion) and ``min_jump_cm`` (so that
a still motion, whose median jump is about 0, is not cut by noise). At most ``max(1, F // 32)`` cuts are kept, the
largest jumps first: a motion that jumps everywhere is noise, not a list of takes.

The cut list travels in the stream (:func:`write_cuts`, :func:`read_cuts`): a count and the gaps, as varints, a few
bytes. Shared by every clip codec (``mcb-linf``, ``lsdt-clip`` and the spatial DCT/DWT clip baselines).
"""

from __future__ import annotations

import numpy as np

from mocapbench.entropy.bitio import ByteReader, ByteWriter
from mocapbench.entropy.errors import BitstreamError

__all__ = [
    "CUT_MIN_JUMP_CM",
    "CUT_RATIO",
    "find_cuts",
    "frame_jumps",
    "read_cuts",
    "segment_bounds",
    "window_lengths",
    "write_cuts",
]

#: A jump counts as a cut when it is this many times the motion's median jump ...
CUT_RATIO = 8.0
#: ... and at least this large, cm (RMS over joints of one frame's displacement).
CUT_MIN_JUMP_CM = 5.0


def frame_jumps(positions: np.ndarray) -> np.ndarray:
    """RMS over joints of the displacement between consecutive frames.

    Parameters
    ----------
    positions : ndarray, shape (F, J, 3), float, cm

    Returns
    -------
    ndarray, shape (F - 1,), float, cm
        Entry ``i - 1`` is the jump into frame ``i``.
    """
    positions = np.asarray(positions, dtype=np.float64)
    if len(positions) < 2:
        return np.zeros(0)
    return np.sqrt(np.mean(np.sum(np.diff(positions, axis=0) ** 2, axis=-1), axis=-1))


def find_cuts(positions: np.ndarray, *, ratio: float = CUT_RATIO, min_jump_cm: float = CUT_MIN_JUMP_CM) -> np.ndarray:
    """Frames that start a new segment: the discontinuities of ``positions``.

    Parameters
    ----------
    positions : ndarray, shape (F, J, 3), float, cm
    ratio : float, keyword-only
        A jump is a cut when it is over ``ratio`` times the median jump (and over ``min_jump_cm``).
    min_jump_cm : float, keyword-only, cm

    Returns
    -------
    ndarray, shape (N,), int64
        Sorted frame indices in ``[1, F - 1]``; empty for a continuous motion.
    """
    jumps = frame_jumps(positions)
    if jumps.size < 2:
        return np.zeros(0, dtype=np.int64)
    threshold = max(ratio * float(np.median(jumps)), min_jump_cm)
    candidates = np.flatnonzero(jumps > threshold)
    limit = max(1, len(positions) // 32)
    if len(candidates) > limit:
        candidates = candidates[np.argsort(jumps[candidates], kind="stable")[::-1][:limit]]
    return np.sort(candidates).astype(np.int64) + 1


def segment_bounds(num_frames: int, cuts) -> list[tuple[int, int]]:
    """``[(start, stop), ...]`` of the segments between ``cuts`` (frames that start a segment), covering ``[0, F)``."""
    edges = [0, *(int(cut) for cut in cuts), num_frames]
    return [(start, stop) for start, stop in zip(edges[:-1], edges[1:]) if stop > start]


def window_lengths(num_frames: int, clip_frames: int, cuts=()) -> list[int]:
    """Transform windows in time order: each segment in windows of ``clip_frames``, then its remainder.

    Without cuts: ``F // L`` windows of L frames and one of ``F mod L`` (if not 0), the usual clip layout.
    """
    lengths: list[int] = []
    for start, stop in segment_bounds(num_frames, cuts):
        length = stop - start
        lengths += [clip_frames] * (length // clip_frames)
        if length % clip_frames:
            lengths.append(length % clip_frames)
    return lengths


def write_cuts(writer: ByteWriter, cuts) -> None:
    """The cut list: its count, then the gaps between cuts (first from frame 0), varints."""
    cuts = np.asarray(cuts, dtype=np.int64)
    writer.write_varint(len(cuts))
    if len(cuts):
        writer.write_varints(np.diff(cuts, prepend=0))


def read_cuts(reader: ByteReader, num_frames: int, what: str) -> np.ndarray:
    """Inverse of :func:`write_cuts`, checked: strictly increasing frames in ``[1, F - 1]``.

    Raises
    ------
    BitstreamError
        A count over ``F - 1`` or cuts out of order or out of range; ``what`` names the codec.
    """
    count = reader.read_varint(f"{what}: cut count")
    if count > max(num_frames - 1, 0):
        raise BitstreamError(f"{what}: expected at most {max(num_frames - 1, 0)} cuts, found {count}.")
    if not count:
        return np.zeros(0, dtype=np.int64)
    gaps = reader.read_varints(count, f"{what}: cuts").astype(np.int64)
    cuts = np.cumsum(gaps)
    if gaps.min() < 1 or cuts[-1] > num_frames - 1:
        raise BitstreamError(f"{what}: cuts must increase within frames 1..{num_frames - 1}, found {cuts.tolist()}.")
    return cuts
