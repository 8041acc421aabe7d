"""The benchmark report: ``python -m mocapbench.experiments.report SWEEP_DIR... [--name NAME] [--anchor CODEC]``.

Writes ``reports/<date>-<time>-<name>/`` with ``report.md`` and ``index.html`` (the same content) and the figures
as PNG; an existing report folder is never overwritten (a suffix ``-2``, ``-3``... is added). Contents: the
headline table (ACL's style: each codec at its best point under 1 cm and under 3 cm L∞, with published reference
points quoted in their own rows), rate-distortion figures per dataset and per clip, the BD-rate table against an
anchor codec, the reproduction tables of the three papers, an error heat map and a skeleton overlay per codec, the
full RD table, the failed jobs, and "Data and method".
"""

from __future__ import annotations

import argparse
import datetime as _dt
import os
import platform
import shlex
import sys
from pathlib import Path
from typing import Iterable, Sequence

import numpy as np
import pandas as pd

from mocapbench.experiments import plots
from mocapbench.experiments.aggregate import aggregate, curve_points, read_errors
from mocapbench.experiments.bdrate import DEFAULT_ANCHOR, bd_rate_table
from mocapbench.experiments.document import Document, markdown_table
from mocapbench.experiments.reproduction import reproduction_sections
from mocapbench.experiments.run import EXAMPLE_FILE
from mocapbench.io.safe_output import check_name, write_text

__all__ = ["build_report", "headline_table", "QUOTED_REFERENCES", "CMU_ACKNOWLEDGEMENT", "unique_report_folder"]

BOUNDS_CM = (1.0, 3.0)

CMU_ACKNOWLEDGEMENT = (
    "The data used in this project was obtained from mocap.cs.cmu.edu. The database was created with funding "
    "from NSF EIA-0196217."
)

# Published reference points: quoted from their sources, not measured here; their raw-size definitions differ.
QUOTED_REFERENCES = (
    {"codec": "ACL 2.1 [quoted, not measured here]", "dataset": "CMU, 24 fps (ACL docs/cmu_performance.md)",
     "compression_ratio": 21.77, "max_err_cm": 0.0495,
     "note": "raw = 10 float32 per bone per sample (rotation, translation, scale); error on a virtual shell 3 cm "
             "from each bone"},
    {"codec": "neural Fourier [quoted]", "dataset": "116 random CMU clips (Tojo et al.)",
     "compression_ratio": "2-15", "max_err_cm": "< 2 % of height (~3 cm)",
     "note": "raw = pose parameters (3 + 4 + 3(J-1) per frame) / network parameters"},
    {"codec": "PGA [quoted]", "dataset": "CMU 09_06 (Tournier et al., Table 2)", "compression_ratio": 18.0,
     "max_err_cm": "distortion rate 0.36 %", "note": "raw = 3(m+1) numbers per frame; KG-style distortion rate"},
)

_HEADLINE_COLUMNS = {
    "compression_ratio": "CR", "bits_per_joint_frame": "bits/joint/frame", "max_err_cm": "L∞ cm",
    "p99_err_cm": "p99 cm", "mean_err_cm": "mean cm", "kg_percent": "KG %", "encode_fps": "encode frames/s",
    "decode_fps": "decode frames/s", "model_bytes": "model bytes",
}


def unique_report_folder(root: Path, name: str, now: _dt.datetime | None = None) -> Path:
    """``root/<date>-<time>-<name>``, created; never an existing folder (``-2``, ``-3``... appended).

    ``name`` must be one plain path component (:func:`mocapbench.io.safe_output.check_name`).
    """
    check_name(name, "report name")
    now = now or _dt.datetime.now()
    base = f"{now:%Y-%m-%d-%H%M%S}-{name}"
    root.mkdir(parents=True, exist_ok=True)
    for attempt in range(1, 1000):
        folder = root / (base if attempt == 1 else f"{base}-{attempt}")
        try:
            folder.mkdir()
            return folder
        except FileExistsError:
            continue
    raise RuntimeError(f"could not create a new report folder under {root} named {base}-N")


def _param_text(value) -> str:
    if isinstance(value, float) and value.is_integer():
        return str(int(value))  # ints read back as floats when other codecs lack the column
    return str(value)


def _config_text(row: pd.Series, keys: Sequence[str] | None = None) -> str:
    """``k=v`` of the row's codec parameters: ``keys`` (the swept ones) or every ``param_*`` column that is set."""
    keys = [k for k in row.index if k.startswith("param_")] if keys is None else list(keys)
    return ", ".join(f"{k[6:]}={_param_text(row[k])}" for k in keys if k in row.index and _present(row[k]))


