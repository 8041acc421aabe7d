"""``mocapbench compare FILES|DIR [--max-error-cm E]``: every available codec on the user's clips, one ranked table.

For each codec, each clip is coded at the bound by the rate search (:mod:`mocapbench.ratesearch`: exact for the
codecs with a guarantee, a search over the main knob for the others). Codecs with learned state are fit on the
compared clips themselves (one model per skeleton; *in-sample*, said in the table's note) and their model bytes are
a column. The table ranks codecs by the pooled ratio at the bound (total float32 position bytes over total stream
bytes); a codec that cannot reach the bound on some clip, cannot run here, or fails, gets a row with the one-line
reason at the bottom. The rows (one per codec and clip, :func:`mocapbench.experiments.evaluate.evaluate`) go to
``<runs>/<codec>/results.jsonl`` and the usual report is built from them (:func:`mocapbench.experiments.report.
build_report`).
"""

from __future__ import annotations

import dataclasses
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from mocapbench.cli.arguments import add_motion_options, read_clips

if TYPE_CHECKING:  # the CLI registers this command without importing numpy
    from mocapbench.motion import Motion

__all__ = ["CodecOutcome", "add_parser", "compare", "format_table"]


@dataclasses.dataclass
class CodecOutcome:
    """One codec's result over the clips: rows of the chosen settings, or the reason it has none."""

    codec: str
    rows: list[dict[str, Any]]
    reason: str = ""
    rotations: bool = False
    latency_frames: int = -1
    settings: list[dict[str, Any]] = dataclasses.field(default_factory=list)
    seconds: float = 0.0

    @property
    def ratio(self) -> float:
        raw = sum(row["raw_bytes"] for row in self.rows)
        coded = sum(row["bitstream_bytes"] for row in self.rows)
        return raw / coded if coded else 0.0


def _one_line(error: BaseException) -> str:
    text = error.args[0] if isinstance(error, KeyError) and error.args else str(error)
    return f"{type(error).__name__}: {' '.join(str(text).split())}"


def _compare_codec(name: str, motions: Sequence[Motion], bound_cm: float, dataset: str) -> CodecOutcome:
    from mocapbench.codecs import CODECS, Codec, create
    from mocapbench.experiments.evaluate import evaluate
    from mocapbench.ratesearch import search, with_config

    start = time.perf_counter()
    cls = CODECS[name]
    outcome = CodecOutcome(name, [], rotations=bool(cls.codes_rotations))
    try:
        fitted = create(name).fit(list(motions)) if cls.fit is not Codec.fit else None  # learned state: in-sample
        prepare = (lambda codec: with_config(fitted, codec)) if fitted is not None else None
        for motion in motions:
            result = search(name, motion, bound_cm, prepare=prepare)
            if not result.met:
                chosen = ", ".join(f"{key}={value}" for key, value in result.settings.items())
                outcome.reason = (
                    f"cannot reach L-inf <= {bound_cm:g} cm on {motion.name}: the closest setting ({chosen}) gives "
                    f"{result.max_error_cm:.3g} cm"
                )
                outcome.rows = []
                break
            row = evaluate(result.codec, motion)
            row.update({"dataset": dataset, "train_set": f"in-sample: {dataset}", "rate_search_tries": result.tries,
                        "max_error_bound_cm": bound_cm})
            outcome.rows.append(row)
            outcome.settings.append(result.settings)
            outcome.latency_frames = int(result.codec.latency_frames)
    except Exception as error:  # noqa: BLE001 - a codec that fails gets its row and reason; the others go on
        outcome.rows, outcome.reason = [], _one_line(error)
    outcome.seconds = time.perf_counter() - start
    return outcome


def compare(
    motions: Sequence[Motion], bound_cm: float, codecs: Sequence[str] | None = None, *, dataset: str = "your clips",
    progress=None,
) -> list[CodecOutcome]:
    """Every codec of ``codecs`` (default: every registered one, then the unavailable ones) on ``motions``.

    Returns the outcomes ranked: codecs with rows by decreasing pooled ratio, then the others by name.
    """
    from mocapbench.codecs import CODECS, UNAVAILABLE

    names = list(codecs) if codecs else sorted(CODECS) + sorted(UNAVAILABLE)
    outcomes = []
    for name in names:
        if name in UNAVAILABLE and name not in CODECS:
            outcomes.append(CodecOutcome(name, [], reason=f"unavailable here: {UNAVAILABLE[name]}"))
        elif name not in CODECS:
            outcomes.append(CodecOutcome(name, [], reason=f"unknown codec; registered codecs are {sorted(CODECS)}"))
        else:
            if progress:
                progress(name)
            outcomes.append(_compare_codec(name, motions, bound_cm, dataset))
    ranked = sorted((o for o in outcomes if o.rows), key=lambda o: -o.ratio)
    return ranked + sorted((o for o in outcomes if not o.rows), key=lambda o: o.codec)


