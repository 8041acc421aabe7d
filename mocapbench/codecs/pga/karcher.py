"""Intrinsic (Karcher) mean on SO(3)^n: the pose minimizing the summed squared geodesic distances (§3.2).

Over a product of groups the mean is taken factor by factor, so the n joints are independent problems; they
are solved together, vectorized. The iteration is the usual fixed point (Pennec 2006, Fletcher 2004)::

    mu <- mu · exp( mean_i log(mu^-1 · q_i) )

started from the chordal (quaternion eigenvector) mean, which is sign-invariant, so quaternion sign flips in
the data do not matter anywhere.
"""

from __future__ import annotations

import numpy as np
from mocapbench.lazy_imports import Rotation

from mocapbench.codecs.pga.so3 import as_rotation

__all__ = ["karcher_mean", "chordal_mean"]


def chordal_mean(quats: np.ndarray) -> np.ndarray:
    """Per-column chordal L2 mean: the leading eigenvector of ``sum_i q_i q_i^T`` (sign-invariant).

    Parameters
    ----------
    quats : ndarray, shape (F, n, 4)

    Returns
    -------
    ndarray, shape (n, 4), unit quaternions with w >= 0
    """
    scatter = np.einsum("fna,fnb->nab", quats, quats)
    _, vectors = np.linalg.eigh(scatter)
    mean = vectors[..., -1]
    return mean * np.where(mean[:, 3:] < 0, -1.0, 1.0)


def karcher_mean(rotations, *, tol: float = 1e-12, max_iterations: int = 100) -> Rotation:
    """Intrinsic mean of each column of a set of rotations.

    Parameters
    ----------
    rotations : Rotation of shape (F, n) or ndarray, shape (F, n, 4) quaternions (any signs)
        F samples of n independent rotations (e.g. the n inner joints over F frames).
    tol : float, rad
        Stop when the largest update angle falls below ``tol``.
    max_iterations : int
        Upper bound on fixed-point iterations (it typically converges in < 10).

    Returns
    -------
    Rotation of shape (n,)

    Raises
    ------
    ValueError
        If ``rotations`` is not (F, n) / (F, n, 4) with F >= 1.
    """
    rot = as_rotation(rotations, "rotations")
    quats = rot.as_quat()
    if quats.ndim != 3 or quats.shape[0] == 0:
        raise ValueError(
            f"Expected `rotations` of shape (F, n) (quaternions (F, n, 4)) with F >= 1, got {quats.shape}."
        )
    samples = Rotation.from_quat(quats)
    mean = Rotation.from_quat(chordal_mean(quats))
    for _ in range(max_iterations):
        tangent = (mean.inv() * samples).as_rotvec()  # (F, n, 3), log at the mean
        update = tangent.mean(axis=0)
        mean = mean * Rotation.from_rotvec(update)
        if np.max(np.linalg.norm(update, axis=-1)) < tol:
            break
    return mean
