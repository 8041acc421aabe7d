"""Every unit and axis caught: body proportions against size, the up axis from the frames, per-file units, --strict."""

from __future__ import annotations

import dataclasses
import os

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mocapbench.io.bvh import write_bvh
from mocapbench.io.formats import UnitCheckError, read_motion
from mocapbench.io.unit_choice import UnitChoice, read_sidecar, sidecar_path
from mocapbench.io.units import body_shape, detect_up_axis, rest_height_warning, rest_up_axis
from mocapbench.motion import Motion, Skeleton
from mocapbench.synthetic import rig_motion


def _write(motion: Motion, path, unit_cm: float):
    """``motion`` (cm) written as a BVH whose numbers are in a unit of ``unit_cm`` cm."""
    return write_bvh(motion, path, length_unit_cm=unit_cm)


def test_an_adult_in_inches_read_as_cm_warns_inside_the_body_window(tmp_path):
    path = _write(rig_motion(num_joints=31, seed=1), tmp_path / "inches.bvh", 2.54)
    motion, warnings = read_motion(path)
    shape = body_shape(motion.skeleton, "y")
    assert 50 < shape.stature_cm < 90 and shape.legs == 2 and shape.adult_human
    assert len(warnings) == 1 and "\n" not in warnings[0]
    assert "an adult's proportions" in warnings[0] and "pass --units inch" in warnings[0]
    right, none = read_motion(path, units="inch")
    assert none == [] and 150 < body_shape(right.skeleton, "y").stature_cm < 190


@pytest.mark.parametrize("unit_cm", [1.0, 1.7])  # an adult in cm; a 105 cm body with an adult's legs (no unit fits)
def test_bodies_whose_size_fits_their_unit_do_not_warn(tmp_path, unit_cm):
    path = _write(rig_motion(num_joints=40, seed=2), tmp_path / "body.bvh", unit_cm)
    assert read_motion(path)[1] == []


def test_a_small_quadruped_is_not_taken_for_an_adult_in_inches(tmp_path):
    dog = rig_motion(num_joints=40, topology="quadruped", seed=3)
    shape = body_shape(dog.skeleton, "y")
    assert shape.legs > 2 and not shape.adult_human
    path = _write(dog, tmp_path / "dog.bvh", 1.3)  # about 64 cm tall read as cm: inside the window, no warning
    assert read_motion(path)[1] == []


def _turned_by_the_root(motion: Motion) -> Motion:
    """A rig whose rest pose stands along Y and whose root turns it to stand along Z in every frame."""
    turn = Rotation.from_euler("X", 90, degrees=True)
    rotations = motion.rotations.copy()
    rotations[:, 0] = (turn * Rotation.from_quat(rotations[:, 0])).as_quat()
    return dataclasses.replace(motion, rotations=rotations, root_positions=turn.apply(np.array(motion.root_positions)))


def test_up_axis_comes_from_the_frames_not_the_rest_pose(tmp_path):
    standing = rig_motion(num_joints=31, speed_cm_s=0.0, seed=4)
    turned = _turned_by_the_root(standing)
    axis, reason = detect_up_axis(turned)
    assert axis == "z" and "root-to-Head" in reason
    assert detect_up_axis(standing)[0] == "y"
    assert rest_up_axis(dataclasses.replace(turned, up_axis="z")) == "y"
    path = _write(turned, tmp_path / "turned.bvh", 1.0)
    motion, warnings = read_motion(path)
    assert motion.up_axis == "z" and warnings == []  # 179 cm measured along the rest pose's own Y


def _ground_rooted(motion: Motion) -> Motion:
    """The game-rig layout: a root on the floor under the pelvis, the pelvis its child (what it moved is its own)."""
    skeleton = motion.skeleton
    hip_height = float(np.median(motion.root_positions[:, 1]))
    offsets = np.concatenate([[[0.0, 0.0, 0.0], [0.0, hip_height, 0.0]], skeleton.offsets[1:]])
    grounded = Skeleton(
        names=("root", *skeleton.names),
        parents=np.concatenate([[-1, 0], skeleton.parents[1:] + 1]),
        offsets=offsets,
        channel_orders=(skeleton.channel_orders[0], *skeleton.channel_orders),
        end_site_parents=skeleton.end_site_parents + 1,
        end_site_offsets=skeleton.end_site_offsets,
    )
    identity = np.zeros((motion.num_frames, 1, 4))
    identity[..., 3] = 1.0
    root = motion.root_positions - [0.0, hip_height, 0.0]
    return Motion(skeleton=grounded, fps=motion.fps, root_positions=root,
                  rotations=np.concatenate([identity, motion.rotations], axis=1), name="ground-rooted")


