"""The benchmark report: ``python -m mocapbench.experiments.report SWEEP_DIR... [--name NAME] [--bounds CM]``.

Writes ``reports/<date>-<time>-<name>/`` with ``index.html`` (from a jinja2 template, with a table of contents)
and ``report.md`` (the same content), the figures as PNG and SVG, and the machine-readable results
(``results/<dataset>/<codec>.json`` and ``results/rows.csv``, :mod:`mocapbench.experiments.results_files`); an
existing report folder is never overwritten (a suffix ``-2``, ``-3``... is added). Contents: the headline that
decides (:mod:`mocapbench.experiments.headline`: per dataset and bound, codecs ranked by ratio, the winner in a
sentence), rate-distortion figures (one metric per figure) per dataset and per clip, distributions over clips,
the BD-rate table against an anchor codec, the reproduction tables of the three papers, per-codec error heat maps
and skeleton overlays, the full RD table, the failed jobs grouped by reason, and "Data and method".
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime as _dt
import os
import platform
import shlex
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterable, Sequence

import numpy as np
import pandas as pd

from mocapbench.experiments import plots
from mocapbench.experiments.aggregate import aggregate, curve_points, read_errors
from mocapbench.experiments.animator_report import FLAG_COLUMN, add_animator_section
from mocapbench.experiments.animator_report import method_bullets as animator_method_bullets
from mocapbench.experiments.bdrate import DEFAULT_ANCHOR, bd_rate_table
from mocapbench.experiments.document import Document, image_fill, markdown_table
from mocapbench.experiments.headline import (DEFAULT_BOUNDS_CM, EQUAL_AT, EQUAL_CR, EQUAL_FACTOR, bounds_with,
                                             datasets_side_by_side,
                                             headline_table, is_synthetic, synthetic_only_note, winner_sentences)
from mocapbench.experiments.reproduction import reproduction_sections
from mocapbench.experiments.run import EXAMPLE_FILE
from mocapbench.io.safe_output import check_name, write_text

__all__ = ["ReportData", "build_report", "write_report", "headline_table", "headline_tables", "headline_text", "QUOTED_REFERENCES",
           "CMU_ACKNOWLEDGEMENT", "unique_report_folder"]

BOUNDS_CM = DEFAULT_BOUNDS_CM

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


def headline_tables(points: pd.DataFrame, errors: pd.DataFrame | None = None,
                    bounds: Sequence[float] = BOUNDS_CM) -> pd.DataFrame:
    """:func:`mocapbench.experiments.headline.headline_table` with each config written as its swept parameters."""
    swept = _swept_params(points) if not points.empty else {}
    return headline_table(points, bounds, errors=errors,
                          config_text=lambda row: _config_text(row, swept.get(row["codec"])))


def headline_text(rows: pd.DataFrame, points: pd.DataFrame, errors: pd.DataFrame | None = None,
                  bounds: Sequence[float] = BOUNDS_CM, table: pd.DataFrame | None = None) -> str:
    """The headline as a user sees it in the terminal: synthetic-only note, winners, one ranked table per bound.

    ``table``: the :func:`headline_tables` of ``points`` if already computed (a report's ``headline``).
    """
    if table is None:
        table = headline_tables(points, errors, bounds)
    lines = []
    note = synthetic_only_note(rows)
    if note:
        lines += [note, ""]
    lines += [f"- {sentence}" for sentence in winner_sentences(table)]
    shown = ["rank", "codec", "config", "CR", EQUAL_FACTOR, EQUAL_AT, "bits/joint/frame", "L∞ cm", "decode frames/s (via Python)",
             "rotations (BVH/glTF)", "needs model", "latency frames"]
    for (dataset, bound), group in table.groupby(["dataset", "L∞ bound"], sort=False):
        notes = [c for c in (FLAG_COLUMN, "note") if group[c].fillna("").astype(str).str.len().gt(0).any()]
        lines += ["", f"{dataset}, L∞ {bound}:", "", markdown_table(group[shown + notes])]
    if table["dataset"].nunique() > 1:
        lines += ["", "Every dataset side by side (ratio and L∞ cm of each codec's headline config):", "",
                  markdown_table(datasets_side_by_side(table))]
    return "\n".join(lines)


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


def _per_clip_at_bound(rows: pd.DataFrame, headline: pd.DataFrame, dataset: str, bound: float,
                       points: pd.DataFrame) -> pd.DataFrame:
    """Per (codec, clip): ratio, max error and share of samples under ``bound`` of the codec's headline config."""
    picks = headline[(headline["dataset"] == dataset) & (headline["L∞ bound"] == f"< {bound:g} cm")
                     & (headline["rank"] != "–")]
    out = []
    ds_points = points[points["dataset"] == dataset]
    for _, pick in picks.iterrows():
        candidates = ds_points[(ds_points["codec"] == pick["codec"]) & ds_points["complete"]
                               & (ds_points["max_err_cm"] < bound)]
        if candidates.empty:
            continue
        best = candidates.loc[candidates["compression_ratio"].idxmax()]
        clip_rows = rows[(rows["dataset"] == dataset) & (rows["codec"] == pick["codec"])
                         & (rows["config_hash"] == best["config_hash"])]
        for _, row in clip_rows.drop_duplicates("clip").iterrows():
            quantiles = row.get("error_quantiles_cm")
            share = float("nan")
            if isinstance(quantiles, list) and len(quantiles) == 101:
                share = float(np.interp(bound, np.asarray(quantiles, float), np.linspace(0, 1, 101),
                                        left=0.0, right=1.0))
            out.append({"codec": pick["codec"], "clip": row["clip"], "compression_ratio": row["compression_ratio"],
                        "max_err_cm": row["max_err_cm"], "share_under_bound": share})
    return pd.DataFrame(out)


def _timing_note(rows: pd.DataFrame) -> str:
    """How the speeds were taken, from the rows' own timing columns."""
    from mocapbench.metrics.timing import METHOD

    if "encode_repeats" not in rows:
        return ("Speeds: one encode and one decode per clip, wall clock (rows written before repeated timing "
                "existed): indicative only.")
    repeats = int(rows["encode_repeats"].max())
    fewer = rows[(rows["encode_repeats"] < repeats) | (rows["decode_repeats"] < rows["decode_repeats"].max())]
    load = pd.concat([rows.get("encode_load_after"), rows.get("decode_load_after")]).dropna()
    threads = int(rows["encode_threads"].max()) if "encode_threads" in rows else 1
    text = ("Speeds (frames per CPU second of the process, total frames over the summed per-clip medians): "
            + METHOD.format(repeats=repeats, warmup=int(rows["encode_warmup"].max()), threads=threads) + ". ")
    if repeats < 3:
        text += "Fewer than 3 timed runs: these speeds are indicative only. "
    if len(load):
        text += f"Load average during the runs: {load.min():.2f} to {load.max():.2f} on {os.cpu_count()} cores. "
    if not fewer.empty:
        slow = ", ".join(sorted(fewer["codec"].unique()))
        text += (f"Slower calls were timed fewer times to bound the run time ({slow}: a call over the budget is "
                 "timed once); the encode_repeats / decode_repeats columns of results/rows.csv say how many.")
    return text


def _failure_summary(errors: pd.DataFrame) -> pd.DataFrame:
    """Failed jobs grouped by (dataset, codec, stage, first line of the error) with a count and example clips."""
    frame = errors.copy()
    for column in ("dataset", "codec", "stage", "clip"):
        if column not in frame:
            frame[column] = ""
    frame["reason"] = frame["error"].astype(str).str.split("\n").str[0].str.slice(0, 200)
    grouped = frame.groupby(["dataset", "codec", "stage", "reason"], dropna=False, sort=True)
    out = grouped.agg(count=("reason", "size"),
                      clips=("clip", lambda c: ", ".join(sorted({str(x) for x in c if x})[:5]))).reset_index()
    return out.sort_values(["count"], ascending=False)


@dataclass(frozen=True)
class ReportData:
    """What every section of the report reads: the aggregated sweep and where the report goes.

    Attributes
    ----------
    rows : DataFrame
        One row per job and clip (:func:`mocapbench.experiments.aggregate.aggregate`).
    points : DataFrame
        One row per dataset, codec and configuration, pooled over clips (:func:`curve_points`).
    errors : DataFrame
        The failure records of the jobs (:func:`read_errors`).
    headline : DataFrame
        Per dataset and bound, the ranked codecs (:func:`headline_tables`).
    datasets, codecs : list of str
        Sorted names present in ``rows``.
    bounds : tuple of float, cm
        The headline's L∞ bounds.
    out : Path
        The new report folder; figures go to ``figures`` (``out / "figures"``).
    name, anchor : str
        The report's name and the BD-rate anchor codec.
    folders : list of Path
        The sweep folders read.
    command : str or None
        The command that produced everything, quoted in "Data and method".
    draw : callable
        ``draw(figure function, *args, **kwargs) -> Future`` of the figure's path: a
        :class:`~mocapbench.experiments.plots.FigurePool`'s (the sections place each figure with
        :meth:`Document.later <mocapbench.experiments.document.Document.later>`).
    """

    rows: pd.DataFrame
    points: pd.DataFrame
    errors: pd.DataFrame
    headline: pd.DataFrame
    datasets: list[str]
    codecs: list[str]
    bounds: tuple[float, ...]
    out: Path
    name: str
    anchor: str
    folders: list[Path]
    command: str | None
    draw: Callable[..., Any] = plots.FigurePool().draw

    @property
    def figures(self) -> Path:
        return self.out / "figures"


def build_report(folders: Iterable[str | Path], **options) -> Path:
    """Aggregate the sweep folders and write the report; returns the new report folder (:func:`write_report`, with
    its keyword options)."""
    return write_report(folders, **options).out


def write_report(
    folders: Iterable[str | Path],
    *,
    name: str | None = None,
    reports_root: str | Path = "reports",
    anchor: str = DEFAULT_ANCHOR,
    command: str | None = None,
    bounds: Sequence[float] | None = None,
    workers: int | None = None,
) -> ReportData:
    """Aggregate the sweep folders and write the report; returns what it read (rows, points, headline, folder),
    so that a caller printing the headline does not read and pool the sweeps a second time.

    Each section is one function of the document and :class:`ReportData`, called here in the report's order (a
    new section is a function, in its own module if it is long, and one line here).

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
    bounds : floats, cm, optional
        L∞ bounds of the headline beside 1 cm and 3 cm.
    workers : int, optional
        Processes that draw the figures while this one computes the other sections (default: 2 where two cores
        are free to this process, else 1, the figures drawn here in turn); the report is the same either way.
    """
    from mocapbench.experiments.results_files import write_results

    data = _read_sweeps(folders, name=name, reports_root=reports_root, anchor=anchor, command=command, bounds=bounds)
    doc = Document(f"mocapbench report: {data.name}")
    with plots.FigurePool(_figure_workers() if workers is None else workers) as pool:
        data = dataclasses.replace(data, draw=pool.draw)
        _summary_section(doc, data)
        _headline_section(doc, data)
        _rate_distortion_section(doc, data)
        _distributions_section(doc, data)
        add_animator_section(doc, data.rows, data.points, data.bounds, data.out, _config_labels(data.points),
                             draw=data.draw)
        _bd_rate_section(doc, data)
        _reproduction_section(doc, data.rows)
        _pictures_section(doc, data)
        _all_points_section(doc, data)
        _failures_section(doc, data)
        _method_section(doc, data)
        _acknowledgement_section(doc, data)
        write_results(data.out, data.rows, data.points)
        doc.resolve()
    write_text(data.out / "report.md", doc.markdown())
    write_text(data.out / "index.html", doc.html())
    return data


def _figure_workers() -> int:
    """Figure processes of a report: 2 where this process may run on two cores or more, else 1 (drawn here)."""
    from mocapbench.metrics.timing import usable_cores

    return 2 if usable_cores() >= 2 else 1


def _config_labels(points: pd.DataFrame):
    """A point's config text with the parameters swept for its codec (the label the sections print)."""
    swept = _swept_params(points)
    return lambda point: _config_text(point, swept[point["codec"]])


def _read_sweeps(folders: Iterable[str | Path], *, name: str | None, reports_root: str | Path, anchor: str,
                 command: str | None, bounds: Sequence[float] | None) -> ReportData:
    """Aggregate the sweep folders and make the new report folder (with its ``figures/``)."""
    bounds = bounds_with(bounds)
    folders = [Path(f) for f in folders]
    name = check_name(name or folders[0].resolve().name, "report name")
    rows = aggregate(folders)
    points = curve_points(rows)
    errors = read_errors(folders)
    out = unique_report_folder(Path(reports_root), name)
    (out / "figures").mkdir()
    return ReportData(rows=rows, points=points, errors=errors, headline=headline_tables(points, errors, bounds),
                      datasets=sorted(rows["dataset"].unique()), codecs=sorted(rows["codec"].unique()),
                      bounds=tuple(bounds), out=out, name=name, anchor=anchor, folders=folders, command=command)


def _summary_section(doc: Document, data: ReportData) -> None:
    """The opening lines: a warning when every clip is synthetic, and what the report covers."""
    rows, points, datasets, codecs = data.rows, data.points, data.datasets, data.codecs
    note = synthetic_only_note(rows)
    if note:
        doc.paragraph(note, strong=True)
    doc.paragraph(f"{len(rows)} result rows, {len(points)} codec configurations, {len(codecs)} codecs, "
                  f"datasets {', '.join(datasets)}. Generated {_dt.datetime.now():%Y-%m-%d %H:%M}.")


def _headline_section(doc: Document, data: ReportData) -> None:
    """Which codec to pick: the winners in sentences, one ranked table per dataset and bound, the quoted points."""
    headline = data.headline
    doc.heading("Headline: which codec to pick")
    doc.bullets(winner_sentences(headline))
    doc.paragraph("Per dataset and L∞ bound, every codec at the configuration with the highest compression ratio "
                  "whose worst joint error over every clip stays under the bound, ranked by ratio. Rate pooled over "
                  "the dataset (total bytes, container header included); CR = raw float32 positions / bitstream. "
                  "Speeds in frames per CPU second (see Data and method). Rotations: the decoder returns joint "
                  "rotations, so the clip can be written as BVH/glTF; needs model: decoding needs learned state fit "
                  "for this skeleton (model bytes, not in the rate); latency: frames the encoder must see before it "
                  "emits a frame. Codecs without a rank keep their row with the reason. A ratio between two codecs "
                  f"is taken at one L∞, read off each codec's curve (log-log on its Pareto front): '{EQUAL_CR}' is "
                  f"a codec's ratio at exactly the bound, '{EQUAL_FACTOR}' rank 1's ratio over this codec's at the "
                  f"L∞ of '{EQUAL_AT}' (the bound, or the largest L∞ below it that both curves reach).")
    if headline["dataset"].nunique() > 1:
        doc.heading("Every dataset side by side", 3)
        doc.paragraph("Each codec's headline config per dataset and bound: its ratio and its L∞ (cm) over every "
                      "clip of the dataset; – where no config of the codec stays under the bound (or it did not "
                      "run there: the tables below say why).")
        doc.table(datasets_side_by_side(headline))
    shown = [c for c in headline.columns if c not in ("dataset", "L∞ bound")]
    for (dataset, bound), group in headline.groupby(["dataset", "L∞ bound"], sort=False):
        doc.heading(f"{dataset}, L∞ {bound}", 3)
        empty_notes = not group["note"].fillna("").astype(str).str.len().gt(0).any()
        doc.table(group[[c for c in shown if not (c == "note" and empty_notes)]])
    doc.paragraph("Published reference points, quoted and not measured here (their raw-size definitions differ "
                  "from ours, so their ratios are not directly comparable; the figures convert them to bits per "
                  "joint per frame):")
    doc.table(_quoted_table())


def _rate_distortion_section(doc: Document, data: ReportData) -> None:
    """One rate-distortion figure per dataset and error metric, and one per clip."""
    from mocapbench.experiments.published import points_for

    rows = data.rows
    points = data.points
    datasets = data.datasets
    bounds = data.bounds
    out = data.out
    figures = data.figures
    doc.heading("Rate-distortion")
    doc.paragraph("One metric per figure; rate in bits per joint per frame (lower is better) against each error. "
                  "Colours and markers are fixed per codec across reports; line style by family: solid = paper, "
                  "dashed = generic baseline, dash-dot = production reference, thick = mocapbench. Lossless points "
                  "are kept off the log axes and marked at the left edge with their rate. Black stars: published "
                  "points (converted as stated in the quoted table).")
    for dataset in datasets:
        slug = dataset.replace("/", "_")
        ds_points = points[points["dataset"] == dataset]
        ds_rows = rows[rows["dataset"] == dataset]
        cmu = bool(ds_rows["cmu_data"].fillna(False).astype(bool).any()) if "cmu_data" in ds_rows else False
        published = points_for(set(map(str, ds_rows["clip"])), cmu=cmu)
        for metric, label in plots.DISTORTIONS:
            doc.later(data.draw(plots.rd_metric_figure, ds_points, dataset, metric,
                                figures / f"rd_{metric}_{slug}.png", bounds=bounds, published=published),
                      image_fill(out, f"{dataset}: bits/joint/frame vs {label}"))
        doc.later(data.draw(plots.rd_per_clip_figure, ds_rows, dataset, figures / f"rd_per_clip_{slug}.png"),
                  image_fill(out, f"{dataset}: per clip, bits/joint/frame vs L∞"))


def _distributions_section(doc: Document, data: ReportData) -> None:
    """Per dataset and bound, each ranked codec's ratio, max error and share under the bound over the clips."""
    rows = data.rows
    points = data.points
    headline = data.headline
    datasets = data.datasets
    bounds = data.bounds
    out = data.out
    figures = data.figures
    doc.heading("Distributions over clips")
    doc.paragraph("For each bound, every ranked codec at its headline configuration: the compression ratio of each "
                  "clip, the max error of each clip and the share of joint samples (every joint of every frame) "
                  "under the bound, as ACL's CMU report shows them. The bar is the median over clips.")
    for dataset in datasets:
        slug = dataset.replace("/", "_")
        for bound in bounds:
            per_clip = _per_clip_at_bound(rows, headline, dataset, bound, points)
            doc.later(data.draw(plots.clip_distribution_figure, per_clip, dataset, bound,
                                figures / f"clips_{slug}_{bound:g}cm.png"),
                      image_fill(out, f"{dataset}: over clips at L∞ < {bound:g} cm",
                                f"{dataset}, {bound:g} cm: no codec under the bound."))


def _bd_rate_section(doc: Document, data: ReportData) -> None:
    """Per dataset, the BD-rate of every codec against the anchor, for L∞ and for the mean error."""
    points, anchor = data.points, data.anchor
    doc.heading(f"BD-rate against {anchor}")
    doc.paragraph("Bjontegaard-delta rate (bjontegaard package, pchip): average extra rate (%) a codec needs for the "
                  "same quality as the anchor; negative = fewer bits. Quality = -log(error cm), rate = bits per joint "
                  "per frame; each curve reduced to its Pareto front; lossless points left out. One section per "
                  "dataset: curves of different datasets are never compared.")
    tables = {error: bd_rate_table(points, anchor=anchor, error=error) for error in ("max_err_cm", "mean_err_cm")}
    for dataset in data.datasets:
        doc.heading(f"{dataset}: BD-rate against {anchor}", 3)
        for error, table in tables.items():
            doc.table(table[table["dataset"] == dataset].drop(columns="dataset"), caption=f"quality = -log({error})")


def _pictures_section(doc: Document, data: ReportData) -> None:
    """Per dataset: the error heat maps and skeleton overlays of the example clips the jobs saved."""
    rows, points, datasets, out, figures = data.rows, data.points, data.datasets, data.out, data.figures
    doc.heading("Pictures")
    for dataset in datasets:
        examples = _examples(points, rows, dataset)
        if not examples:
            doc.paragraph(f"{dataset}: no example.npz saved by the jobs (save_example=false?).")
            continue
        slug = dataset.replace("/", "_")
        doc.later(data.draw(plots.error_heatmap_figure, examples, figures / f"heatmap_{slug}.png"),
                  image_fill(out, f"{dataset}: per-joint × time error of one clip, each codec at its headline point "
                                 "under 3 cm (else its most accurate config), each on its own colour scale"))
        doc.later(data.draw(plots.skeleton_overlay_figure, examples, figures / f"overlay_{slug}.png"),
                  image_fill(out, f"{dataset}: original vs decoded at each codec's worst joint, whole body and zoomed"))


def _all_points_section(doc: Document, data: ReportData) -> None:
    """Every rate-distortion point, with the parameters swept for its codec."""
    points = data.points
    doc.heading("All rate-distortion points")
    doc.paragraph("Config shows the parameters swept for each codec; every other parameter is at its default "
                  "(configs/codec/<name>.yaml). The same numbers are in results/<dataset>/<codec>.json (one file per "
                  "codec and dataset) and every per-clip row in results/rows.csv; overlay any of them with "
                  "`mocapbench plot FILE_OR_REPORT_FOLDER... -o OUT`.")
    columns = ["dataset", "codec", "clips", "compression_ratio", "bits_per_joint_frame", "max_err_cm", "p99_err_cm",
               "mean_err_cm", "kg_percent", "encode_fps", "decode_fps", "model_bytes"]
    table = points.sort_values(["dataset", "codec", "bits_per_joint_frame"]).copy()
    swept = _swept_params(points)
    table.insert(2, "config", [_config_text(r, swept[r["codec"]]) for _, r in table.iterrows()])
    doc.table(table[columns[:2] + ["config"] + columns[2:]])


def _failures_section(doc: Document, data: ReportData) -> None:
    """The failed jobs and clips grouped by reason (no section when nothing failed)."""
    errors = data.errors
    if not errors.empty:
        doc.heading("Failed jobs and clips")
        doc.paragraph(f"{len(errors)} failure record(s), grouped by reason; errors.jsonl in each job folder holds "
                      "the tracebacks.")
        doc.table(_failure_summary(errors))


def _method_section(doc: Document, data: ReportData) -> None:
    """Data and method: the clips, the definitions of rate and error, the machine, versions, the commands."""
    rows = data.rows
    bounds = data.bounds
    name = data.name
    anchor = data.anchor
    folders = data.folders
    command = data.command
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
        _timing_note(rows),
        "Verdicts on the papers' claims are given only on at least 5 real (non-synthetic) clips; otherwise the "
        "verdict reads \"too few clips\".",
    ]
    for _, r in train.iterrows():
        bullets.append(f"Learned state for {r['dataset']}: fit on {r['train_set']}.")
    bullets += animator_method_bullets()
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
                             "--name", name, "--anchor", anchor,
                             *[a for b in bounds if b not in BOUNDS_CM for a in ("--bounds", f"{b:g}")]]))
    doc.code("\n".join(lines))


