"""Short reprs: Motion, Skeleton and Decoded print one line of facts, never their arrays."""

from __future__ import annotations

from mocapbench.codecs import create
from mocapbench.motion import Motion
from mocapbench.synthetic import sinusoidal_motion


def test_motion_and_skeleton_reprs_are_one_short_line(cmu_09_06):
    assert repr(cmu_09_06.skeleton) == "Skeleton(31 joints, root 'root', 7 end sites)"
    assert repr(cmu_09_06) == "Motion('09_06', 141 frames at 120 fps = 1.18 s, Skeleton(31 joints, root 'root', 7 end sites))"
    assert str(cmu_09_06) == repr(cmu_09_06)


def test_motion_repr_names_a_source_unit_and_up_axis_other_than_the_defaults():
    motion = sinusoidal_motion(num_frames=30, seed=2)
    other = Motion(motion.skeleton, 30.0, motion.root_positions, motion.rotations, "walk", source_unit_cm=0.1,
                   up_axis="z")  # fmt: skip
    assert repr(other) == ("Motion('walk', 30 frames at 30 fps = 1.00 s, Skeleton(31 joints, root 'Hips', 7 end sites), "
                           "source unit 0.1 cm, z-up)")  # fmt: skip


def test_decoded_repr_says_what_was_decoded_and_the_stream_size(synthetic_motion):
    for name, what in (("quant-delta-zstd", "positions only"), ("quant-rot-zstd", "positions and rotations")):
        data = create(name).encode(synthetic_motion)
        decoded = create(name).decode(data)
        assert repr(decoded) == f"Decoded({name!r}, 240 frames x 31 joints, {what}, {len(data)} bytes)"
        assert len(repr(decoded)) < 100
