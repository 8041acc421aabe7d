"""A folder of users' files: several skeletons and one unreadable file still give every learned codec its rows."""

from __future__ import annotations

import pytest

from mocapbench.experiments.results import read_rows
from mocapbench.experiments.run import run_job
from mocapbench.io import write_bvh
from mocapbench.synthetic import sinusoidal_motion
from mocapbench.synthetic.rigs import rig_motion


@pytest.mark.parametrize("codec, overrides", [
    ("mcb-linf", ["codec.eps_cm=1.0"]),
    ("lsdt-clip", ["codec.step_cm=0.5", "codec.train_iterations=10"]),
])
def test_mixed_skeletons_fit_one_model_each_and_a_broken_file_is_skipped(compose_benchmark, tmp_path, caplog,
                                                                        codec, overrides):
    clips = tmp_path / "clips"
    clips.mkdir()
    write_bvh(sinusoidal_motion(num_frames=60, seed=1), clips / "walk31.bvh")
    write_bvh(rig_motion(num_joints=15, num_frames=60, seed=2), clips / "biped15.bvh")
    write_bvh(rig_motion(num_joints=40, topology="quadruped", num_frames=60, seed=3), clips / "dog40.bvh")
    (clips / "broken.bvh").write_text("HIERARCHY\nROOT Hips\n{\n")
    cfg = compose_benchmark([f"codec={codec}", "dataset=folder", f"dataset.path={clips}", *overrides])
    with caplog.at_level("WARNING"):
        record = run_job(cfg, tmp_path / "job")
    assert record["status"] == "done", (tmp_path / "job" / "errors.jsonl").read_text()
    rows = read_rows(tmp_path / "job" / "results.jsonl")
    assert sorted(row["clip"] for row in rows) == ["biped15", "dog40", "walk31"]
    assert {row["joints"] for row in rows} == {15, 31, 40}
    assert all(row["model_bytes"] > 0 for row in rows)
    if codec == "mcb-linf":
        assert all(row["model_mode"] == "model" for row in rows)
        assert all(row["max_err_cm"] <= 1.0 for row in rows)
    skipped = [r.getMessage() for r in caplog.records if "broken.bvh" in r.getMessage()]
    assert skipped and all(m.startswith(f"skipped {clips / 'broken.bvh'}: ") for m in skipped)
    # A second job of the sweep loads the shared state (every skeleton's model) instead of fitting again.
    again = run_job(cfg, tmp_path / "job2", fitted_dir=tmp_path / "job" / "fitted")
    assert again["status"] == "done"
    shared = {row["clip"]: row for row in read_rows(tmp_path / "job2" / "results.jsonl")}
    assert {row["clip"]: row["bitstream_bytes"] for row in rows} == {c: r["bitstream_bytes"] for c, r in shared.items()}
    assert {r["fit_source"] for r in shared.values()} == {"sweep"}
