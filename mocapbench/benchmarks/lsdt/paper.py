"""Reproduce Figs. 4-7 of Hou et al. 2016 (LSDT) on ``cmu_test`` and measure the codecs' speed.

``python -m mocapbench.benchmarks.lsdt.paper [--data-dir D] [--out reports/lsdt] [--only fig5,fig4,rd,speed]``

* Fig. 5: distortion (eq. 12, cm) vs percentage of nonzero spatial coefficients, keeping the k largest-magnitude
  coefficients of every pose vector (per frame, per coordinate) for LSDT (P = 8), spatial DCT and spatial DWT; on the
  frames themselves (the paper's setting) and on frame-to-frame residuals (what the frame codec transforms).
* Fig. 4: CR–distortion of ``lsdt-frame`` and ``lsdt-clip`` (L = 240) with the bases trained for P in {2, 5, 8, 11}.
* Figs. 6/7: CR–distortion of ``lsdt-frame``, ``dct-spatial-frame`` (Kwak & Bajic 2011), ``dwt-spatial-frame``,
  ``lsdt-clip`` at L = 60/120/240 and the DCT/DWT clip pipelines at L = 120; then a check of each claim.
* Speed: encode and decode frames/s of ``lsdt-clip`` (L = 120) and ``lsdt-frame`` on the longest CMU clip, one core.

CR = raw bytes (12 bytes per joint per frame: three float32, the paper's 96 bits per key point) / stream bytes,
totalled over the 12 clips; distortion = eq. (12) averaged over every joint of every frame of the split. Figures
and CSVs go to ``--out``; tables are printed as markdown.
"""

from __future__ import annotations

import argparse
import csv
import platform
from pathlib import Path

import numpy as np

from mocapbench import metrics
from mocapbench.codecs import create
from mocapbench.codecs.lsdt.bases import COMMITTED_SPARSITIES, load_committed_bases
from mocapbench.codecs.lsdt.spatial import spatial_basis
from mocapbench.codecs.lsdt.training import train_lsdt_bases, truncate
from mocapbench.datasets.cmu import load_clip, load_split
from mocapbench.metrics.timing import time_call

STEPS_CM = (0.05, 0.1, 0.2, 0.35, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0, 12.0, 16.0)
J = 31


# -- helpers ------------------------------------------------------------------------------------------------


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def rd_curve(name: str, motions, steps=STEPS_CM, bases=None, **params) -> list[dict]:
    """One row per step: totals over ``motions`` of stream bytes and of eq. (12) errors.

    ``bases`` (3, J, J): LSDT bases to use instead of the committed ones (with ``basis="fit"`` in ``params``).
    """
    references = [motion.positions() for motion in motions]
    frames = sum(motion.num_frames for motion in motions)
    rows = []
    for step in steps:
        codec = create(name, step_cm=step, **params)
        if bases is not None:
            codec.set_bases(bases)
        total_bytes, error_sum, nonzero = 0, 0.0, 0
        for motion, reference in zip(motions, references):
            data = codec.encode(motion)
            decoded = codec.decode(data).positions
            total_bytes += len(data)
            error_sum += float(metrics.joint_errors(reference, decoded).sum())
            nonzero += codec.last_encode_stats["nonzero_coefficients"]
        rows.append(
            {
                "codec": name,
                **params,
                "step_cm": step,
                "bytes": total_bytes,
                "cr": metrics.raw_position_bytes(J, frames) / total_bytes,
                "distortion_cm": error_sum / (J * frames),
                "nonzero_percent": 100.0 * nonzero / (3 * J * frames),
            }
        )
    return rows


def distortion_at(rows: list[dict], cr: float) -> float:
    """Distortion at compression ratio ``cr`` by log-log interpolation along a curve; NaN outside its range."""
    crs = np.array([row["cr"] for row in rows])
    ds = np.array([row["distortion_cm"] for row in rows])
    order = np.argsort(crs)
    crs, ds = crs[order], ds[order]
    if not crs[0] <= cr <= crs[-1]:
        return float("nan")
    return float(np.exp(np.interp(np.log(cr), np.log(crs), np.log(ds))))


def _label(row: dict) -> str:
    extra = [f"{key}={row[key]}" for key in ("clip_length", "sparsity", "count_coding") if key in row]
    return row["codec"] + (f" ({', '.join(extra)})" if extra else "")