@pytest.mark.parametrize("turn", [False, True])
def test_game_rigs_with_a_root_on_the_floor_are_measured_and_detected(turn):
    rig = _ground_rooted(rig_motion(num_joints=31, speed_cm_s=0.0, seed=5))
    if turn:
        rig = _turned_by_the_root(rig)
    axis, _ = detect_up_axis(rig)
    assert axis == ("z" if turn else "y")
    rig = dataclasses.replace(rig, up_axis=axis)
    shape = body_shape(rig.skeleton, rest_up_axis(rig))
    assert 150 < shape.stature_cm < 190 and shape.adult_human
    assert rest_height_warning(rig) is None


def test_strict_turns_the_warning_into_an_error(tmp_path):
    path = _write(rig_motion(num_joints=31, seed=6), tmp_path / "inches.bvh", 2.54)
    with pytest.raises(UnitCheckError, match=r"inches\.bvh: .*pass --units inch\. \(--strict\)$"):
        read_motion(path, strict=True)
    read_motion(path, units="inch", strict=True)  # the right unit passes


def test_a_sidecar_gives_a_file_its_unit_and_axis(tmp_path):
    path = _write(rig_motion(num_joints=31, seed=7), tmp_path / "walk.bvh", 2.54)
    sidecar_path(path).write_text("# exported from the studio's old pipeline\nunits: inch\nup: y\n")
    assert read_sidecar(path) == {"units": "inch", "up": "y"}
    motion, warnings = read_motion(path)
    assert warnings == [] and motion.source_unit_cm == 2.54
    # An explicit unit beats the sidecar.
    assert read_motion(path, units="cm")[1] != []


@pytest.mark.parametrize(("text", "message"), [
    ("units: furlong\n", r"walk\.bvh\.units: line 1: --units 'furlong'"),
    ("units: cm\nunits: mm\n", r"line 2: expected `units: UNIT` or `up: y\|z` once each"),
    ("colour: red\n", "line 1: expected"),
    ("x" * 5000, "over 4096 bytes"),
])
def test_bad_sidecars_are_one_line(tmp_path, text, message):
    path = tmp_path / "walk.bvh"
    path.write_text("HIERARCHY\n")
    sidecar_path(path).write_text(text)
    with pytest.raises(ValueError, match=message) as error:
        read_sidecar(path)
    assert "\n" not in str(error.value)


def test_a_sidecar_link_is_refused(tmp_path):
    path = tmp_path / "walk.bvh"
    (tmp_path / "elsewhere").write_text("units: inch\n")
    os.symlink(tmp_path / "elsewhere", sidecar_path(path))
    with pytest.raises(ValueError, match="plain file, not a link"):
        read_sidecar(path)


def test_units_per_file_on_the_command_line(tmp_path):
    a, b, c = (tmp_path / name for name in ("a.bvh", "b.bvh", "c.bvh"))
    sidecar_path(c).write_text("mm\n")
    choice = UnitChoice.parse(["cm", f"{a}:inch", "b.bvh:cmu"])
    assert choice.units_for(a) == ("inch", "--units a.bvh:inch")
    assert choice.units_for(b) == ("cmu", "--units b.bvh:cmu")
    assert choice.units_for(c) == (None, "sidecar c.bvh.units")  # read_motion reads it
    assert choice.units_for(tmp_path / "d.bvh") == ("cm", "--units")
    assert UnitChoice.parse(None).units_for(a) == (None, "default; --units to change")  # BVH declares no unit
    assert UnitChoice.parse(None).units_for(tmp_path / "d.fbx") == (None, "declared by the file's UnitScaleFactor")
    assert UnitChoice.parse("a.bvh:inch,typo.bvh:m").unmatched([a, b]) == ["typo.bvh"]


@pytest.mark.parametrize(("values", "message"), [
    (["cm", "inch"], "two units for every file"),
    (["a.bvh:parsec"], "--units 'parsec'"),
])
def test_bad_unit_choices_are_one_line(values, message):
    with pytest.raises(ValueError, match=message):
        UnitChoice.parse(values)


def test_the_hydra_folder_dataset_runs_the_same_checks(tmp_path, caplog):
    from mocapbench.experiments.datasets import DatasetError, load_clips

    _write(rig_motion(num_joints=31, seed=8), tmp_path / "inches.bvh", 2.54)
    _write(_turned_by_the_root(rig_motion(num_joints=31, speed_cm_s=0.0, seed=9)), tmp_path / "turned.bvh", 1.0)
    spec = {"name": "studio", "kind": "folder", "path": str(tmp_path)}
    with caplog.at_level("WARNING"):
        motions = load_clips(spec)
    assert [m.up_axis for m in motions] == ["y", "z"]
    assert any("inches.bvh" in r.message and "pass --units inch" in r.message for r in caplog.records)
    with pytest.raises(DatasetError, match=r"'studio': .*inches\.bvh.*--strict.*strict_units: true"):
        load_clips({**spec, "strict_units": True})
    sidecar_path(tmp_path / "inches.bvh").write_text("units: inch\n")
    assert [m.source_unit_cm for m in load_clips({**spec, "strict_units": True})] == [2.54, 1.0]
