"""Distortion metrics on joint positions: pure functions, no I/O, no state.

Every function takes ``reference`` and ``decoded`` joint positions of shape (F, J, 3) in cm.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "joint_errors",
    "max_joint_error",
    "max_joint_error_percent",
    "worst_joint_and_frame",
    "mean_joint_error",
    "p99_joint_error",
    "kg_distortion",
]


def _check_pair(reference, decoded) -> tuple[np.ndarray, np.ndarray]:
    """Validate two (F, J, 3) position arrays of equal shape; return them as float64 arrays."""
    arrays = []
    for name, value in (("reference", reference), ("decoded", decoded)):
        array = np.asarray(value, dtype=np.float64)
        if array.ndim != 3 or array.shape[2] != 3 or array.shape[0] == 0 or array.shape[1] == 0:
            raise ValueError(f"Expected `{name}` to have shape (F, J, 3) with F, J > 0, got {array.shape}.")
        if not np.all(np.isfinite(array)):
            bad = tuple(int(i) for i in np.argwhere(~np.isfinite(array))[0])
            raise ValueError(f"`{name}` holds a non-finite value at (frame, joint, axis) {bad}.")
        arrays.append(array)
    if arrays[0].shape != arrays[1].shape:
        raise ValueError(f"Expected `decoded` to have the shape of `reference` {arrays[0].shape}, got {arrays[1].shape}.")
    return arrays[0], arrays[1]


def joint_errors(reference, decoded) -> np.ndarray:
    """Euclidean distance of every joint in every frame.

    Parameters
    ----------
    reference, decoded : array_like, shape (F, J, 3), float, cm

    Returns
    -------
    ndarray, shape (F, J), float, cm
    """
    reference, decoded = _check_pair(reference, decoded)
    return np.linalg.norm(reference - decoded, axis=-1)


def max_joint_error(reference, decoded) -> float:
    """L-infinity joint-position error: the largest joint distance over all joints and frames, cm.

    The error measure of the neural Fourier paper (its stopping criterion) and of ACL's ``max_error``.
    """
    return float(joint_errors(reference, decoded).max())


def max_joint_error_percent(reference, decoded, height_cm: float) -> float:
    """:func:`max_joint_error` as a percentage of the character's height (``Skeleton.rest_height``)."""
    if not np.isfinite(height_cm) or height_cm <= 0:
        raise ValueError(f"`height_cm` must be a finite number > 0, got {height_cm}.")
    return 100.0 * max_joint_error(reference, decoded) / float(height_cm)


def worst_joint_and_frame(reference, decoded) -> tuple[int, int]:
    """Where the L-infinity error occurs (ACL's ``worst_bone``/``worst_time``).

    Returns
    -------
    (joint, frame) : tuple of int
        Indices of the largest joint distance (the first one on ties).
    """
    errors = joint_errors(reference, decoded)
    frame, joint = np.unravel_index(int(np.argmax(errors)), errors.shape)
    return int(joint), int(frame)


def mean_joint_error(reference, decoded) -> float:
    """Mean Euclidean joint distance over all joints and frames, cm.

    The distortion of the LSDT paper, eq. 12: ``(1 / (J F)) * sum_i sum_j ||p_ij - p^_ij||``.
    """
    return float(joint_errors(reference, decoded).mean())


def p99_joint_error(reference, decoded) -> float:
    """99th percentile of the per-joint, per-frame Euclidean distances, cm (ACL reports it)."""
    return float(np.percentile(joint_errors(reference, decoded), 99))


def kg_distortion(reference, decoded) -> float:
    """Karni–Gotsman distortion rate, in %.

    ``KG = 100 * ||A - Â||_F / ||A - E(A)||_F`` where ``A`` stacks the positions (3J rows by F columns) and
    ``E(A)`` holds each joint coordinate's temporal mean, as defined in the PGA paper (§4, after Karni and
    Gotsman 2004). It is invariant to a translation applied to both motions.

    Raises
    ------
    ValueError
        If the reference never moves (the denominator is 0): KG is undefined for a static clip.
    """
    reference, decoded = _check_pair(reference, decoded)
    spread = np.linalg.norm(reference - reference.mean(axis=0, keepdims=True))
    if spread <= 1e-12 * max(1.0, float(np.abs(reference).max())):
        raise ValueError(
            "KG distortion is undefined for a static clip: the reference positions never move "
            "(||A - E(A)||_F = 0)."
        )
    return float(100.0 * np.linalg.norm(reference - decoded) / spread)