def _write_csv(rows: list[dict], path: Path) -> None:
    """Rows as CSV over the union of their keys (sorted); a label holding a comma is quoted, as CSV readers expect."""
    keys = sorted({key for row in rows for key in row})
    with path.open("w", newline="") as handle:
        writer = csv.writer(handle, lineterminator="\n")
        writer.writerow(keys)
        writer.writerows([str(row.get(key, "")) for key in keys] for row in rows)


def _rd_table(curves: dict[str, list[dict]], targets) -> str:
    names = list(curves)
    lines = ["| CR | " + " | ".join(names) + " |", "|---:|" + "---:|" * len(names)]
    for cr in targets:
        cells = [distortion_at(curves[name], cr) for name in names]
        lines.append(f"| {cr:g} | " + " | ".join("—" if np.isnan(c) else f"{c:.3f}" for c in cells) + " |")
    return "\n".join(lines)


def _plot_curves(curves: dict[str, list[dict]], path: Path, title: str) -> None:
    plt = _plt()
    fig, axis = plt.subplots(figsize=(6.5, 4.5))
    for name, rows in curves.items():
        axis.plot([r["cr"] for r in rows], [r["distortion_cm"] for r in rows], "o-", ms=3, label=name)
    axis.set_xscale("log")
    axis.set_yscale("log")
    axis.set_xlabel("compression ratio (raw float32 / stream bytes)")
    axis.set_ylabel("mean distortion, eq. (12), cm")
    axis.set_title(title)
    axis.grid(True, which="both", alpha=0.3)
    axis.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


# -- Fig. 5 ------------------------------------------------------------------------------------------------


def fig5(motions, out: Path) -> str:
    """Distortion vs % nonzero coefficients, top-k per pose vector, on frames and on frame residuals."""
    transforms = {"LSDT (P=8)": load_committed_bases(8), "DCT": spatial_basis("dct", J), "DWT (Haar, 3 levels)": spatial_basis("dwt", J)}
    signals = {
        "frames": [motion.positions() for motion in motions],
        "residuals": [np.diff(motion.positions(), axis=0) for motion in motions],
    }
    ks = list(range(1, J + 1))
    results: dict[tuple[str, str], list[float]] = {}
    for signal_name, arrays in signals.items():
        data = np.concatenate(arrays)  # (N, J, 3)
        for name, bases in transforms.items():
            squared = np.zeros((data.shape[0], J))
            per_k = []
            coefficients = [bases[d] @ data[:, :, d].T for d in range(3)]  # (J, N) each
            for k in ks:
                errors = np.zeros((data.shape[0], J))
                for d in range(3):
                    kept = truncate(coefficients[d], k)
                    errors += ((bases[d].T @ kept).T - data[:, :, d]) ** 2
                per_k.append(float(np.sqrt(errors).mean()))
            del squared
            results[(signal_name, name)] = per_k
    plt = _plt()
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.2))
    for axis, signal_name in zip(axes, signals):
        for name in transforms:
            # k = 31 (and k = 30 for DCT/DWT, which then drop an always-zero coefficient: 31 CMU joints sit at only
            # 24 distinct positions) is lossless to rounding; the axis stops above that.
            axis.plot(100 * np.array(ks) / J, results[(signal_name, name)], "o-", ms=3, label=name)
        axis.set_yscale("log")
        axis.set_ylim(bottom=1e-4 if signal_name == "frames" else 1e-5)
        axis.set_xlabel("nonzero coefficients per pose vector, %")
        axis.set_ylabel("mean distortion, eq. (12), cm")
        axis.set_title(f"cmu_test {signal_name}" + (" (the paper's Fig. 5)" if signal_name == "frames" else ""))
        axis.grid(True, which="both", alpha=0.3)
        axis.legend()
    fig.tight_layout()
    fig.savefig(out / "fig5_nonzero_vs_distortion.png", dpi=120)
    plt.close(fig)
    rows = []
    for (signal_name, name), values in results.items():
        for k, value in zip(ks, values):
            rows.append({"signal": signal_name, "transform": name, "k": k, "percent": 100 * k / J, "distortion_cm": value})
    _write_csv(rows, out / "fig5_nonzero_vs_distortion.csv")
    show = (1, 2, 3, 4, 6, 8, 12, 16, 24)
    lines = []
    for signal_name in signals:
        lines.append(f"\n**{signal_name}** (distortion cm at k kept coefficients of 31 per vector)\n")
        lines.append("| transform | " + " | ".join(f"k={k} ({100 * k / J:.0f}%)" for k in show) + " |")
        lines.append("|---|" + "---:|" * len(show))
        for name in transforms:
            values = results[(signal_name, name)]
            lines.append(f"| {name} | " + " | ".join(f"{values[k - 1]:.3f}" for k in show) + " |")
        lsdt = np.array(results[(signal_name, "LSDT (P=8)")][: J - 1])
        others = np.minimum(results[(signal_name, "DCT")][: J - 1], results[(signal_name, "DWT (Haar, 3 levels)")][: J - 1])
        not_lowest = [k for k in ks[:-1] if lsdt[k - 1] >= others[k - 1]]
        lines.append(
            f"\nLSDT lowest at every k in 1..30: {not not_lowest} (k = 31 is lossless for all); "
            + (", ".join(f"not at k={k}: LSDT {lsdt[k - 1]:.2e} vs best other {others[k - 1]:.2e} cm" for k in not_lowest)
               if not_lowest else "")
        )
    return "\n".join(lines)