def _acknowledgement_section(doc: Document, data: ReportData) -> None:
    """The acknowledgement each data set used asks for (none for synthetic data alone)."""
    rows = data.rows
    used = {column: column in rows and rows[column].fillna(False).astype(bool).any()
            for column in ("cmu_data", "bandai_data")}
    if any(used.values()):
        from mocapbench.datasets.bandai import ACKNOWLEDGEMENT as BANDAI_ACKNOWLEDGEMENT

        doc.heading("Acknowledgement")
        if used["cmu_data"]:
            doc.paragraph(CMU_ACKNOWLEDGEMENT)
        if used["bandai_data"]:
            doc.paragraph(BANDAI_ACKNOWLEDGEMENT)


def _reproduction_section(doc: Document, rows: pd.DataFrame) -> None:
    """The papers' claims, checked on CMU clips (and on the synthetic fixture as a sanity check); left out for
    other clips (a user's own), on which no paper made a claim."""
    cmu = rows["cmu_data"].fillna(False).astype(bool) if "cmu_data" in rows else pd.Series(False, index=rows.index)
    applies = rows[cmu | is_synthetic(rows)]
    if applies.empty:
        return
    doc.heading("Reproduction of the papers' claims")
    for title, note_text, table in reproduction_sections(applies):
        doc.heading(title, 3)
        if note_text:
            doc.paragraph(note_text)
        doc.table(table)


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
    parser.add_argument("--bounds", type=float, action="append", default=[], metavar="CM",
                        help="an L∞ bound (cm) for the headline beside 1 and 3 cm (repeatable)")
    parser.add_argument("--command", help="the command that produced the sweeps, quoted in the report")
    parser.add_argument("--quiet", action="store_true", help="print only the report path")
    args = parser.parse_args(argv)
    from mocapbench.experiments.results import CorruptResultsError

    try:
        data = write_report(args.folders, name=args.name, reports_root=args.reports_root, anchor=args.anchor,
                            command=args.command, bounds=args.bounds)
    except CorruptResultsError as error:  # a dropped row would change the headline silently
        print(f"report: {error}", file=sys.stderr)
        raise SystemExit(2) from None
    if not args.quiet:
        print(headline_text(data.rows, data.points, data.errors, data.bounds, table=data.headline))
    print(f"report: {data.out / 'index.html'}")
    sys.stdout.flush()


if __name__ == "__main__":
    _main()
