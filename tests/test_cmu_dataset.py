"""The CMU data folder, splits and loaders, and the BVH release checked against the ASF/AMC originals."""

from __future__ import annotations

import csv
import hashlib
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mocapbench.datasets.cmu import (
    ENV_VAR,
    SPLITS,
    DataNotFoundError,
    clip_names,
    cmu_data_dir,
    load_clip,
    load_folder,
    load_split,
)
from mocapbench.io.bvh import write_bvh
from mocapbench.motion import Motion, Skeleton
from mocapbench.synthetic import sinusoidal_motion

FIXTURES = Path(__file__).parent / "fixtures"

# BVH joint -> the ASF bone it takes its rotation from (data README, "Format details"), in BVH order.
BVH_TO_ASF = {
    "Hips": "root", "LHipJoint": "lhipjoint", "LeftUpLeg": "lfemur", "LeftLeg": "ltibia", "LeftFoot": "lfoot",
    "LeftToeBase": "ltoes", "RHipJoint": "rhipjoint", "RightUpLeg": "rfemur", "RightLeg": "rtibia",
    "RightFoot": "rfoot", "RightToeBase": "rtoes", "LowerBack": "lowerback", "Spine": "upperback",
    "Spine1": "thorax", "Neck": "lowerneck", "Neck1": "upperneck", "Head": "head", "LeftShoulder": "lclavicle",
    "LeftArm": "lhumerus", "LeftForeArm": "lradius", "LeftHand": "lwrist", "LeftFingerBase": "lhand",
    "LeftHandIndex1": "lfingers", "LThumb": "lthumb", "RightShoulder": "rclavicle", "RightArm": "rhumerus",
    "RightForeArm": "rradius", "RightHand": "rwrist", "RightFingerBase": "rhand", "RightHandIndex1": "rfingers",
    "RThumb": "rthumb",
}  # fmt: skip
# Joints whose BVH offset is written as 0 0 0 (README): the thorax's children and the wrists' children.
ZEROED_IN_BVH = ("lowerneck", "lclavicle", "rclavicle", "lhand", "lthumb", "rhand", "rthumb")
# Joints whose chain passes through neither: positions comparable as they are.
SAME_POSITION = ("root", "lhipjoint", "lfemur", "ltibia", "lfoot", "ltoes", "rhipjoint", "rfemur", "rtibia",
                 "rfoot", "rtoes", "lowerback", "upperback", "thorax")  # fmt: skip
TOLERANCE_CM = 0.5


# --- the data folder -------------------------------------------------------------------------------------


def test_missing_data_dir_says_where_it_looked(tmp_path):
    missing = tmp_path / "no-such-cmu"
    with pytest.raises(DataNotFoundError, match=r"CMU data folder not found.*no-such-cmu \(from the `path` argument\)"):
        cmu_data_dir(missing)
    with pytest.raises(FileNotFoundError, match=rf"set \${ENV_VAR}"):
        cmu_data_dir(missing)


def test_env_var_is_used(tmp_path, monkeypatch, cmu_fixture_dir):
    monkeypatch.setenv(ENV_VAR, str(tmp_path / "elsewhere"))
    with pytest.raises(DataNotFoundError, match=rf"elsewhere \(from \${ENV_VAR}\)"):
        cmu_data_dir()
    monkeypatch.setenv(ENV_VAR, str(cmu_fixture_dir))
    assert cmu_data_dir() == cmu_fixture_dir.resolve()


def test_folder_without_data_is_refused(tmp_path):
    with pytest.raises(DataNotFoundError, match="a folder holding asf_amc/ or bvh/"):
        cmu_data_dir(tmp_path)


def test_default_is_found_from_the_repository_root(tmp_path, monkeypatch, cmu_fixture_dir):
    """``../shared/data/cmu`` beside the repository holding ``mocapbench/`` is found from any working directory."""
    import mocapbench.datasets.cmu as cmu

    (tmp_path / "shared" / "data").mkdir(parents=True)
    (tmp_path / "shared" / "data" / "cmu").symlink_to(cmu_fixture_dir.resolve(), target_is_directory=True)
    monkeypatch.setattr(cmu, "__file__", str(tmp_path / "repo" / "mocapbench" / "datasets" / "cmu.py"))
    monkeypatch.delenv(ENV_VAR, raising=False)
    (tmp_path / "elsewhere").mkdir()
    monkeypatch.chdir(tmp_path / "elsewhere")  # ../shared/data/cmu from here does not exist
    assert cmu_data_dir() == cmu_fixture_dir.resolve()


# --- the clip shipped with the tests and the full folder -------------------------------------------------


