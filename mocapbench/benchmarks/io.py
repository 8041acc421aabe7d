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
from mocapbench.metrics.timing import time_call

TARGETS_FRAMES_PER_S = {"BVH parse": 20_000, "AMC parse": 10_000, "FK (positions)": 200_000}


def run(data_dir: str | None = None, repeats: int = 3) -> list[dict]:
    """Time the three steps over every ``cmu_all`` clip.

    Returns
    -------
    list of dict
        One row per step: ``step``, ``clips``, ``frames``, ``seconds`` (sum of per-clip medians),
        ``frames_per_s``, ``target_frames_per_s``.
    """
    root = cmu_data_dir(data_dir)
    totals = {step: [0, 0.0] for step in TARGETS_FRAMES_PER_S}
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
        seconds, bvh = time_call(
            lambda path=bvh_path: read_bvh(path, length_unit_cm=CMU_CM_PER_UNIT, drop_first_frame=True), repeats=repeats
        )
        # The parser handles every frame, reference frame 0 included.
        totals["BVH parse"][0] += bvh.num_frames + 1
        totals["BVH parse"][1] += seconds
        seconds, amc = time_call(
            lambda path=amc_path, asf=asf, name=name: read_amc(path, asf, name=name), repeats=repeats
        )
        totals["AMC parse"][0] += amc.num_frames
        totals["AMC parse"][1] += seconds
        seconds, _ = time_call(amc.positions, repeats=repeats)
        totals["FK (positions)"][0] += amc.num_frames
        totals["FK (positions)"][1] += seconds
    return [
        {
            "step": step,
            "clips": len(names),
            "frames": frames,
            "seconds": seconds,
            "frames_per_s": frames / seconds,
            "target_frames_per_s": TARGETS_FRAMES_PER_S[step],
        }
        for step, (frames, seconds) in totals.items()
    ]


def format_table(rows: list[dict]) -> str:
    """Markdown table of :func:`run` rows."""
    lines = [
        "| step | clips | frames | time (s) | frames/s | target frames/s | meets target |",
        "|---|---:|---:|---:|---:|---:|---|",
    ]
    for row in rows:
        ok = "yes" if row["frames_per_s"] >= row["target_frames_per_s"] else "NO"
        lines.append(
            f"| {row['step']} | {row['clips']} | {row['frames']:,} | {row['seconds']:.3f} | "
            f"{row['frames_per_s']:,.0f} | {row['target_frames_per_s']:,} | {ok} |"
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
        f"\nSingle thread; median of {args.repeats} runs per clip after 1 warm-up; {machine}, "
        f"Python {platform.python_version()}."
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
