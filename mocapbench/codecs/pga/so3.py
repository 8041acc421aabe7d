"""Small SO(3) helpers shared by the Karcher mean, the lifting scheme and the IK solver.

Rotations are scipy :class:`~scipy.spatial.transform.Rotation` objects (scalar-last quaternions) for everything
vectorized over frames; the IK inner loop, which works on one frame of a few dozen joints, uses plain numpy
matrices through :func:`rodrigues` because a scipy call costs more than the arithmetic at that size.
"""

from __future__ import annotations

import numpy as np
from mocapbench.lazy_imports import Rotation

__all__ = ["as_rotation", "skew", "rodrigues", "relative_rotvec", "geodesic_distance"]


def as_rotation(value, name: str = "rotations") -> Rotation:
    """``value`` as a scipy Rotation: a Rotation is returned as is, an array ``(..., 4)`` is read as quaternions.

    Raises
    ------
    ValueError
        If ``value`` is neither, or holds non-finite or zero-norm quaternions.
    """
    if isinstance(value, Rotation):
        return value
    quats = np.asarray(value, dtype=np.float64)
    if quats.ndim < 1 or quats.shape[-1] != 4:
        raise ValueError(f"Expected `{name}` to be a Rotation or quaternions of shape (..., 4), got {quats.shape}.")
    if not np.all(np.isfinite(quats)):
        raise ValueError(f"`{name}` holds non-finite quaternion components.")
    if np.any(np.linalg.norm(quats, axis=-1) < 1e-8):
        raise ValueError(f"Found zero-norm quaternions in `{name}`.")
    return Rotation.from_quat(quats)


def skew(vectors: np.ndarray) -> np.ndarray:
    """Cross-product matrices ``[v]x``.

    Parameters
    ----------
    vectors : ndarray, shape (..., 3)

    Returns
    -------
    ndarray, shape (..., 3, 3)
        ``skew(v) @ w == np.cross(v, w)``.
    """
    v = np.asarray(vectors, dtype=np.float64)
    out = np.zeros(v.shape + (3,))
    out[..., 0, 1], out[..., 0, 2] = -v[..., 2], v[..., 1]
    out[..., 1, 0], out[..., 1, 2] = v[..., 2], -v[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -v[..., 1], v[..., 0]
    return out


def rodrigues(angles: np.ndarray, axis_skew: np.ndarray, axis_skew_sq: np.ndarray) -> np.ndarray:
    """Batched Rodrigues formula ``exp(angle [a]x) = I + sin(angle) K + (1 - cos(angle)) K^2`` with K precomputed.

    Parameters
    ----------
    angles : ndarray, shape (...), rad
    axis_skew, axis_skew_sq : ndarray, shape (..., 3, 3)
        ``K = [a]x`` of the unit axis ``a`` and ``K @ K``; a zero K (zero direction) gives the identity.

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
    sin = np.sin(angles)[..., None, None]
    versine = (1.0 - np.cos(angles))[..., None, None]
    return np.eye(3) + sin * axis_skew + versine * axis_skew_sq


def relative_rotvec(base: Rotation, other: Rotation) -> np.ndarray:
    """``log(base^-1 · other)`` as rotation vectors (rad): ``other`` in the tangent space at ``base``.

    Quaternion signs do not matter: scipy returns the rotation vector of angle ≤ π.
    """
    return (base.inv() * other).as_rotvec()


def geodesic_distance(a: Rotation, b: Rotation) -> np.ndarray:
    """Angle of ``a^-1 b`` in rad, in [0, π] (broadcast like ``Rotation`` products)."""
    return (a.inv() * b).magnitude()
