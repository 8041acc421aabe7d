"""Length units and up axes of motion files: parsed, detected, checked and reported, never assumed silently.

Every :class:`~mocapbench.motion.Motion` is in cm; a file is in its own unit. This module turns a user's
``--units`` (``cm``, ``mm``, ``m``, ``inch``, ``cmu`` or a number of cm per unit) into cm per unit, detects the up
axis of a motion from its frames (Y or Z; or takes ``--up``), measures the rest pose along the axis that stands up
in those frames and warns when its size is not a body's (outside 50-250 cm, or an adult's proportions at a size no
adult has), naming the unit that would make it one. Errors and epsilons elsewhere are always in cm of the real
body: that holds only when the unit is right, hence the warning (an error under ``--strict``).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from mocapbench.lazy_imports import Rotation

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
    "rest_up_axis",
    "body_shape",
    "BodyShape",
    "ADULT_HIP_FRACTION",
    "ADULT_STATURE_CM",
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
    from mocapbench.codecs.container import MAX_UNIT_CM, MIN_UNIT_CM, unit_in_range  # the range a stream carries

    if not (math.isfinite(value) and unit_in_range(value)):
        raise ValueError(f"--units {text!r}: a number of cm per unit must be in [{MIN_UNIT_CM:g}, {MAX_UNIT_CM:g}].")
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
    """Which of Y and Z points up in the frames, and why.

    Rules, in order:

    1. When the root travels (more than 50 cm, and 3 times more across one axis than along the other), the axis
       it travels least along is up: people and animals walk on the floor.
    2. Otherwise the body's long axis over the clip: the direction from the root to the head (a joint named like
       ``head``; without one, the rest-pose point farthest from the root along the rest pose's taller axis) is
       measured on every frame (at most 512, evenly spaced); the axis it lies along most on average is up. The
       frames decide, not the rest pose: a rig whose rest pose stands along Y but whose root turns it to stand
       along Z in every frame is Z-up. A ground-level root (game rigs, whose pelvis is a translated child) works
       the same way: the head is above it.
    3. A clip of one joint: the axis along which the rest pose is taller.

    A quadruped that neither walks nor has a head above its root can be wrong: pass ``--up``.

    Returns
    -------
    axis : str
        ``"y"`` or ``"z"``.
    reason : str
        One line for ``inspect``, ``compare`` and warnings, with the measurements.
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
    head, how = _head_joint(motion.skeleton)
    if head > 0:
        share = _body_axis_share(motion, head)
        axis = "yz"[int(np.argmax(share[1:]))]
        return axis, (
            f"the root-to-{motion.skeleton.names[head]} direction ({how}) lies {share[_AXES.index(axis)]:.0%} "
            f"along {axis} on average over the clip ({share[1 + (axis == 'y')]:.0%} along "
            f"{'z' if axis == 'y' else 'y'})"
        )
    extent = np.ptp(_rest_points(motion.skeleton)[:, 1:], axis=0)
    axis = "yz"[int(np.argmax(extent))]
    other = "yz".replace(axis, "")
    return axis, (
        f"the rest pose is {extent['yz'.index(axis)]:.0f} cm tall along {axis} and "
        f"{extent['yz'.index(other)]:.0f} cm along {other}"
    )


_MAX_AXIS_FRAMES = 512


def _head_joint(skeleton: Skeleton) -> tuple[int, str]:
    """The joint whose direction from the root is the body's long axis, and how it was chosen (0: none).

    A joint named like a head (``Head``, ``mixamorig:Head``, ``Bip01 Head``) when there is one; else the rest-pose
    joint farthest from the root along the taller of the rest pose's Y and Z extents (the head or a foot: both lie
    along the body's long axis).
    """
    names = [name.lower().replace(":", " ").replace("_", " ").split() for name in skeleton.names]
    exact = [j for j, words in enumerate(names) if j and words and words[-1] == "head"]
    loose = [j for j, words in enumerate(names) if j and any("head" in word for word in words)]
    if exact or loose:
        return (exact or loose)[0], "named"
    rest = skeleton.rest_positions()
    if len(rest) < 2:
        return 0, ""
    axis = 1 + int(np.argmax(np.ptp(_rest_points(skeleton)[:, 1:], axis=0)))
    distance = np.abs(rest[:, axis] - rest[0, axis])
    return int(np.argmax(distance)), f"the rest pose's farthest joint along {_AXES[axis]}"


