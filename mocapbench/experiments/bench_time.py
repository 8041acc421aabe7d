"""How long ``make bench`` will take before it starts, and what each codec took when it ends.

Before: every sweep of the run is listed by a dry run of the sweeper (its job folders, one per codec config) and
priced by :func:`mocapbench.experiments.cost.estimate` from the per-frame costs measured on this machine
(``configs/costs.json``, a dataset's own entries first: :func:`mocapbench.experiments.cost.for_dataset`) and the
clips' frames; the sweeps run one after another, so the run's wall time is the sum of their schedules on the
workers, each with a sweep's start-up (``costs["sweep"]["wall_s"]``: its process composing the jobs, the workers'
imports), plus the report (:func:`report_cost`) and the time the dry runs of the estimate itself took. After: every job's ``job.json`` holds its wall and CPU seconds; they are summed
per codec.
"""

from __future__ import annotations

import json
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

from mocapbench.experiments.sweep_progress import format_duration

__all__ = ["SweepPlan", "BenchEstimate", "estimate_run", "report_cost", "format_estimate", "format_estimate_table",
           "format_progress", "codec_times",
           "format_codec_times"]


@dataclass(frozen=True)
class SweepPlan:
    """One sweep of a run: ``sweep=<sweep> dataset=<dataset>`` and more overrides (e.g. exclusions)."""

    label: str
    sweep: str
    dataset: str
    overrides: tuple[str, ...] = ()


@dataclass(frozen=True)
class BenchEstimate:
    """Estimated wall seconds (sweeps in sequence), CPU seconds, jobs, and CPU seconds per codec."""

    wall_s: float
    cpu_s: float
    jobs: int
    codec_cpu_s: dict[str, float]
    measured: str  # when and where the costs were measured
    unpriced: tuple[str, ...] = ()  # sweeps that could not be priced, with the reason
    sweep_wall_s: tuple[float, ...] = ()  # per sweep of the plans, in order (0 for one not priced)
    sweep_cpu_s: tuple[float, ...] = ()  # per sweep of the plans, in order (0 for one not priced)
    sweep_jobs: tuple[int, ...] = ()  # per sweep of the plans, in order
    labels: tuple[str, ...] = ()  # the plans' labels, in order
    sweep_codec_cpu_s: tuple[dict[str, float], ...] = ()  # per sweep: CPU seconds per codec
    report_s: float = 0.0  # writing the report after the sweeps (in wall_s)
    prepare_s: float = 0.0  # the estimate's own dry runs, measured as they ran (in wall_s)


def estimate_run(plans: Sequence[SweepPlan], workers: int, common: Sequence[str] = ()) -> BenchEstimate:
    """Price every sweep of ``plans`` (each a dry run of the sweeper, a few seconds) on ``workers`` workers."""
    from mocapbench.experiments import cost

    started = time.perf_counter()
    costs = cost.load_costs()
    wall = cpu = 0.0
    jobs = 0
    per_codec: dict[str, float] = {}
    unpriced = []
    sweep_walls, sweep_cpus, sweep_jobs, sweep_codecs = [], [], [], []
    start_s = float(costs.get("sweep", {}).get("wall_s", 0.0))  # a sweep's process, set-up and workers

    def dry_run(plan: SweepPlan):
        try:
            return cost.sweep_folders(plan.sweep, [f"dataset={plan.dataset}", *plan.overrides, *common])
        except Exception as error:  # noqa: BLE001 - raised again below, in the plan's turn
            return error

    # The dry runs are processes of their own: ``workers`` of them at once (the dataset catalogues are composed
    # here, one at a time: Hydra's global state is this process's).
    with ThreadPoolExecutor(max(1, workers)) as pool:
        dry_runs = list(pool.map(dry_run, plans))
    for plan, folders in zip(plans, dry_runs):
        try:
            if isinstance(folders, Exception):
                raise folders
            frames = cost.dataset_frames(plan.dataset, [o for o in common if not o.startswith("hydra.")])
        except Exception as error:  # noqa: BLE001 - the sweep itself will say what is wrong
            unpriced.append(f"{plan.label} ({str(error).splitlines()[0][:120] if str(error) else type(error).__name__})")
            sweep_walls.append(0.0)
            sweep_cpus.append(0.0)
            sweep_jobs.append(0)
            sweep_codecs.append({})
            continue
        result = cost.estimate(cost.for_dataset(costs, plan.dataset), folders, frames, workers)
        sweep_walls.append(result.wall_h * 3600 + start_s)
        wall += sweep_walls[-1]
        cpu += result.cpu_h * 3600
        jobs += result.jobs
        sweep_cpus.append(result.cpu_h * 3600)
        sweep_jobs.append(result.jobs)
        sweep_codecs.append({row["codec"]: row["cpu_h"] * 3600 for row in result.rows})
        for row in result.rows:
            per_codec[row["codec"]] = per_codec.get(row["codec"], 0.0) + row["cpu_h"] * 3600
    report_s = report_cost(costs, len({plan.dataset for plan in plans}), jobs)
    measured = f"{costs.get('measured', '?')} on {costs.get('machine', '?')}"
    prepare_s = time.perf_counter() - started
    return BenchEstimate(wall + report_s + prepare_s, cpu, jobs, per_codec, measured, tuple(unpriced),
                         tuple(sweep_walls), tuple(sweep_cpus), tuple(sweep_jobs), tuple(p.label for p in plans),
                         tuple(sweep_codecs), report_s, prepare_s)


