"""Synthetic sinusoidal skeletons: the test fixture and the embedded default data of ``make run``.

The skeleton copies the 31-joint CMU tree (the joint names of the CMU BVH release) with bone lengths of an
adult about 175 cm tall; every joint angle is a sum of a few sinusoids with seeded random frequencies,
amplitudes and phases; the root walks forward along +Z at constant speed with a vertical bob. Nothing here
reads a file, so it works on a fresh clone with no ``../shared``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from mocapbench.lazy_imports import Rotation

from mocapbench.motion import Motion, Skeleton

from mocapbench.synthetic.rigs import check_fields

__all__ = [
    "SyntheticConfig",
    "cmu_like_skeleton",
    "sinusoidal_motion",
]

# (name, parent name, rest offset from the parent in cm: Y up, Z forward, +X the character's left)
_CMU_LIKE_JOINTS: tuple[tuple[str, str | None, tuple[float, float, float]], ...] = (
    ("Hips", None, (0.0, 0.0, 0.0)),
    ("LHipJoint", "Hips", (0.0, 0.0, 0.0)),
    ("LeftUpLeg", "LHipJoint", (9.0, -8.0, 0.0)),
    ("LeftLeg", "LeftUpLeg", (0.0, -43.0, 0.0)),
    ("LeftFoot", "LeftLeg", (0.0, -43.0, 0.0)),
    ("LeftToeBase", "LeftFoot", (0.0, -6.0, 13.0)),
    ("RHipJoint", "Hips", (0.0, 0.0, 0.0)),
    ("RightUpLeg", "RHipJoint", (-9.0, -8.0, 0.0)),
    ("RightLeg", "RightUpLeg", (0.0, -43.0, 0.0)),
    ("RightFoot", "RightLeg", (0.0, -43.0, 0.0)),
    ("RightToeBase", "RightFoot", (0.0, -6.0, 13.0)),
    ("LowerBack", "Hips", (0.0, 0.0, 0.0)),
    ("Spine", "LowerBack", (0.0, 12.0, 0.0)),
    ("Spine1", "Spine", (0.0, 12.0, 0.0)),
    ("Neck", "Spine1", (0.0, 12.0, 0.0)),
    ("Neck1", "Neck", (0.0, 9.0, 0.0)),
    ("Head", "Neck1", (0.0, 9.0, 0.0)),
    ("LeftShoulder", "Spine1", (0.0, 10.0, 0.0)),
    ("LeftArm", "LeftShoulder", (17.0, 2.0, 0.0)),
    ("LeftForeArm", "LeftArm", (28.0, 0.0, 0.0)),
    ("LeftHand", "LeftForeArm", (25.0, 0.0, 0.0)),
    ("LeftFingerBase", "LeftHand", (4.0, 0.0, 0.0)),
    ("LeftHandIndex1", "LeftFingerBase", (4.0, 0.0, 0.0)),
    ("LThumb", "LeftHand", (2.0, 0.0, 3.0)),
    ("RightShoulder", "Spine1", (0.0, 10.0, 0.0)),
    ("RightArm", "RightShoulder", (-17.0, 2.0, 0.0)),
    ("RightForeArm", "RightArm", (-28.0, 0.0, 0.0)),
    ("RightHand", "RightForeArm", (-25.0, 0.0, 0.0)),
    ("RightFingerBase", "RightHand", (-4.0, 0.0, 0.0)),
    ("RightHandIndex1", "RightFingerBase", (-4.0, 0.0, 0.0)),
    ("RThumb", "RightHand", (-2.0, 0.0, 3.0)),
)
_END_SITES: tuple[tuple[str, tuple[float, float, float]], ...] = (
    ("LeftToeBase", (0.0, 0.0, 5.0)),
    ("RightToeBase", (0.0, 0.0, 5.0)),
    ("Head", (0.0, 18.0, 0.0)),
    ("LeftHandIndex1", (3.0, 0.0, 0.0)),
    ("LThumb", (2.0, 0.0, 2.0)),
    ("RightHandIndex1", (-3.0, 0.0, 0.0)),
    ("RThumb", (-2.0, 0.0, 2.0)),
)
_ROOT_HEIGHT_CM = 94.0  # hips above the floor: leg chain 8 + 43 + 43 cm


def cmu_like_skeleton() -> Skeleton:
    """The 31-joint CMU joint tree with adult bone lengths (rest height about 175 cm)."""
    names = [name for name, _, _ in _CMU_LIKE_JOINTS]
    parents = [-1 if parent is None else names.index(parent) for _, parent, _ in _CMU_LIKE_JOINTS]
    return Skeleton(
        names=tuple(names),
        parents=np.array(parents),
        offsets=np.array([offset for _, _, offset in _CMU_LIKE_JOINTS]),
        channel_orders=("ZYX",) * len(names),
        end_site_parents=np.array([names.index(joint) for joint, _ in _END_SITES]),
        end_site_offsets=np.array([offset for _, offset in _END_SITES]),
    )


@dataclass(frozen=True)
class SyntheticConfig:
    """Parameters of :func:`sinusoidal_motion`.

    Attributes
    ----------
    num_frames : int
        F, frames, 1..1_000_000. Default 240.
    fps : float
        Frames per second, > 0. Default 120.
    num_frequencies : int
        Sinusoids summed per joint angle, 1..16. Default 3.
    max_frequency_hz : float
        Upper bound of the random frequencies, Hz, > 0. Default 2.
    amplitude_deg : float
        Largest amplitude of one sinusoid, degrees, 0..90. Default 20.
    speed_cm_s : float
        Forward root speed along +Z, cm/s. Default 120.
    seed : int
        Seed of ``numpy.random.default_rng``. Same seed, same arrays.
    """

    num_frames: int = 240
    fps: float = 120.0
    num_frequencies: int = 3
    max_frequency_hz: float = 2.0
    amplitude_deg: float = 20.0
    speed_cm_s: float = 120.0
    seed: int = 0

    def __post_init__(self) -> None:
        checks = [
            ("num_frames", 1 <= self.num_frames <= 1_000_000, "in [1, 1000000]"),
            ("fps", self.fps > 0, "> 0"),
            ("num_frequencies", 1 <= self.num_frequencies <= 16, "in [1, 16]"),
            ("max_frequency_hz", self.max_frequency_hz > 0, "> 0"),
            ("amplitude_deg", 0 <= self.amplitude_deg <= 90, "in [0, 90]"),
        ]
        check_fields(self, checks)


def sinusoidal_motion(config: SyntheticConfig | None = None, **overrides) -> Motion:
    """A seeded sinusoidal motion on :func:`cmu_like_skeleton`.

    Each of the 3 Euler angles of every joint is ``sum_k a_k sin(2 pi f_k t + phi_k)`` with ``f_k`` uniform
    in ``[0.1, max_frequency_hz]`` Hz, ``a_k`` uniform in ``[0, amplitude_deg]`` and ``phi_k`` uniform in
    ``[0, 2 pi)``. The root turns by a small yaw oscillation, moves forward at ``speed_cm_s`` and bobs
    vertically by 2 cm at the first leg frequency.

    Parameters
    ----------
    config : SyntheticConfig, optional
    **overrides
        Fields of :class:`SyntheticConfig`, e.g. ``num_frames=600``.

    Returns
    -------
    Motion
        F = ``num_frames`` frames, 31 joints, named ``"synthetic-seed<seed>"``.
    """
    config = SyntheticConfig(**{**(config.__dict__ if config else {}), **overrides})
    skeleton = cmu_like_skeleton()
    rng = np.random.default_rng(config.seed)
    num_joints = skeleton.num_joints
    shape = (num_joints, 3, config.num_frequencies)
    frequencies = rng.uniform(0.1, config.max_frequency_hz, size=shape)
    amplitudes = rng.uniform(0.0, config.amplitude_deg, size=shape) / config.num_frequencies
    phases = rng.uniform(0.0, 2 * np.pi, size=shape)
    time_s = np.arange(config.num_frames) / config.fps
    angles = np.einsum(
        "jck,fjck->fjc",
        amplitudes,
        np.sin(2 * np.pi * frequencies[None] * time_s[:, None, None, None] + phases[None]),
    )
    # The root's pitch/roll stay small (a walking torso), its yaw sways.
    angles[:, 0, 1:] *= 0.25
    rotations = Rotation.from_euler("ZYX", angles.reshape(-1, 3), degrees=True).as_quat()
    bob_hz = float(frequencies[2, 0, 0])
    root = np.stack(
        [
            np.zeros_like(time_s),
            _ROOT_HEIGHT_CM + 2.0 * np.sin(2 * np.pi * bob_hz * time_s),
            config.speed_cm_s * time_s,
        ],
        axis=1,
    )
    return Motion(
        skeleton=skeleton,
        fps=config.fps,
        root_positions=root,
        rotations=rotations.reshape(config.num_frames, num_joints, 4),
        name=f"synthetic-seed{config.seed}",
    )