def _swept_params(points: pd.DataFrame) -> dict[str, list[str]]:
    """Per codec, the ``param_*`` columns that take more than one value across its configs (its RD knobs)."""
    out = {}
    for codec, group in points.groupby("codec"):
        params = [c for c in group.columns if c.startswith("param_") and group[c].notna().any()]
        swept = [c for c in params if group[c].astype(str).nunique() > 1]
        out[codec] = swept or params
    return out


def _present(value) -> bool:
    try:
        return not pd.isna(value)
    except (TypeError, ValueError):
        return True


def headline_table(points: pd.DataFrame) -> pd.DataFrame:
    """Per dataset and codec, the highest-ratio complete config with L∞ under each bound (1 cm, 3 cm)."""
    out = []
    swept = _swept_params(points)
    for (dataset, codec), group in points.groupby(["dataset", "codec"], sort=True):
        group = group[group["complete"]]
        for bound in BOUNDS_CM:
            ok = group[group["max_err_cm"] < bound]
            row = {"dataset": dataset, "codec": codec, "L∞ bound": f"< {bound:g} cm"}
            if ok.empty:
                row.update({"config": "no config under the bound"})
                out.append(row)
                continue
            best = ok.loc[ok["compression_ratio"].idxmax()]
            row["config"] = _config_text(best, swept[codec])
            row.update({label: best[column] for column, label in _HEADLINE_COLUMNS.items()})
            row["clips"] = int(best["clips"])
            out.append(row)
    return pd.DataFrame(out)


def _quoted_table() -> pd.DataFrame:
    rows = [{"source": "quoted", "codec": q["codec"], "dataset": q["dataset"], "CR": q["compression_ratio"],
             "L∞": q["max_err_cm"], "note": q["note"]} for q in QUOTED_REFERENCES]
    return pd.DataFrame(rows)


def _examples(points: pd.DataFrame, rows: pd.DataFrame, dataset: str, limit: int = 20) -> list[tuple[str, dict]]:
    """One example per codec: its headline point under 3 cm (else its lowest-error config), from example.npz."""
    examples = []
    for codec, group in points[points["dataset"] == dataset].groupby("codec", sort=True):
        ok = group[group["max_err_cm"] < BOUNDS_CM[-1]]
        best = ok.loc[ok["compression_ratio"].idxmax()] if not ok.empty else group.loc[group["max_err_cm"].idxmin()]
        same = (rows["dataset"] == dataset) & (rows["codec"] == codec) & (rows["config_hash"] == best["config_hash"])
        jobs = rows[same]
        for job_dir in jobs["job_dir"].unique():
            path = Path(job_dir) / EXAMPLE_FILE
            if path.exists():
                with np.load(path) as data:
                    example = {key: data[key] for key in data.files}
                label = f"{codec} (CR {best['compression_ratio']:.3g})"
                examples.append((label, example))
                break
        if len(examples) >= limit:
            break
    clips = {str(e["clip"]) for _, e in examples}
    if len(clips) > 1:  # keep the clip most examples show
        common = max(clips, key=lambda c: sum(str(e["clip"]) == c for _, e in examples))
        examples = [(label, e) for label, e in examples if str(e["clip"]) == common]
    return examples


def _sweep_commands(folders: Sequence[Path]) -> list[str]:
    """The command that re-runs each sweep, from Hydra's saved ``multirun.yaml``."""
    from omegaconf import OmegaConf

    commands = []
    for folder in folders:
        saved = Path(folder) / "multirun.yaml"
        if not saved.exists():
            commands.append(f"# {folder}: no multirun.yaml (not a Hydra sweep folder)")
            continue
        cfg = OmegaConf.load(saved)
        task = list(cfg.hydra.overrides.get("task", []))
        commands.append(shlex.join(["python", "-m", "mocapbench.experiments.run", "-m", *task,
                                    f"hydra.sweep.dir={folder}"]))
    return commands


def _machine() -> list[str]:
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return [f"CPU: {cpu}, {os.cpu_count()} logical cores", f"OS: {platform.platform()}",
            f"Python {platform.python_version()}"]


