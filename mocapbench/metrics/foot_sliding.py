"""Foot sliding: how far a foot that is planted in the original moves horizontally in the decoded motion.

Contacts are found on the **original** motion only, so every codec is judged on the same contacts:

1. **Foot joints**: the ankle and toe joints of each leg, by name where the rig is known (:data:`FOOT_JOINT_NAMES`:
   CMU ASF/AMC ``lfoot``/``ltoes``, CMU BVH ``LeftFoot``/``LeftToeBase``, the Bandai Namco game rig
   ``Foot_L``/``Toes_L``, and their right-hand twins; case-insensitive), else the two leaf joints lowest on
   average over the clip and their parents.
2. **Low**: the joint is within :attr:`ContactSettings.height_cm` of its own floor level, the
   :attr:`ContactSettings.floor_percentile` percentile of its height over the clip (its own level, because an
   ankle rests higher above the ground than a toe; a percentile, so that one marker glitch does not set it).
   Height is the coordinate on ``Motion.up_axis``.
3. **Slow**: the joint's 3-D speed (central differences, cm/s) is under :attr:`ContactSettings.speed_cm_s`.
4. A **contact** is a run of consecutive low and slow frames of one joint lasting at least
   :attr:`ContactSettings.min_duration_s`.

The sliding of a contact is the decoded joint's **horizontal travel** over it: the length of its path in the
plane perpendicular to the up axis, summed frame to frame (cm). The original's own travel over the same
contact is measured the same way (the capture's own sliding, bounded by the speed threshold times the
duration): what a codec adds is the difference. Travel is summed over every displayed frame, so a foot that
jitters in place travels too, as an animator sees it at that frame rate. Pure functions, no I/O.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mocapbench.metrics.distortion import _check_pair

__all__ = ["FOOT_JOINT_NAMES", "ContactSettings", "Contact", "foot_joints", "find_contacts", "contact_travel",
           "FootSliding", "foot_sliding"]

FOOT_JOINT_NAMES = (
    ("lfoot", "ltoes", "rfoot", "rtoes"),                          # CMU ASF/AMC
    ("leftfoot", "lefttoebase", "rightfoot", "righttoebase"),      # CMU BVH (cgspeed), Mixamo-like rigs
    ("foot_l", "toes_l", "foot_r", "toes_r"),                      # Bandai Namco Research Motion Dataset
)
"""Ankle and toe joint names of known rigs (lower case; a rig matches when it has all four)."""

_UP_AXES = {"x": 0, "y": 1, "z": 2}


@dataclass(frozen=True)
class ContactSettings:
    """Thresholds that decide a foot contact on the original motion.

    height_cm: a joint is low within this height above its floor level, cm (default 5: an ankle whose heel lifts
    off rises more). speed_cm_s: a joint is slow under this 3-D speed, cm/s (default 20: above the slow roll of a
    planted foot from heel to toe, far below a swinging foot's metres per second).
    floor_percentile: the joint's floor level, a percentile of its height over the clip, in [0, 50] (default 2).
    min_duration_s: shortest contact, s (default 0.1).
    """

    height_cm: float = 5.0
    speed_cm_s: float = 20.0
    floor_percentile: float = 2.0
    min_duration_s: float = 0.1

    def __post_init__(self) -> None:
        for name in ("height_cm", "speed_cm_s", "min_duration_s"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"ContactSettings.{name} must be a finite number > 0, got {value}.")
        if not 0 <= self.floor_percentile <= 50:
            raise ValueError(f"ContactSettings.floor_percentile must be in [0, 50], got {self.floor_percentile}.")


@dataclass(frozen=True)
class Contact:
    """One contact: joint ``joint`` is planted on frames ``start`` .. ``stop - 1``."""

    joint: int
    start: int
    stop: int


def _up_index(up_axis: str) -> int:
    if up_axis not in _UP_AXES:
        raise ValueError(f"`up_axis` must be 'x', 'y' or 'z', got {up_axis!r}.")
    return _UP_AXES[up_axis]


def foot_joints(names, parents, positions, up_axis: str = "y") -> list[int]:
    """Indices of the ankle and toe joints (see the module docstring for the rule).

    Parameters
    ----------
    names : sequence of str, length J
    parents : array_like, shape (J,), int
    positions : array_like, shape (F, J, 3), float, cm
        The original motion, for the fallback (lowest leaves).
    up_axis : str
        ``"x"``, ``"y"`` or ``"z"``.

    Returns
    -------
    list of int
        Sorted joint indices; empty for a skeleton of one joint.
    """
    lower = [str(n).lower() for n in names]
    for rig in FOOT_JOINT_NAMES:
        if all(name in lower for name in rig):
            return sorted(lower.index(name) for name in rig)
    parents = np.asarray(parents, dtype=np.int64)
    if len(parents) < 2:
        return []
    leaves = np.setdiff1d(np.arange(1, len(parents)), parents)
    heights = np.asarray(positions, dtype=np.float64)[:, leaves, _up_index(up_axis)].mean(axis=0)
    lowest = leaves[np.argsort(heights, kind="stable")[:2]]
    return sorted({int(j) for j in lowest} | {int(parents[j]) for j in lowest if parents[j] > 0})


def find_contacts(positions, fps: float, joints, up_axis: str = "y",
                  settings: ContactSettings = ContactSettings()) -> list[Contact]:
    """The contacts of ``joints`` in ``positions`` (module docstring, steps 2-4).

    Parameters
    ----------
    positions : array_like, shape (F, J, 3), float, cm
        The original motion.
    fps : float
        Frames per second, > 0.
    joints : sequence of int
        The foot joints (:func:`foot_joints`).
    up_axis : str
    settings : ContactSettings

    Returns
    -------
    list of Contact
        Per joint in the order given, in time order.
    """
    positions = np.asarray(positions, dtype=np.float64)
    fps = float(fps)
    if not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"`fps` must be a finite number > 0, got {fps}.")
    num_frames = positions.shape[0]
    if num_frames < 2:
        return []
    up = _up_index(up_axis)
    min_frames = max(2, int(np.ceil(settings.min_duration_s * fps - 1e-9)))
    contacts = []
    for joint in joints:
        track = positions[:, int(joint)]
        height = track[:, up]
        floor = np.percentile(height, settings.floor_percentile)
        speed = np.linalg.norm(np.gradient(track, axis=0), axis=-1) * fps
        planted = (height - floor < settings.height_cm) & (speed < settings.speed_cm_s)
        edges = np.flatnonzero(np.diff(np.concatenate([[0], planted.astype(np.int8), [0]])))
        for start, stop in zip(edges[::2], edges[1::2]):
            if stop - start >= min_frames:
                contacts.append(Contact(int(joint), int(start), int(stop)))
    return contacts


def contact_travel(positions, contacts, up_axis: str = "y") -> np.ndarray:
    """Horizontal path length of each contact's joint over the contact's frames.

    Parameters
    ----------
    positions : array_like, shape (F, J, 3), float, cm
    contacts : sequence of Contact
    up_axis : str

    Returns
    -------
    ndarray, shape (len(contacts),), float, cm
    """
    positions = np.asarray(positions, dtype=np.float64)
    plane = [axis for axis in range(3) if axis != _up_index(up_axis)]
    out = np.empty(len(contacts))
    for k, contact in enumerate(contacts):
        path = positions[contact.start:contact.stop, contact.joint][:, plane]
        out[k] = np.linalg.norm(np.diff(path, axis=0), axis=-1).sum()
    return out


@dataclass(frozen=True)
class FootSliding:
    """Per-contact horizontal travel of the decoded and of the original foot (cm), and the contacts themselves."""

    contacts: tuple[Contact, ...]
    decoded_cm: np.ndarray
    reference_cm: np.ndarray

    @property
    def added_cm(self) -> np.ndarray:
        """What the codec added to each contact's travel, cm (negative where it removed some)."""
        return self.decoded_cm - self.reference_cm


def foot_sliding(reference, decoded, fps: float, names, parents, up_axis: str = "y",
                 settings: ContactSettings = ContactSettings()) -> FootSliding:
    """Contacts of the original's feet and the horizontal travel of both motions over each.

    Parameters
    ----------
    reference, decoded : array_like, shape (F, J, 3), float, cm
    fps : float
        Frames per second, > 0.
    names : sequence of str, length J
    parents : array_like, shape (J,), int
    up_axis : str
    settings : ContactSettings

    Returns
    -------
    FootSliding
        Empty arrays when the original never plants a foot.
    """
    reference, decoded = _check_pair(reference, decoded)
    joints = foot_joints(names, parents, reference, up_axis)
    contacts = tuple(find_contacts(reference, fps, joints, up_axis, settings))
    return FootSliding(contacts, contact_travel(decoded, contacts, up_axis),
                       contact_travel(reference, contacts, up_axis))
