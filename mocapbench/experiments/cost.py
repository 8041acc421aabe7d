"""What a sweep costs before it runs: CPU time, wall time on W workers and peak memory per worker.

    python -m mocapbench.experiments.cost --frames 4200000 --clips 2548 --workers 64          # full CMU, sweep=all
    python -m mocapbench.experiments.cost --dataset cmu_full data_dir=/data/cmu --workers 8   # a folder you have
    python -m mocapbench.experiments.cost --sweep small --dataset cmu_test --workers 2
    python -m mocapbench.experiments.cost --calibrate          # measure the per-frame costs on this machine
    python -m mocapbench.experiments.cost --calibrate-from multirun/<date>-bench/cmu_test   # from a finished run
    python -m mocapbench.experiments.cost --calibrate-from DIR --codecs mcb-rot --scale 0.8    # one codec, loaded

The estimate multiplies measured per-frame costs by the dataset's frames. Costs live in
``mocapbench/configs/costs.json`` (written by ``--calibrate``, which runs the sweep on two synthetic clips of
``--calibration-frames`` frames and reads every row's ``encode_cpu_s + decode_cpu_s``, plus the job's overhead per
clip (reading, positions, metrics) and a per-frame memory measurement of each codec at 4,000 frames);
``--calibrate-from`` takes them from a finished sweep's rows instead, and the job's own cost beyond its codec
(``cpu_s_per_job`` plus ``cpu_s_per_frame`` of ``job``: its config, its clips, the metrics, the launcher's share)
from its ``job.json`` (:func:`job_overhead`); each row is priced at the calls the benchmark's timing makes now
(:func:`timing_calls`), so a run timed under another budget still calibrates this one; ``--codecs`` updates only
the configs of the named codecs, ``--scale`` multiplies the CPU times read (a run on a loaded machine). Each codec
config's clips are cut into shards the way the sweeper cuts them (:mod:`mocapbench.experiments.shards`), and the
shards are scheduled on ``--workers`` workers, longest first, for the wall time. The peak memory of a job is the
process's resident baseline plus the motion and the codec's measured peak per frame times the longest clip of its
shard (a job holds one clip at a time); ``--mem-gb`` counts the jobs over a memory limit. ``--packing contiguous``
estimates the shards of sweeps from before the ``balanced`` packing (one long clip made every shard thin).

``--layout config`` estimates the layout before shards (one job per codec config over the whole dataset, every job
holding the whole dataset, its results file rewritten after every clip, ``mcb-linf`` refit in every job) from the
same measured costs plus the measured constants of that layout (``old_layout`` in the costs file), for comparison.
Estimates are for the machine the costs were measured on; per-frame costs of the neural Fourier codecs depend on
the clip length (they train a network per clip), so their figure is the least certain.
"""

from __future__ import annotations

import argparse
import heapq
import json
import math
import os
import platform
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any, Sequence

__all__ = ["COSTS_FILE", "load_costs", "for_dataset", "cpu_cost", "job_costs", "makespan", "Estimate", "estimate",
           "calls_under", "main"]

COSTS_FILE = "configs/costs.json"
# Used for a codec the costs file does not know (a codec added after the last calibration): 1 ms per frame.
_UNKNOWN_CPU_S_PER_FRAME = 1e-3
_UNKNOWN_PEAK_BYTES_PER_FRAME = 20_000.0


def load_costs(path: str | Path | None = None) -> dict[str, Any]:
    """The costs file (``path``, default the package's ``configs/costs.json``); ``{}`` if there is none."""
    try:
        if path is None:
            text = resources.files("mocapbench").joinpath(COSTS_FILE).read_text()
        else:
            text = Path(path).read_text()
    except (FileNotFoundError, OSError):
        return {}
    return json.loads(text)


def _write_costs(costs: dict[str, Any], path: str | Path | None = None) -> Path:
    """Write ``costs`` to ``path`` (default the package's ``configs/costs.json``), replacing it: updating it is what
    ``--calibrate`` and ``--calibrate-from`` are for. Atomically and never through a link
    (:mod:`mocapbench.io.safe_output`): a run stopped while writing leaves the old file, which every estimate
    reads, whole."""
    from mocapbench.io.safe_output import write_text

    target = path or Path(__file__).resolve().parents[1] / COSTS_FILE
    return write_text(target, json.dumps(costs, indent=1, sort_keys=True) + "\n", force=True)


