"""Datasets of a run: synthetic, CMU splits (clear error without the data), any folder of BVH files."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from mocapbench.datasets.cmu import DataNotFoundError, cmu_data_dir
from mocapbench.experiments import datasets
from mocapbench.experiments.main import cmu_available
from mocapbench.io import write_bvh
from mocapbench.synthetic import sinusoidal_motion

SYNTHETIC = {"name": "synthetic", "kind": "synthetic", "clips": {"seeds": [1, 2], "num_frames": 30},
             "train": {"clips": {"seeds": [11], "num_frames": 20}}}


def test_synthetic_clips_and_training_set_differ():
    clips = datasets.load_clips(SYNTHETIC)
    train = datasets.load_training(SYNTHETIC)
    assert [m.name for m in clips] == ["synthetic-seed1", "synthetic-seed2"]
    assert [m.name for m in train] == ["synthetic-seed11"] and train[0].num_frames == 20
    assert datasets.load_clips(SYNTHETIC)[0] is clips[0]  # cached per process
    assert "seeds [11]" in datasets.describe_training(SYNTHETIC)
    assert not datasets.cmu_used(SYNTHETIC)


def test_frame_step_keeps_every_kth_frame_in_clips_catalogue_and_training_set():
    step3 = {**SYNTHETIC, "name": "synthetic-step3", "frame_step": 3}
    full, = [m for m in datasets.load_clips(SYNTHETIC) if m.name == "synthetic-seed1"]
    sub = datasets.load_clips(step3)[0]
    assert sub.num_frames == 10 and sub.fps == pytest.approx(full.fps / 3)
    # The same rotations (a quaternion up to its sign) and joint positions as frames 0, 3, 6, ... of the full clip.
    np.testing.assert_allclose(np.abs(np.sum(sub.rotations * full.rotations[::3], axis=-1)), 1.0, atol=1e-6)
    np.testing.assert_allclose(sub.positions(), full.positions()[::3], atol=1e-5)
    assert [ref.frames for ref in datasets.catalogue(step3)] == [10, 10]
    assert [m.num_frames for m in datasets.iter_clips(step3, ["synthetic-seed2"])] == [10]
    assert datasets.load_training(step3)[0].num_frames == 7  # 20 frames, inherited step 3
    assert "every 3th frame" in datasets.describe_dataset(step3)


@pytest.mark.parametrize("step", [0, -5, 2.5, "5", True])
def test_bad_frame_step_is_named(step):
    with pytest.raises(datasets.DatasetError, match="`frame_step` must be a positive integer"):
        datasets.catalogue({**SYNTHETIC, "name": f"bad-{step}", "frame_step": step})


def test_cmu_dataset_without_data_is_a_clear_error(tmp_path):
    spec = {"name": "cmu_test", "kind": "cmu", "split": "cmu_test", "data_dir": str(tmp_path / "nowhere"),
            "train": {"split": "cmu_train"}}
    with pytest.raises(DataNotFoundError, match="CMU data folder not found.*data_dir="):
        datasets.load_clips(spec)
    assert datasets.cmu_used(spec)
    ok, why = cmu_available(str(tmp_path / "nowhere"))
    assert not ok and "not found" in why


@pytest.mark.parametrize("spec, message", [
    ({"name": "x"}, "missing required key `kind`"),
    ({"name": "x", "kind": "tape"}, "`kind` must be one of"),
    ({"name": "x", "kind": "cmu", "split": "cmu_test", "clips": ["09_06"], "data_dir": "."}, "exactly one of"),
])
def test_malformed_dataset_configs_are_named(spec, message, monkeypatch):
    if spec.get("kind") == "cmu":
        monkeypatch.setattr("mocapbench.datasets.cmu.cmu_data_dir", lambda path=None: path)
    with pytest.raises(datasets.DatasetError, match=message):
        datasets.load_clips(spec)


def test_folder_of_bvh_files_is_a_dataset(tmp_path):
    motion = sinusoidal_motion(num_frames=12, seed=5)
    write_bvh(motion, tmp_path / "a.bvh")
    write_bvh(sinusoidal_motion(num_frames=8, seed=6), tmp_path / "b.bvh")
    spec = {"name": "folder", "kind": "folder", "path": str(tmp_path), "train": None}
    clips = datasets.load_clips(spec)
    assert [m.num_frames for m in clips] == [12, 8]
    assert np.allclose(clips[0].positions(), motion.positions(), atol=1e-3)
    assert datasets.describe_training(spec).startswith("in-sample")
    assert len(datasets.load_training(spec)) == 2


def test_the_make_run_cmu_clip_loads_from_amc(cmu_full_dir):
    spec = {"name": "cmu_09_06", "kind": "cmu", "data_dir": str(cmu_full_dir), "clips": ["09_06"],
            "train": {"clips": ["124_01"]}}
    (clip,) = datasets.load_clips(spec)
    assert clip.name == "09_06" and clip.num_frames == 141 and clip.num_joints == 31
    assert [m.name for m in datasets.load_training(spec)] == ["124_01"]


def _cmu_tree(root):
    """A CMU download in miniature: subjects/SS/SS.asf + SS_TT.amc (the chain fixture), two subjects."""
    fixtures = Path(__file__).resolve().parents[1] / "fixtures"
    for subject, trials in (("7", ("07_02", "07_10")), ("12", ("12_01",))):
        folder = root / "subjects" / subject.zfill(2)
        folder.mkdir(parents=True)
        shutil.copy(fixtures / "chain.asf", folder / f"{subject.zfill(2)}.asf")
        for trial in trials:
            shutil.copy(fixtures / "chain.amc", folder / f"{trial}.amc")
    (root / "subjects" / "07" / "notes.amc").write_text("not a clip name: ignored")
    return root


def test_a_cmu_tree_is_catalogued_without_parsing_and_read_clip_by_clip(tmp_path):
    root = _cmu_tree(tmp_path / "all_asfamc")
    spec = {"name": "cmu_full", "kind": "cmu_tree", "path": str(root), "exclude": ["07_10"],
            "train": {"kind": "cmu_tree", "path": str(root), "clips": ["07_10"]}}
    refs = datasets.catalogue(spec)
    assert [r.name for r in refs] == ["07_02", "12_01"] and all(r.frames >= 1 for r in refs)
    (clip,) = datasets.iter_clips(spec, ["12_01"])
    assert clip.name == "12_01" and clip.num_frames > 0
    assert [m.name for m in datasets.load_training(spec)] == ["07_10"]
    assert datasets.cmu_used(spec) and "except 1 excluded" in datasets.describe_dataset(spec)
    with pytest.raises(datasets.DatasetError, match="no clip named"):
        list(datasets.iter_clips(spec, ["99_99"]))
    (root / "subjects" / "12" / "12.asf").unlink()
    with pytest.raises(DataNotFoundError, match="12_01.amc has no skeleton 12.asf"):
        datasets.catalogue(spec)
    with pytest.raises(DataNotFoundError, match="is not a folder"):
        datasets.catalogue({**spec, "path": str(tmp_path / "missing")})


def test_catalogue_names_match_the_loaded_clips():
    refs = datasets.catalogue(SYNTHETIC)
    assert [r.name for r in refs] == [m.name for m in datasets.load_clips(SYNTHETIC)]
    assert [r.frames for r in refs] == [30, 30]


@pytest.mark.cmu
def test_cmu_full_reads_the_database_folder(compose_benchmark):
    """``dataset=cmu_full`` on the 63-clip folder: 58 clips (cmu_train left out), frames as in the manifest."""
    from omegaconf import OmegaConf

    cfg = compose_benchmark(["dataset=cmu_full", f"data_dir={cmu_data_dir()}"])
    spec = OmegaConf.to_container(cfg.dataset, resolve=True)
    refs = datasets.catalogue(spec)
    assert len(refs) == 58 and "13_17" not in {r.name for r in refs}
    assert 0.95 < sum(r.frames for r in refs) / (44_779 - 13_063 - 63) < 1.05  # estimated from file sizes
    clips = list(datasets.iter_clips(spec, [refs[0].name, refs[-1].name]))
    assert [c.num_joints for c in clips] == [31, 31]
    assert sorted(m.name for m in datasets.load_training(spec)) == sorted(
        ["13_17", "13_18", "124_01", "124_02", "135_06"])
