"""``make run`` and ``make bench``: run the sweeps, write the report, print the headline table and the report path.

``python -m mocapbench.experiments.main``
    The small benchmark (``make run``): every registered codec at a few points of its RD curve
    (``sweep=small``) on the embedded synthetic clips, plus the real CMU clip 09_06 when the CMU data folder
    exists (otherwise one line says so and the run goes on), as one sweep over both datasets.
``python -m mocapbench.experiments.main --cmu``
    The benchmark (``make bench``): ``sweep=all`` over ``cmu_test`` (learned state fit on ``cmu_train``), over
    ``cmu_test_24fps`` (the same clips at 24 fps, every 5th frame; every codec but the neural Fourier ones) and over
    ``bandai_test`` (a game studio's capture at its 30 fps, a game rig; learned state fit on ``bandai_train``; when
    its data folder exists, else one line says so), then the LSDT claim sweeps (``sweep=lsdt_sparsity``, ``sweep=lsdt_clip_length``) when the LSDT codecs exist.

Before the sweeps, ``make bench`` prints how long they will take (:mod:`mocapbench.experiments.bench_time`: the
jobs it is about to run priced with the per-frame costs measured on this machine; ``--no-estimate`` skips it;
``--estimate-only`` prints it per sweep and per codec, in seconds, and runs nothing).
Each sweep runs as its own ``python -m mocapbench.experiments.run -m ...`` process (Hydra owns its process), which
prints its estimate, a line per finished job with its time beside its estimate and an ETA, and a summary at the
end; at the end of the run a table gives each codec's wall and CPU time; ``--resume DIR`` re-runs into an existing
sweep root, skipping the finished jobs. Then the report is written and its headline printed: per dataset and L∞
bound (1 cm, 3 cm and ``--bounds``), the codecs ranked by ratio with the winner in a sentence. The exit status is
1 when any job failed, unless ``--allow-failures``.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import os
import subprocess
import sys
import time
from pathlib import Path

__all__ = ["main", "cmu_available", "bandai_available"]


_NEURAL = "fourier-mlp-int,fourier-mlp-dct"


def cmu_available(data_dir: str | None) -> tuple[bool, str]:
    """Whether the CMU data folder can be used, and the folder (or the reason it cannot)."""
    try:
        from mocapbench.datasets.cmu import cmu_data_dir
    except ImportError as error:  # the CMU loader is not installed in this checkout
        return False, f"the CMU loader is unavailable ({error})"
    try:
        return True, str(cmu_data_dir(data_dir))
    except Exception as error:  # noqa: BLE001 - DataNotFoundError, or anything else that says why
        return False, str(error)


def bandai_available() -> tuple[bool, str]:
    """Whether the Bandai Namco data folder can be used, and the folder (or the reason it cannot)."""
    from mocapbench.datasets.bandai import bandai_data_dir

    try:
        return True, str(bandai_data_dir())
    except Exception as error:  # noqa: BLE001 - DataNotFoundError, or anything else that says why
        return False, str(error)


def _sweep(root: Path, name: str, overrides: list[str]) -> tuple[Path, int]:
    folder = root / name
    command = [sys.executable, "-m", "mocapbench.experiments.run", "-m", *overrides, f"hydra.sweep.dir={folder}"]
    print("$ " + " ".join(command[1:]), flush=True)
    return folder, subprocess.run(command).returncode


def _bench_plans():
    """The sweeps of ``make bench``, in order."""
    from mocapbench.codecs import codec_names
    from mocapbench.experiments.bench_time import SweepPlan

    # Every codec at 120 fps, then at 24 fps (every 5th frame: ACL's published CMU rate) without the neural Fourier
    # codecs: they train a network per clip for a fixed number of steps, so at 24 fps they would cost nearly as much
    # as at 120 fps again.
    plans = [SweepPlan("cmu_test", "all", "cmu_test"),
             SweepPlan("cmu_test_24fps", "all", "cmu_test_24fps", (f"hydra.sweeper.exclude=[{_NEURAL}]",))]
    # The game studio's capture at its own 30 fps, beside CMU (its rig, its frame rate, its motion vocabulary).
    ok, where = bandai_available()
    if ok:
        plans.append(SweepPlan("bandai_test", "all", "bandai_test"))
    else:
        print(f"Bandai Namco data not found, bandai_test left out ({where})", flush=True)
    # The extra grids behind the LSDT paper's Figs. 4 (sparsity P) and 7 (clip length L), when registered.
    for sweep, needs in (("lsdt_sparsity", {"lsdt-frame", "lsdt-clip"}), ("lsdt_clip_length", {"lsdt-clip"})):
        if needs <= set(codec_names()):
            plans.append(SweepPlan(f"cmu_test_{sweep}", sweep, "cmu_test"))
    return plans


def _print_estimate(plans, common: list[str]):
    """How long the run will take, before it starts (see :mod:`mocapbench.experiments.bench_time`)."""
    from mocapbench.experiments.bench_time import estimate_run, format_estimate

    workers = 2  # the local launcher's n_jobs (configs/hydra/launcher/local.yaml)
    for override in common:
        if override.startswith("hydra.launcher.n_jobs="):
            workers = int(override.split("=", 1)[1])
    try:
        estimate = estimate_run(plans, workers, common)
    except Exception as error:  # noqa: BLE001 - an estimate is a courtesy: the run goes on without it
        print(f"no estimate ({error}); starting the sweeps", flush=True)
        return None
    print("make bench: " + format_estimate(estimate, workers), flush=True)
    return estimate


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cmu", action="store_true",
                        help="the benchmark (sweep=all over cmu_test, cmu_test_24fps and bandai_test)")
    parser.add_argument("--data-dir", default=None, help="CMU data folder (default: the config's data_dir)")
    parser.add_argument("--resume", help="an existing sweep root to continue (skips finished jobs)")
    parser.add_argument("--reports-root", default="reports")
    parser.add_argument("--max-points", type=int, default=None, help="RD points per codec (make run: 3)")
    parser.add_argument("--bounds", type=float, action="append", default=[], metavar="CM",
                        help="an L∞ bound (cm) for the headline beside 1 and 3 cm (repeatable)")
    parser.add_argument("--allow-failures", action="store_true",
                        help="exit 0 even if some job failed (the summary and the report still list them)")
    parser.add_argument("--no-estimate", action="store_true", help="do not price the run before it starts")
    parser.add_argument("--estimate-only", action="store_true",
                        help="print the estimate (per sweep and per codec) and exit without running anything")
    parser.add_argument("extra", nargs="*", help="more Hydra overrides for every sweep")
    args = parser.parse_args(argv)
    from mocapbench.experiments.headline import bounds_with

    try:
        bounds = bounds_with(args.bounds)
    except ValueError as error:
        parser.error(str(error))
    start = time.perf_counter()
    stamp = f"{_dt.datetime.now():%Y-%m-%d-%H%M%S}"
    kind = "bench" if args.cmu else "run"
    root = Path(args.resume) if args.resume else Path("multirun") / f"{stamp}-{kind}"
    common = list(args.extra)
    if args.data_dir:
        common.append(f"data_dir={args.data_dir}")
    if args.max_points:
        common.append(f"hydra.sweeper.max_points={args.max_points}")
    if args.allow_failures:
        common.append("hydra.sweeper.allow_failures=true")
    folders, failures = [], 0
    estimate = None
    if args.cmu:
        ok, where = cmu_available(args.data_dir)
        if not ok:
            print(f"make bench needs the CMU clips: {where}", file=sys.stderr)
            return 2
        plans = _bench_plans()
        if args.estimate_only:
            estimate = _print_estimate(plans, common)
            if estimate is None:
                return 1
            from mocapbench.experiments.bench_time import format_estimate_table

            print(format_estimate_table(estimate))
            return 0
        estimate = None if args.no_estimate else _print_estimate(plans, common)
        sweeps_start = time.perf_counter()
        from mocapbench.experiments.bench_time import format_progress

        for done, plan in enumerate(plans, 1):
            folder, code = _sweep(root, plan.label, [f"sweep={plan.sweep}", f"dataset={plan.dataset}",
                                                     *plan.overrides, *common])
            folders.append(folder)
            failures += code != 0
            print(format_progress(done, time.perf_counter() - sweeps_start, estimate), flush=True)
    else:
        # One sweep over both datasets, so the two workers stay busy until the last job.
        datasets = "synthetic"
        ok, where = cmu_available(args.data_dir)
        if ok:
            datasets += ",cmu_09_06"
        else:
            print(f"CMU data not found, running on synthetic data only ({where})", flush=True)
        folder, code = _sweep(root, "small", ["sweep=small", f"dataset={datasets}", *common])
        folders.append(folder)
        failures += code != 0
    sweep_s = time.perf_counter() - start
    from mocapbench.experiments.report import headline_text, write_report

    present = [f for f in folders if any(f.rglob("results.jsonl"))]
    if not present:
        print("no results were written; see the sweep logs above", file=sys.stderr)
        return 1
    command = "make bench" if args.cmu else "make run"
    arguments = " ".join(argv if argv is not None else sys.argv[1:])
    report_start = time.perf_counter()
    data = write_report(present, name=kind, reports_root=args.reports_root, bounds=bounds,
                        command=f"{command}  # = python -m mocapbench.experiments.main {arguments}".rstrip())
    report, report_s = data.out, time.perf_counter() - report_start
    print()
    print(headline_text(data.rows, data.points, data.errors, data.bounds, table=data.headline))
    print()
    total = time.perf_counter() - start
    from mocapbench.experiments.bench_time import codec_times, format_codec_times

    print("time per codec (its jobs' wall and CPU seconds, summed; two jobs run at once):")
    print(format_codec_times(codec_times(folders)))
    print(f"sweeps {sweep_s:.0f} s, report {report_s:.0f} s, total {total:.0f} s on {os.cpu_count()} cores; "
          f"results in {root}")
    if args.cmu and estimate is not None and estimate.wall_s > 0:
        print(f"make bench: estimated {estimate.wall_s:.0f} s, took {total:.0f} s "
              f"({100 * (total / estimate.wall_s - 1):+.0f} %)")
    print(f"report: {report / 'index.html'} (and {report / 'report.md'}); machine-readable results in "
          f"{report / 'results'}")
    if failures and not args.allow_failures:
        print("some jobs failed (see the sweep summary above and the report's Failed jobs section); exit status 1 "
              "(--allow-failures accepts them)", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
