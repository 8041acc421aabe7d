"""``mcb-rot`` long captures: a capture longer than one window is coded as independent windows (bounded memory).

The encoder's working set is about 20 times the positions array of what it codes (the signal, its spectra, the
compensated quantizer's levels, the closed loop's decoded rotations and targets). A capture of more than
:data:`WINDOW_FRAMES` frames is therefore coded window by window, each window a self-contained ``mcb-rot`` payload
(its own skeleton, cuts, rate search, entropy classes, closed loop and check of the bound), so the encoder holds one
window's arrays whatever the length; the decoder writes each window into the motion's arrays. Layout::

    u8 MARKER (0) | varint LAYOUT_VERSION | varint window frames W | per window: varint size, mcb-rot payload

Windows are back to back (``[0, W)``, ``[W, 2W)``, ..., the last one shorter), each decoded with a header of its
own frame count; the encoder makes them about equal (:func:`window_length`: as many as windows of
:data:`WINDOW_FRAMES` frames need, each a whole number of segments where it can). A one-window payload starts with
its format byte (2 or more), never 0, so the marker tells the two apart: every stream written before windows
existed (of any length) decodes as before, and every clip up to :data:`WINDOW_FRAMES` frames keeps its bytes. The
skeleton (149 bytes on the 31-joint CMU skeleton) is repeated in every window: about 0.5 % of a window's payload at
eps 1 cm, and it keeps each window a plain ``mcb-rot`` payload.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from mocapbench.codecs import windows
from mocapbench.codecs.base import Header
from mocapbench.entropy.bitio import ByteReader, ByteWriter
from mocapbench.entropy.errors import BitstreamError

__all__ = ["MARKER", "LAYOUT_VERSION", "WINDOW_FRAMES", "is_windowed", "window_length", "encode", "read_windows",
           "window_header", "windows_of_range", "merged_stats"]

#: First byte of a windowed payload (a one-window payload starts with its format, 2 or more).
MARKER = 0
#: Version of the windowed layout (module docstring); a decoder refuses any other.
LAYOUT_VERSION = 1
#: Frames of a window: captures longer than this are windowed (tests patch it to exercise windows on short clips).
WINDOW_FRAMES = windows.WINDOW_FRAMES

Window = tuple[int, int, memoryview]  # (first frame, stop frame, window payload)


def is_windowed(payload: memoryview) -> bool:
    """Whether ``payload`` is a sequence of windows (it starts with :data:`MARKER`)."""
    return len(payload) > 0 and payload[0] == MARKER


def window_length(num_frames: int, segment_frames: int) -> int:
    """Frames of the windows of a capture of ``num_frames`` > :data:`WINDOW_FRAMES` frames (the last one may be
    shorter): as many windows as windows of :data:`WINDOW_FRAMES` need, made about equal and rounded up to whole
    segments of ``segment_frames``, so that no window is a short remainder (7,681 frames: two windows of 3,840 and
    3,841 frames, not 7,680 and 1) and the largest window, which sets the encoder's peak memory, is as small as that
    count allows (10,000 frames: 5,120 and 4,880)."""
    count = -(-num_frames // WINDOW_FRAMES)
    length = -(-num_frames // count)
    rounded = -(-length // segment_frames) * segment_frames
    return rounded if rounded < num_frames and -(-num_frames // rounded) == count else length


def encode(num_frames: int, segment_frames: int,
           encode_window: Callable[[int, int], tuple[bytes, dict]]) -> tuple[bytes, list[dict]]:
    """The windowed payload of a capture of ``num_frames`` > :data:`WINDOW_FRAMES` frames, and every window's stats.

    ``encode_window(start, stop) -> (payload, stats)`` codes frames ``start:stop`` (windows of
    :func:`window_length` frames, back to back) as a one-window ``mcb-rot`` payload; it is called window after
    window, so only one window's arrays live at once.
    """
    if num_frames <= WINDOW_FRAMES:
        raise ValueError(f"mcb-rot: windows of {WINDOW_FRAMES} frames are for captures longer than that, "
                         f"not {num_frames} frames.")
    window_frames = window_length(num_frames, segment_frames)
    head = ByteWriter()
    head.write_u8(MARKER)
    head.write_varints([LAYOUT_VERSION, window_frames])
    body, stats = windows.encode_frame_windows(num_frames, window_frames, encode_window)
    return head.getvalue() + body, stats


def read_windows(payload: memoryview, num_frames: int) -> tuple[int, list[Window]]:
    """The window length and ``(start, stop, window payload)`` of every window of a windowed payload.

    Every extent is checked against the payload before anything is decoded.

    Raises
    ------
    BitstreamError
        If the layout version is unknown, the window length is not in ``1 .. num_frames - 1``, a window's size runs
        past the payload, or bytes are left over after the last window.
    """
    reader = ByteReader(payload)
    if reader.read_u8("window marker") != MARKER:
        raise BitstreamError("mcb-rot: the payload does not start with the window marker.")
    version = reader.read_varint("window layout version")
    if version != LAYOUT_VERSION:
        raise BitstreamError(f"mcb-rot: expected window layout version {LAYOUT_VERSION}, found {version}.")
    window_frames = reader.read_varint("window frames")
    if not 1 <= window_frames < num_frames:
        raise BitstreamError(f"mcb-rot: expected windows of 1..{num_frames - 1} frames for a capture of "
                             f"{num_frames} frames, found {window_frames}.")
    # At least one byte per window (its size): a hostile window length cannot ask for more windows than bytes.
    if -(-num_frames // window_frames) > len(payload) - reader.offset:
        raise BitstreamError(f"mcb-rot: windows of {window_frames} frames make {-(-num_frames // window_frames)} "
                             f"windows, more than the {len(payload) - reader.offset} bytes left.")
    try:
        parts = windows.split_windows(payload[reader.offset :], num_frames, window_frames)
    except BitstreamError as error:  # one line that says whose stream and which layout
        raise BitstreamError(f"mcb-rot: windows of {window_frames} frames: {error}") from error
    return window_frames, parts


def window_header(header: Header, start: int, stop: int) -> Header:
    """The header a window ``start:stop`` of a stream is decoded with (its own frame count)."""
    return Header(header.codec, stop - start, header.num_joints, header.fps)


def windows_of_range(parts: list[Window], start: int, stop: int) -> list[Window]:
    """The windows holding any of the frames ``start:stop``, in order."""
    firsts = np.array([first for first, _, _ in parts])
    low = int(np.searchsorted(firsts, start, side="right")) - 1
    high = int(np.searchsorted(firsts, stop, side="left"))
    return parts[low:high]


def merged_stats(stats: list[dict]) -> dict:
    """One stats row for a windowed capture from its windows' rows: counts summed, the slack the smallest, the
    step multiplier the median over windows, and the number of windows."""
    merged = {"windows": len(stats)}
    for key in ("corrections", "segments", "cuts"):
        merged[key] = int(sum(window[key] for window in stats))
    merged["bound_slack_cm"] = min(window["bound_slack_cm"] for window in stats)
    merged["step_multiplier"] = float(np.median([window["step_multiplier"] for window in stats]))
    return merged
