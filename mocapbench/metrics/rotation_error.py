"""Local-rotation error of codecs that return joint rotations: the angle between two local rotations, degrees.

For joint ``j`` at frame ``f`` the error is the angle of the relative rotation ``q_ref^-1 q_dec``,
``2 atan2(|v|, |w|)`` with ``(v, w)`` the vector and scalar parts of that quaternion (the absolute value makes
``q`` and ``-q``, the same rotation, agree; ``atan2`` keeps small angles exact where ``acos`` of a dot product
near 1 would not). It is what a
rigger sees in the joint's channels; its effect on positions grows with the length of the chain below the joint,
which the position metrics measure. Pure functions, no I/O.
"""

from __future__ import annotations

import numpy as np

__all__ = ["local_rotation_errors", "local_rotation_error"]


def local_rotation_errors(reference, decoded) -> np.ndarray:
    """Angle between the reference and decoded local rotation of every joint in every frame.

    Parameters
    ----------
    reference, decoded : array_like, shape (F, J, 4), float
        Unit quaternions, scalar-last (``Motion.rotations``).

    Returns
    -------
    ndarray, shape (F, J), float, degrees in [0, 180]

    Raises
    ------
    ValueError
        On shapes that differ or are not (F, J, 4), or non-finite values.
    """
    arrays = []
    for name, value in (("reference", reference), ("decoded", decoded)):
        array = np.asarray(value, dtype=np.float64)
        if array.ndim != 3 or array.shape[-1] != 4 or 0 in array.shape:
            raise ValueError(f"Expected `{name}` quaternions of shape (F, J, 4) with F, J > 0, got {array.shape}.")
        if not np.all(np.isfinite(array)):
            raise ValueError(f"`{name}` holds a non-finite quaternion component.")
        arrays.append(array / np.linalg.norm(array, axis=-1, keepdims=True))
    if arrays[0].shape != arrays[1].shape:
        raise ValueError(f"Expected `decoded` to have the shape of `reference` {arrays[0].shape}, "
                         f"got {arrays[1].shape}.")
    a, b = arrays
    # conj(a) * b for scalar-last quaternions: w = a_w b_w + a_v . b_v, v = a_w b_v - b_w a_v - a_v x b_v.
    scalar = np.abs(a[..., 3] * b[..., 3] + np.einsum("fjk,fjk->fj", a[..., :3], b[..., :3]))
    vector = a[..., 3:] * b[..., :3] - b[..., 3:] * a[..., :3] - np.cross(a[..., :3], b[..., :3])
    return np.degrees(2.0 * np.arctan2(np.linalg.norm(vector, axis=-1), scalar))


def local_rotation_error(reference, decoded) -> tuple[float, float]:
    """Maximum and mean of :func:`local_rotation_errors` over every joint and frame, degrees."""
    errors = local_rotation_errors(reference, decoded)
    return float(errors.max()), float(errors.mean())
