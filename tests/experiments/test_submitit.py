"""The same sweep through a cluster engine: hydra/launcher=submitit_local runs real submitit jobs (local executor)
and measures the rows the joblib launcher measures; a sweep started with one launcher resumes with the other."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from mocapbench.experiments.aggregate import aggregate
from mocapbench.experiments.results import read_rows

REPO = Path(__file__).resolve().parents[2]
# 3 cheap codec configs (one learned: mcb-linf fits its model once for the sweep) on 2 tiny synthetic clips.
SWEEP = ["sweep=small", "hydra.sweeper.codecs=[quant-delta-zstd,raw-zstd,mcb-linf]", "hydra.sweeper.max_points=1",
         "dataset.clips.seeds=[1,2]", "dataset.clips.num_frames=40", "dataset.train.clips.num_frames=40",
         "save_example=false"]
MEASURED = ["codec", "config_hash", "clip", "frames", "bitstream_bytes", "max_err_cm", "mean_err_cm", "fit_source"]


def _run(folder: Path, launcher: str) -> subprocess.CompletedProcess:
    extra = ["hydra/launcher=submitit_local", "hydra.launcher.timeout_min=5"] if launcher == "submitit" else []
    command = [sys.executable, "-m", "mocapbench.experiments.run", "-m", *SWEEP, *extra, f"hydra.sweep.dir={folder}"]
    return subprocess.run(command, cwd=REPO, capture_output=True, text=True, timeout=600)


def _rows(folder: Path):
    return aggregate([folder]).sort_values(["codec", "config_hash", "clip"])[MEASURED].reset_index(drop=True)


def test_submitit_local_sweep_equals_joblib_and_resumes_across_launchers(tmp_path):
    joblib_dir, submitit_dir = tmp_path / "joblib", tmp_path / "submitit"
    first = _run(joblib_dir, "joblib")
    assert first.returncode == 0, first.stderr[-3000:]
    second = _run(submitit_dir, "submitit")
    assert second.returncode == 0, second.stderr[-3000:]
    assert list((submitit_dir / ".submitit").rglob("*_result.pkl")), "the jobs did not run through submitit"
    expected = _rows(joblib_dir)
    assert len(expected) == 3 * 2 and (expected["max_err_cm"] > 0).any()
    assert _rows(submitit_dir).equals(expected)

    # Damage the submitit sweep (a torn row, a job that never finished), then resume it with joblib.
    torn = submitit_dir / "raw-zstd" / "codec.zstd_level=19" / "results.jsonl"
    text = torn.read_text()
    torn.write_text(text[: len(text) - 40])
    (submitit_dir / "quant-delta-zstd" / "codec.step_cm=0.5" / "job.json").unlink()
    resumed = _run(submitit_dir, "joblib")
    assert resumed.returncode == 0, resumed.stderr[-3000:]
    assert "1 already done, 2 to run" in resumed.stdout + resumed.stderr
    assert _rows(submitit_dir).equals(expected)
    assert len(read_rows(torn)) == 2 and (torn.parent / "results.jsonl.corrupt-1").exists()
