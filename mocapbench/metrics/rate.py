"""Rate metrics: one written definition of the raw size, and the papers' own raw definitions.

The canonical raw size used in every mocapbench comparison is **float32 joint positions**: ``12 * J * F``
bytes (96 bits per joint per frame, as in the LSDT paper, §5). The papers' own definitions are here too so
that their figures can be reproduced next to ours, and are labelled as theirs wherever they are shown.
"""

from __future__ import annotations

__all__ = [
    "RAW_BITS_PER_JOINT_FRAME",
    "raw_position_bytes",
    "compression_ratio",
    "bits_per_joint_frame",
    "neural_fourier_pose_parameters",
    "pga_raw_numbers",
]

RAW_BITS_PER_JOINT_FRAME = 96  # float32 x, y, z


def _positive_int(name: str, value) -> int:
    if isinstance(value, bool) or int(value) != value or value <= 0:
        raise ValueError(f"`{name}` must be a positive integer, got {value!r}.")
    return int(value)


def raw_position_bytes(num_joints: int, num_frames: int) -> int:
    """Canonical raw size: float32 joint positions, ``12 * J * F`` bytes."""
    return 12 * _positive_int("num_joints", num_joints) * _positive_int("num_frames", num_frames)


def compression_ratio(raw_bytes: int, bitstream_bytes: int) -> float:
    """``raw_bytes / bitstream_bytes``: how many times smaller the real bitstream is."""
    return _positive_int("raw_bytes", raw_bytes) / _positive_int("bitstream_bytes", bitstream_bytes)


def bits_per_joint_frame(bitstream_bytes: int, num_joints: int, num_frames: int) -> float:
    """Bits of bitstream per joint per frame (96 = the raw float32 positions)."""
    bits = 8 * _positive_int("bitstream_bytes", bitstream_bytes)
    return bits / (_positive_int("num_joints", num_joints) * _positive_int("num_frames", num_frames))


def neural_fourier_pose_parameters(num_joints: int, num_frames: int) -> int:
    """Size of the neural Fourier paper's pose matrix Y, in numbers (its raw definition, §3).

    Per frame: root translation (3) + root quaternion (4) + an axis-angle (3) per child joint.
    The paper's compression ratio is this divided by the number of network parameters.
    """
    joints = _positive_int("num_joints", num_joints)
    return _positive_int("num_frames", num_frames) * (3 + 4 + 3 * (joints - 1))


def pga_raw_numbers(num_markers: int, num_frames: int) -> int:
    """The PGA paper's raw size ``3 (m + 1) n`` in numbers (§3.6): m joint positions + the root, n frames."""
    return 3 * (_positive_int("num_markers", num_markers) + 1) * _positive_int("num_frames", num_frames)
