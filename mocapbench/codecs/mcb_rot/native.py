"""The native runtime (``runtime/``, C) from Python: built on first use, loaded with ctypes, one context per stream.

``mcb-rot`` decodes format 6 streams through the runtime when it is available: the same entropy decoding, synthesis,
re-references and corrections as the numpy decoder (:mod:`.decoder`, kept as the reference: older formats, and
every machine without a C compiler), in float64, so that both give the same rotations up to float rounding (a test
compares them on every stream the suite makes). Forward kinematics stays in Python (:mod:`.kinematics`).

The library is compiled from ``runtime/src/mcbrot.c`` with the system C compiler (``$CC``, else ``cc``, ``gcc``,
``clang``) into ``<cache>/mcbrot-<hash>/`` (:mod:`mocapbench.codecs.native_build`, as the ACL shim; the hash covers
the sources, the compiler and its flags), under a file lock, once; ``make -C runtime`` builds the same
library for an engine. Without a compiler, or when the build fails, :func:`library` returns None once, logs one line
saying why, and the numpy decoder runs. ``MOCAPBENCH_NATIVE=0`` turns the runtime off (the numpy path, e.g. to
time it).
"""

from __future__ import annotations

import ctypes
import logging
import os
from functools import cache
from pathlib import Path

import numpy as np

from mocapbench.codecs.native_build import build_library, find_program
from mocapbench.entropy.errors import BitstreamError

__all__ = ["ABI_VERSION", "RUNTIME_DIR", "library", "NativeClip", "NativeError"]

log = logging.getLogger(__name__)

ABI_VERSION = 3
RUNTIME_DIR = Path(__file__).resolve().parents[3] / "runtime"
_SOURCES = ("src/mcbrot.c", "src/mcbrot_tables.h", "include/mcbrot.h")
_FLAGS = ["-O2", "-std=c99", "-fPIC", "-shared", "-fvisibility=hidden"]
_STATUS_BITSTREAM = {2, 3, 4, 5, 9, 10}  # truncated, corrupt, not mcb-rot, format, unsupported, prior


class NativeError(RuntimeError):
    """The runtime refused a call for a reason that is not the stream's (a context too small, an argument)."""


def _compiler() -> str | None:
    return find_program((os.environ.get("CC"), "cc", "gcc", "clang"))


def _build() -> Path:
    compiler = _compiler()
    if compiler is None:
        raise RuntimeError("no C compiler found (set $CC or install gcc)")
    if not all((RUNTIME_DIR / source).is_file() for source in _SOURCES):
        raise RuntimeError(f"the runtime's sources are not in {RUNTIME_DIR}")
    parts = [(RUNTIME_DIR / source).read_bytes() for source in _SOURCES] + [compiler.encode(), " ".join(_FLAGS).encode()]
    return build_library(
        "mcbrot", "libmcbrot.so", parts,
        lambda output: [compiler, *_FLAGS, "-I", str(RUNTIME_DIR / "include"), str(RUNTIME_DIR / "src" / "mcbrot.c"),
                        "-o", output, "-lm"],
        RuntimeError, "the runtime")


@cache
def library() -> ctypes.CDLL | None:
    """The runtime, built and loaded on first use; None (and one logged line) when it cannot be."""
    if os.environ.get("MOCAPBENCH_NATIVE", "1") == "0":
        return None
    try:
        lib = ctypes.CDLL(str(_build()))
    except (RuntimeError, OSError) as error:
        log.warning("mcb-rot: the native runtime is not available (%s); decoding with numpy.", error)
        return None
    u8p, size_p = ctypes.POINTER(ctypes.c_uint8), ctypes.POINTER(ctypes.c_size_t)
    dp = ctypes.POINTER(ctypes.c_double)
    lib.mcbrot_abi_version.restype = ctypes.c_int
    lib.mcbrot_payload_context_size_with_prior.argtypes = [u8p, ctypes.c_size_t, ctypes.c_uint32, ctypes.c_uint32,
                                                           ctypes.c_double, u8p, ctypes.c_size_t, size_p,
                                                           ctypes.c_char_p, ctypes.c_size_t]
    lib.mcbrot_open_payload_with_prior.argtypes = [ctypes.c_void_p, ctypes.c_size_t, u8p, ctypes.c_size_t,
                                                   ctypes.c_uint32, ctypes.c_uint32, ctypes.c_double, u8p,
                                                   ctypes.c_size_t]
    lib.mcbrot_decode_frames.argtypes = [ctypes.c_void_p, ctypes.c_uint32, ctypes.c_uint32, dp, dp]
    lib.mcbrot_decode_pose_frames.argtypes = [ctypes.c_void_p, ctypes.c_uint32, ctypes.c_uint32, dp, dp]
    lib.mcbrot_decode_scale_frames.argtypes = [ctypes.c_void_p, ctypes.c_uint32, ctypes.c_uint32, dp]
    lib.mcbrot_message.argtypes = [ctypes.c_void_p]
    lib.mcbrot_message.restype = ctypes.c_char_p
    if lib.mcbrot_abi_version() != ABI_VERSION:
        log.warning("mcb-rot: the native runtime's ABI is %d, this module speaks %d; decoding with numpy.",
                    lib.mcbrot_abi_version(), ABI_VERSION)
        return None
    return lib