def test_shipped_clip_matches_its_manifest(cmu_fixture_dir):
    """tests/fixtures/cmu holds 09_06 byte for byte as the data folder lists it (a rewritten CRLF would fail)."""
    with open(cmu_fixture_dir / "manifest.csv", newline="", encoding="utf-8") as handle:
        rows = list(csv.DictReader(handle))
    assert sorted(row["file"] for row in rows) == ["asf_amc/09/09.asf", "asf_amc/09/09_06.amc", "bvh/09_06.bvh"]
    for row in rows:
        data = (cmu_fixture_dir / row["file"]).read_bytes()
        assert len(data) == int(row["bytes"]) and hashlib.sha256(data).hexdigest() == row["sha256"], row["file"]
    assert clip_names("cmu_all", data_dir=cmu_fixture_dir) == ("09_06",)
    assert "NSF EIA-0196217" in (cmu_fixture_dir / "README.md").read_text()  # CMU's acknowledgement travels along


FULL_FOLDER_TEST = """
def test_needs_it(cmu_full_dir):
    assert (cmu_full_dir / "manifest.csv").is_file()
"""


@pytest.mark.parametrize("ci", ["", "true"])
def test_full_folder_missing_skips_with_reason_except_under_ci(pytester, monkeypatch, tmp_path, ci):
    pytester.makeconftest((Path(__file__).parent / "conftest.py").read_text())
    pytester.makepyfile(FULL_FOLDER_TEST)
    monkeypatch.setenv(ENV_VAR, str(tmp_path / "no-cmu-here"))
    monkeypatch.setenv("CI", ci)
    result = pytester.runpytest("-rs")
    if ci:
        result.assert_outcomes(errors=1)
        result.stdout.fnmatch_lines(["*DataNotFoundError: CMU data folder not found*no-cmu-here*"])
    else:
        result.assert_outcomes(skipped=1)
        result.stdout.fnmatch_lines(["SKIPPED*needs the full CMU data folder*no-cmu-here*"])


# --- splits -----------------------------------------------------------------------------------------------


def test_splits(cmu_full_dir):
    assert SPLITS["cmu_train"] == ("13_17", "13_18", "124_01", "124_02", "135_06")
    assert len(SPLITS["cmu_test"]) == 12 and "09_06" in SPLITS["cmu_test"]
    assert not set(SPLITS["cmu_train"]) & set(SPLITS["cmu_test"])
    everything = clip_names("cmu_all", data_dir=cmu_full_dir)
    assert len(everything) == 63 and len(set(everything)) == 63
    assert set(SPLITS["cmu_train"]) | set(SPLITS["cmu_test"]) <= set(everything)
    with pytest.raises(ValueError, match="Unknown split 'cmu_val'; expected one of"):
        clip_names("cmu_val")


def test_load_split_frame_counts(cmu_full_dir):
    """Frame totals from the data README: cmu_test 5,587, cmu_train 13,063 AMC frames."""
    test = load_split("cmu_test", data_dir=cmu_full_dir)
    assert [m.name for m in test] == list(SPLITS["cmu_test"])
    assert sum(m.num_frames for m in test) == 5587
    assert sum(m.num_frames for m in load_split("cmu_train", data_dir=cmu_full_dir)) == 13063
    # one ASF per subject: both 02 clips share one Skeleton object
    assert test[0].skeleton is test[1].skeleton


def test_load_clip(cmu_fixture_dir):
    amc, bvh = load_clip("09_06", data_dir=cmu_fixture_dir), load_clip("09_06", fmt="bvh", data_dir=cmu_fixture_dir)
    assert amc.name == bvh.name == "09_06"
    assert amc.num_frames == bvh.num_frames == 141
    assert amc.fps == bvh.fps == 120.0
    with pytest.raises(DataNotFoundError, match=r"Clip '09_99' \(amc\): .*09_99\.amc does not exist"):
        load_clip("09_99", data_dir=cmu_fixture_dir)
    with pytest.raises(ValueError, match="Unknown clip format 'c3d'"):
        load_clip("09_06", fmt="c3d", data_dir=cmu_fixture_dir)


# --- load_folder ------------------------------------------------------------------------------------------


def test_load_folder_of_one_subject(cmu_fixture_dir):
    motions = load_folder(cmu_fixture_dir / "asf_amc" / "09")
    assert [m.name for m in motions] == ["09_06"] and motions[0].num_joints == 31


def test_load_folder_pairs_amc_with_subject_asf(tmp_path):
    for subject in ("07", "08"):
        (tmp_path / f"{subject}.asf").write_text((FIXTURES / "chain.asf").read_text())
    (tmp_path / "07_01.amc").write_text((FIXTURES / "chain.amc").read_text())
    write_bvh(sinusoidal_motion(num_frames=7), tmp_path / "walk.bvh")
    motions = load_folder(tmp_path)
    assert [(m.name, m.num_frames, m.num_joints) for m in motions] == [("07_01", 3, 3), ("walk", 7, 31)]



