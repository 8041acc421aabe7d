"""Per-joint principal axes: the rotation-vector channels of each joint turned onto its axes of motion.

A knee or an elbow bends about one axis (a 1-DOF joint in the ASF), which is fixed in the joint's frame but not a
coordinate axis: its rotation vector moves along one line, yet all three of its components move, and a transform
coder pays for three signals. Turning each joint's three channels by an orthonormal matrix ``V_j`` (the eigenvectors
of the covariance of its rotation vectors over the clip, largest first) puts a 1-DOF joint's motion in one channel and
leaves two near-empty ones that cost almost nothing. ``V_j`` is orthonormal, so quantization errors keep their length
and the error budgets hold unchanged. Each ``V_j`` travels as a rotation vector of three int16 (step pi / 32768); the
decoder rebuilds the same matrix from them.
"""

from __future__ import annotations

import numpy as np

from mocapbench.codecs.mcb_rot import quaternions as quat

__all__ = ["AXIS_STEP", "principal_axes", "axes_from_codes", "to_axes", "from_axes"]

AXIS_STEP = np.pi / 32768
_DEGENERATE = 1e-6  # an eigenvalue this small relative to the largest marks a missing degree of freedom


def principal_axes(rotvecs: np.ndarray) -> np.ndarray:
    """int16 codes (J, 3) of each joint's principal axes from rotation vectors (F, J, 3); zeros where still."""
    num_joints = rotvecs.shape[1]
    codes = np.zeros((num_joints, 3), dtype=np.int64)
    if len(rotvecs) < 2:
        return codes
    centred = rotvecs - rotvecs.mean(axis=0)
    covariance = np.einsum("fji,fjk->jik", centred, centred)
    values, vectors = np.linalg.eigh(covariance)  # ascending
    vectors = vectors[:, :, ::-1]
    vectors[:, :, 2] *= np.sign(np.linalg.det(vectors))[:, None]  # a proper rotation
    # Only joints with a direction they never move along (fewer than 3 degrees of freedom): on a 3-DOF joint
    # the turn gains less than its 6 bytes.
    moving = (values[:, -1] > 1e-12) & (values[:, 0] < _DEGENERATE * values[:, -1])
    rotvec = quat.log_map(quat.from_matrix(vectors))
    codes[moving] = np.clip(np.round(rotvec[moving] / AXIS_STEP), -32767, 32767).astype(np.int64)
    return codes


def axes_from_codes(codes: np.ndarray) -> np.ndarray:
    """Orthonormal matrices (J, 3, 3) from int16 codes (J, 3) (columns: the axes)."""
    return quat.as_matrix(quat.exp_map(codes * AXIS_STEP))


def to_axes(rotvecs: np.ndarray, axes: np.ndarray) -> np.ndarray:
    """Components (..., J, 3) of rotation vectors (..., J, 3) on each joint's axes (J, 3, 3)."""
    return np.sum(rotvecs[..., :, None] * axes, axis=-2)


def from_axes(components: np.ndarray, axes: np.ndarray) -> np.ndarray:
    """Inverse of :func:`to_axes`."""
    return np.sum(components[..., None, :] * axes, axis=-1)
