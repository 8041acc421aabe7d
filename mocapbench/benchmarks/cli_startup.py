"""Start-up time of the ``mocapbench`` command, optionally beside an older checkout, in one interleaved run.

``python -m mocapbench.benchmarks.cli_startup [--old OLD_CHECKOUT] [--repeats 9] [--clip FILE.bvh]``

Each command (``--help``, ``codecs``, ``compress`` of a small clip with ``quant-delta-zstd``, and ``python -c pass``
as the interpreter's floor) runs as a fresh ``python -m mocapbench.cli ...`` process with ``PYTHONPATH`` set to
the checkout under test and an empty working directory, so nothing else can be imported by accident (the
script checks which ``mocapbench`` each checkout imports). Runs of the two checkouts alternate, so load changes
hit both alike; one warm-up run per command and checkout fills the page cache and ``__pycache__``.

Reported per command and checkout: the median and minimum wall time, and the median CPU time of the child
process (user + system, from ``resource.getrusage(RUSAGE_CHILDREN)``), which depends far less on the load of
the machine than wall time does; the 1-minute load average before and after the run is printed with the table.
On a quiet machine wall time is close to CPU time.

Default clip: ``tests/fixtures/cmu/bvh/09_06.bvh`` (142 frames, 31 joints) of the source checkout when present,
else a synthetic 142-frame, 31-joint BVH written to a temporary folder.
"""

from __future__ import annotations

import argparse
import os
import platform
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import mocapbench
from mocapbench.metrics.timing import load_average

CODEC = "quant-delta-zstd"
"""The codec of the ``compress`` command: light to run, so the row is mostly start-up."""


def this_checkout() -> Path:
    """The folder holding the ``mocapbench`` package that runs this script (a source tree or site-packages)."""
    return Path(mocapbench.__file__).resolve().parents[1]


def _child_env(tree: Path) -> dict[str, str]:
    env = {key: value for key, value in os.environ.items() if key != "PYTHONPATH"}
    env["PYTHONPATH"] = str(tree)
    return env


def check_checkout(tree: Path, python: str, workdir: Path) -> Path:
    """The ``mocapbench/__init__.py`` that ``python`` imports with ``PYTHONPATH=tree``; it must lie in ``tree``."""
    probe = subprocess.run(
        [python, "-c", "import mocapbench; print(mocapbench.__file__)"],
        cwd=workdir, env=_child_env(tree), capture_output=True, text=True, check=True,
    )  # fmt: skip
    imported = Path(probe.stdout.strip()).resolve()
    if tree.resolve() not in imported.parents:
        raise SystemExit(f"cli_startup: PYTHONPATH={tree} imports {imported}, not the checkout under test")
    return imported


