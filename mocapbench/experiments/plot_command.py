"""``mocapbench plot FILE... [-o OUT]``: overlay results JSON files (or whole report folders) on RD figures.

Each FILE is a ``results/<dataset>/<codec>.json`` written by a report, or a report folder (all its JSON files).
When the same codec and dataset come from two sources, the legend names them ``codec [folder]`` so two runs
can be compared. The published points of the papers (:mod:`mocapbench.experiments.published`) are drawn as
black stars; a measured ``acl`` codec is plotted like any other. One figure per metric, PNG and SVG::

    OUT/rd_max_err_cm.png  OUT/rd_mean_err_cm.png  OUT/rd_kg_percent.png  [OUT/rd_shell_max_err_cm.png]

and, when the files cover several datasets, one per metric and dataset (``OUT/rd_max_err_cm_cmu_test.png``, ...).

``OUT`` (default ``plots``) is created; existing figures in it are not overwritten unless ``--force``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

__all__ = ["add_parser", "run"]


def add_parser(commands) -> argparse.ArgumentParser:
    """Register ``plot`` on the ``mocapbench`` sub-parsers."""
    parser = commands.add_parser("plot", help="overlay results JSON files or report folders on RD figures")
    parser.add_argument("files", nargs="+", metavar="FILE", help="results/<dataset>/<codec>.json, or a report folder")
    parser.add_argument("-o", "--output", default="plots", help="folder for the figures (default: plots)")
    parser.add_argument("--no-published", action="store_true", help="leave out the papers' published points")
    parser.add_argument("--force", action="store_true", help="replace figures that exist in the output folder")
    parser.set_defaults(run=run)
    return parser


def _labels(frame):
    """``codec`` or, when one codec/dataset comes from several sources, ``codec [source]``."""
    import pandas as pd

    sources = frame["source_file"].map(lambda p: Path(p).parents[2].name if len(Path(p).parents) > 2
                                       else Path(p).parent.name)
    clash = frame.groupby(["codec", "dataset"])["source_file"].transform("nunique") > 1
    return pd.Series([f"{c} [{s}]" if k else c for c, s, k in zip(frame["codec"], sources, clash)],
                     index=frame.index)


def run(args) -> None:
    """Write one figure per metric to ``args.output``; prints the paths."""
    from mocapbench.experiments import plots
    from mocapbench.experiments.published import points_for
    from mocapbench.experiments.results_files import ResultsFileError, load_many

    try:
        frame = load_many(args.files)
    except ResultsFileError as error:
        raise ValueError(str(error)) from None
    out = Path(args.output)
    if out.exists() and not out.is_dir():
        raise ValueError(f"{out}: exists and is not a folder")
    out.mkdir(parents=True, exist_ok=True)
    frame = frame.assign(codec=_labels(frame))
    datasets = sorted(set(frame["dataset"]))
    # One figure per metric and dataset: a codec's curves on two datasets (e.g. 120 and 24 fps) do not compare.
    targets = {(metric, dataset): out / (f"rd_{metric}.png" if len(datasets) == 1 else f"rd_{metric}_{dataset}.png")
               for metric, _ in plots.DISTORTIONS for dataset in datasets}
    if not args.force:
        existing = [str(p) for p in targets.values() if p.exists() or p.with_suffix(".svg").exists()]
        if existing:
            raise ValueError(f"{existing[0]} exists; pass --force to replace the figures in {out}")
    else:
        for path in targets.values():
            for target in (path, path.with_suffix(".svg")):
                if target.is_symlink() or target.is_file():
                    target.unlink()
    published = [] if args.no_published else points_for(None)
    written = []
    for (metric, dataset), path in targets.items():
        figure = plots.rd_metric_figure(frame[frame["dataset"] == dataset], dataset, metric, path, bounds=(1.0, 3.0),
                                        published=published)
        if figure is not None:
            written.append(figure)
    if not written:
        raise ValueError("the files hold no metric to plot (no max_err_cm, mean_err_cm, kg_percent or shell column)")
    for path in written:
        print(f"{path} (and {path.with_suffix('.svg').name})")
