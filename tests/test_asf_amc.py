"""ASF/AMC reading: hand-computed FK on a two-bone chain, the CMU skeleton, every malformed input."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mocapbench.io.asf_amc import CMU_CM_PER_UNIT, AsfSkeleton, read_amc, read_asf
from mocapbench.motion import MotionFormatError

FIXTURES = Path(__file__).parent / "fixtures"
ASF = FIXTURES / "chain.asf"  # root > upper (+Y, 10 units, axis Z 90, dof rx ry) > lower (+X, 4 units, dof rz)
AMC = FIXTURES / "chain.amc"  # 3 frames; see the file for line numbers


def variant(tmp_path: Path, source: Path, old: str, new: str) -> Path:
    """A copy of ``source`` in ``tmp_path`` with the first ``old`` replaced by ``new``."""
    text = source.read_text()
    assert old in text, f"fixture text {old!r} not found"
    path = tmp_path / source.name
    path.write_text(text.replace(old, new, 1))
    return path


# --- hand-computed forward kinematics -------------------------------------------------------------------


def test_chain_skeleton():
    asf = read_asf(ASF, cm_per_unit=1.0)
    skeleton = asf.skeleton
    assert skeleton.names == ("root", "upper", "lower")
    assert skeleton.parents.tolist() == [-1, 0, 1]
    # joints sit at the start of their bone: upper at the root, lower at the end of upper
    np.testing.assert_allclose(skeleton.offsets, [[0, 0, 0], [0, 0, 0], [0, 10, 0]])
    np.testing.assert_array_equal(skeleton.end_site_parents, [2])
    np.testing.assert_allclose(skeleton.end_site_offsets, [[4, 0, 0]])
    assert asf.dofs == (("tx", "ty", "tz", "rx", "ry", "rz"), ("rx", "ry"), ("rz",))
    assert asf.num_values("upper") == 2 and asf.num_values("root") == 6
    assert skeleton.rest_height() == pytest.approx(10.0)


def test_default_units_follow_the_cmu_convention():
    # ':units length 1.0' -> 1 unit = 1 inch = 2.54 cm
    assert read_asf(ASF).cm_per_unit == pytest.approx(2.54)
    np.testing.assert_allclose(read_asf(ASF).skeleton.offsets[2], [0, 25.4, 0])
    assert CMU_CM_PER_UNIT == pytest.approx(5.644444, abs=1e-6)


def test_chain_positions_by_hand():
    motion = read_amc(AMC, read_asf(ASF, cm_per_unit=1.0))
    assert motion.num_frames == 3 and motion.name == "chain" and motion.fps == 120.0
    expected = np.array(
        [
            # frame 1: root at (1,2,3); upper rx=90 about its axis-rotated X (axis Z 90: world Y) -> Ry(90)
            [[1, 2, 3], [1, 2, 3], [1, 12, 3]],
            # frame 2: root rz=90 turns upper's (0,10,0) to (-10,0,0)
            [[0, 0, 0], [0, 0, 0], [-10, 0, 0]],
            # frame 3: upper rx=90 then ry=90 (dof order): C Ry Rx C^-1 (0,10,0) = (0,0,-10)
            [[0, 0, 0], [0, 0, 0], [0, 0, -10]],
        ],
        dtype=float,
    )
    np.testing.assert_allclose(motion.positions(), expected, atol=1e-9)
    # end of lower: frame 1 Ry(90) (4,0,0) = (0,0,-4); frame 2 Rz(90) Rz(90) (4,0,0) = (-4,0,0)
    np.testing.assert_allclose(motion.end_site_positions()[:2, 0], [[1, 12, -1], [-14, 0, 0]], atol=1e-9)


def test_read_amc_accepts_an_asf_path():
    by_path = read_amc(AMC, ASF, name="x")
    assert by_path.name == "x"
    np.testing.assert_allclose(by_path.positions(), read_amc(AMC, read_asf(ASF)).positions())


def test_radians(tmp_path):
    path = variant(tmp_path, AMC, ":DEGREES", ":RADIANS")
    path.write_text(path.read_text().replace("upper 90 0", f"upper {np.pi / 2} 0"))
    motion = read_amc(path, read_asf(ASF, cm_per_unit=1.0))
    np.testing.assert_allclose(motion.positions()[0, 2], [1, 12, 3], atol=1e-9)


def test_bones_in_any_order_and_comments_take_the_general_path(tmp_path):
    reference = read_amc(AMC, ASF)
    path = variant(
        tmp_path, AMC, "root 0 0 0 0 0 90\nupper 0 0\nlower 90", "lower 90\n# a comment\nupper 0 0\nroot 0 0 0 0 0 90"
    )
    np.testing.assert_allclose(read_amc(path, ASF).rotations, reference.rotations)
    np.testing.assert_allclose(read_amc(path, ASF).root_positions, reference.root_positions)


# --- the CMU skeleton ------------------------------------------------------------------------------------


def test_cmu_skeleton(cmu_fixture_dir):
    asf = read_asf(cmu_fixture_dir / "asf_amc" / "09" / "09.asf")
    assert isinstance(asf, AsfSkeleton)
    skeleton = asf.skeleton
    assert skeleton.num_joints == 31 and len(skeleton.end_site_parents) == 7
    assert skeleton.names[:6] == ("root", "lhipjoint", "lfemur", "ltibia", "lfoot", "ltoes")
    assert asf.cm_per_unit == pytest.approx(CMU_CM_PER_UNIT)
    assert sum(len(d) for d in asf.dofs) == 62  # root 6 + 56 (data README)
    assert asf.dofs[skeleton.index("lhipjoint")] == ()
    # femur 7.54288 units = 42.58 cm (the data README: 0.426 m)
    ltibia = skeleton.index("ltibia")
    assert np.linalg.norm(skeleton.offsets[ltibia]) == pytest.approx(7.54288 * CMU_CM_PER_UNIT, rel=1e-5)
    height = skeleton.rest_height()
    assert 150.0 < height < 200.0, f"subject 09 rest height {height:.1f} cm is not a human height"


def test_cmu_clip(cmu_fixture_dir):
    folder = cmu_fixture_dir / "asf_amc" / "09"
    motion = read_amc(folder / "09_06.amc", folder / "09.asf")
    assert motion.num_frames == 141 and motion.num_joints == 31 and motion.name == "09_06"
    # data README: the mean Hips height over 09_06 is 18.0 units (1.016 m)
    assert motion.root_positions[:, 1].mean() == pytest.approx(101.6, abs=1.0)
    identity = motion.rotations[:, motion.skeleton.index("lhipjoint")]
    np.testing.assert_allclose(identity, np.tile([0, 0, 0, 1.0], (141, 1)))


@pytest.mark.cmu
def test_every_cmu_subject_has_a_human_height(cmu_full_dir):
    for asf_path in sorted((cmu_full_dir / "asf_amc").glob("*/*.asf")):
        height = read_asf(asf_path).skeleton.rest_height()
        assert 140.0 < height < 210.0, f"{asf_path.name}: rest height {height:.1f} cm"


# --- malformed AMC ---------------------------------------------------------------------------------------


def test_missing_files(tmp_path):
    with pytest.raises(MotionFormatError, match=r"none\.amc: AMC file does not exist"):
        read_amc(tmp_path / "none.amc", ASF)
    with pytest.raises(MotionFormatError, match=r"none\.asf: ASF file does not exist"):
        read_amc(AMC, tmp_path / "none.asf")
    with pytest.raises(FileNotFoundError):
        read_asf(tmp_path / "none.asf")


def test_empty_amc(tmp_path):
    (tmp_path / "empty.amc").write_text("\n")
    with pytest.raises(MotionFormatError, match=r"empty\.amc: the AMC file is empty"):
        read_amc(tmp_path / "empty.amc", ASF)


def test_no_frames(tmp_path):
    (tmp_path / "header.amc").write_text(":FULLY-SPECIFIED\n:DEGREES\n")
    with pytest.raises(MotionFormatError, match=r"header\.amc: no frames: expected a frame number line"):
        read_amc(tmp_path / "header.amc", ASF)


def test_bone_line_before_the_first_frame(tmp_path):
    path = variant(tmp_path, AMC, ":DEGREES\n1\n", ":DEGREES\n")
    with pytest.raises(
        MotionFormatError, match=r"line 4: expected a frame number \(e\.g\. '1'\), got 'root 1 2 3 0 0 0'"
    ):
        read_amc(path, ASF)


def test_unknown_bone(tmp_path):
    path = variant(tmp_path, AMC, "lower 90", "elbow 90")
    with pytest.raises(MotionFormatError, match=r"chain\.amc: line 11: unknown bone 'elbow'"):
        read_amc(path, ASF)


@pytest.mark.parametrize(("line", "count"), [("upper 90", 1), ("upper 90 0 0", 3)])
def test_wrong_value_count(tmp_path, line, count):
    path = variant(tmp_path, AMC, "upper 90 90", line)
    with pytest.raises(MotionFormatError, match=rf"line 14: expected 2 values for bone 'upper' .*got {count}"):
        read_amc(path, ASF)


def test_non_numeric(tmp_path):
    path = variant(tmp_path, AMC, "upper 0 0", "upper 0 zero")
    with pytest.raises(MotionFormatError, match=r"line 10: expected a number for bone 'upper', got 'zero'"):
        read_amc(path, ASF)


@pytest.mark.parametrize("token", ["nan", "inf"])
def test_non_finite(tmp_path, token):
    path = variant(tmp_path, AMC, "root 0 0 0 0 0 90", f"root 0 {token} 0 0 0 90")
    with pytest.raises(MotionFormatError, match=r"line 9: expected finite numbers for bone 'root'"):
        read_amc(path, ASF)


def test_frames_not_consecutive(tmp_path):
    path = variant(tmp_path, AMC, "\n3\n", "\n4\n")
    with pytest.raises(
        MotionFormatError, match=r"line 12: expected frame number 3 \(frames must be consecutive\), got 4"
    ):
        read_amc(path, ASF)


def test_frame_missing_a_bone(tmp_path):
    path = variant(tmp_path, AMC, "lower 90\n", "")
    with pytest.raises(MotionFormatError, match=r"line 8: frame 2 has no line for bones \['lower'\]"):
        read_amc(path, ASF)


def test_truncated_last_frame(tmp_path):
    path = tmp_path / "chain.amc"
    path.write_text(AMC.read_text().rsplit("upper 90 90", 1)[0])
    with pytest.raises(MotionFormatError, match=r"line 12: frame 3 has no line for bones \['upper', 'lower'\]"):
        read_amc(path, ASF)


def test_bone_twice_in_a_frame(tmp_path):
    path = variant(tmp_path, AMC, "lower 90\n", "lower 90\nlower 90\n")
    with pytest.raises(MotionFormatError, match=r"line 12: bone 'lower' appears twice in frame 2"):
        read_amc(path, ASF)


# --- malformed ASF ---------------------------------------------------------------------------------------


@pytest.mark.parametrize(("dof", "name"), [("dof rz tx", "tx"), ("dof l", "l")])
def test_translation_or_length_dof_on_a_bone(tmp_path, dof, name):
    path = variant(tmp_path, ASF, "dof rz", dof)
    with pytest.raises(
        MotionFormatError, match=rf"line 32: bone dof '{name}' \(translation or length\) is not supported"
    ):
        read_asf(path)


def test_unknown_bone_in_hierarchy(tmp_path):
    path = variant(tmp_path, ASF, "upper lower", "upper lowr")
    with pytest.raises(MotionFormatError, match=r"line 38: unknown bone 'lowr' in :hierarchy"):
        read_asf(path)


def test_bone_not_connected(tmp_path):
    path = variant(tmp_path, ASF, "    upper lower\n", "")
    with pytest.raises(MotionFormatError, match=r"chain\.asf: bones \['lower'\] are not connected to the root"):
        read_asf(path)


def test_no_hierarchy_section(tmp_path):
    path = tmp_path / "chain.asf"
    path.write_text(ASF.read_text().split(":hierarchy")[0])
    with pytest.raises(MotionFormatError, match=r"chain\.asf: no :hierarchy section"):
        read_asf(path)


def test_bone_without_end(tmp_path):
    path = variant(tmp_path, ASF, "    dof rz\n    limits (-180.0 180.0)\n  end\n", "    dof rz\n")
    with pytest.raises(
        MotionFormatError, match=r"line 33: expected 'end' closing the bone opened at line 26, got ':hierarchy'"
    ):
        read_asf(path)


def test_bone_without_length(tmp_path):
    path = variant(tmp_path, ASF, "     length 4\n", "")
    with pytest.raises(
        MotionFormatError, match=r"line 26: the bone opened here has no 'length' before its 'end' \(line 33\)"
    ):
        read_asf(path)


def test_bad_units(tmp_path):
    path = variant(tmp_path, ASF, "angle deg", "angle grad")
    with pytest.raises(MotionFormatError, match=r"line 7: expected ':units angle deg' or 'rad', got \['grad'\]"):
        read_asf(path)


def test_bad_axis(tmp_path):
    path = variant(tmp_path, ASF, "axis 0 0 90  XYZ", "axis 0 0 90  XYY")
    with pytest.raises(MotionFormatError, match=r"line 21: expected an axis order such as XYZ"):
        read_asf(path)
