"""Reproduction of Tournier et al. 2008 (PGA motion compression) with the ``pga-ik`` codec.

``python -m mocapbench.benchmarks.pga.paper [--data-dir D] [--out reports/pga] [--repeats 3] [--quick]``

Prints markdown tables (and writes them to ``<out>/pga.md``):

1. **Table 2, clip 1 (09_06)** with the paper's settings (6 geodesics, 4 of 9 levels kept for root and end
   joints), beside diagnostic variants (lossless trajectories; more geodesics).
2. **The same protocol over ``cmu_test``**, k chosen the paper's ways (fixed 12, the 95 % and the 99 %
   variance rules), per clip and in total.
3. **The paper's other rows' settings** applied to the most similar clips available (walks; boxing from
   ``cmu_train``, which pga-ik may use since it learns nothing across clips; jumps/kicks for the dynamic rows).
4. **Fig. 3's observation**: geodesics reaching 95 % and 99 % of the tangent variance on every CMU clip here.
5. **Speed**: decompression ms/frame and compression time, one thread.

Ratios: "paper" = numbers stored vs ``3 (m + 1) n`` (§3.6, m inner joints, n frames); "real" = float32 joint
positions (``12 J F`` bytes) / bytes of the whole bitstream (skeleton, container and model included).
Errors on the 31 joint positions in cm; KG as in the paper (§4). Times: median of ``--repeats`` runs, one
thread (``OMP_NUM_THREADS=1`` etc. set before numpy loads); decoding is given as process CPU time (the cost on
one unshared core, robust to other jobs on a shared machine) and as wall time.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

from mocapbench import metrics
from mocapbench.codecs import create
from mocapbench.codecs.pga.codec import select_end_joints
from mocapbench.codecs.pga.geodesics import fit_pga, variance_count
from mocapbench.codecs.pga.lifting import (
    EUCLIDEAN,
    ROTATIONS,
    level_sizes,
    lifting_decompose,
    num_lifting_levels,
)
from mocapbench.datasets.cmu import ALL_SPLIT, clip_names, load_clip
from mocapbench.metrics.timing import measure
from mocapbench.motion import Motion

# The paper's Table 2: clip, description, frames, k, #LOD root, #LOD end joints, ratio, KG %, ms/frame.
PAPER_TABLE_2 = [
    ("09_06", "running, short", 141, 6, "4/9", "4/9", 18, 0.36, 7.88),
    ("17_08", "walking, slow", 6179, 12, "8/14", "8/14", 182, 0.049, 16.2),
    ("15_04", "various, dancing, boxing", 22948, 17, "12/16", "12/16", 69, 1.55, 30.6),
    ("85_12", "breakdance", 4499, 15, "9/14", "9/14", 97, 0.56, 20.42),
    ("17_10", "boxing", 2783, 12, "8/13", "9/13", 61, 0.49, 15.97),
]

# Paper rows' settings as dropped levels (total - kept), applied to our most similar clips.
def setting(k: int, root_dropped: int, end_dropped: int, **extra) -> dict:
    """``pga-ik`` parameters: k geodesics, finest levels dropped for the root and the end joints, and extras."""
    return dict(num_geodesics=k, root_levels_dropped=root_dropped, end_levels_dropped=end_dropped, **extra)


LOSSLESS = dict(trajectory_bits=24, model_bits=24)

PAPER_ROW_SETTINGS = [
    ("walk (17_08)", setting(12, 6, 6), ["02_01", "02_02", "05_01"]),
    ("boxing (17_10)", setting(12, 5, 4), ["13_17", "13_18"]),
    ("breakdance (85_12)", setting(15, 5, 5), ["16_01", "16_07", "118_01", "10_01"]),
    ("dance/various (15_04)", setting(17, 4, 4), ["135_06", "64_01"]),
]

_COLUMNS = [
    ("clip", "clip"),
    ("frames", "F"),
    ("K", "k"),
    ("root_lod", "LOD root"),
    ("end_lod", "LOD end"),
    ("paper_ratio", "ratio (paper)"),
    ("real_ratio", "ratio (bytes)"),
    ("bytes", "bytes"),
    ("kg", "KG %"),
    ("linf", "L∞ cm"),
    ("mean", "mean cm"),
    ("end_linf", "end-joint L∞ cm"),
    ("decode_cpu_ms", "decode CPU ms/frame"),
    ("decode_ms", "decode wall ms/frame"),
    ("encode_s", "encode s"),
    ("explained", "variance in k"),
]


def evaluate_setting(motion, params: dict, repeats: int) -> dict:
    """Encode once (timed), decode ``repeats`` times (median), and measure one ``pga-ik`` setting on a clip."""
    codec = create("pga-ik", **params)
    start = time.perf_counter()
    data = codec.encode(motion)
    encode_s = time.perf_counter() - start
    stats = dict(codec.last_encode_stats)
    # Wall and CPU time of this (single-threaded) process: CPU is what one unshared core needs, whatever else
    # runs beside it (the shared helper: warm-up, median of the repeats).
    timing, decoded = measure(lambda: create("pga-ik").decode(data), repeats=repeats, warmup=1)
    decode_s = timing.wall_s
    reference = motion.positions()
    ends = select_end_joints(motion.skeleton)
    return {
        "clip": motion.name,
        "frames": motion.num_frames,
        "joints": motion.num_joints,
        "K": stats["K"],
        "root_lod": stats["root_lod"],
        "end_lod": stats["end_lod"],
        "paper_ratio": stats["paper_compression_ratio"],
        "real_ratio": metrics.raw_position_bytes(motion.num_joints, motion.num_frames) / len(data),
        "bytes": len(data),
        "kg": metrics.kg_distortion(reference, decoded.positions),
        "linf": metrics.max_joint_error(reference, decoded.positions),
        "mean": metrics.mean_joint_error(reference, decoded.positions),
        "end_linf": metrics.max_joint_error(reference[:, ends], decoded.positions[:, ends]),
        "decode_ms": 1e3 * decode_s / motion.num_frames,
        "decode_cpu_ms": 1e3 * timing.cpu_s / motion.num_frames,
        "encode_s": encode_s,
        "explained": stats["explained_variance"],
        "k_95": stats["k_95"],
        "k_99": stats["k_99"],
    }


_ORACLE_COLUMNS = [
    ("dropped", "D"),
    ("lod", "LOD kept/total"),
    ("samples", "samples per track"),
    ("root_kg", "root-only KG %"),
    ("root_linf", "root-only L∞ cm"),
    ("end_linf", "end trajectories L∞ cm"),
    ("end_mean", "end trajectories mean cm"),
]


def root_only_rows(motion) -> list[dict]:
    """Error floors of the trajectory coding alone, for D = 0..5 finest levels dropped (no quantization)."""
    reference = motion.positions()
    ends = select_end_joints(motion.skeleton)
    rows = []
    for dropped in range(6):
        _, _, root = lifting_decompose(motion.root_positions, EUCLIDEAN, dropped)
        _, _, orientation = lifting_decompose(motion.rotations[:, 0], ROTATIONS, dropped)
        _, _, tracks = lifting_decompose(reference[:, ends].reshape(motion.num_frames, -1), EUCLIDEAN, dropped)
        rotations = np.concatenate([orientation[:, None], motion.rotations[:, 1:]], axis=1)
        oracle = Motion(motion.skeleton, motion.fps, root, rotations).positions()
        end_errors = np.linalg.norm(tracks.reshape(reference[:, ends].shape) - reference[:, ends], axis=-1)
        levels = num_lifting_levels(motion.num_frames)
        rows.append(
            {
                "dropped": dropped,
                "lod": f"{max(levels - dropped, 0) + 1}/{levels + 1}",
                "samples": level_sizes(motion.num_frames)[max(levels - dropped, 0)],
                "root_kg": metrics.kg_distortion(reference, oracle),
                "root_linf": metrics.max_joint_error(reference, oracle),
                "end_linf": float(end_errors.max()),
                "end_mean": float(end_errors.mean()),
            }
        )
    return rows


def _format(value) -> str:
    if isinstance(value, float):
        if abs(value) >= 100:
            return f"{value:.0f}"
        if abs(value) >= 10:
            return f"{value:.1f}"
        return f"{value:.3f}" if abs(value) < 1 else f"{value:.2f}"
    return str(value)


def markdown_table(rows: list[dict], columns=_COLUMNS, extra: list[tuple[str, str]] = ()) -> str:
    """Rows as a markdown table over ``columns`` (key, header) plus ``extra`` leading columns."""
    cols = list(extra) + list(columns)
    lines = ["| " + " | ".join(h for _, h in cols) + " |", "|" + "|".join("---" for _ in cols) + "|"]
    for row in rows:
        lines.append("| " + " | ".join(_format(row.get(key, "")) for key, _ in cols) + " |")
    return "\n".join(lines)


def total_row(rows: list[dict], label: str) -> dict:
    """Totals over clips: ratios of summed sizes, mean KG, worst L∞, frame-weighted mean error and ms/frame."""
    frames = sum(r["frames"] for r in rows)
    raw = sum(12 * r["joints"] * r["frames"] for r in rows)
    paper_raw = sum(3 * r["joints"] * r["frames"] for r in rows)  # 3 (m + 1) n
    paper_stored = sum(3 * r["joints"] * r["frames"] / r["paper_ratio"] for r in rows)
    return {
        "clip": label,
        "frames": frames,
        "K": f"{min(r['K'] for r in rows)}-{max(r['K'] for r in rows)}",
        "paper_ratio": paper_raw / paper_stored,
        "real_ratio": raw / sum(r["bytes"] for r in rows),
        "bytes": sum(r["bytes"] for r in rows),
        "kg": float(np.mean([r["kg"] for r in rows])),
        "linf": max(r["linf"] for r in rows),
        "mean": sum(r["mean"] * r["frames"] for r in rows) / frames,
        "end_linf": max(r["end_linf"] for r in rows),
        "decode_ms": sum(r["decode_ms"] * r["frames"] for r in rows) / frames,
        "decode_cpu_ms": sum(r["decode_cpu_ms"] * r["frames"] for r in rows) / frames,
        "encode_s": sum(r["encode_s"] for r in rows),
    }


def run(data_dir: str | None, repeats: int, quick: bool) -> str:
    """Run every section; returns the markdown report (each line is also printed as it comes)."""
    out: list[str] = []

    def emit(text: str = "") -> None:
        print(text)
        sys.stdout.flush()
        out.append(text)

    _header(emit)
    _table2_section(emit, load_clip("09_06", data_dir=data_dir), repeats)
    test_names = clip_names("cmu_test", data_dir=data_dir)
    if quick:
        test_names = test_names[:3]
    motions = {name: load_clip(name, data_dir=data_dir) for name in test_names}
    _cmu_test_section(emit, motions)
    _paper_rows_section(emit, motions, data_dir, quick)
    _fig3_section(emit, motions, data_dir, quick)
    _speed_section(emit, motions, data_dir, repeats, quick)
    return "\n".join(out)


def _clip(motions: dict[str, Motion], name: str, data_dir: str | None) -> Motion:
    """A clip of cmu_test already loaded in ``motions``, or read from the data folder."""
    return motions.get(name) or load_clip(name, data_dir=data_dir)


def _header(emit) -> None:
    emit("# pga-ik: reproduction of Tournier et al. 2008 (INRIA RR-6648)")
    emit()
    emit(f"Command: `python -m mocapbench.benchmarks.pga.paper {' '.join(sys.argv[1:])}`  ")
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    emit(
        f"Machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, load average {load:.1f} at "
        f"start, Python {platform.python_version()}, numpy {np.__version__}, one thread."
    )
    emit()


def _table2_section(emit, clip: Motion, repeats: int) -> None:
    """Section 1: Table 2's clip 1 (09_06) at the paper's setting and diagnostic variants, then its error floors."""
    emit("## 1. Table 2, clip 1: 09_06 (running, 141 frames)")
    emit()
    emit("Paper: 6 geodesics, 4/9 levels kept (root and end joints) → 1:18, KG 0.36 %, 7.88 ms/frame (C++).")
    emit()
    variants = [
        ("paper setting", setting(6, 5, 5)),
        ("paper setting, 16-bit", setting(6, 5, 5, trajectory_bits=16, model_bits=16)),
        ("k = 6, 6/9 levels", setting(6, 3, 3)),
        ("k = 6, lossless trajectories", setting(6, 0, 0, **LOSSLESS)),
        ("k = 12, 4/9 levels", setting(12, 5, 5)),
        ("k = 12, lossless trajectories", setting(12, 0, 0, **LOSSLESS)),
    ]
    rows = []
    for label, params in variants:
        row = evaluate_setting(clip, params, repeats)
        row["setting"] = label
        rows.append(row)
    emit(markdown_table(rows, extra=[("setting", "setting")]))
    emit()

    emit("Where the 09_06 error comes from: the exact poses with only the root trajectories (position and")
    emit("orientation) passed through the lifting scheme with D finest levels dropped (no PGA, no IK), and the")
    emit("error of the lifted end-joint trajectories themselves (what the IK is asked to reach):")
    emit()
    emit(markdown_table(root_only_rows(clip), columns=_ORACLE_COLUMNS))
    emit()


def _cmu_test_section(emit, motions: dict[str, Motion]) -> None:
    """Section 2: the protocol over cmu_test with k chosen the paper's ways; totals, then two settings per clip."""
    emit("## 2. The same protocol over cmu_test")
    emit()
    protocols = [
        ("k = 12, D = 4 (default)", setting(12, 4, 4)),
        ("k = 95 % rule, D = 4", setting(60, 4, 4, variance_fraction=0.95)),
        ("k = 99 % rule, D = 4", setting(60, 4, 4, variance_fraction=0.99)),
        ("k = 6, D = 5 (09_06's setting)", setting(6, 5, 5)),
        ("k = 12, D = 2", setting(12, 2, 2)),
        ("k = 12, D = 0 (lossless trajectories)", setting(12, 0, 0, **LOSSLESS)),
        ("k = 12, D = 4, lambda = 1 cm^2", setting(12, 4, 4, ik_length_unit_cm=1.0)),
        ("k = 12, D = 0, lambda = 1 cm^2", setting(12, 0, 0, ik_length_unit_cm=1.0, **LOSSLESS)),
    ]
    totals = []
    per_clip = {}
    for label, params in protocols:
        clip_rows = [evaluate_setting(m, params, 1) for m in motions.values()]
        per_clip[label] = clip_rows
        totals.append(total_row(clip_rows, label))
    emit("Totals over the clips (ratios of summed sizes, KG averaged over clips, worst L∞, frame-weighted mean "
         "error and ms/frame; D = finest levels dropped for root and end joints):")
    emit()
    emit(markdown_table(totals, columns=[c for c in _COLUMNS if c[0] not in ("root_lod", "end_lod", "explained")]))
    emit()
    for label in (protocols[0][0], protocols[2][0]):
        emit(f"Per clip, {label}:")
        emit()
        emit(markdown_table(per_clip[label]))
        emit()


