"""What animators see, as result columns: end sites, jitter, foot sliding, rigid bones, joint rotations.

:func:`animator_columns` adds these columns to every results row (:func:`mocapbench.experiments.evaluate.evaluate`);
:func:`pool_animator_columns` pools them over the clips of a dataset for the curve points
(:func:`mocapbench.experiments.aggregate.curve_points`). The definitions live with the metrics:

``end_site_max_err_cm``, ``end_site_mean_err_cm``
    L∞ and mean Euclidean error of the BVH end sites (finger, toe and head tips), cm; NaN for a codec that
    returns joint positions only (it returns no end site) and for a skeleton without end sites.
``accel_rms_err_cm_s2``, ``accel_max_err_cm_s2``, ``accel_rms_ref_cm_s2``
    RMS and max over joints and inner frames of the acceleration error, cm/s² (:mod:`mocapbench.metrics.acceleration`),
    and the RMS acceleration of the original itself (its motion and its capture noise), the scale the error is
    judged against.
``foot_contacts``, ``foot_slide_mean_cm``, ``foot_slide_max_cm``, ``foot_slide_ref_mean_cm``, ``foot_slide_ref_max_cm``
    The original's foot contacts and the decoded (``foot_slide_*``) and original (``foot_slide_ref_*``) foot's
    horizontal travel per contact, mean and max, cm (:mod:`mocapbench.metrics.foot_sliding`); NaN without contacts.
``bone_len_max_dev_cm``, ``bone_len_mean_dev_cm``
    Max and mean bone-length deviation, cm (:mod:`mocapbench.metrics.bones`).
``rot_max_err_deg``, ``rot_mean_err_deg``
    Max and mean local-rotation error, degrees (:mod:`mocapbench.metrics.rotation_error`); NaN for a codec that
    returns joint positions only.

Pooled over clips: the maxima are the worst clip's; the means are weighted by what they average (frames, inner
frames for the RMS, contacts for the sliding), NaN clips left out.
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np
import pandas as pd

from mocapbench.metrics.acceleration import acceleration_error, accelerations
from mocapbench.metrics.bones import bone_length_deviation
from mocapbench.metrics.distortion import joint_errors
from mocapbench.metrics.foot_sliding import foot_sliding
from mocapbench.metrics.rotation_error import local_rotation_error
from mocapbench.motion import Motion

__all__ = ["ANIMATOR_COLUMNS", "animator_columns", "pool_animator_columns"]

_NAN = float("nan")

# Column -> how it pools over clips: "max", or ("mean", weight column) / ("rms", weight column).
_POOLING: dict[str, Any] = {
    "end_site_max_err_cm": "max",
    "end_site_mean_err_cm": ("mean", "frames"),
    "accel_rms_err_cm_s2": ("rms", "_inner_frames"),
    "accel_max_err_cm_s2": "max",
    "accel_rms_ref_cm_s2": ("rms", "_inner_frames"),
    "foot_contacts": "sum",
    "foot_slide_mean_cm": ("mean", "foot_contacts"),
    "foot_slide_max_cm": "max",
    "foot_slide_ref_mean_cm": ("mean", "foot_contacts"),
    "foot_slide_ref_max_cm": "max",
    "bone_len_max_dev_cm": "max",
    "bone_len_mean_dev_cm": ("mean", "frames"),
    "rot_max_err_deg": "max",
    "rot_mean_err_deg": ("mean", "frames"),
}
ANIMATOR_COLUMNS = tuple(_POOLING)
"""The columns :func:`animator_columns` adds to a results row."""


def _end_site_columns(motion: Motion, decoded: Motion | None) -> dict[str, float]:
    if decoded is None or len(motion.skeleton.end_site_parents) == 0 or decoded.num_joints != motion.num_joints:
        return {"end_site_max_err_cm": _NAN, "end_site_mean_err_cm": _NAN}
    errors = joint_errors(motion.end_site_positions(), decoded.end_site_positions())
    return {"end_site_max_err_cm": float(errors.max()), "end_site_mean_err_cm": float(errors.mean())}


def _rotation_columns(motion: Motion, decoded: Motion | None) -> dict[str, float]:
    if decoded is None or decoded.rotations.shape != motion.rotations.shape:
        return {"rot_max_err_deg": _NAN, "rot_mean_err_deg": _NAN}
    worst, mean = local_rotation_error(motion.rotations, decoded.rotations)
    return {"rot_max_err_deg": worst, "rot_mean_err_deg": mean}


def animator_columns(motion: Motion, decoded_positions: np.ndarray, decoded_motion: Motion | None,
                     reference_positions: np.ndarray | None = None) -> dict[str, float]:
    """The columns of the module docstring for one clip.

    Parameters
    ----------
    motion : Motion
        The original clip.
    decoded_positions : ndarray, shape (F, J, 3), float, cm
    decoded_motion : Motion or None
        The decoded rotations (``Decoded.motion``), None for a codec that returns joint positions only.
    reference_positions : ndarray, shape (F, J, 3), float, cm, optional
        ``motion.positions()``, if the caller already has it.

    Returns
    -------
    dict
        One float per name of :data:`ANIMATOR_COLUMNS` (``foot_contacts`` an int).
    """
    reference = motion.positions() if reference_positions is None else reference_positions
    skeleton = motion.skeleton
    rms, worst = acceleration_error(reference, decoded_positions, motion.fps)
    own = accelerations(reference, motion.fps)
    own_rms = float(np.sqrt(np.mean(np.einsum("fjk,fjk->fj", own, own)))) if own.size else _NAN
    sliding = foot_sliding(reference, decoded_positions, motion.fps, skeleton.names, skeleton.parents,
                           motion.up_axis)
    contacts = len(sliding.contacts)
    bone_max, bone_mean = bone_length_deviation(reference, decoded_positions, skeleton.parents)
    return {
        **_end_site_columns(motion, decoded_motion),
        "accel_rms_err_cm_s2": rms,
        "accel_max_err_cm_s2": worst,
        "accel_rms_ref_cm_s2": own_rms,
        "foot_contacts": contacts,
        "foot_slide_mean_cm": float(sliding.decoded_cm.mean()) if contacts else _NAN,
        "foot_slide_max_cm": float(sliding.decoded_cm.max()) if contacts else _NAN,
        "foot_slide_ref_mean_cm": float(sliding.reference_cm.mean()) if contacts else _NAN,
        "foot_slide_ref_max_cm": float(sliding.reference_cm.max()) if contacts else _NAN,
        "bone_len_max_dev_cm": bone_max,
        "bone_len_mean_dev_cm": bone_mean,
        **_rotation_columns(motion, decoded_motion),
    }


def pool_animator_columns(rows: pd.DataFrame, keys: Sequence[str]) -> pd.DataFrame:
    """The columns of :data:`ANIMATOR_COLUMNS` pooled over the clips of each group of ``keys``.

    Parameters
    ----------
    rows : DataFrame
        Results rows, one per clip (``frames`` and the animator columns; rows written before these columns
        existed pool to NaN).
    keys : column names
        The groups, e.g. ``dataset, codec, config_hash``.

    Returns
    -------
    DataFrame
        ``keys`` and one column per animator column present in ``rows``.
    """
    frame = rows.copy()
    frame["_inner_frames"] = (frame["frames"] - 2).clip(lower=0)
    by = [frame[k] for k in keys]
    pooled = {}
    for column in (c for c in ANIMATOR_COLUMNS if c in frame):
        rule = _POOLING[column]
        values = pd.to_numeric(frame[column], errors="coerce")
        if rule == "max":
            pooled[column] = values.groupby(by, dropna=False).max()
        elif rule == "sum":
            pooled[column] = values.groupby(by, dropna=False).sum(min_count=1)
        else:
            kind, weight_column = rule
            weight = pd.to_numeric(frame[weight_column], errors="coerce").where(values.notna(), 0.0)
            term = (values**2 if kind == "rms" else values).fillna(0.0)
            weights = weight.groupby(by, dropna=False).sum()
            mean = (term * weight).groupby(by, dropna=False).sum() / weights.where(weights > 0)
            pooled[column] = np.sqrt(mean) if kind == "rms" else mean
    if not pooled:
        return frame[list(keys)].drop_duplicates().reset_index(drop=True)
    out = pd.DataFrame(pooled)
    out.index.names = list(keys)
    return out.reset_index()
