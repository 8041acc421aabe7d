"""ctypes calls into the compiled ACL shim (``shim.cpp``): compress, validate, decompress, time single poses.

Arrays cross the boundary as C-contiguous float32; every call returns a status, and a non-zero status comes with
one line of text from the shim, raised here as :class:`AclError` (the codec turns it into a ``BitstreamError``
on decode and a ``ValueError`` on encode).
"""

from __future__ import annotations

import ctypes
import os
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from mocapbench.codecs.acl.build import ACL_DIR_ENV, build_shim

__all__ = ["AclError", "BufferInfo", "AclLibrary", "load_library", "LEVELS", "ROTATION_FORMATS", "TRANSLATION_FORMATS"]

# ACL's serialized enum values (acl/compression/compression_level.h, acl/core/track_formats.h).
LEVELS = {"lowest": 0, "low": 1, "medium": 2, "high": 3, "highest": 4, "automatic": 100}
ROTATION_FORMATS = {"quatf_full": 0, "quatf_drop_w_full": 2, "quatf_drop_w_variable": 3}
TRANSLATION_FORMATS = {"vector3f_full": 0, "vector3f_variable": 1}

_ERROR_SIZE = 512
_f32p = ctypes.POINTER(ctypes.c_float)
_u8p = ctypes.POINTER(ctypes.c_uint8)
_u32 = ctypes.c_uint32


class AclError(RuntimeError):
    """The shim refused an input or a buffer; the message is its one line."""


@dataclass(frozen=True)
class BufferInfo:
    """Facts of a validated ACL buffer."""

    num_tracks: int
    num_samples: int
    sample_rate: float
    rotation_format: str
    translation_format: str


def _name_of(table: dict[str, int], value: int) -> str:
    return next((name for name, code in table.items() if code == value), f"unknown({value})")


def _pointer(array: np.ndarray, kind):
    return array.ctypes.data_as(kind)