def _raise(status: int, message: str) -> None:
    if status in _STATUS_BITSTREAM:
        raise BitstreamError(message)
    raise NativeError(message)


class NativeClip:
    """One opened payload (format 6): its context (a numpy buffer) and the payload bytes it points into.

    ``prior``: the bytes of the prior a stream with flags bit 15 names (:mod:`.prior`; read at open only), or None.
    """

    def __init__(self, lib: ctypes.CDLL, payload: bytes, num_frames: int, num_joints: int, fps: float,
                 prior: bytes | None = None) -> None:
        self._lib = lib
        self._payload = bytes(payload)  # kept alive: the context points into it
        self.num_frames, self.num_joints = num_frames, num_joints
        data = (ctypes.c_uint8 * len(self._payload)).from_buffer_copy(self._payload)
        self._data = data
        size = ctypes.c_size_t()
        message = ctypes.create_string_buffer(256)
        model = None if prior is None else (ctypes.c_uint8 * len(prior)).from_buffer_copy(prior)
        model_bytes = 0 if prior is None else len(prior)
        status = lib.mcbrot_payload_context_size_with_prior(data, len(self._payload), num_frames, num_joints, fps,
                                                            model, model_bytes, ctypes.byref(size), message, 256)
        if status:
            _raise(status, message.value.decode(errors="replace"))
        self.context_bytes = size.value
        self._context = np.zeros(size.value // 8 + 2, dtype=np.float64)  # 16-aligned (numpy aligns to 16 or more)
        status = lib.mcbrot_open_payload_with_prior(self._pointer, size.value, data, len(self._payload), num_frames,
                                                    num_joints, fps, model, model_bytes)
        if status:
            _raise(status, lib.mcbrot_message(self._pointer).decode(errors="replace"))

    @property
    def _pointer(self) -> int:
        return self._context.ctypes.data

    def frames(self, start: int, stop: int, roots: np.ndarray, quats: np.ndarray) -> None:
        """Write frames ``start:stop``: roots (n, 3) cm and rotations (n, J, 4), C-contiguous float64."""
        dp = ctypes.POINTER(ctypes.c_double)
        status = self._lib.mcbrot_decode_frames(self._pointer, start, stop - start, quats.ctypes.data_as(dp),
                                                roots.ctypes.data_as(dp))
        if status:
            _raise(status, self._lib.mcbrot_message(self._pointer).decode(errors="replace"))

    def poses(self, start: int, stop: int, translations: np.ndarray, quats: np.ndarray) -> None:
        """Write frames ``start:stop`` as whole poses: translations (n, J, 3) cm (row 0 the root's, row j the joint's
        step from its parent: its track's value, else its offset) and rotations (n, J, 4), C-contiguous float64."""
        dp = ctypes.POINTER(ctypes.c_double)
        status = self._lib.mcbrot_decode_pose_frames(self._pointer, start, stop - start, quats.ctypes.data_as(dp),
                                                     translations.ctypes.data_as(dp))
        if status:
            _raise(status, self._lib.mcbrot_message(self._pointer).decode(errors="replace"))

    def scales(self, start: int, stop: int, scales: np.ndarray) -> None:
        """Write every joint's scale on frames ``start:stop`` (n, J, 3), C-contiguous float64 (1 where a joint has
        no scale track)."""
        dp = ctypes.POINTER(ctypes.c_double)
        status = self._lib.mcbrot_decode_scale_frames(self._pointer, start, stop - start, scales.ctypes.data_as(dp))
        if status:
            _raise(status, self._lib.mcbrot_message(self._pointer).decode(errors="replace"))
