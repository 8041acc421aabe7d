"""ACL's error metric: the virtual-vertex ("shell") error of each joint's object-space transform.

ACL (``docs/error_metrics.md``; ``qvvf_transform_error_metric::calculate_error`` in
``acl/compression/transform_error_metrics.h``, called by ``calculate_compression_error``) measures a lossy pose
on a rigid shell around every joint: three virtual vertices at distance ``d`` along the joint's local x, y and z
axes, carried to object space by the raw and by the lossy transform of that joint. A joint's error at a frame is
the largest of the three vertex distances::

    e[f, j] = max_k || (R_ref[f, j] - R_dec[f, j]) (d e_k) + (p_ref[f, j] - p_dec[f, j]) ||,  k in {x, y, z}

with ``R`` the joint's global rotation (joint frame to world), ``p`` its global position (cm) and ``d`` the
shell distance (cm; ACL's default is 3 cm, a skinned vertex near the bone). With ``d = 0`` it is the joint
position error. It needs rotations, so only codecs that return a :class:`~mocapbench.motion.Motion` get it.

This is the three-vertex ``calculate_error`` that ACL's ``calculate_compression_error`` reports. While it
compresses a clip without scale ACL checks only the x and y vertices (``calculate_error_no_scale``), so the z
vertex can exceed ACL's precision: on ``cmu_test`` at precision 0.01 cm, x/y give 0.013 cm and x/y/z 0.017 cm.
Pure functions, no I/O.
"""

from __future__ import annotations

import numpy as np

__all__ = ["ACL_SHELL_DISTANCE_CM", "shell_errors", "motion_shell_errors"]

ACL_SHELL_DISTANCE_CM = 3.0
"""ACL's default shell distance (``track_desc_transformf::shell_distance``), cm."""


def shell_errors(
    reference_matrices,
    reference_positions,
    decoded_matrices,
    decoded_positions,
    shell_cm: float = ACL_SHELL_DISTANCE_CM,
) -> np.ndarray:
    """ACL's shell error of every joint in every frame.

    Parameters
    ----------
    reference_matrices, decoded_matrices : array_like, shape (F, J, 3, 3), float
        Global rotation of each joint (joint frame to world), as ``Motion.global_transforms()[0]``.
    reference_positions, decoded_positions : array_like, shape (F, J, 3), float, cm
    shell_cm : float
        Distance of the virtual vertices from the joint, cm, >= 0.

    Returns
    -------
    ndarray, shape (F, J), float, cm

    Raises
    ------
    ValueError
        On mismatched shapes, non-finite values or a negative or non-finite shell distance.
    """
    arrays = [np.asarray(a, dtype=np.float64) for a in (reference_matrices, reference_positions, decoded_matrices,
                                                       decoded_positions)]
    names = ("reference_matrices", "reference_positions", "decoded_matrices", "decoded_positions")
    ref_r, ref_p, dec_r, dec_p = arrays
    if ref_p.ndim != 3 or ref_p.shape[-1] != 3 or 0 in ref_p.shape:
        raise ValueError(f"Expected `reference_positions` to have shape (F, J, 3) with F, J > 0, got {ref_p.shape}.")
    expected = {names[0]: ref_p.shape + (3,), names[1]: ref_p.shape, names[2]: ref_p.shape + (3,), names[3]: ref_p.shape}
    for name, array in zip(names, arrays):
        if array.shape != expected[name]:
            raise ValueError(f"Expected `{name}` to have shape {expected[name]}, got {array.shape}.")
        if not np.all(np.isfinite(array)):
            raise ValueError(f"`{name}` holds a non-finite value.")
    if not (np.isfinite(shell_cm) and shell_cm >= 0):
        raise ValueError(f"`shell_cm` must be a finite distance >= 0 cm, got {shell_cm}.")
    # Vertex k of the shell in world space is R[..., :, k] * d + p; its displacement, for each k at once:
    displacement = shell_cm * (ref_r - dec_r) + (ref_p - dec_p)[..., :, None]  # (F, J, 3 coords, 3 vertices)
    return np.linalg.norm(displacement, axis=-2).max(axis=-1)


def motion_shell_errors(reference, decoded, shell_cm: float = ACL_SHELL_DISTANCE_CM) -> np.ndarray:
    """:func:`shell_errors` of two :class:`~mocapbench.motion.Motion` objects on the same joints.

    Returns
    -------
    ndarray, shape (F, J), float, cm
    """
    if reference.num_joints != decoded.num_joints or reference.num_frames != decoded.num_frames:
        raise ValueError(
            f"Expected motions of equal size, got {reference.num_frames}x{reference.num_joints} and "
            f"{decoded.num_frames}x{decoded.num_joints} (frames x joints)."
        )
    ref_r, ref_p = reference.global_transforms()
    dec_r, dec_p = decoded.global_transforms()
    return shell_errors(ref_r, ref_p, dec_r, dec_p, shell_cm)
