"""Unit-quaternion arithmetic for ``mcb-rot`` (scalar-last ``(x, y, z, w)``, as scipy), vectorized over any leading axes.

Encoder and decoder call these same functions, so both compute bit-identical rotations on one machine. Only
elementwise numpy operations are used (no BLAS reductions whose summation order could change with the thread
count).
"""

from __future__ import annotations

import numpy as np

__all__ = ["multiply", "cross", "rotate", "conjugate", "norm3", "exp_map", "log_map", "angle", "sign_continuous", "as_matrix", "from_matrix"]


def multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product ``a b`` of quaternions, shapes (..., 4) broadcast; the rotation ``b`` then ``a``."""
    ax, ay, az, aw = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    bx, by, bz, bw = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    return np.stack(
        [
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz,
        ],
        axis=-1,
    )


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross products of vectors (..., 3), componentwise (faster than np.cross on small trailing axes)."""
    ax, ay, az = a[..., 0], a[..., 1], a[..., 2]
    bx, by, bz = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx], axis=-1)


def rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Vectors ``v`` (..., 3) turned by unit quaternions ``q`` (..., 4), shapes broadcast."""
    u, w = q[..., :3], q[..., 3:]
    t = 2.0 * cross(u, v)
    return v + w * t + cross(u, t)


def conjugate(q: np.ndarray) -> np.ndarray:
    """Inverse of unit quaternions (..., 4)."""
    return q * np.array([-1.0, -1.0, -1.0, 1.0])


def norm3(v: np.ndarray) -> np.ndarray:
    """Euclidean norms (...) of vectors (..., 3), summed x + y + z as ``np.sum`` does (same bits, several times
    faster: numpy reductions over a trailing axis of 3 pay a loop setup per vector)."""
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    return np.sqrt(x * x + y * y + z * z)


def exp_map(rotvec: np.ndarray) -> np.ndarray:
    """Unit quaternions (..., 4) of rotation vectors (..., 3) in radians (any length: the map is 4 pi periodic)."""
    angle_ = norm3(rotvec)
    half = 0.5 * angle_
    small = angle_ < 1e-6
    # sin(theta/2)/theta, with its Taylor series near 0 (exact to float precision below 1e-6 rad).
    scale = np.where(small, 0.5 - angle_ * angle_ / 48.0, np.sin(half) / np.where(small, 1.0, angle_))
    return np.concatenate([rotvec * scale[..., None], np.cos(half)[..., None]], axis=-1)


def log_map(q: np.ndarray) -> np.ndarray:
    """Rotation vectors (..., 3) of quaternions (..., 4), *without* choosing the short way.

    A quaternion with ``w < 0`` maps to an angle in (pi, 2 pi): along a sign-continuous quaternion track
    (:func:`sign_continuous`) the rotation vectors are then continuous through half turns, which is what a
    transform along time needs. Call it on ``q * sign(w)`` for the usual angle in [0, pi].
    """
    vector = q[..., :3]
    norm = norm3(vector)
    angle_ = 2.0 * np.arctan2(norm, q[..., 3])
    small = norm < 1e-9
    scale = np.where(small, 2.0 / np.where(small, q[..., 3], 1.0), angle_ / np.where(small, 1.0, norm))
    return vector * scale[..., None]


def angle(q: np.ndarray) -> np.ndarray:
    """Rotation angle in [0, pi] (radians) of quaternions (..., 4)."""
    norm = norm3(q)
    return 2.0 * np.arctan2(norm, np.abs(q[..., 3]))


def sign_continuous(q: np.ndarray) -> np.ndarray:
    """Quaternions (F, ..., 4) with signs flipped so that consecutive frames have a non-negative dot product.

    ``q`` and ``-q`` are the same rotation; input tracks (a BVH reader's Euler angles wrapping at +-180 deg, another
    tool's canonical ``w >= 0``) can flip sign between frames, which would put a jump into any transform along time.
    """
    if len(q) < 2:
        return np.array(q, dtype=np.float64)
    dots = np.sum(q[1:] * q[:-1], axis=-1)
    flips = np.concatenate([np.ones((1,) + dots.shape[1:]), np.where(dots < 0, -1.0, 1.0)])
    return q * np.cumprod(flips, axis=0)[..., None]


def as_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) of unit quaternions (..., 4)."""
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], axis=-1),
            np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], axis=-1),
            np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], axis=-1),
        ],
        axis=-2,
    )


def from_matrix(matrix: np.ndarray) -> np.ndarray:
    """Unit quaternions (..., 4), ``w >= 0``, of rotation matrices (..., 3, 3) (via scipy)."""
    from scipy.spatial.transform import Rotation

    q = Rotation.from_matrix(matrix.reshape(-1, 3, 3)).as_quat().reshape(matrix.shape[:-2] + (4,))
    return q * np.where(q[..., 3:] < 0, -1.0, 1.0)
