"""Long captures coded as a sequence of length-prefixed windows of frames (bounded memory at any length).

A codec whose working set grows with the clip (a rate search over a whole-clip transform, a pose model over every
frame) codes a capture longer than its window as independent windows, each payload prefixed by its length, so
the encoder holds one window's arrays and the decoder one window's temporaries beside its output. Windows are
back to back unless the codec gives their ``(start, stop)`` extents (``pga-ik``'s last window overlaps the one
before it); the decoder passes the same extents to :func:`split_windows`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

from mocapbench.entropy.bitio import ByteReader, ByteWriter
from mocapbench.motion import Motion

__all__ = ["WINDOW_FRAMES", "encode_frame_windows", "encode_windows", "split_windows"]

#: Frames of a window of a long capture (64 s at 120 fps; a multiple of the usual clip lengths 60, 120, 240, 256).
WINDOW_FRAMES = 7680

Extents = Sequence[tuple[int, int]]


def _extents(num_frames: int, window_frames: int, extents: Extents | None) -> Extents:
    """``extents`` if given (``(start, stop)`` of every window, in order), else back-to-back windows."""
    if extents is not None:
        return extents
    return [(start, min(num_frames, start + window_frames)) for start in range(0, num_frames, window_frames)]


def encode_windows(
    motion: Motion, window_frames: int, encode_window: Callable[[Motion], tuple[bytes, dict]],
    extents: Extents | None = None,
) -> tuple[bytes, list[dict]]:
    """Payload of ``motion`` coded window by window, and the per-window stats ``encode_window`` returned.

    ``encode_window(part) -> (payload, stats)`` codes one window of at most ``window_frames`` frames. ``extents``
    (optional) gives the windows' ``(start, stop)`` frames instead of back-to-back windows (windows may overlap).
    """
    return encode_frame_windows(
        motion.num_frames, window_frames, lambda start, stop: encode_window(motion.slice(start, stop)), extents
    )


def encode_frame_windows(
    num_frames: int, window_frames: int, encode_window: Callable[[int, int], tuple[bytes, dict]],
    extents: Extents | None = None,
) -> tuple[bytes, list[dict]]:
    """As :func:`encode_windows` for any source of frames: ``encode_window(start, stop) -> (payload, stats)`` codes
    frames ``start:stop`` (at most ``window_frames`` of them), e.g. a slice of a positions array."""
    writer = ByteWriter()
    stats = []
    for start, stop in _extents(num_frames, window_frames, extents):
        window, window_stats = encode_window(start, stop)
        writer.write_varint(len(window))
        writer.write_bytes(window)
        stats.append(window_stats)
    return writer.getvalue(), stats


def split_windows(payload: memoryview, num_frames: int, window_frames: int,
                  extents: Extents | None = None) -> list[tuple[int, int, memoryview]]:
    """``(start, stop, window payload)`` of every window; every extent is checked before anything is decoded.

    Raises
    ------
    BitstreamError
        If a window length runs past the payload or bytes are left over.
    """
    reader = ByteReader(payload)
    windows = []
    for start, stop in _extents(num_frames, window_frames, extents):
        size = reader.read_varint("window length")
        offset = reader.offset
        reader.read_bytes(size, "window")
        windows.append((start, stop, payload[offset : offset + size]))
    reader.expect_end()
    return windows