# -- Fig. 4 ------------------------------------------------------------------------------------------------


def fig4(motions, out: Path, extra_sparsities=(), data_dir=None, iterations: int = 3000) -> str:
    """The effect of the training sparsity P on both schemes (clip scheme at L = 240, as in the paper).

    ``extra_sparsities``: P values beyond the committed ones, trained here on ``cmu_train`` (DCT init, ``iterations``).
    """
    text = []
    all_rows = []
    extra = {}
    if extra_sparsities:
        train = np.concatenate([m.positions() for m in load_split("cmu_train", data_dir=data_dir)])
        for p in extra_sparsities:
            extra[p], _ = train_lsdt_bases(train, p, init="dct", max_iterations=iterations, tol=1e-10)
    for scheme, name, params, targets in (
        ("frame", "lsdt-frame", {}, (8, 12, 16, 24, 32, 48, 64, 96)),
        ("clip", "lsdt-clip", {"clip_length": 240}, (10, 20, 40, 60, 80, 100)),
    ):
        curves = {}
        for p in COMMITTED_SPARSITIES:
            rows = rd_curve(name, motions, sparsity=p, **params)
            curves[f"P={p}"] = rows
            all_rows += rows
        for p, bases in extra.items():
            rows = rd_curve(name, motions, bases=bases, sparsity=p, basis="fit", **params)
            curves[f"P={p}"] = rows
            all_rows += rows
        _plot_curves(curves, out / f"fig4_sparsity_{scheme}.png", f"{name}{' L=240' if params else ''}: training sparsity P")
        text.append(f"\n**{name}{' (L = 240)' if params else ''}**: distortion (cm) at equal CR, by training sparsity P\n")
        text.append(_rd_table(curves, targets))
        best = []
        for cr in targets:
            values = {label: distortion_at(rows, cr) for label, rows in curves.items()}
            values = {label: v for label, v in values.items() if not np.isnan(v)}
            if values:
                best.append(min(values, key=values.get))
        text.append(f"\nbest P at each CR: {best}")
    _write_csv(all_rows, out / "fig4_sparsity.csv")
    return "\n".join(text)


# -- Figs. 6 and 7 -----------------------------------------------------------------------------------------


FIG67_CONFIGS = {
    "lsdt-frame": ("lsdt-frame", {}),
    "dct-spatial-frame (Kwak & Bajic)": ("dct-spatial-frame", {}),
    "dwt-spatial-frame": ("dwt-spatial-frame", {}),
    "lsdt-clip L=60": ("lsdt-clip", {"clip_length": 60}),
    "lsdt-clip L=120": ("lsdt-clip", {"clip_length": 120}),
    "lsdt-clip L=240": ("lsdt-clip", {"clip_length": 240}),
    "dct-spatial-clip L=120": ("dct-spatial-clip", {"clip_length": 120}),
    "dwt-spatial-clip L=120": ("dwt-spatial-clip", {"clip_length": 120}),
    # Not in the paper: the per-vector nonzero counts Huffman-coded instead of fixed-length.
    "lsdt-frame, Huffman counts": ("lsdt-frame", {"count_coding": "huffman"}),
    "lsdt-clip L=120, Huffman counts": ("lsdt-clip", {"clip_length": 120, "count_coding": "huffman"}),
}
# The compression ratios at which Figs. 6/7's curves are compared.
FIG67_TARGET_CRS = (5, 8, 10, 15, 20, 30, 40, 60, 80, 100, 150)


