"""Reader and forward-kinematics speed on the CMU clips: ``python -m mocapbench.benchmarks.io [--data-dir D]``.

Loads every clip of ``cmu_all`` from BVH and from ASF/AMC, runs FK (``Motion.positions()``) on the AMC
motions, and prints frames per second (total frames / total median time over ``--repeats`` runs per
clip) for each step, single-threaded, next to the targets: BVH parsing >= 20,000 frames/s, AMC parsing
>= 10,000 frames/s (ASF already parsed, as ``load_split`` does once per subject), FK >= 200,000 frames/s
(31 joints). File reading is included in the parsing times (the page cache is warm after the warm-up run).
"""

from __future__ import annotations

import argparse
import platform
import sys

from mocapbench.datasets.cmu import ALL_SPLIT, CMU_CM_PER_UNIT, clip_names, cmu_data_dir
from mocapbench.io.asf_amc import read_amc, read_asf
from mocapbench.io.bvh import read_bvh
from mocapbench.metrics.timing import METHOD, load_average, measure

TARGETS_FRAMES_PER_S = {"BVH parse": 20_000, "AMC parse": 10_000, "FK (positions)": 200_000}


def run(data_dir: str | None = None, repeats: int = 3) -> list[dict]:
    """Time the three steps over every ``cmu_all`` clip.

    Returns
    -------
    list of dict
        One row per step: ``step``, ``clips``, ``frames``, ``seconds`` (sum of per-clip median CPU seconds of
        the process), ``wall_seconds`` (sum of per-clip median wall seconds), ``frames_per_s`` (per CPU second),
        ``wall_frames_per_s``, ``target_frames_per_s``.
    """
    root = cmu_data_dir(data_dir)
    totals = {step: [0, 0.0, 0.0] for step in TARGETS_FRAMES_PER_S}

    def timed(step: str, function, frames_of) -> object:
        timing, result = measure(function, repeats=repeats, warmup=1)
        totals[step][0] += frames_of(result)
        totals[step][1] += timing.cpu_s
        totals[step][2] += timing.wall_s
        return result

    asf_cache = {}
    names = clip_names(ALL_SPLIT, data_dir=root)
    for name in names:
        subject = name.split("_", 1)[0]
        bvh_path = root / "bvh" / f"{name}.bvh"
        amc_path = root / "asf_amc" / subject / f"{name}.amc"
        asf_path = root / "asf_amc" / subject / f"{subject}.asf"
        if asf_path not in asf_cache:
            asf_cache[asf_path] = read_asf(asf_path)
        asf = asf_cache[asf_path]
        # The parser handles every frame, reference frame 0 included.
        timed("BVH parse", lambda path=bvh_path: read_bvh(path, length_unit_cm=CMU_CM_PER_UNIT, drop_first_frame=True),
              lambda motion: motion.num_frames + 1)
        amc = timed("AMC parse", lambda path=amc_path, asf=asf, name=name: read_amc(path, asf, name=name),
                    lambda motion: motion.num_frames)
        timed("FK (positions)", amc.positions, lambda _positions, amc=amc: amc.num_frames)
    return [
        {
            "step": step,
            "clips": len(names),
            "frames": frames,
            "seconds": seconds,
            "wall_seconds": wall,
            "frames_per_s": frames / seconds,
            "wall_frames_per_s": frames / wall,
            "target_frames_per_s": TARGETS_FRAMES_PER_S[step],
        }
        for step, (frames, seconds, wall) in totals.items()
    ]


def format_table(rows: list[dict]) -> str:
    """Markdown table of :func:`run` rows."""
    lines = [
        "| step | clips | frames | CPU s | frames/CPU s | wall s | frames/wall s | target frames/s | meets target |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---|",
    ]
    for row in rows:
        ok = "yes" if row["frames_per_s"] >= row["target_frames_per_s"] else "NO"
        lines.append(
            f"| {row['step']} | {row['clips']} | {row['frames']:,} | {row['seconds']:.3f} | "
            f"{row['frames_per_s']:,.0f} | {row['wall_seconds']:.3f} | {row['wall_frames_per_s']:,.0f} | "
            f"{row['target_frames_per_s']:,} | {ok} |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m mocapbench.benchmarks.io", description=__doc__.split("\n")[0])
    parser.add_argument("--data-dir", default=None, help="CMU data folder (default: see mocapbench.datasets.cmu)")
    parser.add_argument("--repeats", type=int, default=3, help="timed runs per clip and step (median), default 3")
    args = parser.parse_args(argv)
    rows = run(args.data_dir, repeats=args.repeats)
    print(format_table(rows))
    machine = platform.processor() or platform.machine()
    print(
        f"\nPer clip: {METHOD.format(repeats=args.repeats, warmup=1, threads=1)}; the target is met on CPU time. "
        f"Load average after the run {load_average():.2f}; {machine}, Python {platform.python_version()}."
    )
    return 0


if __name__ == "__main__":
    from mocapbench.benchmarks.entry import run_script

    raise SystemExit(run_script(main))