def test_load_folder_skips_an_unreadable_file_naming_it(tmp_path, caplog):
    """One bad file (an AMC with no ASF, a broken BVH) is skipped with one line; the rest of the folder loads."""
    write_bvh(sinusoidal_motion(num_frames=7), tmp_path / "walk.bvh")
    (tmp_path / "09_01.amc").write_text((FIXTURES / "chain.amc").read_text())
    (tmp_path / "broken.bvh").write_text("HIERARCHY\nROOT Hips\n")
    with caplog.at_level("WARNING", logger="mocapbench.datasets.cmu"):
        motions = load_folder(tmp_path)
    assert [m.name for m in motions] == ["walk"]
    lines = [record.getMessage() for record in caplog.records]
    assert len(lines) == 2 and all("\n" not in line for line in lines)
    assert lines[0].startswith(f"skipped {tmp_path / '09_01.amc'}: ") and "no skeleton" in lines[0]
    assert lines[1].startswith(f"skipped {tmp_path / 'broken.bvh'}: ")
    (tmp_path / "walk.bvh").unlink()
    with pytest.raises(DataNotFoundError, match="none of its 2 motion file"):
        load_folder(tmp_path)


def test_load_folder_errors(tmp_path):
    with pytest.raises(DataNotFoundError, match="holds no .bvh or .amc file"):
        load_folder(tmp_path)
    with pytest.raises(DataNotFoundError, match="is not a folder"):
        load_folder(tmp_path / "missing")


# --- BVH release against the ASF/AMC originals -----------------------------------------------------------


def bvh_quirk_skeleton(skeleton: Skeleton) -> Skeleton:
    """``skeleton`` with the offsets the BVH release writes as 0 0 0 set to zero."""
    offsets = skeleton.offsets.copy()
    offsets[[skeleton.index(name) for name in ZEROED_IN_BVH]] = 0.0
    return Skeleton(
        skeleton.names, skeleton.parents, offsets, skeleton.channel_orders,
        skeleton.end_site_parents, skeleton.end_site_offsets,
    )  # fmt: skip


def compare_formats(name: str, data_dir: Path) -> dict[str, float]:
    """Check BVH (frame 0 dropped) against ASF/AMC for clip ``name``; return the largest differences in cm."""
    amc = load_clip(name, data_dir=data_dir)
    bvh = load_clip(name, fmt="bvh", data_dir=data_dir)
    # joint i <-> joint i, verified by name
    assert tuple(BVH_TO_ASF) == bvh.skeleton.names
    assert tuple(BVH_TO_ASF.values()) == amc.skeleton.names
    assert np.array_equal(amc.skeleton.parents, bvh.skeleton.parents)
    assert amc.num_frames == bvh.num_frames
    # rest pose: BVH offsets are the ASF ones (5 decimals of an ASF unit) except the zeroed ones
    quirk = bvh_quirk_skeleton(amc.skeleton)
    np.testing.assert_allclose(bvh.skeleton.offsets[1:], quirk.offsets[1:], atol=1e-3)
    np.testing.assert_allclose(bvh.skeleton.end_site_offsets, quirk.end_site_offsets, atol=1e-3)

    np.testing.assert_allclose(bvh.root_positions, amc.root_positions, atol=1e-3)  # 4 decimals of a unit
    root_angle = (Rotation.from_quat(bvh.rotations[:, 0]) * Rotation.from_quat(amc.rotations[:, 0]).inv()).magnitude()
    assert root_angle.max() < 1e-5  # radians; angles are printed with 4 decimals of a degree

    amc_positions, bvh_positions = amc.positions(), bvh.positions()
    same = [amc.skeleton.index(joint) for joint in SAME_POSITION]
    distance = np.linalg.norm(amc_positions - bvh_positions, axis=-1)  # (F, J) cm
    assert distance[:, same].max() < TOLERANCE_CM, (
        f"{name}: lower body/spine differ by {distance[:, same].max():.3f} cm"
    )
    # every joint, once the BVH's zeroed offsets are applied to the ASF skeleton too
    like_bvh = Motion(quirk, amc.fps, amc.root_positions, amc.rotations, name)
    quirk_distance = np.linalg.norm(like_bvh.positions() - bvh_positions, axis=-1)
    assert quirk_distance.max() < TOLERANCE_CM, f"{name}: all joints differ by {quirk_distance.max():.3f} cm"
    # global rotations of all 31 joints agree
    amc_matrices, _ = amc.global_transforms()
    bvh_matrices, _ = bvh.global_transforms()
    assert np.abs(amc_matrices - bvh_matrices).max() < 1e-4
    upper = [j for j in range(amc.num_joints) if j not in same]
    return {
        "lower_body_and_spine_cm": float(distance[:, same].max()),
        "upper_body_as_is_cm": float(distance[:, upper].max()),
        "all_joints_bvh_offsets_cm": float(quirk_distance.max()),
    }


def test_bvh_matches_amc_09_06(cmu_fixture_dir):
    differences = compare_formats("09_06", cmu_fixture_dir)
    # the upper body really is shifted by the thorax vector (2.0 units = 11.3 cm for subject 09), as documented
    assert 10.0 < differences["upper_body_as_is_cm"] < 25.0


@pytest.mark.cmu
def test_bvh_matches_amc_every_clip(cmu_full_dir):
    worst: dict[str, float] = {}
    for name in clip_names("cmu_all", data_dir=cmu_full_dir):
        for key, value in compare_formats(name, cmu_full_dir).items():
            worst[key] = max(worst.get(key, 0.0), value)
    print("largest BVH vs ASF/AMC differences over cmu_all:", worst)