def build_report(
    folders: Iterable[str | Path],
    *,
    name: str | None = None,
    reports_root: str | Path = "reports",
    anchor: str = DEFAULT_ANCHOR,
    command: str | None = None,
) -> Path:
    """Aggregate the sweep folders and write the report; returns the new report folder.

    Parameters
    ----------
    folders : paths of sweep folders (or results.jsonl files)
    name : str, optional
        Suffix of the folder name (default: the first sweep folder's name).
    reports_root : path
        Where report folders are created (default ``reports``).
    anchor : str
        Anchor codec of the BD-rate table.
    command : str, optional
        The command that produced everything (e.g. ``make run``), quoted in "Data and method".
    """
    folders = [Path(f) for f in folders]
    name = check_name(name or folders[0].resolve().name, "report name")
    rows = aggregate(folders)
    points = curve_points(rows)
    errors = read_errors(folders)
    out = unique_report_folder(Path(reports_root), name)
    figures = out / "figures"
    figures.mkdir()
    datasets = sorted(rows["dataset"].unique())
    codecs = sorted(rows["codec"].unique())

    doc = Document(f"mocapbench report: {name}")
    doc.paragraph(f"{len(rows)} result rows, {len(points)} codec configurations, {len(codecs)} codecs "
                  f"({', '.join(codecs)}), datasets {', '.join(datasets)}. "
                  f"Generated {_dt.datetime.now():%Y-%m-%d %H:%M}.")

    doc.heading("Headline: best compression under 1 cm and 3 cm L∞")
    doc.paragraph("Per codec, the configuration with the highest compression ratio whose worst joint error over every "
                  "clip of the dataset stays under the bound. Rate pooled over the dataset (total bytes, container "
                  "header included); CR = raw float32 positions / bitstream; speeds = frames / wall-clock seconds.")
    headline = headline_table(points)
    doc.table(headline)
    doc.paragraph("Published reference points, quoted and not measured here (their raw-size definitions differ "
                  "from ours, so their ratios are not directly comparable):")
    doc.table(_quoted_table())

    doc.heading("Rate-distortion")
    for dataset in datasets:
        slug = dataset.replace("/", "_")
        ds_points = points[points["dataset"] == dataset]
        ds_rows = rows[rows["dataset"] == dataset]
        path = plots.rd_figure(ds_points, dataset, figures / f"rd_{slug}.png")
        doc.image(path.relative_to(out).as_posix(), f"{dataset}: compression ratio vs L∞, mean error and KG")
        path = plots.rd_figure(ds_points, dataset, figures / f"rd_bits_{slug}.png", rate="bits_per_joint_frame")
        doc.image(path.relative_to(out).as_posix(), f"{dataset}: bits per joint per frame vs L∞, mean error and KG")
        path = plots.rd_per_clip_figure(ds_rows, dataset, figures / f"rd_per_clip_{slug}.png")
        doc.image(path.relative_to(out).as_posix(), f"{dataset}: per clip, compression ratio vs L∞")

    doc.heading(f"BD-rate against {anchor}")
    doc.paragraph("Bjontegaard-delta rate (bjontegaard package, pchip): average extra rate (%) a codec needs for the "
                  "same quality as the anchor; negative = fewer bits. Quality = -log(error cm), rate = bits per joint "
                  "per frame; each curve reduced to its Pareto front; lossless points left out.")
    for error in ("max_err_cm", "mean_err_cm"):
        doc.table(bd_rate_table(points, anchor=anchor, error=error), caption=f"quality = -log({error})")

    doc.heading("Reproduction of the papers' claims")
    for title, note, table in reproduction_sections(rows):
        doc.heading(title, 3)
        if note:
            doc.paragraph(note)
        doc.table(table)

    doc.heading("Pictures")
    for dataset in datasets:
        examples = _examples(points, rows, dataset)
        if not examples:
            doc.paragraph(f"{dataset}: no example.npz saved by the jobs (save_example=false?).")
            continue
        slug = dataset.replace("/", "_")
        path = plots.error_heatmap_figure(examples, figures / f"heatmap_{slug}.png")
        doc.image(path.relative_to(out).as_posix(), f"{dataset}: per-joint × time error of one clip, each codec at "
                                                    "its headline point under 3 cm (else its most accurate config)")
        path = plots.skeleton_overlay_figure(examples, figures / f"overlay_{slug}.png")
        doc.image(path.relative_to(out).as_posix(), f"{dataset}: original vs decoded skeleton, a few frames")

    doc.heading("All rate-distortion points")
    doc.paragraph("Config shows the parameters swept for each codec; every other parameter is at its default "
                  "(configs/codec/<name>.yaml) and every row of results.jsonl holds all of them.")
    columns = ["dataset", "codec", "clips", "compression_ratio", "bits_per_joint_frame", "max_err_cm", "p99_err_cm",
               "mean_err_cm", "kg_percent", "encode_fps", "decode_fps", "model_bytes"]
    table = points.sort_values(["dataset", "codec", "bits_per_joint_frame"]).copy()
    swept = _swept_params(points)
    table.insert(2, "config", [_config_text(r, swept[r["codec"]]) for _, r in table.iterrows()])
    doc.table(table[columns[:2] + ["config"] + columns[2:]])

    if not errors.empty:
        doc.heading("Failed jobs and clips")
        keep = [c for c in ("codec", "clip", "stage", "error", "config", "job_dir") if c in errors]
        shown = errors[keep].copy()
        if "config" in shown:
            shown["config"] = shown["config"].astype(str)
        doc.table(shown)

    doc.heading("Data and method")
    clips = rows.groupby(["dataset", "clip"], sort=True).agg(frames=("frames", "first"), fps=("fps", "first"),
                                                               joints=("joints", "first"),
                                                               height_cm=("height_cm", "first")).reset_index()
    doc.table(clips, caption="Clips")
    train = rows.groupby("dataset")["train_set"].first().reset_index() if "train_set" in rows else pd.DataFrame()
    bullets = [
        "Raw size (the denominator of every ratio here): float32 x, y, z of every joint in every frame, "
        "12·J·F bytes = 96 bits per joint per frame.",
        "Rate: len() of the bitstream as written (container header, skeleton and everything the decoder needs); "
        "learned state shared across clips is reported separately as model bytes, never hidden.",
        "L∞: largest Euclidean joint-position error over every frame and joint (cm); p99: 99th percentile of the "
        "per-joint-frame errors; mean: mean over joint-frames (cm); "
        "KG: Karni-Gotsman 100·||A−Ã||/||A−E(A)|| (%); "
        "% of height: L∞ / rest-pose height of the skeleton.",
        "Dataset figures pool the clips: rate = total bytes / total joint-frames, L∞ and p99 = worst clip, mean "
        "and KG frame-weighted.",
        "Timing: one encode and one decode per clip with time.perf_counter, jobs run 2 at a time on this machine "
        "with 1 BLAS/torch thread each: indicative, not a benchmark of peak speed.",
    ]
    for _, r in train.iterrows():
        bullets.append(f"Learned state for {r['dataset']}: fit on {r['train_set']}.")
    doc.bullets(bullets)
    doc.paragraph("Machine:")
    doc.bullets(_machine())
    versions = [c for c in rows.columns if c.startswith("version_")]
    if versions:
        vt = pd.DataFrame([{"package": c[8:], "version": ", ".join(sorted(map(str, rows[c].dropna().unique())))}
                           for c in versions])
        doc.table(vt, caption="Package versions (from the result rows)")
    doc.paragraph("Commands that reproduce this report:")
    lines = ([command] if command else []) + _sweep_commands(folders)
    lines.append(shlex.join(["python", "-m", "mocapbench.experiments.report", *map(str, folders),
                             "--name", name, "--anchor", anchor]))
    doc.code("\n".join(lines))
    if "cmu_data" in rows and rows["cmu_data"].fillna(False).astype(bool).any():
        doc.heading("Acknowledgement")
        doc.paragraph(CMU_ACKNOWLEDGEMENT)

    write_text(out / "report.md", doc.markdown())
    write_text(out / "index.html", doc.html())
    return out