def time_child(command: list[str], env: dict[str, str], workdir: Path) -> tuple[float, float]:
    """Run ``command`` to completion; return (wall seconds, CPU seconds of the child: user + system)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    result = subprocess.run(command, cwd=workdir, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if result.returncode != 0:
        raise SystemExit(f"cli_startup: {' '.join(command)} failed: {result.stderr.strip().splitlines()[-1:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def default_clip(workdir: Path) -> tuple[Path, list[str]]:
    """(clip, extra ``compress`` arguments): the shipped 09_06 BVH in CMU units, else a synthetic BVH in cm."""
    shipped = this_checkout() / "tests" / "fixtures" / "cmu" / "bvh" / "09_06.bvh"
    if shipped.is_file():
        return shipped, ["--length-unit-cm", "5.6444", "--drop-first-frame"]
    from mocapbench.io import write_bvh
    from mocapbench.synthetic import sinusoidal_motion

    return write_bvh(sinusoidal_motion(num_frames=142, seed=1), workdir / "synthetic_142.bvh"), []


def commands(clip: Path, extra: list[str], workdir: Path) -> dict[str, list[str]]:
    """Label -> arguments after ``python``."""
    cli = ["-m", "mocapbench.cli"]
    return {
        "python -c pass (floor)": ["-c", "pass"],
        "mocapbench --help": [*cli, "--help"],
        "mocapbench codecs": [*cli, "codecs"],
        f"mocapbench compress {clip.name} ({CODEC})": [
            *cli, "compress", str(clip), str(workdir / "out.mcb"), "--codec", CODEC, "--force", *extra,
        ],
    }  # fmt: skip


def run(trees: dict[str, Path], *, repeats: int = 9, clip: Path | None = None, python: str = sys.executable) -> dict:
    """Time every command in every checkout, interleaved.

    Returns
    -------
    dict
        ``rows``: one dict per (command, checkout) with ``command``, ``checkout``, ``wall_median_s``,
        ``wall_min_s``, ``cpu_median_s``, ``repeats``; ``load_before``/``load_after``: 1-minute load averages;
        ``imported``: checkout label -> the ``mocapbench/__init__.py`` it ran.
    """
    with tempfile.TemporaryDirectory(prefix="mocapbench-startup-") as folder:
        workdir = Path(folder)
        imported = {label: str(check_checkout(tree, python, workdir)) for label, tree in trees.items()}
        if clip is None:
            clip, extra = default_clip(workdir)
        else:
            extra = []
        plan = commands(clip, extra, workdir)
        envs = {label: _child_env(tree) for label, tree in trees.items()}
        for arguments in plan.values():  # warm-up: page cache, __pycache__
            for env in envs.values():
                time_child([python, *arguments], env, workdir)
        load_before = load_average()
        samples: dict[tuple[str, str], list[tuple[float, float]]] = {}
        for _ in range(repeats):
            for name, arguments in plan.items():
                for label, env in envs.items():
                    samples.setdefault((name, label), []).append(time_child([python, *arguments], env, workdir))
        load_after = load_average()
    rows = []
    for (name, label), values in samples.items():
        walls, cpus = [w for w, _ in values], [c for _, c in values]
        rows.append({
            "command": name, "checkout": label, "wall_median_s": statistics.median(walls),
            "wall_min_s": min(walls), "cpu_median_s": statistics.median(cpus), "repeats": len(values),
        })  # fmt: skip
    return {"rows": rows, "load_before": load_before, "load_after": load_after, "imported": imported}


def format_table(result: dict) -> str:
    """Markdown: one line per command, the checkouts side by side (wall median / min, CPU median, in s)."""
    labels = list(result["imported"])
    by_key = {(row["command"], row["checkout"]): row for row in result["rows"]}
    header = "| command | " + " | ".join(
        f"{label} wall median | {label} wall min | {label} CPU median" for label in labels
    )
    lines = [header + (" | CPU old/new |" if len(labels) == 2 else " |")]
    lines.append("|---|" + "---:|" * (3 * len(labels) + (1 if len(labels) == 2 else 0)))
    for command in dict.fromkeys(row["command"] for row in result["rows"]):
        cells = []
        for label in labels:
            row = by_key[(command, label)]
            cells += [f"{row['wall_median_s']:.3f}", f"{row['wall_min_s']:.3f}", f"{row['cpu_median_s']:.3f}"]
        if len(labels) == 2:
            old, new = (by_key[(command, label)]["cpu_median_s"] for label in labels)
            cells.append(f"{old / new:.1f}x" if new > 0 else "n/a")
        lines.append(f"| {command} | " + " | ".join(cells) + " |")
    repeats = result["rows"][0]["repeats"]
    lines.append("")
    lines.append(
        f"Seconds; median of {repeats} interleaved runs after one warm-up each; CPU = user + system of the child "
        f"process (getrusage RUSAGE_CHILDREN). 1-minute load average {result['load_before']:.2f} before, "
        f"{result['load_after']:.2f} after, on {os.cpu_count()} CPUs; Python {platform.python_version()}."
    )
    for label, path in result["imported"].items():
        lines.append(f"- {label}: {path}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--old", type=Path, help="root of an older checkout to time beside this one")
    parser.add_argument("--new", type=Path, help="root of the checkout to time (default: the one running this)")
    parser.add_argument("--repeats", type=int, default=9, help="runs per command and checkout (default 9)")
    parser.add_argument("--clip", type=Path, help="BVH or AMC file for the compress command")
    parser.add_argument("--python", default=sys.executable, help="interpreter of the children (default: this one)")
    args = parser.parse_args(argv)
    if args.repeats < 1:
        parser.error("--repeats must be at least 1")
    trees = {}
    if args.old is not None:
        if not any((args.old / "mocapbench" / cli).exists() for cli in ("cli", "cli.py")):
            parser.error(f"--old {args.old}: no mocapbench/cli there")
        trees["old"] = args.old.resolve()
    trees["new"] = (args.new or this_checkout()).resolve()
    print(format_table(run(trees, repeats=args.repeats, clip=args.clip, python=args.python)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
