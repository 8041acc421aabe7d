"""The pose parameterization of the neural Fourier paper (Tojo, Chen, Umetani, §3), shared by its codecs.

Per frame ``y ∈ R^m`` with ``m = 3 + 4 + 3 (J - 1)``:

* root translation (3, cm);
* root rotation as a unit quaternion (4, scalar-last), its sign chosen per frame to be the closer (L2) of
  ``±q`` to the previous frame's quaternion, so that the track has no jumps (§3, "Pose Parameterization");
* the local rotation of every other joint as an axis-angle vector (3, radians).

The loss weights ``w`` of eq. (3) are 1 for the translation and, for each joint's rotation parameters, the
distance from that joint to the farthest of its descendants' positions in the first frame. "Descendants"
here includes the skeleton's end sites below the joint (the ends of the child bones), so that a leaf joint
with an end site (toes, head, fingers) has a non-zero weight; a leaf without any end site gets weight 0
(its rotation moves no point). The paper does not say how leaves are treated; this is our reading.

It also holds the quantized storage of real-valued tensors both codecs write (:func:`write_tensor` /
:func:`read_tensor`: IEEE float16, or uniform n-bit indices over the tensor's own float32 range, bit-packed), and
:func:`quantize_tensor`, which returns exactly the values a decoder will read, so that an encoder can measure the
error of what it writes.

This module is numpy-only: both :mod:`mocapbench.codecs.neural_fourier.svd` and :mod:`mocapbench.codecs.neural_fourier.codec`
use it, and decoders run without torch.
"""

from __future__ import annotations

import numpy as np
from mocapbench.lazy_imports import Rotation

from mocapbench.entropy.quantize import RangeQuantizer
from mocapbench.motion import Motion, OwnedQuaternions, Skeleton

__all__ = [
    "num_pose_parameters",
    "pose_matrix",
    "pose_weights",
    "motion_from_pose_matrix",
    "motion_from_pose_blocks",
    "POSE_BLOCK_FRAMES",
    "TENSOR_FORMATS",
    "read_tensor_format",
    "quantize_tensor",
    "write_tensor",
    "read_tensor",
]


def num_pose_parameters(num_joints: int) -> int:
    """m, the length of one frame's pose vector: ``3 + 4 + 3 (J - 1)``."""
    if num_joints < 1:
        raise ValueError(f"`num_joints` must be >= 1, got {num_joints}.")
    return 3 + 4 + 3 * (num_joints - 1)


def pose_matrix(motion: Motion) -> np.ndarray:
    """The pose matrix Y of a motion (§3).

    Parameters
    ----------
    motion : Motion

    Returns
    -------
    ndarray, shape (F, m), float64
        Columns: root translation (cm, 3), root quaternion (x, y, z, w, sign-continuous, 4), axis-angle of
        joints 1..J-1 (radians, 3 each, in ``[0, π]`` of angle).
    """
    root_quat = motion.rotations[:, 0].copy()
    # Sign continuity: flip q_f when -q_f is closer (L2) to q_{f-1}, i.e. when their dot product is negative.
    for frame in range(1, motion.num_frames):
        if np.dot(root_quat[frame], root_quat[frame - 1]) < 0:
            root_quat[frame] = -root_quat[frame]
    num_frames, num_joints = motion.num_frames, motion.num_joints
    rotvecs = Rotation.from_quat(motion.rotations[:, 1:].reshape(-1, 4)).as_rotvec()
    return np.concatenate(
        [motion.root_positions, root_quat, rotvecs.reshape(num_frames, 3 * (num_joints - 1))], axis=1
    )


def pose_weights(motion: Motion) -> np.ndarray:
    """The loss weights ``w`` of eq. (3), one per pose parameter.

    Parameters
    ----------
    motion : Motion
        Only its first frame is used.

    Returns
    -------
    ndarray, shape (m,), float64
        1 for the 3 translation columns; for joint j's rotation columns (4 for the root, 3 for the others)
        the largest distance (cm) in the first frame from joint j to a joint or end site below it.
    """
    skeleton: Skeleton = motion.skeleton
    first = motion.slice(0, 1)
    joints = first.positions()[0]
    ends = first.end_site_positions()[0] if len(skeleton.end_site_parents) else np.zeros((0, 3))
    # below[j] = the points (joints and end sites) in the subtree of j, j excluded.
    reach = np.zeros(skeleton.num_joints)
    for j in range(skeleton.num_joints):
        below = skeleton.descendants(j)
        points = [joints[below]]
        subtree = set(below) | {j}
        end_mask = np.array([int(p) in subtree for p in skeleton.end_site_parents], dtype=bool)
        if end_mask.size:
            points.append(ends[end_mask])
        stacked = np.concatenate(points, axis=0)
        if len(stacked):
            reach[j] = float(np.linalg.norm(stacked - joints[j], axis=1).max())
    return np.concatenate([np.ones(3), np.full(4, reach[0]), np.repeat(reach[1:], 3)])


