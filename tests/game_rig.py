"""A synthetic game rig for the codec tests, made to imitate the Bandai Namco files (not copied from them).

A ground-level ``joint_Root`` (it slides along the floor and turns about the vertical) above a ``Hips`` whose local
translation moves every frame (it walks forward and bobs: the pelvis of a game rig), a spine to a head, two arms and
two legs, an end site below every chain (head top, fingers, toes): 22 joints, 5 end sites, 30 fps, cm, Y up. The
Hips OFFSET is the rest pose a MotionBuilder export writes, far from where the pelvis is on any frame (as in the
dataset), so a codec that drops the translation track misses by metres. ``scaled`` adds a scale track on one forearm
(a stretching bone) for the codecs that carry scale.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from mocapbench.motion import Motion, Skeleton

__all__ = ["game_rig_motion", "still_root_rig", "GAME_RIG_NAMES"]

_JOINTS = [  # name, parent, offset (cm)
    ("joint_Root", -1, (0.0, 0.0, 0.0)),
    ("Hips", 0, (0.85, 93.98, -452.2)),
    ("Spine", 1, (0.0, 15.7, 0.0)),
    ("Chest", 2, (0.0, 9.0, -0.4)),
    ("Neck", 3, (0.0, 16.4, 0.0)),
    ("Head", 4, (0.0, 6.5, 0.0)),
    ("Shoulder_L", 3, (5.0, 13.0, -0.2)),
    ("UpperArm_L", 6, (12.0, 0.0, 0.0)),
    ("LowerArm_L", 7, (24.3, 0.0, 0.0)),
    ("Hand_L", 8, (22.3, 0.0, 0.0)),
    ("Shoulder_R", 3, (-5.0, 13.0, -0.2)),
    ("UpperArm_R", 10, (-12.0, 0.0, 0.0)),
    ("LowerArm_R", 11, (-24.3, 0.0, 0.0)),
    ("Hand_R", 12, (-22.3, 0.0, 0.0)),
    ("UpperLeg_L", 1, (9.0, -3.0, 0.0)),
    ("LowerLeg_L", 14, (0.0, -42.0, 0.0)),
    ("Foot_L", 15, (0.0, -40.0, 0.0)),
    ("Toes_L", 16, (0.0, -6.0, 12.0)),
    ("UpperLeg_R", 1, (-9.0, -3.0, 0.0)),
    ("LowerLeg_R", 18, (0.0, -42.0, 0.0)),
    ("Foot_R", 19, (0.0, -40.0, 0.0)),
    ("Toes_R", 20, (0.0, -6.0, 12.0)),
]
GAME_RIG_NAMES = tuple(name for name, _, _ in _JOINTS)


def game_rig_motion(num_frames: int = 90, seed: int = 0, *, scaled: bool = False, fps: float = 30.0) -> Motion:
    """The rig walking for ``num_frames`` frames at ``fps``: smooth joint rotations (up to ~40 degrees), a root that
    slides and turns slowly, a Hips translation that moves forward ~1.2 m/s and bobs 3 cm; with ``scaled`` the left
    forearm stretches by up to 20 %."""
    rng = np.random.default_rng(seed)
    names = GAME_RIG_NAMES
    num_joints = len(names)
    skeleton = Skeleton(
        names=names,
        parents=np.array([parent for _, parent, _ in _JOINTS]),
        offsets=np.array([offset for _, _, offset in _JOINTS]),
        end_site_parents=np.array([5, 9, 13, 17, 21]),
        end_site_offsets=np.array([[0, 17.0, 0], [9.0, 0, 0], [-9.0, 0, 0], [0, 0, 6.0], [0, 0, 6.0]]),
    )
    t = np.arange(num_frames)[:, None] / fps
    frequency = rng.uniform(0.5, 1.5, (1, 3 * num_joints))
    amplitude = rng.uniform(0.05, 0.7, (1, 3 * num_joints))
    angles = amplitude * np.sin(2 * np.pi * frequency * t + rng.uniform(0, 2 * np.pi, (1, 3 * num_joints)))
    angles[:, :3] = 0.0
    angles[:, 1] = 0.3 * np.sin(0.4 * t[:, 0])  # the root turns slowly about Y
    rotations = Rotation.from_rotvec(angles.reshape(-1, 3)).as_quat().reshape(num_frames, num_joints, 4)
    roots = np.stack([10 * np.sin(0.5 * t[:, 0]), np.zeros(num_frames), 8 * t[:, 0]], axis=1)
    translations = np.broadcast_to(skeleton.offsets, (num_frames, num_joints, 3)).copy()
    translations[:, 1] = np.stack(
        [3 * np.sin(2.1 * t[:, 0]), 92 + 3 * np.sin(2 * np.pi * 1.8 * t[:, 0]), 120 * t[:, 0] - 3]
        , axis=1,
    )
    scales = None
    if scaled:
        scales = np.ones((num_frames, num_joints, 3))
        scales[:, 8] = 1 + 0.2 * np.sin(2 * np.pi * 0.7 * t)
    return Motion(skeleton, fps, roots, rotations, name=f"game-rig-seed{seed}", translations=translations,
                  scales=scales)


def still_root_rig(num_frames: int = 120, seed: int = 3, position=(0.0, 0.0, 0.0)) -> Motion:
    """The rig with its ground root held still at ``position`` with the identity rotation (as the Bandai Namco files'
    ``joint_Root``): only the pelvis' translation track moves the body."""
    motion = game_rig_motion(num_frames, seed)
    rotations = motion.rotations.copy()
    rotations[:, 0] = (0.0, 0.0, 0.0, 1.0)
    roots = np.broadcast_to(np.asarray(position, dtype=np.float64), (num_frames, 3)).copy()
    return Motion(motion.skeleton, motion.fps, roots, rotations, name="still-root", translations=motion.translations)