def for_dataset(costs: dict[str, Any], dataset: str | None) -> dict[str, Any]:
    """The costs of a sweep over the dataset config ``dataset``: its own measurements over the general ones.

    ``costs["datasets"][dataset]`` (written by ``--calibrate-from ... --per-dataset``) holds ``configs`` and
    ``job`` entries measured on that dataset's clips; they replace the general entries of the same config. A rig
    other than CMU's costs another amount per frame (the game rig's moving pelvis, its end sites; a codec that
    refuses the rig costs only the refusal), so its sweeps are priced from its own rows where they exist.
    """
    own = costs.get("datasets", {}).get(dataset or "", {})
    if not own:
        return costs
    return {**costs, "configs": {**costs.get("configs", {}), **own.get("configs", {})},
            "job": {**costs.get("job", {}), **own.get("job", {})}}


def cpu_cost(costs: dict[str, Any], folder: str) -> tuple[float, float]:
    """``(CPU s per frame, CPU s per clip)`` of the job folder ``<codec>/<overrides>``.

    The config's own measurement if the costs file has it, else the most expensive config of the same codec, else
    1 ms per frame.
    """
    configs = costs.get("configs", {})
    if folder in configs:
        entry = configs[folder]
        return float(entry["cpu_s_per_frame"]), float(entry.get("cpu_s_per_clip", 0.0))
    codec = folder.split("/", 1)[0]
    same = [entry for key, entry in configs.items() if key.split("/", 1)[0] == codec]
    if same:
        worst = max(same, key=lambda entry: entry["cpu_s_per_frame"])
        return float(worst["cpu_s_per_frame"]), float(worst.get("cpu_s_per_clip", 0.0))
    return _UNKNOWN_CPU_S_PER_FRAME, 0.0


def job_costs(costs: dict[str, Any], folder: str, frames: Sequence[int], count: int,
              packing: str = "balanced") -> list[float]:
    """Estimated CPU s of each of the ``count`` shards of the config ``folder`` over clips of ``frames`` frames.

    Per clip: the config's per-frame and per-clip cost plus the job's (reading, positions, metrics).
    """
    from mocapbench.experiments.shards import pack

    per_frame, per_clip = cpu_cost(costs, folder)
    overhead = costs.get("job", {})
    per_frame += float(overhead.get("cpu_s_per_frame", 0.0))
    per_clip += float(overhead.get("cpu_s_per_clip", 0.0))
    per_job = float(overhead.get("cpu_s_per_job", 0.0))
    if not frames:
        return [per_clip + per_job]
    return [per_job + sum(per_frame * frames[i] + per_clip for i in shard) for shard in pack(frames, count, packing)]


def _peak_bytes_per_frame(costs: dict[str, Any], codec: str) -> float:
    return float(costs.get("memory", {}).get(codec, {}).get("peak_bytes_per_frame", _UNKNOWN_PEAK_BYTES_PER_FRAME))


@dataclass(frozen=True)
class Estimate:
    """The cost of one sweep on one dataset.

    Attributes
    ----------
    rows : list of dict
        Per codec: ``codec``, ``configs``, ``jobs``, ``cpu_h``, ``longest_job_h``, ``peak_gb``.
    cpu_h : float
        Total CPU hours.
    wall_h : float
        Wall hours on the given workers (longest-first schedule of the jobs).
    peak_gb : float
        The largest peak memory of one worker, GB.
    jobs : int
    jobs_over_mem : int
        Jobs whose peak is over ``mem_gb`` (0 when no ``mem_gb`` was given).
    """

    rows: list[dict[str, Any]]
    cpu_h: float
    wall_h: float
    peak_gb: float
    jobs: int
    jobs_over_mem: int = 0


def makespan(durations: Sequence[float], workers: int) -> float:
    """Longest-processing-time-first schedule of ``durations`` on ``workers`` machines: the finish time."""
    loads = [0.0] * max(1, workers)
    heapq.heapify(loads)
    for duration in sorted(durations, reverse=True):
        heapq.heappush(loads, heapq.heappop(loads) + duration)
    return max(loads)