def _body_axis_share(motion: Motion, head: int) -> np.ndarray:
    """Mean absolute x, y, z components of the unit root-to-``head`` vector over the frames, shape (3,)."""
    step = max(1, -(-motion.num_frames // _MAX_AXIS_FRAMES))
    positions = motion.every(step).positions() if step > 1 else motion.positions()
    vectors = positions[:, head] - positions[:, 0]
    lengths = np.linalg.norm(vectors, axis=1, keepdims=True)
    vectors = vectors[lengths[:, 0] > 1e-9] / lengths[lengths[:, 0] > 1e-9]
    return np.abs(vectors).mean(axis=0) if len(vectors) else np.zeros(3)


def rest_up_axis(motion: Motion, up_axis: str | None = None) -> str:
    """The axis of the rest pose that stands along ``up_axis`` (default ``motion.up_axis``) in the frames.

    Usually the same axis; a rig whose root turns its Y-standing rest pose to stand along Z in every frame has
    ``"y"`` here for ``"z"`` up. The world's up vector is taken into the root's frame on every frame (at most 512)
    and the rest axis (Y or Z) it lies along most on average is returned.
    """
    up = _AXES.index(up_axis or motion.up_axis)
    step = max(1, -(-motion.num_frames // _MAX_AXIS_FRAMES))
    root = Rotation.from_quat(motion.rotations[::step, 0])
    in_root = root.inv().apply(np.eye(3)[up])
    share = np.abs(in_root).mean(axis=0)
    return "yz"[int(np.argmax(share[1:]))]


@dataclasses.dataclass(frozen=True)
class BodyShape:
    """The rest pose measured along its up axis, to tell a body's size from its proportions.

    Attributes
    ----------
    stature_cm : float
        Extent of the rest pose (joints and end sites) along the axis, cm.
    hip_height_cm : float
        Height above the lowest rest point of the joint where the legs meet (the lowest common ancestor of the
        leaves near the floor, within 10 % of the stature), cm; 0 when no leaf is near the floor.
    legs : int
        How many branches of that joint reach near the floor: 2 for a biped (a quadruped's front legs hang from
        the spine, so its floor leaves meet in 3 or more branches).
    """

    stature_cm: float
    hip_height_cm: float
    legs: int

    @property
    def hip_fraction(self) -> float:
        """Hip height over stature (an adult human's is about 0.5; a toddler's 0.4 or less)."""
        return self.hip_height_cm / self.stature_cm if self.stature_cm > 0 else 0.0

    @property
    def adult_human(self) -> bool:
        """Two legs, and hips at an adult's fraction of the stature (see :data:`ADULT_HIP_FRACTION`)."""
        low, high = ADULT_HIP_FRACTION
        return self.legs == 2 and low <= self.hip_fraction <= high


#: Hip height over stature of an adult human skeleton (the joint where the legs meet, over the rest pose's extent).
#: Adults' legs are about half their stature (more on a skeleton that stops at the neck or lacks a head-top end
#: site, as CMU's BVH release does); a child's are shorter (below 0.42 before the age of about 4), so a body of
#: these proportions is an adult's, and an adult's stature lies in :data:`ADULT_STATURE_CM`.
ADULT_HIP_FRACTION = (0.42, 0.75)
#: Statures (cm) of adult-proportioned skeletons that need no warning.
ADULT_STATURE_CM = (120.0, 230.0)


def body_shape(skeleton: Skeleton, axis: str) -> BodyShape:
    """The rest pose's stature, hip height and legs along ``axis`` (see :class:`BodyShape`)."""
    joints = skeleton.rest_positions()
    column = _AXES.index(axis)
    has_child = np.zeros(skeleton.num_joints, dtype=bool)
    has_child[skeleton.parents[skeleton.parents >= 0]] = True
    leaf_joints = np.flatnonzero(~has_child)
    ends = skeleton.end_site_parents
    heights = np.concatenate([joints[leaf_joints, column], (joints[ends] + skeleton.end_site_offsets)[:, column]])
    owners = np.concatenate([leaf_joints, ends]).astype(int)
    all_heights = _rest_points(skeleton)[:, column]
    low, stature = float(all_heights.min()), float(np.ptp(all_heights))
    near = sorted({int(j) for j in owners[heights - low <= 0.1 * stature]})
    if not near or stature <= 0:
        return BodyShape(stature, 0.0, 0)
    paths = [_path_from_root(skeleton.parents, joint) for joint in near]
    common = 0
    while all(len(p) > common + 1 for p in paths) and len({p[common + 1] for p in paths}) == 1:
        common += 1
    meet = paths[0][common]
    branches = {p[common + 1] if len(p) > common + 1 else meet for p in paths}
    return BodyShape(stature, float(joints[meet, column] - low), len(branches))


def _path_from_root(parents: np.ndarray, joint: int) -> list[int]:
    path = [int(joint)]
    while parents[path[-1]] >= 0:
        path.append(int(parents[path[-1]]))
    return path[::-1]


def rest_height_warning(motion: Motion, up_axis: str | None = None) -> str | None:
    """A one-line warning when the rest pose's size is not a body's in the unit it was read with, else None.

    Two checks, both on the rest pose along the axis that stands up in the frames (:func:`rest_up_axis`, or
    ``up_axis`` when given):

    * the stature is outside 50-250 cm (:data:`REST_HEIGHT_RANGE_CM`);
    * the skeleton has an adult human's proportions (two legs, hips at 42-75 % of the stature: an adult's, see
      :class:`BodyShape`) but not an adult's stature (:data:`ADULT_STATURE_CM`), and another unit of
      :data:`UNITS_CM` gives one closer to 170 cm: a file in inches read as cm is a 64 cm person with an adult's
      legs, which no person is.

    The motion's arrays are in cm, read with ``motion.source_unit_cm`` cm per file unit. The warning names the
    height, the unit it was read with, and the unit that makes the body a body (if any).
    """
    axis = up_axis or rest_up_axis(motion)
    shape = body_shape(motion.skeleton, axis)
    height = shape.stature_cm
    used = motion.source_unit_cm
    low, high = REST_HEIGHT_RANGE_CM
    message = f"rest height is {height:.1f} cm along {axis} read as {unit_label(used)}"
    if low <= height <= high:
        if not shape.adult_human or ADULT_STATURE_CM[0] <= height <= ADULT_STATURE_CM[1]:
            return None
        fits = _units_closer_to_a_body(height, used, ADULT_STATURE_CM)
        if not fits:
            return None
        name, likely = fits[0]
        return (message + f", but its hips are at {shape.hip_fraction:.0%} of its height, an adult's proportions, "
                f"and no adult is {height:.0f} cm tall: the file is likely in {name} ({likely:.1f} cm tall); "
                f"pass --units {name}.")
    message += f"; a body is {low:.0f}-{high:.0f} cm"
    if height <= 0:
        return message + ": the rest pose is flat along the up axis; check --up."
    fits = _units_closer_to_a_body(height, used, REST_HEIGHT_RANGE_CM)
    if not fits:
        return message + ": no unit of --units makes it one; check --units and --up."
    name, likely = fits[0]
    return message + f": the file is likely in {name} ({likely:.1f} cm tall); pass --units {name}."


def _units_closer_to_a_body(height_cm: float, used_cm: float, window: tuple[float, float]) -> list[tuple[str, float]]:
    """Units of :data:`UNITS_CM` that put the height inside ``window`` and closer to 170 cm than ``used_cm`` does.

    Returns ``(name, height in cm)`` pairs, closest first (in log ratio to 170 cm).
    """
    in_units = height_cm / used_cm
    current = abs(math.log(height_cm / _TYPICAL_HEIGHT_CM))
    candidates = sorted(
        (abs(math.log(in_units * cm / _TYPICAL_HEIGHT_CM)), name, in_units * cm) for name, cm in UNITS_CM.items()
    )
    return [(name, value) for distance, name, value in candidates
            if window[0] <= value <= window[1] and distance < current - 1e-9]


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