def report_cost(costs: dict[str, Any], datasets: int, jobs: int) -> float:
    """Wall seconds to write the report of ``jobs`` jobs over ``datasets`` datasets.

    ``costs["report"]``: ``cpu_s`` (reading, pooling, the tables) plus ``cpu_s_per_dataset`` (its figures) plus
    ``cpu_s_per_job`` (reading each job's rows and pictures), measured by timing the report of finished sweeps,
    as the wall time of the report with its figures drawn in two processes beside it (the names keep the file's
    keys: one process's wall time was its CPU time).
    """
    entry = costs.get("report", {})
    return (float(entry.get("cpu_s", 0.0)) + datasets * float(entry.get("cpu_s_per_dataset", 0.0))
            + jobs * float(entry.get("cpu_s_per_job", 0.0)))


def format_progress(done: int, elapsed_s: float, estimate: BenchEstimate | None) -> str:
    """One line after the ``done``-th sweep: elapsed time, and the time left by the estimate of the sweeps still
    to run, scaled by how the finished sweeps compared with theirs (a loaded machine runs late throughout)."""
    total = len(estimate.sweep_wall_s) if estimate is not None else 0
    line = f"make bench: {done} sweep(s) done, {format_duration(elapsed_s)} elapsed"
    if not total or done > total:
        return line
    expected = sum(estimate.sweep_wall_s[:done])
    left = sum(estimate.sweep_wall_s[done:])
    scale = elapsed_s / expected if expected > 0 else 1.0
    return (f"{line} (estimated {format_duration(expected)}); {done}/{total} sweeps, about "
            f"{format_duration(left * scale)} left")


def format_estimate(estimate: BenchEstimate, workers: int, top: int = 4) -> str:
    """One line: the run's estimated wall time, CPU time and jobs, and the costliest codecs."""
    heavy = sorted(estimate.codec_cpu_s.items(), key=lambda item: -item[1])[:top]
    share = ", ".join(f"{codec} {format_duration(seconds)}" for codec, seconds in heavy)
    return (f"estimated {format_duration(estimate.wall_s)} wall on {workers} workers "
            f"(sweeps {format_duration(sum(estimate.sweep_wall_s))}, report {format_duration(estimate.report_s)}, "
            f"this estimate {format_duration(estimate.prepare_s)}) "
            f"({format_duration(estimate.cpu_s)} CPU, {estimate.jobs} jobs; most CPU: {share}); "
            f"per-frame costs measured {estimate.measured}"
            + (f"; not priced: {', '.join(estimate.unpriced)}" if estimate.unpriced else ""))


def format_estimate_table(estimate: BenchEstimate) -> str:
    """Markdown tables of the estimate in seconds: per sweep (jobs, CPU, wall on the workers, the sweep's start-up
    included), then each codec's CPU per sweep."""
    lines = ["| sweep | jobs | CPU s | wall s |", "|---|---:|---:|---:|"]
    for label, jobs, cpu, wall in zip(estimate.labels, estimate.sweep_jobs, estimate.sweep_cpu_s,
                                      estimate.sweep_wall_s):
        lines.append(f"| {label} | {jobs} | {cpu:.0f} | {wall:.0f} |")
    lines.append(f"| report | | {estimate.report_s:.0f} | {estimate.report_s:.0f} |")
    lines.append(f"| the estimate's dry runs (measured) | | | {estimate.prepare_s:.0f} |")
    lines.append(f"| all | {estimate.jobs} | {estimate.cpu_s + estimate.report_s:.0f} | {estimate.wall_s:.0f} |")
    lines += ["", "| codec CPU s | " + " | ".join(estimate.labels) + " | all |",
              "|---|" + "---:|" * (len(estimate.labels) + 1)]
    for codec, total in sorted(estimate.codec_cpu_s.items(), key=lambda item: -item[1]):
        cells = [f"{each[codec]:.0f}" if codec in each else "-" for each in estimate.sweep_codec_cpu_s]
        lines.append(f"| {codec} | " + " | ".join(cells) + f" | {total:.0f} |")
    return "\n".join(lines)


def codec_times(folders: Sequence[Path]) -> list[dict[str, Any]]:
    """Per codec: jobs, summed wall seconds and CPU seconds of its jobs (``job.json``) in the sweep ``folders``.

    Jobs written before ``job.json`` held ``cpu_s`` count no CPU (``cpu_s`` then reads NaN for their codec).
    """
    rows: dict[str, dict[str, Any]] = {}
    for folder in folders:
        for job in sorted(Path(folder).rglob("job.json")):
            try:
                record = json.loads(job.read_text())
            except (OSError, ValueError):
                continue
            codec = job.parent.relative_to(folder).parts[0]
            row = rows.setdefault(codec, {"codec": codec, "jobs": 0, "wall_s": 0.0, "cpu_s": 0.0})
            row["jobs"] += 1
            row["wall_s"] += float(record.get("seconds", 0.0))
            row["cpu_s"] += float(record.get("cpu_s", float("nan")))
    return sorted(rows.values(), key=lambda r: -r["wall_s"])


def format_codec_times(rows: Sequence[dict[str, Any]]) -> str:
    """A Markdown table: codec, jobs, wall time and CPU time of its jobs (summed; jobs ran side by side)."""
    lines = ["| codec | jobs | wall (sum of its jobs) | CPU |", "|---|---:|---:|---:|"]
    for row in rows:
        lines.append(f"| {row['codec']} | {row['jobs']} | {format_duration(row['wall_s'])} | "
                     f"{format_duration(row['cpu_s'])} |")
    total_wall = sum(r["wall_s"] for r in rows)
    total_cpu = sum(r["cpu_s"] for r in rows)
    lines.append(f"| all | {sum(r['jobs'] for r in rows)} | {format_duration(total_wall)} | "
                 f"{format_duration(total_cpu)} |")
    return "\n".join(lines)
