"""A Motion from a node hierarchy's local transforms (what glTF and FBX store), with identity rest rotations.

Scene formats animate nodes whose static ("rest") rotation need not be the identity, under parent nodes that may
rotate, translate and scale the whole rig. A :class:`~mocapbench.motion.Motion` has the BVH convention: identity
rotations give the rest pose, offsets are in the parent's rest frame. This module converts, keeping every joint
and end-site position:

* local rotations are re-expressed relative to the static global rotations ``G``: ``R'_j = G_parent R_j G_j^-1``
  (for the root, ``G_parent`` is the rotation of the nodes above it); a translation ``t`` (an offset, a frame of a
  translation track) becomes ``s G_parent t``, an end site's ``s G_joint t``;
* a scale track ``S_j`` becomes ``G_j S_j G_j^-1`` (the same rebasing, ``local = T R S``), which is a scale along
  the rest axes when ``G_j`` permutes the axes or the scale is uniform; a non-uniform scale along turned axes would
  be a shear and is refused in one line naming the joint and the frame;
* the nodes above the root must be a similarity (rotation, uniform scale ``s``, translation): it is baked into the
  root position, the offsets and the tracks;
* a joint whose translation stays within :data:`FOLD_TOLERANCE_CM` of its first frame is *still*: its offset is
  that translation and it has no track (a file that animates every bone with constant keys costs nothing); a
  joint that moves keeps its rest translation as offset and its samples as ``Motion.translations``. Scales within
  :data:`SCALE_TOLERANCE` of 1 are 1.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from scipy.spatial.transform import Rotation

from mocapbench.motion import Motion, MotionFormatError, Skeleton

__all__ = ["motion_from_nodes", "FOLD_TOLERANCE_CM", "SCALE_TOLERANCE"]

#: A joint whose translation stays this close (cm) to its first frame in every frame has no translation track.
FOLD_TOLERANCE_CM = 1e-4
#: A scale this close to 1 (relative) is 1: float32 keys of 1.0 are exact, exporters' rounding is not.
SCALE_TOLERANCE = 1e-6


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
    rest_translations: np.ndarray | None = None,
    scales: np.ndarray | None = None,
    end_site_parents: np.ndarray | None = None,
    end_site_offsets: np.ndarray | None = None,
) -> Motion:
    """Build the Motion of a joint tree sampled at ``fps``.

    Parameters
    ----------
    names : sequence of str, length J
        Joint names (made unique with a suffix if they repeat).
    parents : ndarray, shape (J,), int
        Parent of each joint, ``parents[j] < j``, ``-1`` for the root only.
    translations : ndarray, shape (F, J, 3), float, file units
        Local translation of every joint at every frame.
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
    rest_translations : ndarray, shape (J, 3), float, file units, optional
        Static local translations (the rest pose): the offset of a joint that moves. Default frame 0.
    scales : ndarray, shape (F, J, 3), float, optional
        Local scales (> 0) of every joint at every frame; default 1.
    end_site_parents : ndarray, shape (E,), int, optional
        Joint each end site hangs from.
    end_site_offsets : ndarray, shape (E, 3), float, file units, optional
        Each end site's translation in its joint's node frame.
    """
    above_scale, above_rotation = _similarity(above, names[0], error)
    to_cm = above_scale * length_unit_cm
    rest_global, parent_rest = _rest_frames(rest_rotations, parents, above_rotation)
    rotations = _rebased_rotations(rotations, rest_global, parent_rest)

    moved = np.abs(translations[:, 1:] - translations[:1, 1:]).max(axis=(0, 2)) * to_cm
    moving = np.flatnonzero(moved > FOLD_TOLERANCE_CM) + 1
    offset_source = translations[0].copy()
    if rest_translations is not None:
        offset_source[moving] = rest_translations[moving]
    offsets = np.zeros((len(names), 3))
    offsets[1:] = Rotation.from_quat(parent_rest[1:]).apply(offset_source[1:]) * to_cm
    root_positions = (above_rotation.apply(translations[:, 0]) * above_scale + above[:3, 3]) * length_unit_cm
    track = None
    if moving.size:
        track = np.broadcast_to(offsets, translations.shape).copy()
        for j in moving:
            track[:, j] = Rotation.from_quat(parent_rest[j]).apply(translations[:, j]) * to_cm

    ends = np.zeros((0, 3))
    end_parents = np.zeros(0, dtype=np.int64) if end_site_parents is None else np.asarray(end_site_parents)
    if end_parents.size:
        ends = Rotation.from_quat(rest_global[end_parents]).apply(np.asarray(end_site_offsets, float)) * to_cm
    names = [str(n) for n in names]
    if len(set(names)) != len(names):
        names = [f"{n}_{j}" for j, n in enumerate(names)]
    skeleton = Skeleton(names=tuple(names), parents=np.asarray(parents), offsets=offsets,
                        end_site_parents=end_parents, end_site_offsets=ends.reshape(-1, 3))
    return Motion(
        skeleton=skeleton,
        fps=fps,
        root_positions=root_positions,
        rotations=rotations,
        name=name,
        source_unit_cm=length_unit_cm,
        up_axis=up_axis,
        translations=track,
        scales=None if scales is None else _rebased_scales(scales, rest_global, names, error),
    )


def _similarity(above: np.ndarray, root_name: str, error) -> tuple[float, Rotation]:
    """The uniform scale and the rotation of the transform above the root; refuses a shear or a mirror."""
    scales = np.linalg.norm(above[:3, :3], axis=0)
    if np.ptp(scales) > 1e-6 * scales.max() or np.linalg.det(above[:3, :3]) <= 0:
        raise error(f"the nodes above the root joint ({root_name!r}) scale unevenly or mirror")
    return float(scales[0]), Rotation.from_matrix(above[:3, :3] / scales[0])


def _rest_frames(rest_rotations: np.ndarray, parents: np.ndarray, above_rotation: Rotation):
    """Static global rotations ``G_j`` (J, 4) and each joint's parent's (the root's: the rotation above it)."""
    rest_global = np.empty((len(parents), 4))
    for j, parent in enumerate(parents):
        parent_rotation = above_rotation if parent < 0 else Rotation.from_quat(rest_global[parent])
        rest_global[j] = (parent_rotation * Rotation.from_quat(rest_rotations[j])).as_quat()
    parent_rest = np.concatenate([above_rotation.as_quat()[None], rest_global[parents[1:]]])
    return rest_global, parent_rest


def _rebased_rotations(rotations: np.ndarray, rest_global: np.ndarray, parent_rest: np.ndarray) -> np.ndarray:
    """``R'_j = G_parent R_j G_j^-1`` for every frame, (F, J, 4), as Hamilton products in numpy."""
    inverse_rest = rest_global * [-1.0, -1.0, -1.0, 1.0]  # the conjugate of a unit quaternion is its inverse
    return _quaternion_product(_quaternion_product(parent_rest, rotations), inverse_rest)


def _quaternion_product(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product ``a b`` of scalar-last quaternions (..., 4), broadcasting (the rotation ``a`` after ``b``)."""
    ax, ay, az, aw = np.moveaxis(a, -1, 0)
    bx, by, bz, bw = np.moveaxis(b, -1, 0)
    return np.stack([
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    ], axis=-1)


def _rebased_scales(scales: np.ndarray, rest_global: np.ndarray, names: Sequence[str], error) -> np.ndarray | None:
    """``G_j S_j G_j^-1`` as a scale along the rest axes, (F, J, 3); ``None`` when every scale is 1."""
    scales = np.where(np.abs(scales - 1.0) <= SCALE_TOLERANCE, 1.0, scales)
    scaled = np.flatnonzero(np.any(scales != 1.0, axis=(0, 2)))
    if not scaled.size:
        return None
    rebased = scales.copy()
    for j in scaled:
        turn = Rotation.from_quat(rest_global[j]).as_matrix()
        permutation = np.abs(np.rint(turn))
        if np.allclose(np.abs(turn), permutation, atol=1e-6):
            rebased[:, j] = scales[:, j] @ permutation.T
            continue
        uneven = np.ptp(scales[:, j], axis=1) > SCALE_TOLERANCE * scales[:, j].max(axis=1)
        if uneven.any():
            frame = int(np.flatnonzero(uneven)[0])
            raise error(
                f"joint {names[j]!r} has the non-uniform scale [{', '.join(f'{v:.6g}' for v in scales[frame, j])}] at frame "
                f"{frame} along "
                "axes turned from its rest frame; a Motion scales along the rest axes (a shear otherwise)"
            )
    return rebased