def motion_from_pose_matrix(y: np.ndarray, skeleton: Skeleton, fps: float, name: str = "") -> Motion:
    """Map decoded pose parameters back to a :class:`Motion` (the quaternion is normalized).

    Parameters
    ----------
    y : ndarray, shape (F, m), float
        Pose matrix as laid out by :func:`pose_matrix`.
    skeleton : Skeleton
    fps : float

    Returns
    -------
    Motion

    Raises
    ------
    ValueError
        If ``y`` has the wrong width, holds non-finite values, or a root quaternion of (near) zero norm.
    """
    y = np.asarray(y, dtype=np.float64)
    m = num_pose_parameters(skeleton.num_joints)
    if y.ndim != 2 or y.shape[1] != m:
        raise ValueError(f"Expected the pose matrix to have shape (F, {m}), got {y.shape}.")
    return motion_from_pose_blocks(len(y), lambda start, stop: y[start:stop], skeleton, fps, name)


#: Frames per block when a decoder turns pose rows into a motion: the rows and scipy's rotation temporaries exist
#: for one block at a time (about 1 MB for 31 joints), never for the whole clip.
POSE_BLOCK_FRAMES = 1024


def motion_from_pose_blocks(num_frames: int, rows, skeleton: Skeleton, fps: float, name: str = "") -> Motion:
    """A :class:`Motion` from pose rows made block by block: ``rows(start, stop)`` gives ``y[start:stop]``.

    Memory is the motion's own arrays (root positions ``(F, 3)``, quaternions ``(F, J, 4)``, float64) plus one
    block of :data:`POSE_BLOCK_FRAMES` rows and its temporaries: the pose matrix of a long capture is never held.
    The quaternions are handed to :class:`Motion` for keeps (:class:`~mocapbench.motion.OwnedQuaternions`), so
    they are normalized in place, not copied.

    Parameters
    ----------
    num_frames : int
        F >= 1.
    rows : callable ``(start, stop) -> ndarray, shape (stop - start, m)``
        Pose rows as laid out by :func:`pose_matrix`; the block may be a temporary (it is not kept).
    skeleton : Skeleton
    fps : float

    Raises
    ------
    ValueError
        If a block has the wrong shape, holds non-finite values, or a root quaternion of (near) zero norm.
    """
    m = num_pose_parameters(skeleton.num_joints)
    roots = np.empty((num_frames, 3))
    quats = np.empty((num_frames, skeleton.num_joints, 4))
    for start in range(0, num_frames, POSE_BLOCK_FRAMES):
        stop = min(num_frames, start + POSE_BLOCK_FRAMES)
        y = np.asarray(rows(start, stop), dtype=np.float64)
        if y.ndim != 2 or y.shape != (stop - start, m):
            raise ValueError(f"Expected the pose matrix to have shape (F, {m}), got {y.shape} for frames {start}:{stop}.")
        if not np.all(np.isfinite(y)):
            raise ValueError("The decoded pose matrix holds non-finite values.")
        root_quat = y[:, 3:7]
        norms = np.linalg.norm(root_quat, axis=1, keepdims=True)
        if np.any(norms < 1e-8):
            raise ValueError(f"Decoded root quaternion of (near) zero norm at frame {start + int(np.argmin(norms))}.")
        roots[start:stop] = y[:, :3]
        quats[start:stop, 0] = root_quat / norms
        if skeleton.num_joints > 1:
            quats[start:stop, 1:] = Rotation.from_rotvec(y[:, 7:].reshape(-1, 3)).as_quat().reshape(stop - start, -1, 4)
    return Motion(skeleton=skeleton, fps=fps, root_positions=roots, rotations=OwnedQuaternions(quats), name=name)


# -- quantized storage of real-valued tensors (network weights, SVD factors) -------------------------------------

#: Storage formats of :func:`write_tensor`.
TENSOR_FORMATS = ("float16", "uniform")


def quantize_tensor(values: np.ndarray, fmt: str, bits: int) -> np.ndarray:
    """The values a decoder will read back after :func:`write_tensor` (float64, same shape).

    Parameters
    ----------
    values : ndarray, any shape, float, finite
    fmt : {"float16", "uniform"}
        ``"float16"``: IEEE half precision. ``"uniform"``: ``bits``-bit indices over the tensor's own
        ``[min, max]``, the range stored as float32.
    bits : int
        Bits per value for ``"uniform"`` (2..16); ignored for ``"float16"``.
    """
    values = np.asarray(values, dtype=np.float64)
    if not np.all(np.isfinite(values)):
        raise ValueError("quantize_tensor: the tensor holds non-finite values.")
    if fmt == "float16":
        if values.size and np.abs(values).max() > 65504.0:
            raise ValueError(f"quantize_tensor: |value| {np.abs(values).max():.4g} overflows float16 (max 65504).")
        return values.astype(np.float16).astype(np.float64)
    if fmt != "uniform":
        raise ValueError(f"quantize_tensor: `fmt` must be one of {TENSOR_FORMATS}, got {fmt!r}.")
    if not 2 <= bits <= 16:
        raise ValueError(f"quantize_tensor: `bits` must be in [2, 16] for the uniform format, got {bits}.")
    if values.size == 0:
        return values.copy()
    low, high = _uniform_range(values)
    quantizer = RangeQuantizer(bits, low, high)
    return quantizer.dequantize(quantizer.quantize(values))


