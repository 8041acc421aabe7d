"""Bone-length deviation: does the decoded skeleton stay rigid where the original is? Pure functions, no I/O.

A **bone** is the segment from a joint's parent to the joint (every joint but the root); its length at a frame
is the distance between the two global positions, whatever carries the joint there: the skeleton offset, a
per-frame translation track (game rigs whose joints move), or a parent's scale. The deviation compares the
decoded and the original length frame by frame, ``| L_decoded[f, b] - L_reference[f, b] |`` (cm), so a rig
whose bones legitimately stretch counts only the stretch the codec changed. End sites are not bones here (a
decoder that returns joint positions only has none).

A codec that codes joint rotations on the original offsets keeps every bone length by construction (only
float rounding remains); a codec that codes positions returns points, and its bones stretch by up to twice its
position error.
"""

from __future__ import annotations

import numpy as np

from mocapbench.metrics.distortion import _check_pair

__all__ = ["bone_lengths", "bone_length_deviations", "bone_length_deviation"]


def _check_parents(parents, num_joints: int) -> np.ndarray:
    parents = np.asarray(parents, dtype=np.int64)
    if parents.shape != (num_joints,) or parents[0] != -1 or np.any(parents[1:] < 0) or np.any(
            parents[1:] >= np.arange(1, num_joints)):
        raise ValueError(f"`parents` must have shape ({num_joints},), -1 for joint 0 and parents[j] < j, "
                         f"got {parents.tolist()}.")
    return parents


def bone_lengths(positions, parents) -> np.ndarray:
    """Length of every bone (parent to joint) in every frame.

    Parameters
    ----------
    positions : array_like, shape (F, J, 3), float, cm
    parents : array_like, shape (J,), int
        ``-1`` for the root (joint 0), else ``parents[j] < j``.

    Returns
    -------
    ndarray, shape (F, J - 1), float, cm
        Column ``b`` is the bone ending at joint ``b + 1``.
    """
    positions = np.asarray(positions, dtype=np.float64)
    parents = _check_parents(parents, positions.shape[1])
    return np.linalg.norm(positions[:, 1:] - positions[:, parents[1:]], axis=-1)


def bone_length_deviations(reference, decoded, parents) -> np.ndarray:
    """``| L_decoded - L_reference |`` of every bone in every frame.

    Parameters
    ----------
    reference, decoded : array_like, shape (F, J, 3), float, cm
    parents : array_like, shape (J,), int

    Returns
    -------
    ndarray, shape (F, J - 1), float, cm
    """
    reference, decoded = _check_pair(reference, decoded)
    return np.abs(bone_lengths(decoded, parents) - bone_lengths(reference, parents))


def bone_length_deviation(reference, decoded, parents) -> tuple[float, float]:
    """Maximum and mean of :func:`bone_length_deviations` over every bone and frame.

    Returns
    -------
    (max, mean) : tuple of float, cm
        Both 0 for a single-joint skeleton (no bone).
    """
    deviations = bone_length_deviations(reference, decoded, parents)
    if deviations.size == 0:
        return 0.0, 0.0
    return float(deviations.max()), float(deviations.mean())