def fig67(motions, out: Path) -> str:
    """Figs. 6 and 7: every curve of ``FIG67_CONFIGS``, written as CSV and plots; the RD points, the distortions
    at equal CR and a check of each of the paper's claims, as markdown."""
    curves = {label: rd_curve(name, motions, **params) for label, (name, params) in FIG67_CONFIGS.items()}
    _write_csv([dict(row, label=label) for label, rows in curves.items() for row in rows], out / "fig67_rd.csv")
    frame_curves = {k: v for k, v in curves.items() if "frame" in k and "Huffman" not in k}
    _plot_curves(frame_curves, out / "fig6_frame_based.png", "Fig. 6: frame-based schemes, cmu_test")
    _plot_curves(curves, out / "fig7_clip_based.png", "Fig. 7: clip-based schemes (and frame-based), cmu_test")
    text = _rd_points_lines(curves)
    text.append("\n**Distortion (cm) at equal CR** (log-log interpolation; — outside a curve's range)\n")
    text.append(_rd_table(curves, FIG67_TARGET_CRS))
    text.append("\n**Claims**\n")
    text += _claims(curves)
    return "\n".join(text)


def _rd_points_lines(curves: dict[str, list[dict]]) -> list[str]:
    """Every curve's RD points as a markdown table."""
    text = ["\n**RD points** (totals over cmu_test; CR = raw float32 bytes / stream bytes)\n"]
    text.append("| codec | step cm | CR | D cm | nonzero % |")
    text.append("|---|---:|---:|---:|---:|")
    for label, rows in curves.items():
        for row in rows:
            text.append(f"| {label} | {row['step_cm']:g} | {row['cr']:.2f} | {row['distortion_cm']:.4f} | "
                        f"{row['nonzero_percent']:.2f} |")
    return text


def _reductions(curve: list[dict], other: list[dict]) -> list[tuple[float, float]]:
    """At each point of ``curve``: (CR, % less distortion of ``other`` there), where ``other`` reaches that CR."""
    reductions = []
    for row in curve:
        distortion = distortion_at(other, row["cr"])
        if not np.isnan(distortion):
            reductions.append((row["cr"], 100 * (1 - distortion / row["distortion_cm"])))
    return reductions


def _claims(curves: dict[str, list[dict]]) -> list[str]:
    """One line per claim of the paper (and for the Huffman-coded counts): the distortion reductions measured."""
    frame_l = curves["lsdt-frame"]
    reductions = _reductions(curves["dct-spatial-frame (Kwak & Bajic)"], frame_l)
    text = ["LSDT vs DCT, frame-based: distortion reduction at the DCT curve's CRs: "
            + ", ".join(f"CR {cr:.1f}: {r:.0f}%" for cr, r in reductions)]
    if reductions:
        text.append(f"max reduction {max(r for _, r in reductions):.0f}% (paper: up to 70% at high CR); "
                    f"LSDT better at every CR: {all(r > 0 for _, r in reductions)}")
    clip_vs_frame = []
    for row in curves["lsdt-clip L=120"]:
        other = distortion_at(frame_l, row["cr"])
        if not np.isnan(other):
            clip_vs_frame.append((row["cr"], 100 * (1 - row["distortion_cm"] / other)))
    text.append("lsdt-clip L=120 vs lsdt-frame: distortion reduction at equal CR: "
                + ", ".join(f"CR {cr:.1f}: {r:.0f}%" for cr, r in clip_vs_frame))
    text += _clip_length_claims(curves)
    for label_a, label_b in (("lsdt-clip L=120", "dct-spatial-clip L=120"),
                             ("lsdt-clip L=120", "dwt-spatial-clip L=120"), ("lsdt-frame", "dwt-spatial-frame")):
        ratios = _reductions(curves[label_b], curves[label_a])
        text.append(f"{label_a} vs {label_b}: distortion reduction at equal CR: "
                    + ", ".join(f"CR {cr:.1f}: {r:.0f}%" for cr, r in ratios))
    for base in ("lsdt-frame", "lsdt-clip L=120"):
        pairs = [(a["step_cm"], 100 * (1 - b["bytes"] / a["bytes"]))
                 for a, b in zip(curves[base], curves[f"{base}, Huffman counts"])]
        text.append(f"{base} with Huffman-coded counts (not in the paper): bytes saved at the same step: "
                    + ", ".join(f"step {step:g}: {saved:.0f}%" for step, saved in pairs))
    return text


