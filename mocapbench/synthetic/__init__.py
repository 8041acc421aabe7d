"""Synthetic motions made from seeds, with no file: the test fixture, the embedded default data of ``make run``, and
the users' rigs the tests and benchmarks throw at every codec.

Modules
-------
motions
    The 31-joint CMU-like skeleton and its sinusoidal motion.
rigs
    Users' rigs: 15-70 joints, three topologies, Y- or Z-up, any unit and Euler order, T-pose frames, cuts.
game
    Game rigs: a ground-level root above a translated pelvis, stretched bones and scaled joints.
"""

from mocapbench.synthetic.motions import SyntheticConfig, cmu_like_skeleton, sinusoidal_motion
from mocapbench.synthetic.rigs import (
    RigCase,
    RigConfig,
    concatenate_takes,
    rig_motion,
    rig_skeleton,
    user_case,
    user_cases,
    with_tpose_first_frame,
    write_case_bvh,
)

__all__ = [
    "SyntheticConfig",
    "cmu_like_skeleton",
    "sinusoidal_motion",
    "RigCase",
    "RigConfig",
    "concatenate_takes",
    "rig_motion",
    "rig_skeleton",
    "user_case",
    "user_cases",
    "with_tpose_first_frame",
    "write_case_bvh",
]
