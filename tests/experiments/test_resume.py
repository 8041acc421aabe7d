"""Resume: a job killed mid-way keeps its finished clips; a re-run adds the rest, no duplicate, no loss."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from mocapbench.experiments.aggregate import aggregate
from mocapbench.experiments.run import read_rows, run_job

REPO = Path(__file__).resolve().parents[2]
FOUR_CLIPS = ["dataset.clips.seeds=[1,2,3,4]", "dataset.clips.num_frames=40", "dataset.train.clips.num_frames=40"]


class Killed(BaseException):
    """Stands for a SIGKILL: not an Exception, so the job's error handling does not catch it."""


def test_killed_job_resumes_clip_by_clip(compose_benchmark, tmp_path, monkeypatch):
    cfg = compose_benchmark(["codec=quant-delta-zstd", *FOUR_CLIPS])
    from mocapbench.experiments import evaluate as evaluate_module

    original = evaluate_module.evaluate_with_decoded
    calls = []

    def dying_evaluate(codec, motion, **kwargs):
        if len(calls) == 2:
            raise Killed()
        calls.append(motion.name)
        return original(codec, motion, **kwargs)

    monkeypatch.setattr(evaluate_module, "evaluate_with_decoded", dying_evaluate)
    with pytest.raises(Killed):
        run_job(cfg, tmp_path)
    rows = read_rows(tmp_path / "results.jsonl")
    assert [r["clip"] for r in rows] == ["synthetic-seed1", "synthetic-seed2"]
    assert not (tmp_path / "job.json").exists()
    assert not list(tmp_path.glob(".results.jsonl.tmp*"))  # atomic writes leave no temporary file

    seen = []

    def counting_evaluate(codec, motion, **kwargs):
        seen.append(motion.name)
        return original(codec, motion, **kwargs)

    monkeypatch.setattr(evaluate_module, "evaluate_with_decoded", counting_evaluate)
    record = run_job(cfg, tmp_path)
    assert seen == ["synthetic-seed3", "synthetic-seed4"]  # finished clips are not run again
    resumed = read_rows(tmp_path / "results.jsonl")
    assert [r["clip"] for r in resumed] == [f"synthetic-seed{i}" for i in (1, 2, 3, 4)]
    assert resumed[:2] == rows  # the rows written before the kill are kept as they were
    assert record["status"] == "done" and json.loads((tmp_path / "job.json").read_text())["rows"] == 4
    seen.clear()
    run_job(cfg, tmp_path)
    assert seen == [] and len(read_rows(tmp_path / "results.jsonl")) == 4


def test_failing_clip_is_recorded_and_the_job_goes_on(compose_benchmark, tmp_path, monkeypatch):
    cfg = compose_benchmark(["codec=quant-delta-zstd", *FOUR_CLIPS])
    from mocapbench.experiments import evaluate as evaluate_module

    original = evaluate_module.evaluate_with_decoded

    def flaky(codec, motion, **kwargs):
        if motion.name == "synthetic-seed2":
            raise ValueError("bad clip for this test")
        return original(codec, motion, **kwargs)

    monkeypatch.setattr(evaluate_module, "evaluate_with_decoded", flaky)
    record = run_job(cfg, tmp_path)
    assert record["status"] == "failed" and record["errors"] == 1
    assert [r["clip"] for r in read_rows(tmp_path / "results.jsonl")] == ["synthetic-seed1", "synthetic-seed3",
                                                                          "synthetic-seed4"]
    (error,) = read_rows(tmp_path / "errors.jsonl")
    assert error["clip"] == "synthetic-seed2" and error["codec"] == "quant-delta-zstd"
    assert "bad clip for this test" in error["error"] and error["config"]["step_cm"] == 0.1


def _sweep(folder: Path, log: Path) -> subprocess.Popen:
    command = [sys.executable, "-m", "mocapbench.experiments.run", "-m", "sweep=small",
               "hydra.sweeper.codecs=[quant-delta-zstd,quant-rot-zstd]", "hydra.sweeper.max_batch_size=1",
               "hydra.launcher.n_jobs=1", *FOUR_CLIPS, f"hydra.sweep.dir={folder}"]
    with open(log, "w") as handle:  # a file, not a pipe: a full pipe would stall the sweep
        return subprocess.Popen(command, cwd=REPO, stdout=handle, stderr=subprocess.STDOUT, start_new_session=True)


@pytest.mark.slow
def test_killed_sweep_reruns_without_duplicates_or_loss(tmp_path):
    folder = tmp_path / "sweep"
    process = _sweep(folder, tmp_path / "first.log")
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and len(list(folder.rglob("job.json"))) < 2:
        time.sleep(0.2)
    os.killpg(process.pid, signal.SIGKILL)  # the whole sweep: sweeper and its worker processes
    process.wait()
    finished = {p.parent for p in folder.rglob("job.json")}
    assert 2 <= len(finished) < 6, "the kill should land mid-sweep"
    before = {str(p): read_rows(p) for p in folder.rglob("results.jsonl")}

    _sweep(folder, tmp_path / "second.log").wait(timeout=300)
    output = (tmp_path / "second.log").read_text()
    assert f"{len(finished)} already done" in output or f"{len(finished) + 1} already done" in output, output[-2000:]
    data = aggregate([folder])
    assert len(data) == 6 * 4  # 2 codecs x 3 points x 4 clips
    assert not data.duplicated(subset=["codec", "config_hash", "clip"]).any()
    after = {str(p): read_rows(p) for p in folder.rglob("results.jsonl")}
    for path, rows in before.items():  # nothing written before the kill was lost or changed
        assert after[path][: len(rows)] == rows


def test_a_job_keeps_its_worst_clip_for_the_player(compose_benchmark, tmp_path):
    from mocapbench.experiments.worst_clip import WORST_FILE, load_worst

    cfg = compose_benchmark(["codec=mcb-linf", "codec.eps_cm=2.0", *FOUR_CLIPS])
    assert run_job(cfg, tmp_path)["status"] == "done"
    rows = read_rows(tmp_path / "results.jsonl")
    worst_row = max(rows, key=lambda r: r["max_err_cm"])
    worst = load_worst(tmp_path / WORST_FILE)
    assert worst["clip"] == worst_row["clip"] and worst["max_err_cm"] == worst_row["max_err_cm"]
    assert worst["original"].shape == worst["decoded"].shape == (40, 31, 3)
    assert worst["names"][worst["worst_joint"]] == worst_row["worst_joint"]
    errors = np.linalg.norm(worst["original"] - worst["decoded"], axis=-1)
    assert errors[worst["worst_frame"], worst["worst_joint"]] == pytest.approx(worst_row["max_err_cm"], abs=1e-4)


def test_the_worst_clip_is_written_once_per_job(compose_benchmark, tmp_path, monkeypatch):
    from mocapbench.experiments import worst_clip

    written = []
    original = worst_clip.save_worst
    monkeypatch.setattr(worst_clip, "save_worst", lambda folder, motion, *rest: (written.append(motion.name),
                                                                                 original(folder, motion, *rest)))
    cfg = compose_benchmark(["codec=quant-delta-zstd", "codec.step_cm=2.0", *FOUR_CLIPS])
    assert run_job(cfg, tmp_path)["status"] == "done"
    rows = read_rows(tmp_path / "results.jsonl")
    assert written == [max(rows, key=lambda r: r["max_err_cm"])["clip"]]