def _clip_length_claims(curves: dict[str, list[dict]]) -> list[str]:
    """Longer clips, less distortion: L = 60 -> 120 and 120 -> 240 at each target CR both curves reach."""
    text = []
    for a, b in (("60", "120"), ("120", "240")):
        ratios = []
        for cr in FIG67_TARGET_CRS:
            da, db = distortion_at(curves[f"lsdt-clip L={a}"], cr), distortion_at(curves[f"lsdt-clip L={b}"], cr)
            if not (np.isnan(da) or np.isnan(db)):
                ratios.append((cr, 100 * (1 - db / da)))
        text.append(f"L={a} → L={b}: distortion reduction at equal CR: "
                    + ", ".join(f"CR {cr:g}: {r:.0f}%" for cr, r in ratios))
    return text


# -- speed -------------------------------------------------------------------------------------------------


def speed(data_dir, clip: str = "13_17", repeats: int = 15) -> str:
    motion = load_clip(clip, data_dir=data_dir)
    positions = motion.positions()
    lines = [
        f"\nclip {clip}: {motion.num_frames} frames, J = {motion.num_joints}; one thread; median of {repeats} runs; "
        f"{platform.processor() or platform.machine()}, Python {platform.python_version()}. 'encode' starts from joint "
        "positions (the paper's input: `encode_positions`), 'encode+FK' from the Motion (`encode`, forward kinematics "
        "included); 'decode' is bytes to positions (container check included).\n",
        "| codec | step cm | stream bytes | CR | encode frames/CPU s | encode+FK frames/CPU s | decode frames/CPU s |",
        "|---|---:|---:|---:|---:|---:|---:|",
    ]
    for name, params in (("lsdt-clip", {"clip_length": 120}), ("lsdt-frame", {}), ("dct-spatial-frame", {}),
                         ("dct-spatial-clip", {"clip_length": 120})):
        for step in (0.1, 0.5, 2.0):
            codec = create(name, step_cm=step, **params)
            encode_s, data = time_call(lambda: codec.encode_positions(positions, motion.fps), repeats=repeats)
            full_s, full = time_call(lambda: codec.encode(motion), repeats=repeats)
            if full != data:
                raise RuntimeError(f"{name}: encode_positions and encode disagree")
            decode_s, _ = time_call(lambda: codec.decode(data), repeats=repeats)
            ratio = metrics.raw_position_bytes(J, motion.num_frames) / len(data)
            lines.append(f"| {name}{' L=120' if params else ''} | {step:g} | {len(data)} | {ratio:.1f} | "
                         f"{motion.num_frames / encode_s:,.0f} | {motion.num_frames / full_s:,.0f} | "
                         f"{motion.num_frames / decode_s:,.0f} |")
    return "\n".join(lines)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data-dir", default=None)
    parser.add_argument("--out", default="reports/lsdt")
    parser.add_argument("--only", default="fig5,fig4,rd,speed", help="comma-separated subset of fig5,fig4,rd,speed")
    parser.add_argument("--extra-sparsity", default="", help="Fig. 4: P values to train here besides 2,5,8,11, e.g. 14,20")
    args = parser.parse_args(argv)
    parts = set(args.only.split(","))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    motions = load_split("cmu_test", data_dir=args.data_dir)
    frames = sum(m.num_frames for m in motions)
    print(f"cmu_test: {len(motions)} clips, {frames} frames; figures and CSVs in {out}/")
    if "fig5" in parts:
        print("\n## Fig. 5: distortion vs percentage of nonzero spatial coefficients\n" + fig5(motions, out))
    if "fig4" in parts:
        extra = tuple(int(p) for p in args.extra_sparsity.split(",") if p)
        print("\n## Fig. 4: training sparsity P\n" + fig4(motions, out, extra, args.data_dir))
    if "rd" in parts:
        print("\n## Figs. 6 and 7: CR vs distortion\n" + fig67(motions, out))
    if "speed" in parts:
        print("\n## Speed\n" + speed(args.data_dir))


if __name__ == "__main__":
    from mocapbench.benchmarks.entry import run_script

    raise SystemExit(run_script(main))
