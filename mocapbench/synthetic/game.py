"""Synthetic game rigs: a ground-level root above a translated pelvis, as game studios' mocap is exported.

A game rig (MotionBuilder exports, Unreal's root -> pelvis) differs from a CMU skeleton in what moves: the root
joint slides on the ground under the character and turns with its heading, the pelvis below it carries the height,
the bob and the sway as a local translation track, and a rig may stretch a bone (a translation along it) or scale a
joint (a prop, a cartoon squash). :func:`game_rig_motion` builds such a motion from the seeded biped of
:func:`mocapbench.synthetic.rigs.rig_motion`, so that tests and benchmarks have every track without a data file:

* ``joint_Root`` at the ground projection of the biped's root, turned about Y by the heading (a slow sway of the
  biped's yaw), with position channels on every joint when written as BVH;
* ``Hips`` = the biped's root: its translation under ``joint_Root`` is the biped's root position seen from the
  ground root, its rotation the biped's root rotation seen from it, so the world positions are the biped's;
* optionally a stretching spine (``stretch_cm``: the spine's translation grows and shrinks along its bone) and a
  scale track (``scale``: the chest squashes and stretches, up to the given factor; glTF holds it, BVH cannot).

Everything is seeded: the same arguments give the same arrays.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from mocapbench.motion import Motion, Skeleton
from mocapbench.synthetic.rigs import rig_motion

__all__ = ["game_rig_motion"]


def game_rig_motion(
    *,
    num_joints: int = 21,
    num_frames: int = 60,
    fps: float = 30.0,
    stretch_cm: float = 0.0,
    scale: float = 1.0,
    seed: int = 0,
) -> Motion:
    """A game rig's motion: ``joint_Root`` on the ground, a translated ``Hips`` and the biped under it.

    Parameters
    ----------
    num_joints : int, keyword-only
        Joints of the biped below the ground root (15..70); the rig has one more.
    num_frames : int, keyword-only
    fps : float, keyword-only
        Frame rate (game content is 30 fps).
    stretch_cm : float, keyword-only
        Amplitude in cm of a stretch of the spine along its bone (0: the spine keeps its length).
    scale : float, keyword-only
        Largest scale factor of the chest's scale track, >= 1 (1: no scale track).
    seed : int, keyword-only

    Returns
    -------
    Motion
        J = ``num_joints + 1``, cm, Y-up, Euler order ``ZXY`` on every joint (the Bandai Namco files' order),
        ``translations`` with ``Hips`` (and the spine) moving, ``scales`` when ``scale`` > 1; named
        ``"game-<J>-seed<seed>"``.
    """
    biped = rig_motion(num_joints=num_joints, num_frames=num_frames, fps=fps, euler_orders="ZXY", seed=seed)
    inner = biped.skeleton
    num_frames, num_inner = biped.num_frames, inner.num_joints
    time_s = np.arange(num_frames) / fps
    heading = Rotation.from_euler("y", 30.0 * np.sin(2 * np.pi * 0.2 * time_s + seed)[:, None], degrees=True)
    ground = biped.root_positions * [1.0, 0.0, 1.0]
    hips_translation = heading.inv().apply(biped.root_positions - ground)
    hips_rotation = heading.inv() * Rotation.from_quat(biped.rotations[:, 0])
    # The rest pelvis stands at the biped's mean root height, 3 cm behind the ground root (as the Bandai rig).
    hips_offset = np.array([0.0, float(hips_translation[:, 1].mean()), -3.0])

    offsets = np.concatenate([np.zeros((1, 3)), hips_offset[None], inner.offsets[1:]])
    skeleton = Skeleton(
        names=("joint_Root", *inner.names),
        parents=np.concatenate([[-1], inner.parents + 1]),
        offsets=offsets,
        channel_orders=("ZXY", *inner.channel_orders),
        end_site_parents=inner.end_site_parents + 1,
        end_site_offsets=inner.end_site_offsets,
    )
    rotations = np.concatenate([heading.as_quat()[:, None], hips_rotation.as_quat()[:, None], biped.rotations[:, 1:]],
                               axis=1)
    translations = np.broadcast_to(offsets, (num_frames, num_inner + 1, 3)).copy()
    translations[:, 1] = hips_translation
    rng = np.random.default_rng([seed, 27])
    spine = 2 if num_inner > 1 else None
    if stretch_cm and spine is not None:
        bone = offsets[spine] / max(np.linalg.norm(offsets[spine]), 1e-9)
        wave = stretch_cm * np.sin(2 * np.pi * rng.uniform(0.3, 1.0) * time_s)
        translations[:, spine] = offsets[spine] + wave[:, None] * bone
    scales = None
    if scale != 1.0:
        if not scale > 1.0:
            raise ValueError(f"`scale` must be >= 1, got {scale}.")
        chest = min(3, num_inner)
        phase = np.sin(2 * np.pi * rng.uniform(0.3, 1.0) * time_s)
        scales = np.ones((num_frames, num_inner + 1, 3))
        scales[:, chest] = [1.0, 1.0, 1.0] + (scale - 1.0) * np.stack([phase, -phase / 2, np.abs(phase)], axis=1)
        scales[:, chest] = np.maximum(scales[:, chest], 1.0 / scale)
    return Motion(skeleton, fps, ground, rotations, name=f"game-{num_inner + 1}-seed{seed}",
                  translations=translations, scales=scales)