def _paper_rows_section(emit, motions: dict[str, Motion], data_dir: str | None, quick: bool) -> None:
    """Section 3: the settings of the paper's other Table 2 rows on the most similar clips available."""
    emit("## 3. The paper's other rows' settings on similar clips")
    emit()
    emit("| paper row | paper k, LOD | paper ratio | paper KG % |")
    emit("|---|---|---|---|")
    for row in PAPER_TABLE_2:
        emit(f"| {row[0]} {row[1]} ({row[2]} frames) | {row[3]}, {row[4]} / {row[5]} | 1:{row[6]} | {row[7]} |")
    emit()
    rows = []
    for label, params, names in PAPER_ROW_SETTINGS:
        if quick:
            names = names[:1]
        for name in names:
            row = evaluate_setting(_clip(motions, name, data_dir), params, 1)
            row["paper_row"] = label
            rows.append(row)
    emit(markdown_table(rows, extra=[("paper_row", "paper row's setting")]))
    emit()


def _fig3_section(emit, motions: dict[str, Motion], data_dir: str | None, quick: bool) -> None:
    """Section 4 (Fig. 3): geodesics reaching 95 % and 99 % of the tangent variance on every CMU clip here."""
    emit("## 4. Fig. 3: geodesics reaching 95 % / 99 % of the tangent variance")
    emit()
    names = clip_names(ALL_SPLIT, data_dir=data_dir)
    if quick:
        names = names[:6]
    counts = []
    for name in names:
        motion = _clip(motions, name, data_dir)
        model = fit_pga(motion.rotations[:, 1:], 1)
        k95, k99 = variance_count(model.variances, 0.95), variance_count(model.variances, 0.99)
        counts.append((name, motion.num_frames, k95, k99))
    emit("| clip | F | k (95 %) | k (99 %) |")
    emit("|---|---|---|---|")
    for name, frames, k95, k99 in counts:
        emit(f"| {name} | {frames} | {k95} | {k99} |")
    k95s = np.array([c[2] for c in counts])
    k99s = np.array([c[3] for c in counts])
    walks = [c for c in counts if c[0] in ("02_01", "02_02", "05_01")]
    emit()
    emit(
        f"Over {len(counts)} clips: k(95 %) median {np.median(k95s):.0f} (range {k95s.min()}-{k95s.max()}), "
        f"k(99 %) median {np.median(k99s):.0f} (range {k99s.min()}-{k99s.max()}); clips needing < 20 for 99 %: "
        f"{int(np.sum(k99s < 20))}/{len(counts)}. Walks (02_01, 02_02, 05_01): k(95 %) = "
        f"{[c[2] for c in walks]}, k(99 %) = {[c[3] for c in walks]}."
    )
    emit()


