"""A Motion from a node hierarchy's local transforms (what glTF and FBX store), with identity rest rotations.

Scene formats animate nodes whose static ("rest") rotation need not be the identity, under parent nodes that may
rotate, translate and scale the whole rig. A :class:`~mocapbench.motion.Motion` has the BVH convention: identity
rotations give the rest pose, offsets are in the parent's rest frame, and only the root translates. This module
converts, keeping every joint position:

* local rotations are re-expressed relative to the static global rotations ``G``: ``R'_j = G_parent R_j G_j^-1``
  (for the root, ``G_parent`` is the rotation of the nodes above it), offsets ``o'_j = s G_parent t_j``;
* the nodes above the root must be a similarity (rotation, uniform scale ``s``, translation): it is baked into the
  root position and every offset;
* a non-root joint whose translation moves more than 1e-3 cm is refused in one line naming it.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from scipy.spatial.transform import Rotation

from mocapbench.motion import Motion, MotionFormatError, Skeleton

__all__ = ["motion_from_nodes"]

MOVING_TOLERANCE_CM = 1e-3


def motion_from_nodes(
    names: Sequence[str],
    parents: np.ndarray,
    translations: np.ndarray,
    rotations: np.ndarray,
    rest_rotations: np.ndarray,
    above: np.ndarray,
    *,
    length_unit_cm: float,
    fps: float,
    name: str,
    up_axis: str,
    error: Callable[[str], MotionFormatError],
) -> Motion:
    """Build the Motion of a joint tree sampled at ``fps``.

    Parameters
    ----------
    names : sequence of str, length J
        Joint names (made unique with a suffix if they repeat).
    parents : ndarray, shape (J,), int
        Parent of each joint, ``parents[j] < j``, ``-1`` for the root only.
    translations : ndarray, shape (F, J, 3), float, file units
        Local translation of every joint at every frame (non-root ones must stay constant).
    rotations : ndarray, shape (F, J, 4), float
        Local rotations, scalar-last quaternions.
    rest_rotations : ndarray, shape (J, 4), float
        Static local rotations: the pose the result's identity rotations stand for.
    above : ndarray, shape (4, 4), float
        Global transform of the root's parent (file units), a similarity.
    length_unit_cm : float
        cm per file unit.
    fps, name, up_axis
        For the Motion (``source_unit_cm`` = ``length_unit_cm``).
    error : callable
        Makes the one-line error for a refusal, e.g. ``lambda message: MotionFormatError(f"{path}: {message}.")``.
    """
    scales = np.linalg.norm(above[:3, :3], axis=0)
    if np.ptp(scales) > 1e-6 * scales.max() or np.linalg.det(above[:3, :3]) <= 0:
        raise error(f"the nodes above the root joint ({names[0]!r}) scale unevenly or mirror")
    above_scale = float(scales[0])
    above_rotation = Rotation.from_matrix(above[:3, :3] / above_scale)
    moved = np.abs(translations[:, 1:] - translations[:1, 1:]).max(axis=(0, 2)) * above_scale * length_unit_cm
    if moved.size and moved.max() > MOVING_TOLERANCE_CM:
        j = int(moved.argmax()) + 1
        raise error(
            f"joint {names[j]!r} has an animated translation that moves {moved[j - 1]:.3g} cm; "
            "a Motion carries the root translation only"
        )
    num_joints = len(names)
    rest_global = [None] * num_joints
    for j in range(num_joints):
        rest_local = Rotation.from_quat(rest_rotations[j])
        rest_global[j] = (above_rotation * rest_local) if j == 0 else rest_global[parents[j]] * rest_local
    rest_quats = np.array([g.as_quat() for g in rest_global])
    parent_rest = np.concatenate([above_rotation.as_quat()[None], rest_quats[parents[1:]]])
    shape = rotations.shape
    rebased = (
        Rotation.from_quat(np.broadcast_to(parent_rest, shape).reshape(-1, 4))
        * Rotation.from_quat(rotations.reshape(-1, 4))
        * Rotation.from_quat(np.broadcast_to(Rotation.from_quat(rest_quats).inv().as_quat(), shape).reshape(-1, 4))
    ).as_quat().reshape(shape)
    offsets = np.zeros((num_joints, 3))
    offsets[1:] = Rotation.from_quat(parent_rest[1:]).apply(translations[0, 1:]) * above_scale * length_unit_cm
    root_positions = (above_rotation.apply(translations[:, 0]) * above_scale + above[:3, 3]) * length_unit_cm
    names = [str(n) for n in names]
    if len(set(names)) != len(names):
        names = [f"{n}_{j}" for j, n in enumerate(names)]
    return Motion(
        skeleton=Skeleton(names=tuple(names), parents=np.asarray(parents), offsets=offsets),
        fps=fps,
        root_positions=root_positions,
        rotations=rebased,
        name=name,
        source_unit_cm=length_unit_cm,
        up_axis=up_axis,
    )
