"""Geometry on rotations for the PGA codec: SO(3) helpers, Karcher mean and principal geodesics, the
interpolating lifting scheme for position and rotation trajectories, and the geodesic IK solver.

Modules
-------
so3
    Quaternion/rotation-vector helpers around :class:`scipy.spatial.transform.Rotation` and a batched
    Rodrigues formula for the decoder's inner loop.
karcher
    Intrinsic (Karcher) mean on SO(3)^n by the fixed-point iteration.
pga
    Principal geodesic analysis (Fletcher's tangent-space approximation) and the product-of-exponentials
    pose model of Tournier et al. 2008, §3.3.
lifting
    Interpolating lifting scheme (split, cubic predict, details) for R^3 and SO(3) trajectories, §3.5.
ik
    PGA-based inverse kinematics with an analytic Jacobian and Levenberg–Marquardt, §3.4 and §3.6.
"""

from mocapbench.geometry.ik import GeodesicIK
from mocapbench.geometry.karcher import karcher_mean
from mocapbench.geometry.lifting import (
    EUCLIDEAN,
    ROTATIONS,
    lifting_decompose,
    lifting_reconstruct,
    num_lifting_levels,
)
from mocapbench.geometry.pga import PrincipalGeodesics, fit_pga, geodesic_poses

__all__ = [
    "GeodesicIK",
    "karcher_mean",
    "EUCLIDEAN",
    "ROTATIONS",
    "lifting_decompose",
    "lifting_reconstruct",
    "num_lifting_levels",
    "PrincipalGeodesics",
    "fit_pga",
    "geodesic_poses",
]
