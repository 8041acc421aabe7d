"""Principal geodesic analysis of poses and the product-of-exponentials pose model (Tournier et al. 2008, §3.3).

A pose is the vector of the n inner joints' local rotations, a point of SO(3)^n (the root is left out, as in
the paper: its orientation is "only poorly correlated with the pose"). Following Fletcher's approximation
(paper §3.3), PGA is a PCA of the tangent vectors ``u_i = log(mu^-1 · p_i)`` in R^{3n} at the intrinsic mean mu;
the k leading principal axes ``v_1..v_k`` (unit vectors of R^{3n}) span the k principal geodesics, and a pose
is rebuilt by the paper's product of exponentials over the direct product, per joint J::

    h(x)_J = mu_J · exp(x_1 v_1J) · exp(x_2 v_2J) ··· exp(x_k v_kJ)        (§3.3, p_i = mu · prod_j e^{t_ij v_j})

The geodesic coordinates of a pose are its tangent projections ``t_ij = u_i · v_j``; the product of
exponentials reproduces the pose exactly only when each joint's directions commute (e.g. a joint turning
about one axis), otherwise up to second-order (Baker–Campbell–Hausdorff) terms in t. The IK decoder does not
use these coordinates: it solves for x from end-joint positions (§3.4).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from mocapbench.lazy_imports import Rotation

from mocapbench.codecs.pga.karcher import karcher_mean
from mocapbench.codecs.pga.so3 import as_rotation

__all__ = ["PrincipalGeodesics", "fit_pga", "geodesic_poses", "variance_count"]


@dataclass(frozen=True, eq=False)
class PrincipalGeodesics:
    """The PGA pose model of one clip.

    Attributes
    ----------
    mean : ndarray, shape (n, 4)
        Intrinsic mean of each inner joint's local rotation, unit quaternions (scalar-last).
    directions : ndarray, shape (k, n, 3), rad per unit coordinate
        The k leading principal directions ``v_j``; each is a unit vector of R^{3n} reshaped per joint.
    variances : ndarray, shape (r,), rad^2
        Tangent-space variance along every principal axis (all r = min(F, 3n) of them, decreasing).
    coordinates : ndarray, shape (F, k), rad
        Tangent projections ``t_ij`` of the fitted poses (the paper's matrix T).
    """

    mean: np.ndarray
    directions: np.ndarray
    variances: np.ndarray
    coordinates: np.ndarray

    @property
    def num_geodesics(self) -> int:
        """k."""
        return self.directions.shape[0]

    @property
    def num_joints(self) -> int:
        """n, the number of modelled (inner) joints."""
        return self.mean.shape[0]

    def explained_variance(self, k: int | None = None) -> float:
        """Fraction of the tangent variance in the first ``k`` (default: the model's k) principal axes."""
        k = self.num_geodesics if k is None else k
        total = float(self.variances.sum())
        return 1.0 if total <= 0 else float(self.variances[:k].sum() / total)


def variance_count(variances: np.ndarray, fraction: float) -> int:
    """Smallest number of principal axes whose variance reaches ``fraction`` of the total (Fig. 3's measure).

    Parameters
    ----------
    variances : ndarray, shape (r,), decreasing
    fraction : float in (0, 1]
    """
    if not 0 < fraction <= 1:
        raise ValueError(f"`fraction` must be in (0, 1], got {fraction}.")
    total = float(np.sum(variances))
    if total <= 0:
        return 0
    cumulative = np.cumsum(variances) / total
    return int(min(np.searchsorted(cumulative, fraction - 1e-12) + 1, len(variances)))


def fit_pga(rotations, num_geodesics: int) -> PrincipalGeodesics:
    """Approximate PGA (tangent PCA at the Karcher mean) of a sequence of poses.

    Parameters
    ----------
    rotations : Rotation of shape (F, n) or ndarray, shape (F, n, 4)
        Local rotations of the n modelled joints over F frames (quaternion signs do not matter).
    num_geodesics : int
        k >= 1. When k exceeds the rank min(F, 3n) the extra directions are orthonormal completions with zero
        variance (harmless for the model, they only cost bits).

    Returns
    -------
    PrincipalGeodesics
    """
    rot = as_rotation(rotations, "rotations")
    if len(rot.shape) != 2:
        raise ValueError(f"Expected `rotations` of shape (F, n), got {rot.shape}.")
    num_frames, num_joints = rot.shape
    if not 1 <= num_geodesics <= 3 * num_joints:
        raise ValueError(f"`num_geodesics` must be in [1, 3n] = [1, {3 * num_joints}], got {num_geodesics}.")
    mean = karcher_mean(rot)
    tangent = (mean.inv() * rot).as_rotvec().reshape(num_frames, 3 * num_joints)  # u_i, mean ~ 0 at the Karcher mean
    # Full SVD of the (F, 3n) matrix; the right singular vectors are the principal axes. Deterministic sign:
    # the largest-magnitude component of every axis is made positive.
    # Thin SVD when F >= 3n (it already gives all 3n axes; the full one would build an F x F matrix).
    _, singular, vt = np.linalg.svd(tangent, full_matrices=num_frames < 3 * num_joints)
    variances = np.zeros(min(num_frames, 3 * num_joints))
    variances[: singular.size] = singular**2 / num_frames
    axes = vt[:num_geodesics]
    signs = np.sign(axes[np.arange(num_geodesics), np.argmax(np.abs(axes), axis=1)])
    axes = axes * np.where(signs == 0, 1.0, signs)[:, None]
    mean_quat = mean.as_quat()
    mean_quat = mean_quat * np.where(mean_quat[:, 3:] < 0, -1.0, 1.0)
    return PrincipalGeodesics(
        mean=mean_quat,
        directions=axes.reshape(num_geodesics, num_joints, 3),
        variances=variances,
        coordinates=tangent @ axes.T,
    )


def geodesic_poses(mean, directions: np.ndarray, coordinates: np.ndarray) -> Rotation:
    """The paper's pose model ``h(x) = mu · prod_j exp(x_j v_j)`` (§3.3), vectorized over frames.

    Parameters
    ----------
    mean : Rotation of shape (n,) or ndarray, shape (n, 4)
    directions : ndarray, shape (k, n, 3), rad per unit coordinate
    coordinates : ndarray, shape (F, k) (or (k,) for one pose)

    Returns
    -------
    Rotation of shape (F, n) (or (n,) for one pose)
    """
    mean = as_rotation(mean, "mean")
    directions = np.asarray(directions, dtype=np.float64)
    x = np.asarray(coordinates, dtype=np.float64)
    single = x.ndim == 1
    x = np.atleast_2d(x)
    if directions.ndim != 3 or directions.shape[2] != 3 or directions.shape[1] != len(mean):
        raise ValueError(f"Expected `directions` of shape (k, {len(mean)}, 3), got {directions.shape}.")
    if x.shape[1] != directions.shape[0]:
        raise ValueError(f"Expected `coordinates` with k = {directions.shape[0]} columns, got {x.shape}.")
    pose = mean * Rotation.from_rotvec(x[:, 0, None, None] * directions[0])
    for j in range(1, directions.shape[0]):
        pose = pose * Rotation.from_rotvec(x[:, j, None, None] * directions[j])
    return pose[0] if single else pose