def _report_name(text: str) -> str:
    """argparse type of ``--name``: one plain path component (``a/b`` or ``..`` is a one-line usage error)."""
    try:
        return check_name(text, "report name")
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None


def _main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description="Write a report of one or more sweep folders.")
    parser.add_argument("folders", nargs="+", help="sweep folders (multirun/...)")
    parser.add_argument("--name", type=_report_name, help="report folder suffix (default: first sweep folder name)")
    parser.add_argument("--reports-root", default="reports")
    parser.add_argument("--anchor", default=DEFAULT_ANCHOR, help="anchor codec of the BD-rate table")
    parser.add_argument("--command", help="the command that produced the sweeps, quoted in the report")
    parser.add_argument("--quiet", action="store_true", help="print only the report path")
    args = parser.parse_args(argv)
    from mocapbench.experiments.results import CorruptResultsError

    try:
        folder = build_report(args.folders, name=args.name, reports_root=args.reports_root, anchor=args.anchor,
                              command=args.command)
    except CorruptResultsError as error:  # a dropped row would change the headline silently
        print(f"report: {error}", file=sys.stderr)
        raise SystemExit(2) from None
    if not args.quiet:
        print(markdown_table(headline_table(curve_points(aggregate(args.folders)))))
    print(f"report: {folder / 'index.html'}")
    sys.stdout.flush()


if __name__ == "__main__":
    _main()