def _uniform_range(values: np.ndarray) -> tuple[float, float]:
    """``[min, max]`` of ``values`` widened to float32-representable ends (they are stored as float32)."""
    low32, high32 = np.float32(values.min()), np.float32(values.max())
    if low32 > values.min():
        low32 = np.nextafter(low32, np.float32(-np.inf), dtype=np.float32)
    if high32 < values.max():
        high32 = np.nextafter(high32, np.float32(np.inf), dtype=np.float32)
    return float(low32), float(high32)


def write_tensor(writer, values: np.ndarray, fmt: str, bits: int) -> None:
    """Append ``values`` (shape known to the reader) to a :class:`~mocapbench.entropy.bitio.ByteWriter`.

    Layout: ``"float16"``: the raw little-endian halves. ``"uniform"``: low and high (float32), then the
    ``bits``-bit indices, MSB first, padded to a byte (a varint-length blob).
    """
    from mocapbench.entropy.bitio import BitWriter

    values = np.asarray(values, dtype=np.float64)
    if fmt == "float16":
        quantize_tensor(values, fmt, bits)  # range check
        writer.write_array(values, np.float16)
        return
    quantize_tensor(values, fmt, bits)  # validation
    if values.size == 0:
        return
    low, high = _uniform_range(values)
    writer.write_array(np.array([low, high]), np.float32)
    bit_writer = BitWriter()
    bit_writer.write_array(RangeQuantizer(bits, low, high).quantize(values.ravel()), bits)
    writer.write_blob(bit_writer.getvalue())


def read_tensor_format(reader, codec: str, what: str) -> tuple[str, int]:
    """Read the storage format and bit depth that :func:`write_tensor`'s caller wrote before its tensors.

    Parameters
    ----------
    reader : ByteReader
    codec : str
        The codec's name, for the message.
    what : str
        What the tensors are (``"weight"``, ``"factor"``), for the message.

    Returns
    -------
    (fmt, bits) : one of :data:`TENSOR_FORMATS`, and 2..16 for ``"uniform"`` (0 for ``"float16"``).

    Raises
    ------
    BitstreamError
        If the format code is unknown or the bit depth does not fit the format.
    """
    from mocapbench.entropy.errors import BitstreamError

    code = reader.read_u8(f"{what} format")
    if code >= len(TENSOR_FORMATS):
        raise BitstreamError(f"{codec}: {what} format code must be < {len(TENSOR_FORMATS)}, found {code}.")
    fmt = TENSOR_FORMATS[code]
    bits = reader.read_u8(f"{what} bits")
    if (fmt == "uniform") != (2 <= bits <= 16) or (fmt == "float16" and bits != 0):
        raise BitstreamError(f"{codec}: {what} bits {bits} do not fit the {fmt} format.")
    return fmt, bits


def read_tensor(reader, shape: tuple[int, ...], fmt: str, bits: int, what: str) -> np.ndarray:
    """Read a tensor written by :func:`write_tensor` from a :class:`~mocapbench.entropy.bitio.ByteReader`.

    Returns
    -------
    ndarray, shape ``shape``, float64

    Raises
    ------
    BitstreamError
        If the data is short, or holds non-finite values or an inverted range.
    """
    from mocapbench.entropy.bitio import BitReader
    from mocapbench.entropy.errors import BitstreamError

    count = int(np.prod(shape, dtype=np.int64))
    if fmt == "float16":
        values = reader.read_array(count, np.float16, what).astype(np.float64)
    else:
        if count == 0:
            return np.zeros(shape)
        low, high = (float(v) for v in reader.read_array(2, np.float32, f"range of {what}"))
        if not (np.isfinite(low) and np.isfinite(high) and low <= high):
            raise BitstreamError(f"{what}: expected a finite range low <= high, found [{low}, {high}].")
        blob = reader.read_blob(what)
        expected = (count * bits + 7) // 8
        if len(blob) != expected:
            raise BitstreamError(f"{what}: expected {expected} bytes of {bits}-bit indices, found {len(blob)}.")
        indices = BitReader(blob).read_array(count, bits, what).astype(np.int64)
        values = RangeQuantizer(bits, low, high).dequantize(indices)
    if not np.all(np.isfinite(values)):
        raise BitstreamError(f"{what}: the stream holds non-finite values.")
    return values.reshape(shape)
