"""Motion file readers and writers: BVH (:mod:`mocapbench.io.bvh`) and Acclaim ASF/AMC (:mod:`mocapbench.io.asf_amc`).

Every reader returns a :class:`mocapbench.motion.Motion` in centimetres with scalar-last quaternions and
raises :class:`mocapbench.motion.MotionFormatError` (a ``ValueError``) naming the file, the line and what
was expected when the input is malformed; a missing file raises :class:`MotionFileNotFoundError`, which
is both a ``MotionFormatError`` and a ``FileNotFoundError``.
"""

from mocapbench.io.asf_amc import CMU_CM_PER_UNIT, AsfSkeleton, find_asf, read_amc, read_asf
from mocapbench.io.bvh import read_bvh, write_bvh
from mocapbench.io.text import MotionFileNotFoundError, read_text

__all__ = [
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
