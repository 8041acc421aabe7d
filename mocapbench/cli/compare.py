"""``mocapbench compare FILES|DIR [--max-error-cm E]``: codecs on the user's clips, ranked at one L∞ bound.

The engine is :mod:`mocapbench.experiments.compare_run` (rate search per clip, models held out by default, rows
kept as they finish); this module reads the clips, says what it read (unit and up axis of every file, and why),
tells the cost of the codecs on request before they start, runs the codecs side by side on the machine's cores
(``--workers``), shows progress, prints the ranked table with the model column, the wall and CPU time (in all, the
workers' included, and per codec), and builds the report from rows pooled as the table pools them
(:mod:`mocapbench.experiments.compare_report`). Ctrl-C prints the table of the codecs that finished and keeps every
finished clip's row under ``--runs``: the same command resumes.
"""

from __future__ import annotations

import argparse
import resource
import sys
import time
from pathlib import Path

from mocapbench.cli.arguments import add_motion_options, read_clips

__all__ = ["add_parser", "run"]

#: Exit status of a run stopped by Ctrl-C (128 + SIGINT), as shells report it.
INTERRUPTED_EXIT = 130


def _cpu_s() -> float:
    """CPU seconds of this process and of its finished worker processes (user + system)."""
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + children.ru_utime + children.ru_stime


def _workers(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a whole number of worker processes >= 1, got {text!r}")
    return value


def _codec_names(text: str | None) -> list[str] | None:
    """The names of ``--codecs``, each once, in their order."""
    return list(dict.fromkeys(name.strip() for name in text.split(",") if name.strip())) if text else None


def _announce_costs(names: list[str] | None, motions) -> None:
    """Before the run: the codecs left out of the default set, or the estimated cost of those asked for."""
    from mocapbench.experiments.compare_progress import duration_text
    from mocapbench.experiments.compare_run import ON_REQUEST, estimate_cpu_s

    frames = sum(m.num_frames for m in motions)
    if names is None:
        costs = ", ".join(f"{n} about {duration_text(estimate_cpu_s(n, motions))}" for n in ON_REQUEST)
        print(f"left out by default (their rate search trains a network per try): {costs} of CPU on these "
              f"{frames} frames; add them with --codecs", file=sys.stderr)
        return
    for name in names:
        if name in ON_REQUEST:
            print(f"{name}: at most about {duration_text(estimate_cpu_s(name, motions))} of CPU on these {frames} "
                  f"frames (estimate of one clip at a time; it trains a network per rate-search try, the clips of a "
                  f"try side by side)", file=sys.stderr)


def _print_verdicts(verdicts) -> None:
    """What was read: each file's unit (and where it came from), up axis (and why) and height, or its warning."""
    print("Files (unit, up axis, rest height):")
    for verdict in verdicts:
        print(f"  {verdict}")
    print()


def _interrupted(stop, bound: float, store: Path) -> None:
    from mocapbench.experiments.compare_run import format_table

    print()
    if stop.outcomes:
        print(format_table(stop.outcomes, bound))
    cut = f"; {stop.current} was cut short" if stop.current else ""
    print(f"interrupted: {len(stop.outcomes)} codec(s) finished{cut}. Every finished clip's row is kept in {store}; "
          f"run the same command again to resume.", file=sys.stderr)


def run(args) -> None:
    from mocapbench.experiments.compare_progress import Progress, duration_text
    from mocapbench.experiments.compare_run import (CompareInterrupted, RowStore, compare, default_codecs,
                                                    format_codec_times, format_table, model_note)

    motions, verdicts = read_clips(args, args.clips, verdicts=True)
    _print_verdicts(verdicts)
    names = _codec_names(args.codecs)
    dataset = args.name or "compare"
    store = Path(args.runs) / dataset
    policy = "in-sample" if args.in_sample else "out-of-sample"
    _announce_costs(names, motions)
    chosen = names or default_codecs()
    print(f"comparing {len(chosen)} codec(s) on {len(motions)} clip(s), {sum(m.num_frames for m in motions)} "
          f"frames, L-inf <= {args.max_error_cm:g} cm; models {policy}; rows in {store}", file=sys.stderr)
    from mocapbench.metrics.timing import usable_cores

    workers = args.workers or usable_cores()  # each codec runs on one core
    progress = Progress(len(chosen) * len(motions), workers=min(workers, len(chosen)))
    wall, cpu = time.perf_counter(), _cpu_s()
    try:
        outcomes = compare(motions, args.max_error_cm, chosen, dataset=dataset, policy=policy, folds=args.folds,
                           store=RowStore(store), progress=progress, workers=workers)
    except CompareInterrupted as stop:
        progress.close()
        _interrupted(stop, args.max_error_cm, store)
        raise SystemExit(INTERRUPTED_EXIT) from None
    progress.close()
    print(format_table(outcomes, args.max_error_cm))
    note = model_note(outcomes)
    if note:
        print(note)
    resumed = sum(o.resumed for o in outcomes)
    print(f"{duration_text(time.perf_counter() - wall)} wall, {duration_text(_cpu_s() - cpu)} CPU"
          + (f" ({resumed} clip row(s) kept from an earlier run)" if resumed else ""))
    times = format_codec_times(outcomes)
    if times:
        print(times)
    if args.no_report or not any(o.rows for o in outcomes):
        return
    print(f"rows: {store}; report: {_report(outcomes, args, dataset, store)}")


def _report(outcomes, args, dataset: str, store: Path) -> Path:
    """The report of this run, from its rows pooled as the table pools them (a snapshot folder under the store)."""
    import datetime

    from mocapbench.experiments.compare_report import pooled_rows
    from mocapbench.experiments.report import build_report
    from mocapbench.experiments.results import write_rows_atomic

    snapshot = store / "reports" / f"{datetime.datetime.now():%Y-%m-%d-%H%M%S}"
    for codec, rows in pooled_rows(outcomes, args.max_error_cm).items():
        write_rows_atomic(snapshot / codec / "results.jsonl", rows)
    return build_report([snapshot], name=dataset, reports_root=args.reports, bounds=[args.max_error_cm])


def add_parser(commands) -> None:
    """Register ``compare`` on the CLI's sub-parsers."""
    parser = commands.add_parser("compare", help="rank codecs on your clips at an L-inf bound")
    parser.add_argument("clips", nargs="+", help="motion files, or folders of them (searched recursively)")
    parser.add_argument("--max-error-cm", type=float, default=1.0, help="L-inf bound every codec must meet (cm)")
    parser.add_argument("--codecs", help="comma-separated codec names (default: every codec but the neural ones, "
                                         "whose cost is printed)")
    parser.add_argument("--in-sample", action="store_true",
                        help="fit learned models on the compared clips themselves; their bytes then count in the "
                             "ranked ratio (default: each clip coded with a model fit on other clips of its skeleton)")
    parser.add_argument("--folds", type=int, default=5,
                        help="folds of the out-of-sample fit per skeleton (leave-one-out up to this many clips)")
    parser.add_argument("--name", help="name of the run and report (default: compare); a run of the same name resumes")
    parser.add_argument("--runs", default="multirun/compare", help="folder for the result rows (kept; resumed)")
    parser.add_argument("--reports", default="reports", help="folder for the report")
    parser.add_argument("--no-report", action="store_true", help="print the table only")
    parser.add_argument("--workers", type=_workers, default=None,
                        help="codecs run at once, one process each (default: the cores this process may use)")
    add_motion_options(parser)
    parser.set_defaults(run=run)
