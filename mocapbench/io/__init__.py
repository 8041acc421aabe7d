"""Motion file readers and writers. :func:`read_motion` is the reader to use: every format by its suffix (BVH, AMC,
glTF/GLB, FBX), the unit and up axis recorded and checked (:mod:`mocapbench.io.formats`); the per-format readers
(:func:`read_bvh`, :func:`read_amc`, ...) check nothing about units.

Every reader returns a :class:`mocapbench.motion.Motion` in centimetres with scalar-last quaternions and
raises :class:`mocapbench.motion.MotionFormatError` (a ``ValueError``) naming the file, the line and what
was expected when the input is malformed; a missing file raises :class:`MotionFileNotFoundError`, which
is both a ``MotionFormatError`` and a ``FileNotFoundError``.
"""

from mocapbench.io.asf_amc import CMU_CM_PER_UNIT, AsfSkeleton, find_asf, read_amc, read_asf
from mocapbench.io.bvh import read_bvh, write_bvh
from mocapbench.io.formats import READ_SUFFIXES, WRITE_SUFFIXES, UnitCheckError, read_motion, write_motion
from mocapbench.io.text import MotionFileNotFoundError, read_text

__all__ = [
    "read_motion",
    "write_motion",
    "READ_SUFFIXES",
    "WRITE_SUFFIXES",
    "UnitCheckError",
    "MotionFileNotFoundError",
    "read_text",
    "read_bvh",
    "write_bvh",
    "AsfSkeleton",
    "read_asf",
    "read_amc",
    "find_asf",
    "CMU_CM_PER_UNIT",
]
