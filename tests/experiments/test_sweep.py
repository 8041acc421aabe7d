"""Sweeps end to end: sweep=all covers every registered codec's curve; a tiny sweep feeds a full report."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from omegaconf import OmegaConf

from mocapbench.codecs import codec_names
from mocapbench.experiments.aggregate import aggregate, read_errors
from mocapbench.experiments.report import build_report

REPO = Path(__file__).resolve().parents[2]
TINY = ["dataset.clips.seeds=[1,2]", "dataset.clips.num_frames=40", "dataset.train.clips.num_frames=40",
        "timing.repeats=1", "timing.warmup=0"]  # speeds are not checked here: one timed call is enough


def _run(*overrides: str, timeout: int = 300) -> subprocess.CompletedProcess:
    command = [sys.executable, "-m", "mocapbench.experiments.run", "-m", *overrides]
    return subprocess.run(command, cwd=REPO, capture_output=True, text=True, timeout=timeout)


def _grid_size(name: str) -> int:
    params = OmegaConf.load(REPO / "mocapbench" / "configs" / "sweep" / f"rd_{name}.yaml").hydra.sweeper.params
    size = 1
    for value in params.values():
        size *= len(str(value).split(","))
    return size


def test_sweep_all_expands_every_registered_codec_curve(tmp_path):
    result = _run("sweep=all", "dataset=cmu_test", "hydra.sweeper.dry_run=true", f"hydra.sweep.dir={tmp_path}")
    assert result.returncode == 0, result.stderr[-3000:]
    jobs = json.loads((tmp_path / "jobs.json").read_text())
    by_codec: dict[str, int] = {}
    for job in jobs:
        codec = job["folder"].split("/")[0]
        by_codec[codec] = by_codec.get(codec, 0) + 1
        assert "dataset=cmu_test" in job["overrides"] and not any(o == "sweep=all" for o in job["overrides"])
    ready = [n for n in codec_names() if (REPO / "mocapbench/configs/codec" / f"{n}.yaml").exists()
             and (REPO / "mocapbench/configs/sweep" / f"rd_{n}.yaml").exists()]
    assert sorted(by_codec) == sorted(ready)
    for name in ready:
        assert by_codec[name] == _grid_size(name), name
    assert len({job["folder"] for job in jobs}) == len(jobs)
    assert not list(tmp_path.rglob("results.jsonl"))  # a dry run launches nothing


@pytest.mark.slow
def test_tiny_sweep_then_report(tmp_path):
    sweep = tmp_path / "sweep"
    result = _run("sweep=small", "hydra.sweeper.codecs=[quant-pred-zstd,quant-rot-zstd,raw-zstd]",
                  "hydra.sweeper.max_points=2", *TINY, f"hydra.sweep.dir={sweep}")
    assert result.returncode == 0, result.stderr[-3000:]
    data = aggregate([sweep])
    assert sorted(data.groupby("codec")["config_hash"].nunique().items()) == [
        ("quant-pred-zstd", 2), ("quant-rot-zstd", 2), ("raw-zstd", 1)]
    assert len(data) == 5 * 2
    for job in {Path(d) for d in data["job_dir"]}:  # Hydra's saved configs beside the rows
        assert (job / ".hydra" / "config.yaml").exists() and (job / ".hydra" / "overrides.yaml").exists()
        assert json.loads((job / "job.json").read_text())["status"] == "done"
    assert read_errors([sweep]).empty

    report = build_report([sweep], name="tiny", reports_root=tmp_path / "reports")
    assert report.name.endswith("-tiny")
    markdown = (report / "report.md").read_text()
    headline = markdown.split("## Headline")[1].split("\n## ")[0]
    assert headline.count("### synthetic, L∞ < 1 cm") == 1 and headline.count("### synthetic, L∞ < 3 cm") == 1
    wider = headline.split("### synthetic, L∞ < 3 cm")[1]
    repeats = "the same codecs and configs as under 1 cm" in wider  # a wider bound admitting nothing new: one line
    for codec in ("quant-pred-zstd", "quant-rot-zstd", "raw-zstd"):
        assert headline.count(f" | {codec} | ") == (1 if repeats else 2), codec  # one row per bound shown
    bd_rates = markdown.split("### synthetic: BD-rate against quant-pred-zstd")[1].split("\n## ")[0]  # one per dataset
    assert "| quant-pred-zstd | quant-pred-zstd | 0 | anchor |" in bd_rates
    assert "python -m mocapbench.experiments.run -m sweep=small" in markdown
    for figure in ("rd_max_err_cm_synthetic", "rd_mean_err_cm_synthetic", "rd_kg_percent_synthetic",
                   "rd_per_clip_synthetic", "heatmap_synthetic", "overlay_synthetic"):
        assert (report / "figures" / f"{figure}.png").stat().st_size > 5000
    assert (report / "index.html").read_text().count("<table>") >= 6
    for codec in ("quant-pred-zstd", "quant-rot-zstd", "raw-zstd"):
        assert (report / "results" / "synthetic" / f"{codec}.json").exists()
    assert len((report / "results" / "rows.csv").read_text().splitlines()) == 1 + len(data)


@pytest.mark.slow
def test_a_failing_job_is_logged_and_the_sweep_goes_on(tmp_path):
    sweep = tmp_path / "sweep"
    result = _run("codec=quant-delta-zstd", "codec.step_cm=0.5,-1.0", *TINY, f"hydra.sweep.dir={sweep}")
    assert result.returncode == 1, result.stderr[-3000:]  # a failed job fails the sweep...
    assert "[2/2]" in result.stdout and "ETA" in result.stdout  # one line per finished job
    assert "1/2 jobs done, 1 failed" in result.stdout and "step_cm" in result.stdout.split("failures by reason")[1]
    data = aggregate([sweep])
    assert set(data["param_step_cm"]) == {0.5}
    (error,) = read_errors([sweep]).to_dict("records")
    assert error["stage"] == "setup" and "step_cm" in error["error"] and error["codec"] == "quant-delta-zstd"
    assert error["dataset"] == "synthetic"  # from the job's saved config, for the headline's row
    assert json.loads((sweep / "quant-delta-zstd" / "codec.step_cm=-1.0" / "job.json").read_text())["status"] == "failed"
    again = _run("codec=quant-delta-zstd", "codec.step_cm=0.5,-1.0", *TINY, f"hydra.sweep.dir={sweep}",
                 "hydra.sweeper.allow_failures=true")
    assert again.returncode == 0, again.stderr[-3000:]  # ...unless failures are allowed (the done job is skipped)
    assert "1 skipped (already done)" in again.stdout
