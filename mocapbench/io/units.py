"""Length units and up axes of motion files: parsed, detected, checked and reported, never assumed silently.

Every :class:`~mocapbench.motion.Motion` is in cm; a file is in its own unit. This module turns a user's
``--units`` (``cm``, ``mm``, ``m``, ``inch``, ``cmu`` or a number of cm per unit) into cm per unit, detects the up
axis of a motion (Y or Z; or takes ``--up``), measures the rest height along it and warns when that height is
not a body's (outside 50-250 cm), naming the unit that would make it one. Errors and epsilons elsewhere are
always in cm of the real body: that holds only when the unit is right, hence the warning.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy.spatial.transform import Rotation

from mocapbench.io.asf_amc import CMU_CM_PER_UNIT
from mocapbench.motion import Motion, Skeleton

__all__ = [
    "UNITS_CM",
    "REST_HEIGHT_RANGE_CM",
    "parse_units",
    "unit_label",
    "parse_up_axis",
    "detect_up_axis",
    "rest_height_cm",
    "rest_height_warning",
    "with_source",
    "turn_axes",
]

#: Centimetres per unit of every unit name ``--units`` takes. ``cmu``: the CMU ASF/BVH unit, 1/0.45 inch.
UNITS_CM = {"cm": 1.0, "mm": 0.1, "m": 100.0, "inch": 2.54, "cmu": CMU_CM_PER_UNIT}
#: Rest heights (cm) that look like a body; outside, a warning names the likely unit.
REST_HEIGHT_RANGE_CM = (50.0, 250.0)
_TYPICAL_HEIGHT_CM = 170.0
_AXES = "xyz"


def parse_units(text: str | float) -> float:
    """Centimetres per unit from a ``--units`` value.

    Parameters
    ----------
    text : str or float
        A name of :data:`UNITS_CM` (case-insensitive; ``in``/``inches`` are ``inch``) or a positive number of cm
        per unit (``"5.6444"``).

    Returns
    -------
    float
        cm per unit, finite, > 0.

    Raises
    ------
    ValueError
        One line naming the value and the accepted ones.
    """
    if isinstance(text, (int, float)) and not isinstance(text, bool):
        value = float(text)
    else:
        key = str(text).strip().lower()
        key = {"in": "inch", "inches": "inch", "meter": "m", "metre": "m"}.get(key, key)
        if key in UNITS_CM:
            return UNITS_CM[key]
        try:
            value = float(key)
        except ValueError:
            raise ValueError(
                f"--units {text!r}: expected one of {', '.join(UNITS_CM)} or a number of cm per unit (e.g. 5.6444)."
            ) from None
    if not (math.isfinite(value) and 0 < value <= 1e6):
        raise ValueError(f"--units {text!r}: a number of cm per unit must be finite and in (0, 1e6].")
    return value


def _unit_name(cm_per_unit: float) -> str | None:
    """The name of ``cm_per_unit`` when it is one of :data:`UNITS_CM` (within float32 precision), else None."""
    for name, value in UNITS_CM.items():
        if abs(cm_per_unit - value) <= 1e-6 * value:
            return name
    return None


def unit_label(cm_per_unit: float) -> str:
    """``"mm"``, ``"cmu (5.6444 cm)"`` or ``"3.5 cm per unit"``: a unit as a report shows it."""
    name = _unit_name(cm_per_unit)
    if name is None:
        return f"{cm_per_unit:.6g} cm per unit"
    return name if name in ("cm", "mm", "m", "inch") else f"{name} ({UNITS_CM[name]:.4f} cm)"


def canonical_unit_cm(cm_per_unit: float) -> float:
    """The exact value of a named unit read back at float32 precision (from a stream header), else the value."""
    name = _unit_name(cm_per_unit)
    return UNITS_CM[name] if name else float(cm_per_unit)


def parse_up_axis(text: str) -> str:
    """``"y"`` or ``"z"`` (or ``"x"``) from ``--up``; ``ValueError`` in one line otherwise."""
    key = str(text).strip().lower().lstrip("+")
    if key not in ("x", "y", "z"):
        raise ValueError(f"--up {text!r}: expected y or z (or x).")
    return key


def _rest_points(skeleton: Skeleton) -> np.ndarray:
    """Rest-pose joints and end sites, shape (J + E, 3), cm."""
    joints = skeleton.rest_positions()
    ends = joints[skeleton.end_site_parents] + skeleton.end_site_offsets
    return np.concatenate([joints, ends])


def rest_height_cm(skeleton: Skeleton, up_axis: str) -> float:
    """Extent of the rest pose (identity rotations, end sites included) along ``up_axis``, in cm."""
    return float(np.ptp(_rest_points(skeleton)[:, _AXES.index(up_axis)]))


def detect_up_axis(motion: Motion) -> tuple[str, str]:
    """Which of Y and Z points up, and why.

    Rule: when the root travels (more than 50 cm, and 3 times more across one axis than along the other), the
    axis it travels least along is up (people and animals walk on the floor). Otherwise the axis along which
    the rest pose is taller is up (a standing body is taller than it is deep). A clip that neither travels nor
    stands upright in its rest pose can be wrong: pass ``--up``.

    Returns
    -------
    axis : str
        ``"y"`` or ``"z"``.
    reason : str
        One line for ``inspect`` and warnings, with the measured extents in cm.
    """
    travel = np.ptp(motion.root_positions[:, 1:], axis=0)  # (2,) cm along y, z
    small, large = sorted(travel)
    if large > 50.0 and large > 3.0 * small:
        axis = "yz"[int(np.argmin(travel))]
        other = "yz".replace(axis, "")
        return axis, (
            f"the root travels {travel['yz'.index(other)]:.0f} cm along {other} and "
            f"{travel['yz'.index(axis)]:.0f} cm along {axis}"
        )
    extent = np.ptp(_rest_points(motion.skeleton)[:, 1:], axis=0)
    axis = "yz"[int(np.argmax(extent))]
    other = "yz".replace(axis, "")
    return axis, (
        f"the rest pose is {extent['yz'.index(axis)]:.0f} cm tall along {axis} and "
        f"{extent['yz'.index(other)]:.0f} cm along {other}"
    )


def rest_height_warning(motion: Motion, up_axis: str | None = None) -> str | None:
    """A one-line warning when the rest height is not a body's (outside 50-250 cm), else None.

    The motion's arrays are in cm, read with ``motion.source_unit_cm`` cm per file unit. The warning names the
    height, the unit it was read with, and the unit of :data:`UNITS_CM` that gives the height closest to 170 cm
    inside the range (if any).
    """
    up_axis = up_axis or motion.up_axis
    height = rest_height_cm(motion.skeleton, up_axis)
    low, high = REST_HEIGHT_RANGE_CM
    if low <= height <= high:
        return None
    used = motion.source_unit_cm
    message = (
        f"rest height is {height:.1f} cm along {up_axis} read as {unit_label(used)}; "
        f"a body is {low:.0f}-{high:.0f} cm"
    )
    if height <= 0:
        return message + ": the rest pose is flat along the up axis; check --up."
    in_units = height / used
    candidates = [
        (abs(math.log(in_units * cm / _TYPICAL_HEIGHT_CM)), name, in_units * cm) for name, cm in UNITS_CM.items()
    ]
    fits = sorted(c for c in candidates if low <= c[2] <= high)
    if not fits:
        return message + ": no unit of --units makes it one; check --units and --up."
    _, name, likely = fits[0]
    return message + f": the file is likely in {name} ({likely:.1f} cm tall); pass --units {name}."


def with_source(motion: Motion, *, unit_cm: float | None = None, up_axis: str | None = None) -> Motion:
    """``motion`` with its metadata set: source unit (cm per unit) and up axis (given or detected)."""
    changes = {}
    if unit_cm is not None:
        changes["source_unit_cm"] = float(unit_cm)
    changes["up_axis"] = up_axis or detect_up_axis(motion)[0]
    return dataclasses.replace(motion, **changes)


def turn_axes(motion: Motion, turn: Rotation, up_axis: str) -> Motion:
    """The same motion in axes turned by ``turn``: joint positions become ``turn`` applied to the old ones.

    Offsets, end sites and root positions are rotated and every local rotation conjugated (``turn q turn^-1``),
    so distances and errors are unchanged. Used for Y-up <-> Z-up (+-90 degrees about X).

    Parameters
    ----------
    motion : Motion
    turn : Rotation
        A single rotation.
    up_axis : str
        The ``up_axis`` of the result.
    """
    matrix = turn.as_matrix()
    skeleton = motion.skeleton
    turned = Skeleton(
        names=skeleton.names,
        parents=skeleton.parents,
        offsets=skeleton.offsets @ matrix.T,
        channel_orders=skeleton.channel_orders,
        end_site_parents=skeleton.end_site_parents,
        end_site_offsets=skeleton.end_site_offsets @ matrix.T,
    )
    rotations = turn * Rotation.from_quat(motion.rotations.reshape(-1, 4)) * turn.inv()
    return dataclasses.replace(
        motion,
        skeleton=turned,
        root_positions=motion.root_positions @ matrix.T,
        rotations=rotations.as_quat().reshape(motion.rotations.shape),
        up_axis=up_axis,
        translations=None if motion.translations is None else motion.translations @ matrix.T,
        scales=None if motion.scales is None else _turned_scales(motion.scales, matrix),
    )


def _turned_scales(scales: np.ndarray, matrix: np.ndarray) -> np.ndarray:
    """Local scales in turned axes: ``turn diag(s) turn^-1`` is diagonal when the turn permutes the axes (up to
    sign), and then is ``diag`` of the permuted scales; another turn of a non-uniform scale is a shear, refused."""
    permutation = np.abs(np.rint(matrix))
    if not np.allclose(np.abs(matrix), permutation, atol=1e-9):
        uniform = np.all(scales == scales[..., :1])
        if not uniform:
            raise ValueError("A turn that does not permute the axes makes a non-uniform scale a shear; "
                             "turn by multiples of 90 degrees about an axis.")
        return scales
    return scales @ permutation.T
