"""Encode CPU and bytes of ``mcb-rot`` per dataset, eps and shell, as the sweeps would code them.

Usage::

    python -m mocapbench.benchmarks.mcb_rot.encode_cpu [--datasets bandai_test cmu_test_24fps cmu_test]
        [--eps 0.1 1] [--shell 0 3] [--data-dir D]

Each dataset's codec is fit on its training split first (mcb-rot's prior, as a sweep job's fitted state), then every
clip is encoded once under one BLAS thread; the CPU time of the process (``time.process_time``) of the encode calls
is summed over the clips, beside the bytes and the load average before and after. Each stream is decoded and its
L-inf checked against eps (outside the timing). Run the old and the new code side by side (two processes at once,
``PYTHONPATH`` set to each tree) to compare them: CPU time on a shared machine still varies with its load.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

__all__ = ["main"]


def _spec(name: str, data_dir: str | None) -> dict:
    """The dataset config ``configs/dataset/<name>.yaml`` as a plain dict, ``${data_dir}`` resolved."""
    from pathlib import Path

    import yaml

    from mocapbench import configs

    spec = yaml.safe_load((Path(configs.__file__).parent / "dataset" / f"{name}.yaml").read_text())
    if spec.get("data_dir") == "${data_dir}":
        spec["data_dir"] = data_dir or str(Path.cwd().parent / "shared" / "data" / "cmu")
    return spec


def _dataset_names() -> list[str]:
    """The dataset configs of the package (``configs/dataset/*.yaml``), by name."""
    from pathlib import Path

    from mocapbench import configs

    return sorted(path.stem for path in (Path(configs.__file__).parent / "dataset").glob("*.yaml"))


def _centimetres(low: float, strict: bool):
    """argparse type: a float in cm above ``low`` (``strict``) or at least ``low``; else a one-line usage error."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = float("nan")
        if not (value > low if strict else value >= low) or value == float("inf"):
            sign = ">" if strict else ">="
            raise argparse.ArgumentTypeError(f"expected a finite length in cm {sign} {low:g}, got {text!r}")
        return value

    return parse


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--datasets", nargs="+", default=["bandai_test", "cmu_test_24fps", "cmu_test"],
                        choices=_dataset_names(), metavar="NAME", help="dataset configs (configs/dataset/NAME.yaml)")
    parser.add_argument("--eps", nargs="+", type=_centimetres(0.0, True), default=[0.1, 1.0], metavar="CM")
    parser.add_argument("--shell", nargs="+", type=_centimetres(0.0, False), default=[0.0, 3.0], metavar="CM")
    parser.add_argument("--data-dir", default=None, help="CMU data folder (default: ../shared/data/cmu)")
    args = parser.parse_args(argv)
    from mocapbench.codecs import create
    from mocapbench.experiments import datasets
    from mocapbench.metrics import max_joint_error
    from mocapbench.metrics.timing import single_thread

    print(f"load average before: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    print("| dataset | eps cm | shell cm | encode CPU s | bytes |\n|---|---:|---:|---:|---:|")
    total = 0.0
    for name in args.datasets:
        spec = _spec(name, args.data_dir)
        clips, training = datasets.load_clips(spec), datasets.load_training(spec)
        for shell in args.shell:
            state = create("mcb-rot", shell_cm=shell).fit(training).model_state()
            for eps in args.eps:
                codec = create("mcb-rot", eps_cm=eps, shell_cm=shell)
                codec.load_model_state(state)
                cpu, size = 0.0, 0
                for motion in clips:
                    with single_thread(1):
                        start = time.process_time()
                        data = codec.encode(motion)
                        cpu += time.process_time() - start
                    size += len(data)
                    error = max_joint_error(motion.positions(), codec.decode(data).positions)
                    if not error <= eps:
                        raise SystemExit(f"{name} {motion.name}: L-inf {error} cm exceeds eps {eps} cm")
                total += cpu
                print(f"| {name} | {eps:g} | {shell:g} | {cpu:.2f} | {size:,} |", flush=True)
    print(f"all: {total:.1f} CPU s; load average after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    return 0


if __name__ == "__main__":
    from mocapbench.benchmarks.entry import run_script

    raise SystemExit(run_script(main))  # a missing data folder: one line, exit 2
