"""Synthetic motions that lie *exactly* on a k-geodesic pose model, for testing PGA and the geodesic IK.

Each inner joint turns about one fixed axis, so every joint's factors of the product of exponentials commute and
``mu · prod_j exp(t_j v_j) = mu · exp(sum_j t_j v_j)`` per joint: the tangent vectors at mu span exactly the k
directions, and (the coordinates being centred) mu is exactly their Karcher mean.
"""

from __future__ import annotations

import numpy as np
from mocapbench.lazy_imports import Rotation

from mocapbench.codecs.pga.geodesics import geodesic_poses
from mocapbench.motion import Motion
from mocapbench.synthetic import cmu_like_skeleton

__all__ = ["hinge_model", "geodesic_model_motion"]


def hinge_model(num_inner: int, k: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """A random k-geodesic hinge model.

    Returns
    -------
    mean : ndarray, shape (n, 4), quaternions
    directions : ndarray, shape (k, n, 3)
        Orthonormal in R^{3n}; every joint's k directions are parallel (its hinge axis).
    """
    if not 1 <= k <= num_inner:
        raise ValueError(f"`k` must be in [1, {num_inner}] for {num_inner} hinge joints, got {k}.")
    rng = np.random.default_rng(seed)
    axes = rng.normal(size=(num_inner, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    weights = np.linalg.qr(rng.normal(size=(num_inner, k)))[0].T  # (k, n), orthonormal rows
    directions = weights[:, :, None] * axes[None]
    mean = Rotation.from_rotvec(rng.normal(scale=0.4, size=(num_inner, 3))).as_quat()
    return mean, directions


def geodesic_model_motion(
    num_frames: int = 180, k: int = 4, seed: int = 3
) -> tuple[Motion, np.ndarray, np.ndarray, np.ndarray]:
    """A 120 fps motion on :func:`~mocapbench.synthetic.cmu_like_skeleton` lying exactly on a k-geodesic model.

    The coordinates are centred sinusoids of amplitudes 1.2 .. 0.4 rad; the root walks forward, bobs and turns.

    Returns
    -------
    motion : Motion
    mean : ndarray, shape (n, 4)
    directions : ndarray, shape (k, n, 3)
    coordinates : ndarray, shape (F, k)
    """
    skeleton = cmu_like_skeleton()
    mean, directions = hinge_model(skeleton.num_joints - 1, k, seed)
    rng = np.random.default_rng(seed + 1)
    t = np.arange(num_frames) / 120.0
    amplitudes = np.linspace(1.2, 0.4, k)
    coords = amplitudes * np.sin(2 * np.pi * rng.uniform(0.5, 1.5, k) * t[:, None] + rng.uniform(0, 6, k))
    coords -= coords.mean(axis=0)
    inner = geodesic_poses(mean, directions, coords).as_quat()
    root_rot = Rotation.from_euler("YXZ", np.stack([0.8 * np.sin(2 * t), 0.1 * t, 0.05 * np.cos(3 * t)], 1)).as_quat()
    root_pos = np.stack([30 * np.sin(t), 90 + 3 * np.sin(7 * t), 120 * t], axis=1)
    rotations = np.concatenate([root_rot[:, None], inner], axis=1)
    return Motion(skeleton, 120.0, root_pos, rotations, name=f"geodesic-model-k{k}"), mean, directions, coords