def _speed_section(emit, motions: dict[str, Motion], data_dir: str | None, repeats: int, quick: bool) -> None:
    """Section 5: decoding and encoding time, one thread, by geodesic count and LM iterations."""
    emit("## 5. Speed (one thread)")
    emit()
    speed_clips = ["09_06"] if quick else ["09_06", "05_01", "16_07"]
    rows = []
    for name in speed_clips:
        motion = _clip(motions, name, data_dir)
        for k in (6, 12, 17):
            for iterations in (1, 2, 5):
                row = evaluate_setting(motion, dict(num_geodesics=k, lm_iterations=iterations), repeats)
                row["iterations"] = iterations
                rows.append(row)
    emit("Default levels (D = 4), default 2 LM iterations. Target ≤ 1 ms/frame on one core; the paper: 7.88-30.6")
    emit("ms/frame (C++, 2.6 GHz, 2008).")
    emit()
    keep = ("clip", "frames", "K", "decode_cpu_ms", "decode_ms", "encode_s", "linf", "mean", "kg")
    speed_cols = [c for c in _COLUMNS if c[0] in keep]
    emit(markdown_table(rows, columns=speed_cols, extra=[("iterations", "LM iterations")]))
    emit()


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data-dir", default=None, help="CMU data folder (default: ../shared/data/cmu)")
    parser.add_argument("--out", default="reports/pga", help="folder for pga.md")
    parser.add_argument("--repeats", type=int, default=3, help="decode timing repeats (median)")
    parser.add_argument("--quick", action="store_true", help="a few clips only (smoke run)")
    args = parser.parse_args(argv)
    report = run(args.data_dir, args.repeats, args.quick)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "pga.md").write_text(report + "\n")
    print(f"\nWritten to {out / 'pga.md'}")


if __name__ == "__main__":
    from mocapbench.benchmarks.entry import run_script

    raise SystemExit(run_script(main))