def estimate(costs: dict[str, Any], folders: Sequence[str], frames: Sequence[int], workers: int,
             max_cpu_s: float | None = 1800.0, layout: str = "shards", packing: str = "balanced",
             mem_gb: float | None = None) -> Estimate:
    """Estimate a sweep of the job folders ``folders`` (``<codec>/<overrides>``) over clips of ``frames`` frames.

    Parameters
    ----------
    costs : dict
        :func:`load_costs`.
    folders : sequence of str
        One per codec config (as in ``jobs.json`` of a dry run).
    frames : sequence of int
        Frames of every clip of the dataset, in order.
    workers : int
        Jobs that run at once (SLURM array parallelism, or ``n_jobs`` of the local launcher).
    max_cpu_s : float or None
        The shard budget (``shard.max_cpu_s``).
    layout : {"shards", "config"}
        ``config``: one job per codec config over every clip, as before shards (see the module docstring).
    packing : {"balanced", "contiguous"}
        How clips are packed into shards (``shard.packing``, :mod:`mocapbench.experiments.shards`).
    mem_gb : float or None
        A job's memory limit (``hydra.launcher.mem_gb``): ``Estimate.jobs_over_mem`` counts the jobs whose peak
        (set by the longest clip of the job) is over it.
    """
    from mocapbench.experiments.shards import pack, shard_count

    old = costs.get("old_layout", {})
    overhead = costs.get("job", {})
    per_clip_job = float(overhead.get("cpu_s_per_clip", 0.0))
    per_frame_job = float(overhead.get("cpu_s_per_frame", 0.0))
    per_job = float(overhead.get("cpu_s_per_job", 0.0))
    baseline = float(overhead.get("baseline_rss_bytes", 300e6))
    motion_bytes = float(overhead.get("motion_bytes_per_frame", 1736.0))
    longest = max(frames) if frames else 0
    total_frames = sum(frames)
    by_codec: dict[str, dict[str, Any]] = {}
    durations: list[float] = []
    over_mem = 0
    for folder in folders:
        codec = folder.split("/", 1)[0]
        per_frame, per_clip = cpu_cost(costs, folder)
        per_frame += per_frame_job
        per_clip += per_clip_job
        cost = [per_frame * f + per_clip for f in frames]
        per_frame_bytes = motion_bytes + _peak_bytes_per_frame(costs, codec)
        if layout == "config":
            clips = len(frames)
            extra = float(old.get("rewrite_s_per_clip_squared", 0.0)) * clips * clips
            if codec == "mcb-linf":
                extra += float(old.get("mcb_linf_fit_cpu_s", 0.0))
            jobs = [sum(cost) + extra]
            peaks = [baseline + float(old.get("resident_bytes_per_frame", motion_bytes)) * total_frames
                     + _peak_bytes_per_frame(costs, codec) * longest]
        else:  # a job holds one clip at a time: its peak is set by its longest clip
            shards = pack(frames, shard_count(frames, per_frame, max_cpu_s, per_clip, packing), packing)
            jobs = [per_job + sum(cost[i] for i in shard) for shard in shards]
            peaks = [baseline + per_frame_bytes * max(frames[i] for i in shard) for shard in shards]
        if mem_gb:
            over_mem += sum(1 for p in peaks if p > mem_gb * 1e9)
        peak = max(peaks)
        durations.extend(jobs)
        row = by_codec.setdefault(codec, {"codec": codec, "configs": 0, "jobs": 0, "cpu_h": 0.0,
                                          "longest_job_h": 0.0, "peak_gb": 0.0})
        row["configs"] += 1
        row["jobs"] += len(jobs)
        row["cpu_h"] += sum(jobs) / 3600
        row["longest_job_h"] = max(row["longest_job_h"], max(jobs) / 3600)
        row["peak_gb"] = max(row["peak_gb"], peak / 1e9)
    rows = sorted(by_codec.values(), key=lambda r: -r["cpu_h"])
    cpu_h = sum(r["cpu_h"] for r in rows)
    return Estimate(rows, cpu_h, makespan(durations, workers) / 3600, max((r["peak_gb"] for r in rows), default=0.0),
                    len(durations), over_mem)


# -- the configs of a sweep -------------------------------------------------------------------------------
def sweep_folders(sweep: str, overrides: Sequence[str] = ()) -> list[str]:
    """The job folders (one per codec config, unsharded) of ``sweep=<sweep>``, from a dry run of the sweeper."""
    with tempfile.TemporaryDirectory() as folder:
        command = [sys.executable, "-m", "mocapbench.experiments.run", "-m", f"sweep={sweep}", *overrides,
                   "hydra.sweeper.dry_run=true", "shard.max_cpu_s=null", f"hydra.sweep.dir={folder}"]
        done = subprocess.run(command, capture_output=True, text=True)
        if done.returncode != 0:
            raise RuntimeError(f"dry run of sweep={sweep} failed: {done.stderr.strip().splitlines()[-1:]}")
        return [job["folder"] for job in json.loads((Path(folder) / "jobs.json").read_text())]


# -- calibration ----------------------------------------------------------------------------------------
_MEMORY_CHILD = r"""
import ctypes, gc, json, sys
from mocapbench.codecs import create
from mocapbench.synthetic import sinusoidal_motion

def status(key):
    with open("/proc/self/status") as handle:
        for line in handle:
            if line.startswith(key):
                return int(line.split()[1]) * 1024

frames = int(sys.argv[2])
motion = sinusoidal_motion(num_frames=frames, seed=5)
codec = create(sys.argv[1])
codec.decode(codec.encode(motion.slice(0, 64)))
gc.collect(); ctypes.CDLL("libc.so.6").malloc_trim(0)
open("/proc/self/clear_refs", "w").write("5")
base = status("VmRSS")
positions = motion.positions()
codec.decode(codec.encode(motion))
print(json.dumps({"peak_bytes_per_frame": (status("VmHWM") - base) / frames, "baseline_rss_bytes": base}))
"""


