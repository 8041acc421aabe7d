"""Work arrays of the ``mcb-rot`` decoder, reused from block to block and from call to call.

A fresh array of a few hundred kilobytes is mapped from the system and page-faulted in on first write, which costs
more than the arithmetic the decoder then does in it (on a 465-frame, 31-joint clip about a fifth of the decode).
A :class:`Scratch` keeps one buffer per name and hands out views of it; each thread has its own
(:func:`thread_scratch`). The buffers are sized by one block of chunks, so they do not grow with the stream.
"""

from __future__ import annotations

import math
import threading

import numpy as np

__all__ = ["Scratch", "thread_scratch"]

#: Buffers larger than this are let go after a decode (a skeleton with thousands of joints), not kept for the next.
KEEP_BYTES = 16 << 20


class Scratch:
    """Named, reusable work arrays: :meth:`take` returns an uninitialized view valid until the next take of that name."""

    def __init__(self) -> None:
        self._buffers: dict[str, np.ndarray] = {}

    def take(self, name: str, shape: tuple[int, ...], dtype=np.float64) -> np.ndarray:
        """An uninitialized array of ``shape`` and ``dtype``, a view of the buffer ``name`` (grown when too small)."""
        dtype = _DTYPES.get(dtype) or np.dtype(dtype)
        nbytes = math.prod(shape) * dtype.itemsize
        buffer = self._buffers.get(name)
        if buffer is None or buffer.nbytes < nbytes:
            buffer = self._buffers[name] = np.empty(max(nbytes, 64), dtype=np.uint8)
        return buffer[:nbytes].view(dtype).reshape(shape)

    def trim(self, keep_bytes: int = KEEP_BYTES) -> None:
        """Let go of the buffers larger than ``keep_bytes``."""
        for name in [n for n, b in self._buffers.items() if b.nbytes > keep_bytes]:
            del self._buffers[name]


_DTYPES = {np.float64: np.dtype(np.float64), bool: np.dtype(bool), np.int64: np.dtype(np.int64)}
_LOCAL = threading.local()


def thread_scratch() -> Scratch:
    """This thread's :class:`Scratch`."""
    scratch = getattr(_LOCAL, "scratch", None)
    if scratch is None:
        scratch = _LOCAL.scratch = Scratch()
    return scratch