def _latency(frames: int) -> str:
    return "whole clip" if frames < 0 else ("0 (frame by frame)" if frames == 0 else f"{frames} frames")


def _setting_text(settings: list[dict[str, Any]]) -> str:
    """The knob values chosen over the clips: one value, or the range."""
    if not settings or not settings[0]:
        return "-"
    parts = []
    for key in settings[0]:
        values = [s[key] for s in settings if key in s]
        if all(isinstance(v, (int, float)) for v in values) and len(set(values)) > 1:
            parts.append(f"{key}={min(values):.4g}..{max(values):.4g}")
        else:
            value = values[0]
            parts.append(f"{key}={value:.4g}" if isinstance(value, float) else f"{key}={value}")
    return ", ".join(parts)


def format_table(outcomes: Sequence[CodecOutcome], bound_cm: float) -> str:
    """The ranked table as aligned text (what ``compare`` prints)."""
    header = ["rank", "codec", f"ratio at L-inf <= {bound_cm:g} cm", "L-inf cm", "mean cm", "rotations",
              "model bytes", "latency", "setting"]
    lines = []
    for rank, outcome in enumerate(outcomes, 1):
        if not outcome.rows:
            lines.append([str(rank), outcome.codec, "-", "-", "-", "yes" if outcome.rotations else "no", "-", "-",
                          outcome.reason])
            continue
        frames = sum(row["frames"] for row in outcome.rows)
        mean = sum(row["mean_err_cm"] * row["frames"] for row in outcome.rows) / frames
        lines.append([
            str(rank), outcome.codec, f"{outcome.ratio:.1f}:1", f"{max(r['max_err_cm'] for r in outcome.rows):.3f}",
            f"{mean:.3f}", "yes" if outcome.rotations else "no", str(max(r["model_bytes"] for r in outcome.rows)),
            _latency(outcome.latency_frames), _setting_text(outcome.settings),
        ])
    widths = [max(len(row[i]) for row in [header, *lines]) for i in range(len(header) - 1)]
    text = ["  ".join(cell.ljust(width) for cell, width in zip(row[:-1], widths)) + "  " + row[-1]
            for row in [header, *lines]]
    return "\n".join(text)


def write_runs(outcomes: Sequence[CodecOutcome], folder: Path) -> Path:
    """The rows as ``folder/<codec>/results.jsonl`` (the layout the report reads); returns ``folder``."""
    from mocapbench.experiments.results import write_rows_atomic

    for outcome in outcomes:
        if outcome.rows:
            write_rows_atomic(folder / outcome.codec / "results.jsonl", outcome.rows)
    return folder


def run(args) -> None:
    """Compare the codecs on ``args.clips``; print the table, write the rows and the report."""
    motions = read_clips(args, args.clips)
    codecs = [name.strip() for name in args.codecs.split(",")] if args.codecs else None
    dataset = args.name or "compare"
    print(f"comparing on {len(motions)} clip(s), {sum(m.num_frames for m in motions)} frames, "
          f"L-inf <= {args.max_error_cm:g} cm", file=sys.stderr)
    outcomes = compare(motions, args.max_error_cm, codecs, dataset=dataset,
                       progress=lambda name: print(f"  {name} ...", file=sys.stderr))
    print(format_table(outcomes, args.max_error_cm))
    learned = [o.codec for o in outcomes if o.rows and max(r["model_bytes"] for r in o.rows) > 0]
    if learned:
        print(f"Models of {', '.join(learned)}: fit on these clips (in-sample) unless shipped with the package; "
              f"their bytes are beside the stream, not in the ratio.")
    if args.no_report or not any(o.rows for o in outcomes):
        return
    import datetime

    from mocapbench.experiments.report import build_report

    runs = Path(args.runs) / f"{datetime.datetime.now():%Y-%m-%d-%H%M%S}-{dataset}"
    write_runs(outcomes, runs)
    report = build_report([runs], name=dataset, reports_root=args.reports)
    print(f"rows: {runs}; report: {report}")


def add_parser(commands) -> None:
    """Register ``compare`` on the CLI's sub-parsers."""
    parser = commands.add_parser("compare", help="run every available codec on your clips and rank them at a bound")
    parser.add_argument("clips", nargs="+", help="motion files, or folders of them")
    parser.add_argument("--max-error-cm", type=float, default=1.0, help="L-inf bound every codec must meet (cm)")
    parser.add_argument("--codecs", help="comma-separated codec names (default: every registered codec)")
    parser.add_argument("--name", help="name of the run and report (default: compare)")
    parser.add_argument("--runs", default="multirun/compare", help="folder for the results rows")
    parser.add_argument("--reports", default="reports", help="folder for the report")
    parser.add_argument("--no-report", action="store_true", help="print the table only")
    add_motion_options(parser)
    parser.set_defaults(run=run)