def _measure_memory(codec: str, frames: int) -> dict[str, float] | None:
    try:
        done = subprocess.run([sys.executable, "-c", _MEMORY_CHILD, codec, str(frames)], capture_output=True,
                              text=True, timeout=600, env=dict(os.environ, OMP_NUM_THREADS="1"))
    except subprocess.TimeoutExpired:
        return None
    lines = done.stdout.strip().splitlines()
    return json.loads(lines[-1]) if done.returncode == 0 and lines else None


def calibrate(sweep: str = "all", clip_frames: int = 300, memory_frames: int = 4000,
              out: Path | None = None, workers: int = 2) -> dict[str, Any]:
    """Run ``sweep`` on two synthetic clips of ``clip_frames`` frames and measure each config's CPU per frame.

    Writes the costs file (``out``, default the package's ``configs/costs.json``) and returns its content.
    """
    from mocapbench.experiments.aggregate import aggregate

    start = time.time()
    parse_cost, old_layout = _parse_cost_per_frame(), _old_layout_constants()  # the quick parts first
    with tempfile.TemporaryDirectory() as folder:
        command = [sys.executable, "-m", "mocapbench.experiments.run", "-m", f"sweep={sweep}",
                   "dataset=synthetic", "dataset.clips.seeds=[1,2]", f"dataset.clips.num_frames={clip_frames}",
                   f"dataset.train.clips.num_frames={clip_frames}", "save_example=false", "shard.max_cpu_s=null",
                   f"hydra.launcher.n_jobs={workers}", f"hydra.sweep.dir={folder}"]
        # A config that fails on the calibration clips (a codec unavailable here) is left out, not fatal.
        done = subprocess.run(command, capture_output=True, text=True)
        if not list(Path(folder).rglob("results.jsonl")):
            raise RuntimeError(f"calibration sweep wrote no results: {done.stderr.strip().splitlines()[-1:]}")
        data = aggregate([folder])
        jobs = {}
        for job in Path(folder).rglob("job.json"):
            jobs[str(job.parent.relative_to(folder))] = json.loads(job.read_text())
    configs: dict[str, Any] = {}
    data["folder"] = [str(Path(d).relative_to(Path(d).parents[1])) for d in data["job_dir"]]
    overhead_per_clip = []
    calls = _calls
    for folder_name, group in data.groupby("folder"):
        # Rows hold the median CPU time of one call; the job ran warm-up + repeats calls of each.
        cpu = float((group["encode_cpu_s"] * calls(group, "encode")
                     + group["decode_cpu_s"] * calls(group, "decode")).sum())
        frames = int(group["frames"].sum())
        configs[folder_name] = {"codec": str(group["codec"].iloc[0]), "cpu_s_per_frame": cpu / frames,
                                "cpu_s_per_clip": 0.0, "frames_measured": frames}
        job = jobs.get(folder_name)
        if job:
            wall_clips = float((group["encode_s"] * calls(group, "encode")
                                + group["decode_s"] * calls(group, "decode")).sum()) + float(group["fit_s"].iloc[0])
            overhead_per_clip.append(max(0.0, (job["seconds"] - wall_clips) / len(group)))
    memory = {}
    baselines = []
    for codec in sorted({entry["codec"] for entry in configs.values()}):
        measured = _measure_memory(codec, memory_frames)
        if measured:
            memory[codec] = {"peak_bytes_per_frame": measured["peak_bytes_per_frame"], "frames": memory_frames}
            baselines.append(measured["baseline_rss_bytes"])
    overhead_per_clip.sort()
    costs = {
        "measured": time.strftime("%Y-%m-%d"),
        "machine": f"{platform.machine()}, {os.cpu_count()} CPUs, {platform.python_version()}",
        "command": f"python -m mocapbench.experiments.cost --calibrate --sweep {sweep} "
                   f"--calibration-frames {clip_frames}",
        "calibration_s": round(time.time() - start, 1),
        "clip_frames": clip_frames,
        "configs": configs,
        "memory": memory,
        "job": {
            # Reading a clip, its reference positions and the metrics, per clip (median over the jobs).
            "cpu_s_per_clip": overhead_per_clip[len(overhead_per_clip) // 2] if overhead_per_clip else 0.0,
            "cpu_s_per_frame": parse_cost,
            "baseline_rss_bytes": max(baselines) if baselines else 300e6,
            "motion_bytes_per_frame": 31 * (4 + 3 + 3) * 8.0,
        },
        "old_layout": old_layout,
    }
    _write_costs(costs, out)
    return costs


def _config_folder(job_dir: str) -> str:
    """``<codec>/<overrides>`` of a job folder (a shard's ``shard-i-of-n`` folder belongs to its config)."""
    parts = Path(job_dir).parts
    if parts and parts[-1].startswith("shard-"):
        parts = parts[:-1]
    return "/".join(parts[-2:])


def calibrate_from(sweeps: Sequence[str | Path], out: Path | None = None, per_dataset: bool = False,
                   codecs: Sequence[str] | None = None, scale: float = 1.0) -> dict[str, Any]:
    """Update the per-frame costs of the configs that finished sweeps ran, from their rows (no new run).

    Each config's cost is its rows' encode and decode CPU seconds times the calls the benchmark's timing makes
    now on a quiet machine (:func:`timing_calls`: the sweeps may have been timed under another budget, or on a
    loaded machine) over their frames, as :func:`calibrate` measures it, but on the clips the sweeps ran: for codecs whose
    cost per frame depends on the clips (the neural Fourier codecs train a network per clip, side by side), the
    benchmark's own jobs are the calibration that fits. The other entries of the costs file are kept.
    ``per_dataset``: the sweeps (of one dataset) write the entries of their dataset only
    (``costs["datasets"][name]``, read by :func:`for_dataset`), the general entries are kept; a config that refused
    every clip (a rig it cannot carry) costs what its job spent on the refusals. ``codecs``: only the configs of
    these codecs are updated, and the job's overhead is kept (sweeps of a few codecs, run beside other work).
    ``scale``: a factor on every CPU time read (below 1 for sweeps measured on a loaded machine, where a
    process's CPU time runs longer than on a quiet one: caches and cores shared).
    """
    from mocapbench.experiments.aggregate import aggregate

    data = aggregate([str(s) for s in sweeps])
    if data.empty:
        raise RuntimeError(f"no results in {', '.join(str(s) for s in sweeps)}")
    data["folder"] = [_config_folder(d) for d in data["job_dir"]]
    if codecs:
        unknown = sorted(set(codecs) - set(map(str, data["codec"].unique())))
        if unknown:
            raise RuntimeError(f"--codecs {', '.join(unknown)}: no rows of them in {', '.join(map(str, sweeps))}")
        data = data[data["codec"].isin(list(codecs))]
    costs = load_costs(out)
    if per_dataset:
        names = sorted(map(str, data["dataset"].unique()))
        if len(names) != 1:
            raise RuntimeError(f"--per-dataset takes sweeps of one dataset, these hold {', '.join(names)}")
        own = costs.setdefault("datasets", {}).setdefault(names[0], {})
        configs = own.setdefault("configs", {})
        refused = _refused_configs(sweeps, set(data["folder"]), scale)
        configs.update({k: v for k, v in refused.items() if not codecs or v["codec"] in codecs})
    else:
        configs = costs.setdefault("configs", {})
    import numpy as np

    timing = benchmark_timing()
    for folder_name, group in data.groupby("folder"):
        per_row = scale * (group["encode_cpu_s"] * timing_calls(group, "encode", timing, scale)
                           + group["decode_cpu_s"] * timing_calls(group, "decode", timing, scale))
        cpu = float(per_row.sum())
        frames = int(group["frames"].sum())
        per_frame, per_clip = cpu / frames, 0.0
        if group["dataset"].nunique() > 1 and np.ptp(group["frames"]) > 0:
            # clips of several rates (cmu_test and cmu_test_24fps): a cost per clip beside the cost per frame
            slope, constant = np.polyfit(group["frames"].astype(float), per_row.astype(float), 1)
            if slope > 0 and constant > 0:
                per_frame, per_clip = float(slope), float(constant)
        configs[folder_name] = {"codec": str(group["codec"].iloc[0]), "cpu_s_per_frame": per_frame,
                                "cpu_s_per_clip": per_clip, "frames_measured": frames,
                                "measured_on": f"{time.strftime('%Y-%m-%d')}, results of "
                                               f"{', '.join(sorted(map(str, group['dataset'].unique())))}"
                                               + (f", CPU times x {scale:g}" if scale != 1.0 else "")}
    overhead = None if codecs else job_overhead(sweeps, data, float(costs.get("job", {}).get("cpu_s_per_frame", 0.0)))
    if overhead is not None:
        (own if per_dataset else costs).setdefault("job", {}).update(overhead)
    costs["measured"] = time.strftime("%Y-%m-%d")  # the date the estimate quotes: its latest measurement
    _write_costs(costs, out)
    return costs


def _refused_configs(sweeps: Sequence[str | Path], measured: set[str], scale: float = 1.0) -> dict[str, Any]:
    """Configs of ``sweeps`` with no row, whose jobs finished (every clip refused): their job's CPU per frame."""
    spent: dict[str, list[float]] = {}
    for sweep in sweeps:
        for job in Path(sweep).rglob("job.json"):
            folder = _config_folder(str(job.parent))
            record = json.loads(job.read_text())
            if folder in measured or record.get("status") != "done" or record.get("rows", 0) or "cpu_s" not in record:
                continue
            spent.setdefault(folder, []).append(float(record["cpu_s"]))
    return {folder: {"codec": folder.split("/", 1)[0], "cpu_s_per_frame": 0.0, "cpu_s_per_clip": 0.0,
                     "refused": True, "job_cpu_s": scale * sum(cpu) / len(cpu),
                     "measured_on": f"{time.strftime('%Y-%m-%d')}, every clip refused"}
            for folder, cpu in spent.items()}


def job_overhead(sweeps: Sequence[str | Path], data: Any, per_frame: float = 0.0) -> dict[str, Any] | None:
    """A job's CPU seconds beyond its codec's encodes and decodes, ``cpu_s_per_job + cpu_s_per_frame * frames``.

    Each job's whole cost is the difference of its worker's CPU time at the end of that job and at the end of the
    worker's previous job (``process_cpu_s`` of ``job.json``): composing its config, reading and checking its
    clips, the metrics, writing its files, the launcher's share. Its codec's share is what its rows say
    (``encode_cpu_s``, ``decode_cpu_s`` times the calls). A worker's first job (imports, the clips read for the
    first time) is left out. Over jobs of one length of clips only the constant is fit (``per_frame`` is kept);
    over several, both by least squares. None when no job has a predecessor in its worker.
    """
    import numpy as np

    cpu = (data["encode_cpu_s"] * _calls(data, "encode") + data["decode_cpu_s"] * _calls(data, "decode"))
    by_job = cpu.groupby(data["job_dir"]).sum()
    frames_of = data.groupby("job_dir")["frames"].sum()
    records = []
    for sweep in sweeps:
        for job in Path(sweep).rglob("job.json"):
            record = json.loads(job.read_text())
            if "process_cpu_s" in record and str(job.parent) in by_job.index:
                records.append((record["pid"], record["process_cpu_s"], str(job.parent)))
    samples = []
    last: dict[int, float] = {}
    for pid, at, folder in sorted(records):
        if pid in last:
            samples.append((float(frames_of[folder]), at - last[pid] - float(by_job[folder])))
        last[pid] = at
    if not samples:
        return None
    frames = np.array([f for f, _ in samples])
    rest = np.array([r for _, r in samples])
    if np.ptp(frames) > 0:
        per_frame, per_job = np.polyfit(frames, rest, 1)
        per_frame = max(0.0, float(per_frame))
    per_job = max(0.0, float(np.median(rest - per_frame * frames)))
    return {"cpu_s_per_job": per_job, "cpu_s_per_frame": per_frame, "cpu_s_per_clip": 0.0, "overhead_jobs": len(samples),
            "overhead_measured_on": f"{time.strftime('%Y-%m-%d')}, {len(samples)} jobs of {len(sweeps)} sweep(s)"}


def _calls(group, step: str):
    """Encode/decode calls per clip that the rows' timing made: warm-up and repeats (one in rows without them)."""
    if f"{step}_repeats" not in group:
        return 1
    return group[f"{step}_repeats"].fillna(1) + group.get(f"{step}_warmup", 0).fillna(0)


def benchmark_timing() -> dict[str, Any]:
    """The ``timing`` block of the package's ``configs/benchmark.yaml`` (how the next run times each call)."""
    from omegaconf import OmegaConf

    text = resources.files("mocapbench").joinpath("configs/benchmark.yaml").read_text()
    return dict(OmegaConf.to_container(OmegaConf.create(text).get("timing") or {}))


def calls_under(wall_s: float, repeats: int = 3, warmup: int = 0, budget_s: float | None = None) -> int:
    """Calls :func:`mocapbench.metrics.timing.measure` makes of a function that takes ``wall_s`` seconds.

    ``warmup`` untimed calls (the last one is the measurement when it alone passes the budget), then timed calls
    until ``repeats`` ran or the calls so far passed ``budget_s`` (at least one).
    """
    if warmup and budget_s is not None and wall_s > budget_s:
        return warmup
    calls, spent = 1, wall_s * (warmup + 1)
    while calls < repeats and (budget_s is None or spent <= budget_s):
        calls, spent = calls + 1, spent + wall_s
    return warmup + calls


def timing_calls(group, step: str, timing: dict[str, Any], scale: float = 1.0):
    """Encode/decode calls per row under ``timing`` (:func:`benchmark_timing`) on a quiet machine.

    The budget is wall time; a quiet machine's wall time of a one-thread call is its CPU time, so each row's median
    CPU time (times ``scale``, the loaded machine's inflation taken off) stands for it: the row's own wall time
    would count the other processes of a loaded machine. A row without a median CPU time, or whose encode was one
    call for a batch of clips (``encode_batch_clips``), keeps the calls it made (:func:`_calls`).
    """
    made = _calls(group, step)
    column = f"{step}_cpu_s"
    if column not in group or f"{step}_repeats" not in group or not timing:  # rows from before the timing's repeats
        return made
    planned = group[column].map(lambda cpu: calls_under(float(cpu) * scale, int(timing.get("repeats", 3)),
                                                         int(timing.get("warmup", 0)), timing.get("budget_s")))
    keep = group[column].isna()
    if step == "encode" and "encode_batch_clips" in group:
        keep |= group["encode_batch_clips"].notna()
    return planned.where(~keep, made)


def _parse_cost_per_frame() -> float:
    """CPU s per frame to read a clip: a BVH of a 2,000-frame synthetic motion written and read back."""
    from mocapbench.io.bvh import read_bvh, write_bvh
    from mocapbench.synthetic import sinusoidal_motion

    motion = sinusoidal_motion(num_frames=2000, seed=3)
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "clip.bvh"
        write_bvh(motion, path)
        cpu = time.process_time()
        read_bvh(path)
        return (time.process_time() - cpu) / 2000


def _old_layout_constants() -> dict[str, float]:
    """Measured constants of the layout before shards, for ``--layout config``.

    ``rewrite_s_per_clip_squared``: CPU of rewriting a results file of n rows after each of n clips is about
    ``c n^2``; measured by writing 400 rows that way (atomic rewrite with fsync, as the old ``run.py`` did).
    ``mcb_linf_fit_cpu_s``: a fit of ``mcb-linf`` on ``cmu_train`` (only if the CMU data is there).
    ``resident_bytes_per_frame``: what a whole dataset loaded in memory costs per frame (the motion's arrays).
    """
    from mocapbench.experiments.evaluate import evaluate
    from mocapbench.experiments.results import write_rows_atomic
    from mocapbench.codecs import create
    from mocapbench.synthetic import sinusoidal_motion

    row = evaluate(create("raw-zstd"), sinusoidal_motion(num_frames=40, seed=1))
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        cpu = time.process_time()
        for _ in range(400):
            rows.append(row)
            write_rows_atomic(Path(folder) / "results.jsonl", rows)
        rewrite = (time.process_time() - cpu) / 400**2  # total of n rewrites ~ c n^2
    constants = {"rewrite_s_per_clip_squared": rewrite, "resident_bytes_per_frame": 31 * (4 + 3) * 8.0 + 3 * 8.0}
    try:
        from mocapbench.datasets.cmu import load_split

        motions = load_split("cmu_train")
        cpu = time.process_time()
        create("mcb-linf").fit(motions)
        constants["mcb_linf_fit_cpu_s"] = time.process_time() - cpu
    except Exception:  # noqa: BLE001 - the CMU data is optional here
        pass
    return constants


# -- command line -----------------------------------------------------------------------------------------
def dataset_frames(name: str, overrides: Sequence[str] = ()) -> list[int]:
    """Frames of every clip of the dataset config ``name`` (with ``overrides``, e.g. ``data_dir=...``), in order."""
    from hydra import compose, initialize_config_module
    from hydra.core.global_hydra import GlobalHydra
    from omegaconf import OmegaConf

    from mocapbench.experiments.datasets import catalogue

    GlobalHydra.instance().clear()
    with initialize_config_module(version_base="1.3", config_module="mocapbench.configs"):
        cfg = compose("benchmark", overrides=[f"dataset={name}", *overrides])
    return [ref.frames for ref in catalogue(OmegaConf.to_container(cfg.dataset, resolve=True))]


def _print(result: Estimate, what: str, workers: int, layout: str, mem_gb: float | None = None) -> None:
    print(f"{what}; {workers} workers; layout: {layout}")
    print("| codec | configs | jobs | CPU h | longest job h | peak GB per worker |")
    print("|---|---:|---:|---:|---:|---:|")
    for row in result.rows:
        print(f"| {row['codec']} | {row['configs']} | {row['jobs']} | {row['cpu_h']:.1f} | "
              f"{row['longest_job_h']:.2f} | {row['peak_gb']:.2f} |")
    print(f"total: {result.cpu_h:.1f} CPU h ({result.cpu_h / 24:.1f} CPU-days), {result.jobs} jobs, "
          f"wall {result.wall_h:.1f} h on {workers} workers, peak {result.peak_gb:.2f} GB per worker")
    if mem_gb:
        print(f"jobs over mem_gb {mem_gb:g}: {result.jobs_over_mem}")


def main(argv: list[str] | None = None) -> int:
    from mocapbench.experiments.shards import PACKINGS

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sweep", default="all", help="the sweep whose configs are estimated (default: all)")
    parser.add_argument("--dataset", help="a dataset config (its catalogue gives the clips' frames)")
    parser.add_argument("--frames", type=int, help="total frames, with --clips (clips of equal length)")
    parser.add_argument("--clips", type=int, help="number of clips, with --frames")
    parser.add_argument("--longest-clip", type=int, help="frames of the longest clip (memory); with --frames")
    parser.add_argument("--workers", type=int, default=2, help="jobs at once (default 2)")
    parser.add_argument("--max-cpu-s", type=float, default=1800.0, help="shard budget, CPU s (shard.max_cpu_s)")
    parser.add_argument("--layout", choices=("shards", "config"), default="shards")
    parser.add_argument("--packing", choices=PACKINGS, default=PACKINGS[0],
                        help="clips into shards (shard.packing; contiguous: sweeps from before balanced packing)")
    parser.add_argument("--mem-gb", type=float, help="count the jobs whose peak is over this (hydra.launcher.mem_gb)")
    parser.add_argument("--costs", help="costs file (default: the package's configs/costs.json)")
    parser.add_argument("--calibrate", action="store_true", help="measure the costs on this machine, write them")
    parser.add_argument("--calibration-frames", type=int, default=300)
    parser.add_argument("--calibrate-from", nargs="+", metavar="SWEEP_DIR",
                        help="update the costs of the configs these finished sweeps ran, from their rows")
    parser.add_argument("--per-dataset", action="store_true",
                        help="with --calibrate-from: write the costs of the sweeps' dataset only (a rig of its own)")
    parser.add_argument("--codecs", type=lambda text: [c for c in text.split(",") if c],
                        help="with --calibrate-from: update these codecs' configs only (comma list); the job's "
                             "overhead is kept")
    parser.add_argument("--scale", type=float, default=1.0,
                        help="with --calibrate-from: a factor on the CPU times read (sweeps run on a loaded machine)")
    parser.add_argument("overrides", nargs="*", help="Hydra overrides for the dataset, e.g. data_dir=/data/cmu")
    args = parser.parse_args(argv)
    if args.calibrate_from:
        if not (args.scale > 0 and math.isfinite(args.scale)):
            parser.error(f"--scale must be a finite number > 0, got {args.scale}")
        from mocapbench.experiments.aggregate import AggregateError
        from mocapbench.experiments.results import CorruptResultsError

        try:
            costs = calibrate_from(args.calibrate_from, out=Path(args.costs) if args.costs else None,
                                   per_dataset=args.per_dataset, codecs=args.codecs, scale=args.scale)
        except (RuntimeError, AggregateError, CorruptResultsError) as error:  # no rows, a missing folder, a torn row
            print(f"cost --calibrate-from: {error}", file=sys.stderr)
            return 2
        print(f"updated the costs of the configs in {' '.join(args.calibrate_from)}; wrote {args.costs or COSTS_FILE}")
        return 0
    if args.calibrate:
        costs = calibrate(args.sweep, args.calibration_frames, out=Path(args.costs) if args.costs else None)
        print(f"measured {len(costs['configs'])} configs in {costs['calibration_s']:.0f} s; wrote "
              f"{args.costs or COSTS_FILE}")
        return 0
    costs = load_costs(args.costs)
    if not costs:
        print("no costs file: run python -m mocapbench.experiments.cost --calibrate first", file=sys.stderr)
        return 2
    if args.dataset:
        frames = dataset_frames(args.dataset, args.overrides)
        what = f"dataset {args.dataset}: {len(frames)} clips, {sum(frames):,} frames"
    elif args.frames and args.clips:
        each = args.frames / args.clips
        frames = [math.floor(each)] * args.clips
        if args.longest_clip:
            frames[0] = args.longest_clip
            rest = (args.frames - args.longest_clip) / max(1, args.clips - 1)
            frames[1:] = [max(1, math.floor(rest))] * (args.clips - 1)
        what = f"{args.clips} clips, {sum(frames):,} frames"
    else:
        parser.error("give --dataset NAME or --frames N --clips C")
    folders = sweep_folders(args.sweep)
    costs = for_dataset(costs, args.dataset)
    result = estimate(costs, folders, frames, args.workers, args.max_cpu_s, args.layout, args.packing, args.mem_gb)
    layout = args.layout if args.layout == "config" else f"shards ({args.packing})"
    _print(result, f"sweep={args.sweep} ({len(folders)} configs) over {what}", args.workers, layout, args.mem_gb)
    print(f"per-frame costs measured {costs.get('measured')} on {costs.get('machine')} ({costs.get('command')})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