class AclLibrary:
    """The loaded shim. Build it with :func:`load_library`."""

    def __init__(self, path: Path) -> None:
        self.path = path
        lib = ctypes.CDLL(os.fspath(path))
        lib.mcb_acl_version.restype = ctypes.c_int
        lib.mcb_acl_compress.restype = ctypes.c_int
        lib.mcb_acl_compress.argtypes = [
            _f32p, _f32p, _f32p, ctypes.POINTER(ctypes.c_int32), _u32, _u32, ctypes.c_float, ctypes.c_float,
            ctypes.c_float, ctypes.c_int, ctypes.c_int, ctypes.c_int, ctypes.c_int, ctypes.c_int, ctypes.c_int,
            ctypes.POINTER(ctypes.c_void_p), ctypes.POINTER(_u32), ctypes.c_char_p, _u32,
        ]
        lib.mcb_acl_free.restype = None
        lib.mcb_acl_free.argtypes = [ctypes.c_void_p]
        lib.mcb_acl_info.restype = ctypes.c_int
        lib.mcb_acl_info.argtypes = [
            ctypes.c_char_p, _u32, ctypes.POINTER(_u32), ctypes.POINTER(_u32), ctypes.POINTER(ctypes.c_float),
            ctypes.POINTER(ctypes.c_int), ctypes.POINTER(ctypes.c_int), ctypes.c_char_p, _u32,
        ]
        lib.mcb_acl_decompress.restype = ctypes.c_int
        lib.mcb_acl_decompress.argtypes = [
            ctypes.c_char_p, _u32, _u32, _u32, _u32, _f32p, _f32p, _f32p, ctypes.c_char_p, _u32,
        ]
        lib.mcb_acl_time_single_pose.restype = ctypes.c_int
        lib.mcb_acl_time_single_pose.argtypes = [
            ctypes.c_char_p, _u32, _u32, _u32, ctypes.POINTER(ctypes.c_double), ctypes.POINTER(ctypes.c_double),
            ctypes.POINTER(ctypes.c_float), ctypes.c_char_p, _u32,
        ]
        self._lib = lib
        self.acl_version = int(lib.mcb_acl_version())

    def compress(
        self,
        rotations: np.ndarray,
        translations: np.ndarray,
        parents: np.ndarray,
        sample_rate: float,
        *,
        scales: np.ndarray | None = None,
        precision_cm: float,
        shell_cm: float,
        level: str,
        rotation_format: str,
        translation_format: str,
        optimize_loops: bool,
        strip_trivial: bool,
        pre_process: bool = False,
    ) -> bytes:
        """ACL's compressed buffer for local transforms.

        Parameters
        ----------
        rotations : ndarray, shape (F, J, 4), float32, scalar-last unit quaternions
        translations : ndarray, shape (F, J, 3), float32, cm
        parents : ndarray, shape (J,), int32, -1 for the root
        scales : ndarray, shape (F, J, 3), float32, optional
            Local scales (> 0); ``None`` is 1 everywhere.
        pre_process : bool
            Run ACL's ``pre_process_track_list`` on the raw tracks before compressing them (recommended actions,
            lossy policy, the same qvvf error metric).
        """
        rotations = np.ascontiguousarray(rotations, dtype=np.float32)
        translations = np.ascontiguousarray(translations, dtype=np.float32)
        scales_pointer = None
        if scales is not None:
            scales = np.ascontiguousarray(scales, dtype=np.float32)
            scales_pointer = _pointer(scales, _f32p)
        parents = np.ascontiguousarray(parents, dtype=np.int32)
        num_frames, num_joints = rotations.shape[:2]
        out = ctypes.c_void_p()
        size = _u32()
        error = ctypes.create_string_buffer(_ERROR_SIZE)
        status = self._lib.mcb_acl_compress(
            _pointer(rotations, _f32p), _pointer(translations, _f32p), scales_pointer,
            _pointer(parents, ctypes.POINTER(ctypes.c_int32)), num_joints, num_frames, sample_rate, precision_cm,
            shell_cm, LEVELS[level], ROTATION_FORMATS[rotation_format], TRANSLATION_FORMATS[translation_format],
            int(optimize_loops), int(strip_trivial), int(pre_process), ctypes.byref(out), ctypes.byref(size), error,
            _ERROR_SIZE,
        )
        if status != 0:
            raise AclError(error.value.decode(errors="replace"))
        try:
            return ctypes.string_at(out.value, size.value)
        finally:
            self._lib.mcb_acl_free(out)

    def info(self, buffer: bytes) -> BufferInfo:
        """Validate ``buffer`` (size field, tag, version, hash) and return its facts; :class:`AclError` if invalid."""
        tracks, samples, rate = _u32(), _u32(), ctypes.c_float()
        rotation, translation = ctypes.c_int(), ctypes.c_int()
        error = ctypes.create_string_buffer(_ERROR_SIZE)
        status = self._lib.mcb_acl_info(
            buffer, len(buffer), ctypes.byref(tracks), ctypes.byref(samples), ctypes.byref(rate),
            ctypes.byref(rotation), ctypes.byref(translation), error, _ERROR_SIZE,
        )
        if status != 0:
            raise AclError(error.value.decode(errors="replace"))
        return BufferInfo(
            tracks.value, samples.value, float(rate.value),
            _name_of(ROTATION_FORMATS, rotation.value), _name_of(TRANSLATION_FORMATS, translation.value),
        )

    def decompress(
        self, buffer: bytes, num_joints: int, start: int, stop: int, *, scales: bool = False
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """Frames ``start:stop`` through ACL's decompression context (nearest sample, as ACL's own error check).

        Returns
        -------
        rotations : ndarray, shape (stop - start, J, 4), float32
        translations : ndarray, shape (stop - start, J, 3), float32, cm
        scales : ndarray, shape (stop - start, J, 3), float32, or None unless ``scales``
        """
        count = stop - start
        rotations = np.empty((count, num_joints, 4), dtype=np.float32)
        translations = np.empty((count, num_joints, 3), dtype=np.float32)
        scale_array = np.empty((count, num_joints, 3), dtype=np.float32) if scales else None
        error = ctypes.create_string_buffer(_ERROR_SIZE)
        status = self._lib.mcb_acl_decompress(
            buffer, len(buffer), num_joints, start, stop, _pointer(rotations, _f32p), _pointer(translations, _f32p),
            None if scale_array is None else _pointer(scale_array, _f32p), error, _ERROR_SIZE,
        )
        if status != 0:
            raise AclError(error.value.decode(errors="replace"))
        return rotations, translations, scale_array

    def time_single_pose(self, buffer: bytes, num_frames: int, repeats: int) -> tuple[float, float]:
        """Wall and process-CPU seconds of ``repeats`` single-pose decodes (seek + decompress_tracks) in C."""
        wall, cpu, checksum = ctypes.c_double(), ctypes.c_double(), ctypes.c_float()
        error = ctypes.create_string_buffer(_ERROR_SIZE)
        status = self._lib.mcb_acl_time_single_pose(
            buffer, len(buffer), num_frames, repeats, ctypes.byref(wall), ctypes.byref(cpu), ctypes.byref(checksum),
            error, _ERROR_SIZE,
        )
        if status != 0:
            raise AclError(error.value.decode(errors="replace"))
        return wall.value, cpu.value


@lru_cache(maxsize=None)
def _load(acl_dir: str, env_value: str | None, cwd: str) -> AclLibrary:
    return AclLibrary(build_shim(acl_dir or None))


def load_library(acl_dir: str | None = None) -> AclLibrary:
    """The shim built against ``acl_dir`` (or the default ACL folder), compiled on the first call of a process
    (and found in the cache by later processes)."""
    return _load(acl_dir or "", os.environ.get(ACL_DIR_ENV), os.getcwd())
