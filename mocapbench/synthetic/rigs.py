"""Synthetic rigs users throw at mocapbench: many joint counts and topologies, Y-up or Z-up, any unit and Euler order.

The CMU-like fixture of :mod:`mocapbench.synthetic` is one 31-joint skeleton; real files differ. This module builds
the users' cases from seeds, with no file:

* skeletons of 15 to 70 joints in three topologies (``"biped"``, ``"quadruped"``, ``"random"`` tree), always in
  depth-first order (the order a BVH file lists them, so a BVH round trip keeps indices);
* Y-up (Z forward) or Z-up (-Y forward, the Blender/3ds Max convention): the Z-up motion is the Y-up one turned by
  +90 degrees about X, so both have the same joint distances;
* any of the 6 Tait-Bryan Euler orders for the BVH channels, one for every joint or all six cycled (``"mixed"``);
* clips of 1 to 1,000,000 frames (the cases use 2 to 20,000), a T-pose reference first frame, two takes
  concatenated (a cut with a root teleport);
* a source length unit (``Motion.source_unit_cm``): the motion itself is in cm, as every Motion; the unit says
  which unit a file of the case is written in (:func:`write_case_bvh`, with position channels on every joint as
  MotionBuilder exports when the case asks for it).

Everything is seeded: the same arguments give the same arrays.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from mocapbench.io.bvh import _depth_first_order  # the order a BVH file lists joints
from mocapbench.io.units import UNITS_CM, turn_axes
from mocapbench.motion import Motion, Skeleton

__all__ = [
    "EULER_ORDERS",
    "TOPOLOGIES",
    "UNITS_CM",
    "RigConfig",
    "RigCase",
    "rig_skeleton",
    "rig_motion",
    "with_tpose_first_frame",
    "concatenate_takes",
    "rotate_to_z_up",
    "user_case",
    "user_cases",
    "USER_CASE_NAMES",
    "write_case_bvh",
]

#: The six Tait-Bryan orders a BVH CHANNELS line can list.
EULER_ORDERS = ("XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX")
TOPOLOGIES = ("biped", "quadruped", "random")
MIN_JOINTS, MAX_JOINTS = 15, 70

# A full rig as (name, parent, offset cm (Y up, Z forward, +X left), priority): a rig of J joints keeps the J
# joints of lowest priority; a dropped joint's children hang from its nearest kept ancestor with the offsets summed,
# so the rest pose keeps its proportions at every J.
_Joint = tuple[str, str | None, tuple[float, float, float], int]


def _biped_joints() -> list[_Joint]:
    """A 70-joint human (1.6 m, T-pose: arms along +-X): core 15, clavicles, spine, toes, 30 fingers, twists, face."""
    joints: list[_Joint] = [
        ("Hips", None, (0.0, 0.0, 0.0), 0),
        ("Spine", "Hips", (0.0, 10.0, 0.0), 5),
        ("Spine1", "Spine", (0.0, 12.0, 0.0), 0),
        ("Spine2", "Spine1", (0.0, 12.0, 0.0), 21),
        ("Neck", "Spine2", (0.0, 14.0, 0.0), 16),
        ("Head", "Neck", (0.0, 10.0, 0.0), 0),
        ("HeadTop", "Head", (0.0, 18.0, 0.0), 70),
        ("Jaw", "Head", (0.0, -3.0, 6.0), 71),
        ("LeftEye", "Head", (3.0, 6.0, 8.0), 72),
        ("RightEye", "Head", (-3.0, 6.0, 8.0), 72),
        ("Nose", "Head", (0.0, 4.0, 10.0), 75),
        ("Tongue", "Jaw", (0.0, 0.0, 4.0), 75),
    ]
    for side, sign in (("Left", 1.0), ("Right", -1.0)):
        joints += [
            (f"{side}Shoulder", "Spine2", (sign * 3.0, 10.0, 0.0), 17),
            (f"{side}Arm", f"{side}Shoulder", (sign * 15.0, 0.0, 0.0), 0),
            (f"{side}ForeArm", f"{side}Arm", (sign * 28.0, 0.0, 0.0), 0),
            (f"{side}Hand", f"{side}ForeArm", (sign * 25.0, 0.0, 0.0), 0),
            (f"{side}UpLeg", "Hips", (sign * 9.0, -8.0, 0.0), 0),
            (f"{side}Leg", f"{side}UpLeg", (0.0, -43.0, 0.0), 0),
            (f"{side}Foot", f"{side}Leg", (0.0, -43.0, 0.0), 0),
            (f"{side}ToeBase", f"{side}Foot", (0.0, -6.0, 13.0), 18),
            # Twist bones (game rigs): leaves halfway along the limb bone.
            (f"{side}ArmTwist", f"{side}Arm", (sign * 14.0, 0.0, 0.0), 60),
            (f"{side}ForeArmTwist", f"{side}ForeArm", (sign * 12.5, 0.0, 0.0), 61),
            (f"{side}UpLegTwist", f"{side}UpLeg", (0.0, -21.5, 0.0), 62),
            (f"{side}LegTwist", f"{side}Leg", (0.0, -21.5, 0.0), 63),
            (f"{side}Brow", "Head", (sign * 3.0, 9.0, 8.0), 73),
            (f"{side}Cheek", "Head", (sign * 4.0, 3.0, 8.0), 74),
        ]
        fingers = (("Thumb", (2.0, 0.0, 3.0)), ("Index", (8.0, 0.0, 2.0)), ("Middle", (8.5, 0.0, 0.5)),
                   ("Ring", (8.0, 0.0, -1.0)), ("Pinky", (7.5, 0.0, -2.5)))
        for f, (finger, (x, y, z)) in enumerate(fingers):
            parent = f"{side}Hand"
            for phalanx in range(1, 4):
                name = f"{side}Hand{finger}{phalanx}"
                offset = (sign * x, y, z) if phalanx == 1 else (sign * 3.0, 0.0, 0.0)
                # Priorities 30..59: first knuckles of both hands first, then the second, then the third.
                joints.append((name, parent, offset, 30 + 10 * (phalanx - 1) + 2 * f + (sign < 0)))
                parent = name
    return joints


def _quadruped_joints() -> list[_Joint]:
    """A 70-joint quadruped (a dog about 60 cm at the withers): spine, neck, head, 4 legs, 3 toes per foot, tail."""
    joints: list[_Joint] = [
        ("Pelvis", None, (0.0, 0.0, 0.0), 0),
        ("Spine1", "Pelvis", (0.0, 2.0, 15.0), 0),
        ("Spine2", "Spine1", (0.0, 1.0, 15.0), 0),
        ("Chest", "Spine2", (0.0, 0.0, 15.0), 16),
        ("Neck1", "Chest", (0.0, 8.0, 8.0), 0),
        ("Neck2", "Neck1", (0.0, 8.0, 6.0), 17),
        ("Head", "Neck2", (0.0, 5.0, 6.0), 0),
        ("Jaw", "Head", (0.0, -4.0, 8.0), 25),
        ("LeftEar", "Head", (4.0, 6.0, 0.0), 26),
        ("RightEar", "Head", (-4.0, 6.0, 0.0), 26),
    ]
    for end, hip, parent, depth in (("Front", "Shoulder", "Chest", 0.0), ("Hind", "Hip", "Pelvis", 3.0)):
        for side, sign in (("Left", 1.0), ("Right", -1.0)):
            prefix = f"{side}{end}"
            joints += [
                (f"{prefix}{hip}", parent, (sign * 8.0, -5.0, 0.0), 18),
                (f"{prefix}Upper", f"{prefix}{hip}", (0.0, -15.0, depth), 0),
                (f"{prefix}Lower", f"{prefix}Upper", (0.0, -17.0, -depth), 0),
                (f"{prefix}Paw", f"{prefix}Lower", (0.0, -12.0, 1.0), 19),
            ]
            for toe, x in enumerate((-1.5, 0.0, 1.5)):
                joints.append((f"{prefix}Toe{toe}", f"{prefix}Paw", (sign * x, -3.0, 3.0), 40 + toe))
                joints.append((f"{prefix}Toe{toe}Tip", f"{prefix}Toe{toe}", (0.0, -1.0, 2.0), 50 + toe))
    parent = "Pelvis"
    for t in range(20):
        offset = (0.0, 1.0, -4.0) if t else (0.0, 2.0, -5.0)
        joints.append((f"Tail{t + 1}", parent, offset, 20 + t if t < 4 else 60 + t))
        parent = f"Tail{t + 1}"
    return joints


def check_fields(config, checks: list[tuple[str, bool, str]]) -> None:
    """Raise ``ValueError("<Config>.<field> must be <allowed>, got <value>.")`` for the first failed check.

    Parameters
    ----------
    config : dataclass instance
    checks : list of (field name, passed, what is allowed, e.g. ``"in [1, 16]"``)
    """
    for name, ok, allowed in checks:
        if not ok:
            raise ValueError(f"{type(config).__name__}.{name} must be {allowed}, got {getattr(config, name)!r}.")


def _skeleton_from_tree(names: list[str], parents: list[int], offsets: np.ndarray, orders: tuple[str, ...]) -> Skeleton:
    """A Skeleton in depth-first order from a tree whose parents may come in any order; leaves get an End Site."""
    order = _depth_first_order(np.array(parents))
    where = {old: new for new, old in enumerate(order)}
    new_parents = [-1 if parents[old] < 0 else where[parents[old]] for old in order]
    leaves = [j for j in range(len(order)) if j not in set(new_parents)]
    # End site: a short bone continuing the leaf's direction (3 cm, or 5 cm up for a leaf at the root).
    ends = []
    for leaf in leaves:
        direction = offsets[order[leaf]]
        norm = np.linalg.norm(direction)
        ends.append(direction / norm * 3.0 if norm > 1e-9 else np.array([0.0, 5.0, 0.0]))
    return Skeleton(
        names=tuple(names[old] for old in order),
        parents=np.array(new_parents),
        offsets=offsets[order],
        channel_orders=tuple(orders[j % len(orders)] for j in range(len(order))),
        end_site_parents=np.array(leaves, dtype=np.int64),
        end_site_offsets=np.array(ends).reshape(-1, 3),
    )


def _pruned(joints: list[_Joint], num_joints: int) -> tuple[list[str], list[int], np.ndarray]:
    """Keep the ``num_joints`` joints of lowest priority (stable), re-hang children, sum the dropped offsets."""
    if num_joints > len(joints):
        raise ValueError(f"This topology has at most {len(joints)} joints, got num_joints={num_joints}.")
    rank = sorted(range(len(joints)), key=lambda i: (joints[i][3], i))
    kept = set(rank[:num_joints])
    index = {name: i for i, (name, _, _, _) in enumerate(joints)}
    names, parents, offsets = [], [], []
    for i in sorted(kept):
        name, parent, offset, _ = joints[i]
        total = np.array(offset, dtype=np.float64)
        while parent is not None and index[parent] not in kept:
            total += joints[index[parent]][2]
            parent = joints[index[parent]][1]
        names.append(name)
        parents.append(-1 if parent is None else parent)  # a name for now
        offsets.append(total)
    parents_index = [-1 if p == -1 else names.index(p) for p in parents]
    return names, parents_index, np.array(offsets)


def _random_tree(num_joints: int, rng: np.random.Generator) -> tuple[list[str], list[int], np.ndarray]:
    """A random tree: each joint extends a chain (70 %) or branches from any earlier joint; bones 3-30 cm."""
    parents = [-1]
    for joint in range(1, num_joints):
        parents.append(joint - 1 if rng.random() < 0.7 else int(rng.integers(0, joint)))
    directions = rng.normal(size=(num_joints, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    offsets = directions * rng.uniform(3.0, 30.0, size=(num_joints, 1))
    offsets[0] = 0.0
    return [f"joint{j:02d}" for j in range(num_joints)], parents, offsets


@dataclass(frozen=True)
class RigConfig:
    """Parameters of :func:`rig_skeleton` and :func:`rig_motion`.

    Attributes
    ----------
    num_joints : int
        J, 15..70. Default 31.
    topology : str
        ``"biped"`` (default), ``"quadruped"`` or ``"random"`` (a seeded random tree).
    up_axis : str
        ``"y"`` (default: Y up, Z forward) or ``"z"`` (Z up, -Y forward).
    euler_orders : str
        BVH channel order of every joint: one of :data:`EULER_ORDERS`, or ``"mixed"`` to cycle all six over the
        joints. Default ``"ZYX"``.
    unit : str
        Source length unit recorded in ``Motion.source_unit_cm``: a key of :data:`UNITS_CM`. Default ``"cm"``.
        The motion's arrays are in cm whatever the unit.
    num_frames : int
        F, 1..1_000_000. Default 240.
    fps : float
        Frames per second, > 0. Default 120.
    amplitude_deg : float
        Largest total amplitude of a joint angle, degrees, 0..90. Default 25.
    speed_cm_s : float
        Forward root speed, cm/s. Default 120.
    seed : int
        Seed of every random choice (topology of ``"random"``, frequencies, phases). Default 0.
    """

    num_joints: int = 31
    topology: str = "biped"
    up_axis: str = "y"
    euler_orders: str = "ZYX"
    unit: str = "cm"
    num_frames: int = 240
    fps: float = 120.0
    amplitude_deg: float = 25.0
    speed_cm_s: float = 120.0
    seed: int = 0

    def __post_init__(self) -> None:
        checks = [
            ("num_joints", MIN_JOINTS <= self.num_joints <= MAX_JOINTS, f"in [{MIN_JOINTS}, {MAX_JOINTS}]"),
            ("topology", self.topology in TOPOLOGIES, f"one of {list(TOPOLOGIES)}"),
            ("up_axis", self.up_axis in ("y", "z"), "one of ['y', 'z']"),
            ("euler_orders", self.euler_orders in (*EULER_ORDERS, "mixed"), f"one of {[*EULER_ORDERS, 'mixed']}"),
            ("unit", self.unit in UNITS_CM, f"one of {list(UNITS_CM)}"),
            ("num_frames", 1 <= self.num_frames <= 1_000_000, "in [1, 1000000]"),
            ("fps", self.fps > 0, "> 0"),
            ("amplitude_deg", 0 <= self.amplitude_deg <= 90, "in [0, 90]"),
        ]
        check_fields(self, checks)


def rig_skeleton(config: RigConfig | None = None, **overrides) -> Skeleton:
    """The Y-up skeleton of a rig config, offsets in cm, joints in depth-first order.

    Parameters
    ----------
    config : RigConfig, optional
    **overrides
        Fields of :class:`RigConfig` (``num_joints``, ``topology``, ``euler_orders``, ``seed`` matter here).

    Returns
    -------
    Skeleton
        J = ``num_joints`` joints; the rest pose is a T-pose for ``"biped"``; every leaf has one End Site.
        Always Y-up: :func:`rig_motion` turns Z-up rigs.
    """
    config = RigConfig(**{**(dataclasses.asdict(config) if config else {}), **overrides})
    if config.topology == "random":
        names, parents, offsets = _random_tree(config.num_joints, np.random.default_rng([config.seed, 1]))
    else:
        full = _biped_joints() if config.topology == "biped" else _quadruped_joints()
        names, parents, offsets = _pruned(full, config.num_joints)
    orders = EULER_ORDERS if config.euler_orders == "mixed" else (config.euler_orders,)
    return _skeleton_from_tree(names, parents, offsets, orders)


def rotate_to_z_up(motion: Motion) -> Motion:
    """The same motion in Z-up axes: everything turned by +90 degrees about X (+Y -> +Z, +Z -> -Y).

    Offsets, end sites and root positions are rotated and every local rotation conjugated, so the joint positions
    are the Y-up ones rotated (joint distances unchanged). ``up_axis`` becomes ``"z"``.
    """
    return turn_axes(motion, Rotation.from_euler("X", 90, degrees=True), "z")


def rig_motion(config: RigConfig | None = None, **overrides) -> Motion:
    """A seeded sinusoidal motion on :func:`rig_skeleton`, in cm, Y-up or Z-up.

    Every joint angle is a sum of 3 sinusoids (frequencies uniform in [0.1, 2] Hz, random phases, total amplitude
    up to ``amplitude_deg``); the root's pitch and roll are damped to a quarter (a torso), the root walks forward at
    ``speed_cm_s`` at its rest height above the lowest rest point, bobbing 2 cm.

    Parameters
    ----------
    config : RigConfig, optional
    **overrides
        Fields of :class:`RigConfig`.

    Returns
    -------
    Motion
        F = ``num_frames``, J = ``num_joints``; ``source_unit_cm`` = the unit's cm, ``up_axis`` = the rig's; named
        ``"<topology>-<J>-<up>up-<unit>-<orders>-seed<seed>"``.
    """
    config = RigConfig(**{**(dataclasses.asdict(config) if config else {}), **overrides})
    skeleton = rig_skeleton(config)
    rng = np.random.default_rng([config.seed, 2])
    num_joints, num_frames = skeleton.num_joints, config.num_frames
    shape = (num_joints, 3, 3)
    frequencies = rng.uniform(0.1, 2.0, size=shape)
    amplitudes = rng.uniform(0.0, config.amplitude_deg, size=shape) / 3
    phases = rng.uniform(0.0, 2 * np.pi, size=shape)
    time_s = np.arange(num_frames) / config.fps
    angles = np.einsum(
        "jck,fjck->fjc", amplitudes, np.sin(2 * np.pi * frequencies * time_s[:, None, None, None] + phases)
    )
    angles[:, 0, 1:] *= 0.25
    rotations = Rotation.from_euler("ZYX", angles.reshape(-1, 3), degrees=True).as_quat()
    rest = skeleton.rest_positions()
    ends = rest[skeleton.end_site_parents] + skeleton.end_site_offsets
    ground = min(rest[:, 1].min(), ends[:, 1].min())
    root = np.stack(
        [np.zeros(num_frames), -ground + 2.0 * np.sin(2 * np.pi * frequencies[0, 0, 0] * time_s),
         config.speed_cm_s * time_s],
        axis=1,
    )
    orders = "mixed" if config.euler_orders == "mixed" else config.euler_orders
    motion = Motion(
        skeleton=skeleton,
        fps=config.fps,
        root_positions=root,
        rotations=rotations.reshape(num_frames, num_joints, 4),
        name=f"{config.topology}-{num_joints}-{config.up_axis}up-{config.unit}-{orders.lower()}-seed{config.seed}",
        source_unit_cm=UNITS_CM[config.unit],
    )
    return rotate_to_z_up(motion) if config.up_axis == "z" else motion


def with_tpose_first_frame(motion: Motion) -> Motion:
    """``motion`` with one rest-pose frame (identity rotations: a T-pose for bipeds) put before frame 0.

    The reference frame stands at the first frame's root position, as the first frame of every CMU BVH file.
    Returns F + 1 frames.
    """
    identity = np.zeros((1, motion.num_joints, 4))
    identity[..., 3] = 1.0
    return dataclasses.replace(
        motion,
        root_positions=np.concatenate([motion.root_positions[:1], motion.root_positions]),
        rotations=np.concatenate([identity, motion.rotations]),
        name=f"{motion.name}+tpose",
    )


def concatenate_takes(first: Motion, second: Motion) -> Motion:
    """Two takes on one skeleton played one after the other, with a cut between them (no blending).

    Parameters
    ----------
    first, second : Motion
        Same skeleton structure and fps.

    Returns
    -------
    Motion
        ``first.num_frames + second.num_frames`` frames; the cut lies between frames ``first.num_frames - 1`` and
        ``first.num_frames``; metadata from ``first``.
    """
    if not first.skeleton.same_structure(second.skeleton):
        raise ValueError(f"Takes {first.name!r} and {second.name!r} are on different skeletons; cannot concatenate.")
    if first.fps != second.fps:
        raise ValueError(
            f"Takes {first.name!r} ({first.fps} fps) and {second.name!r} ({second.fps} fps) differ in fps."
        )
    return dataclasses.replace(
        first,
        root_positions=np.concatenate([first.root_positions, second.root_positions]),
        rotations=np.concatenate([first.rotations, second.rotations]),
        name=f"{first.name}|{second.name}",
    )


@dataclass(frozen=True, eq=False)
class RigCase:
    """One users' case: a motion (cm) and how a user's file of it is written.

    Attributes
    ----------
    name : str
        Short key, e.g. ``"quadruped-40-zup-mm"``.
    motion : Motion
        In cm; ``motion.source_unit_cm`` and ``motion.up_axis`` say the file's unit and up axis.
    bvh_position_channels : str
        ``"root"`` or ``"all"`` (every joint gets position channels, as MotionBuilder writes).
    description : str
        One line for tables.
    """

    name: str
    motion: Motion
    bvh_position_channels: str = "root"
    description: str = ""


def _take_pair(**overrides) -> Motion:
    """Two 240-frame takes of one biped: the second another seed starting 3 m to the side (a cut)."""
    first = rig_motion(**overrides, seed=5)
    second = rig_motion(**overrides, seed=6)
    shift = np.array([300.0, 0.0, 0.0])
    return concatenate_takes(first, dataclasses.replace(second, root_positions=second.root_positions + shift))


_CASES = {
    "biped-15-yup-cm-zyx": (lambda: rig_motion(num_joints=15), "root", "15-joint biped, Y-up, cm, ZYX"),
    "biped-22-zup-mm-xyz": (
        lambda: rig_motion(num_joints=22, up_axis="z", unit="mm", euler_orders="XYZ", fps=30.0, seed=1),
        "root", "22-joint biped, Z-up, mm, XYZ, 30 fps"),
    "biped-52-yup-inch-mixed": (
        lambda: rig_motion(num_joints=52, unit="inch", euler_orders="mixed", seed=2),
        "all", "52-joint biped with fingers, Y-up, inch, all 6 Euler orders, position channels on every joint"),
    "biped-70-zup-m-yxz": (
        lambda: rig_motion(num_joints=70, up_axis="z", unit="m", euler_orders="YXZ", fps=60.0, seed=3),
        "root", "70-joint biped with fingers and face, Z-up, m, YXZ, 60 fps"),
    "quadruped-40-zup-mm-zxy": (
        lambda: rig_motion(num_joints=40, topology="quadruped", up_axis="z", unit="mm", euler_orders="ZXY", seed=4),
        "root", "40-joint quadruped, Z-up, mm, ZXY"),
    "random-33-yup-cmu-yzx": (
        lambda: rig_motion(num_joints=33, topology="random", unit="cmu", euler_orders="YZX", seed=7),
        "root", "33-joint random tree, Y-up, CMU units, YZX"),
    "biped-31-2-frames": (lambda: rig_motion(num_frames=2, seed=8), "root", "31-joint biped, 2 frames"),
    "biped-31-tpose-first": (
        lambda: with_tpose_first_frame(rig_motion(num_frames=480, seed=9)), "root",
        "31-joint biped, 480 frames after a T-pose reference frame"),
    "biped-31-two-takes": (lambda: _take_pair(num_frames=240), "root", "two 240-frame takes concatenated (a cut)"),
    "biped-31-20000-frames": (
        lambda: rig_motion(num_frames=20_000, seed=10), "root", "31-joint biped, 20,000 frames (167 s at 120 fps)"),
}
#: Every case name, in table order; the 20,000-frame case is last.
USER_CASE_NAMES = tuple(_CASES)


def user_case(name: str) -> RigCase:
    """The named case of :data:`USER_CASE_NAMES` (built on each call, deterministic)."""
    if name not in _CASES:
        raise KeyError(f"No synthetic case {name!r}; cases are {list(_CASES)}.")
    make, channels, description = _CASES[name]
    return RigCase(name=name, motion=make(), bvh_position_channels=channels, description=description)


def user_cases(*, include_long: bool = False) -> list[RigCase]:
    """Every case of :data:`USER_CASE_NAMES`; the 20,000-frame one only with ``include_long``."""
    return [user_case(name) for name in USER_CASE_NAMES if include_long or not name.endswith("20000-frames")]


def write_case_bvh(case: RigCase, path: str | Path, *, overwrite: bool = False) -> Path:
    """Write a case as the user's BVH file: in its source unit, with its position channels (root or all joints)."""
    from mocapbench.io.bvh import write_bvh

    return write_bvh(
        case.motion,
        path,
        length_unit_cm=case.motion.source_unit_cm,
        position_channels=case.bvh_position_channels,
        overwrite=overwrite,
    )
