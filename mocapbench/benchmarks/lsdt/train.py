"""Train the LSDT bases (Hou et al. 2016, Algorithm 1) on ``cmu_train`` and plot the objective (Fig. 3).

``python -m mocapbench.benchmarks.lsdt.train [--data-dir D] [--write-model] [--out reports/lsdt]``

* Trains ``B^x, B^y, B^z`` for every sparsity P in {2, 5, 8, 11} from the DCT basis (the bases the codecs use;
  P = 8 is the default) and, for Fig. 3, P = 8 again from the 3-level Haar DWT basis.
* Prints a markdown table of the objective (eq. 6, cm²) at a few iterations and its final value per init.
* Writes ``fig3_convergence.png`` and ``fig3_objective.csv`` (objective per iteration) under ``--out``.
* With ``--write-model``: writes the committed bases ``mocapbench/models/lsdt_bases_v1.npz`` (arrays ``P2``,
  ``P5``, ``P8``, ``P11``, each (3, 31, 31) float64) and its provenance sidecar ``lsdt_bases_v1.json``.

Single-threaded numerics (set before numpy is imported).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import time
from pathlib import Path

import numpy as np

from mocapbench.codecs.lsdt.bases import COMMITTED_SPARSITIES, basis_fingerprint
from mocapbench.codecs.lsdt.spatial import is_orthogonal
from mocapbench.codecs.lsdt.training import train_lsdt_bases
from mocapbench.datasets.cmu import load_split

MODEL_PATH = Path(__file__).resolve().parents[2] / "models" / "lsdt_bases_v1.npz"
COORDINATES = "xyz"


def _git_commit() -> str:
    try:
        return subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def train_all(positions: np.ndarray, *, max_iterations: int, tol: float) -> dict:
    """Bases for every committed P (DCT init) and the P = 8 Haar-init run of Fig. 3.

    Parameters
    ----------
    positions : ndarray, shape (N, J, 3), cm

    Returns
    -------
    dict
        ``{(init, P): (bases (3, J, J), [LsdtResult x 3], seconds)}``.
    """
    runs = [("dct", p) for p in COMMITTED_SPARSITIES] + [("dwt", 8)]
    out = {}
    for init, sparsity in runs:
        start = time.perf_counter()
        bases, results = train_lsdt_bases(positions, sparsity, init=init, max_iterations=max_iterations, tol=tol)
        seconds = time.perf_counter() - start
        out[(init, sparsity)] = (bases, results, seconds)
        iterations = [r.iterations for r in results]
        print(f"trained P={sparsity:2d} from {init}: {iterations} iterations, {seconds:.1f} s", flush=True)
    return out


def objective_table(runs: dict, checkpoints=(0, 1, 10, 100, 300, 1000)) -> str:
    """Markdown: objective (cm², summed over N frames) per coordinate at a few iterations, P = 8, both inits."""
    lines = ["| init | coord | " + " | ".join(f"it {k}" for k in checkpoints) + " | final (iterations) | converged |"]
    lines.append("|---|---|" + "---:|" * len(checkpoints) + "---:|---|")
    for init in ("dct", "dwt"):
        _, results, _ = runs[(init, 8)]
        for coord, result in zip(COORDINATES, results):
            cells = [f"{result.objective[min(k, result.iterations)]:.4g}" for k in checkpoints]
            lines.append(
                f"| {init} | {coord} | " + " | ".join(cells)
                + f" | {result.objective[-1]:.6g} ({result.iterations}) | {result.converged} |"
            )
    return "\n".join(lines)


def plot_convergence(runs: dict, out_dir: Path, num_frames: int) -> Path:
    """Fig. 3: objective per iteration from DCT and Haar initialization, one panel per coordinate."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(13, 3.8))
    for d, axis in enumerate(axes):
        longest = 0
        for init, style, label in (("dct", "-", "DCT init"), ("dwt", "--", "Haar DWT init")):
            objective = runs[(init, 8)][1][d].objective
            axis.plot(np.arange(len(objective)), objective, style, label=label)
            longest = max(longest, len(objective) - 1)
        axis.set_yscale("log")
        axis.set_xscale("symlog", linthresh=10)
        axis.set_xlim(0, longest)
        axis.set_xlabel("iteration")
        axis.set_title(f"({'abc'[d]}) {COORDINATES[d]}-coordinate")
        axis.grid(True, which="both", alpha=0.3)
    axes[0].set_ylabel("objective of eq. (6), cm²")
    axes[0].legend()
    fig.suptitle(f"Algorithm 1 on cmu_train (N = {num_frames} frames, P = 8): DCT vs Haar initialization")
    fig.tight_layout()
    path = out_dir / "fig3_convergence.png"
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def write_objective_csv(runs: dict, out_dir: Path) -> Path:
    """Objective per iteration, long format: init, P, coordinate, iteration, objective_cm2."""
    path = out_dir / "fig3_objective.csv"
    with path.open("w") as handle:
        handle.write("init,sparsity,coordinate,iteration,objective_cm2\n")
        for (init, sparsity), (_, results, _) in sorted(runs.items()):
            for coord, result in zip(COORDINATES, results):
                for iteration, value in enumerate(result.objective):
                    handle.write(f"{init},{sparsity},{coord},{iteration},{float(value)!r}\n")
    return path


def read_objective_csv(path: Path) -> dict:
    """Inverse of :func:`write_objective_csv`: ``{(init, P): (None, [records x 3], nan)}`` for plotting."""
    from types import SimpleNamespace

    values: dict = {}
    with path.open() as handle:
        next(handle)
        for line in handle:
            init, sparsity, coord, _, value = line.strip().split(",")
            values.setdefault((init, int(sparsity)), {}).setdefault(coord, []).append(float(value))
    return {
        key: (None, [SimpleNamespace(objective=np.array(per[c])) for c in COORDINATES], float("nan"))
        for key, per in values.items()
    }


def write_model(runs: dict, clips: list, num_frames: int, max_iterations: int, tol: float) -> None:
    """The committed bases file and its provenance sidecar."""
    arrays = {f"P{p}": runs[("dct", p)][0] for p in COMMITTED_SPARSITIES}
    for name, bases in arrays.items():
        if not all(is_orthogonal(b) for b in bases):
            raise RuntimeError(f"bases {name} are not orthogonal to 1e-10; not writing them")
    MODEL_PATH.parent.mkdir(parents=True, exist_ok=True)
    np.savez(MODEL_PATH, **arrays)
    provenance = {
        "paper": "Hou, Chau, Magnenat-Thalmann, He. Low-latency compression of mocap data using learned spatial "
        "decorrelation transform. CAGD 43 (2016). Algorithm 1.",
        "command": "python -m mocapbench.benchmarks.lsdt.train --write-model",
        "git_commit_at_training": _git_commit(),
        "training_split": "cmu_train",
        "training_clips": clips,
        "training_frames": num_frames,
        "data": "joint positions (cm) of the ASF/AMC clips, forward kinematics of mocapbench.datasets.cmu",
        "init": "dct",
        "max_iterations": max_iterations,
        "tol_relative_decrease": tol,
        "layout": "array P<p>: (3, J, J) float64, [x, y, z]; rows are basis functions, coefficients c = B @ m",
        "bases": {
            f"P{p}": {
                "fingerprint": basis_fingerprint(runs[("dct", p)][0]).hex(),
                "iterations": [r.iterations for r in runs[("dct", p)][1]],
                "converged": [bool(r.converged) for r in runs[("dct", p)][1]],
                "objective_initial_cm2": [float(r.objective[0]) for r in runs[("dct", p)][1]],
                "objective_final_cm2": [float(r.objective[-1]) for r in runs[("dct", p)][1]],
                "train_s": round(runs[("dct", p)][2], 2),
                "bytes": int(runs[("dct", p)][0].nbytes),
            }
            for p in COMMITTED_SPARSITIES
        },
    }
    MODEL_PATH.with_suffix(".json").write_text(json.dumps(provenance, indent=2) + "\n")
    print(f"wrote {MODEL_PATH} ({MODEL_PATH.stat().st_size} bytes) and its .json sidecar")


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data-dir", default=None, help="CMU data folder (default: ../shared/data/cmu or $MOCAPBENCH_CMU)")
    parser.add_argument("--max-iterations", type=int, default=3000, help="K of Algorithm 1")
    parser.add_argument("--tol", type=float, default=1e-10, help="stop when one iteration lowers the objective by less than tol × its value")
    parser.add_argument("--out", default="reports/lsdt", help="folder for the figure and the CSV")
    parser.add_argument("--write-model", action="store_true", help="write mocapbench/models/lsdt_bases_v1.npz")
    parser.add_argument("--plot-only", action="store_true", help="redraw Fig. 3 from the CSV of an earlier run under --out")
    args = parser.parse_args(argv)
    if args.plot_only:
        runs = read_objective_csv(Path(args.out) / "fig3_objective.csv")
        print(f"wrote {plot_convergence(runs, Path(args.out), 13063)}")
        return

    motions = load_split("cmu_train", data_dir=args.data_dir)
    positions = np.concatenate([motion.positions() for motion in motions])
    clips = [motion.name for motion in motions]
    print(f"cmu_train: {len(motions)} clips {clips}, {positions.shape[0]} frames, J = {positions.shape[1]}")
    runs = train_all(positions, max_iterations=args.max_iterations, tol=args.tol)

    out_dir = Path(args.out)
    out_dir.mkdir(parents=True, exist_ok=True)
    print("\n## Fig. 3: objective of eq. (6) per iteration, P = 8 (cm², summed over the training frames)\n")
    print(objective_table(runs))
    final = {init: sum(r.objective[-1] for r in runs[(init, 8)][1]) for init in ("dct", "dwt")}
    print(f"\nfinal objective summed over x, y, z: DCT init {final['dct']:.6g}, Haar init {final['dwt']:.6g} "
          f"(Haar/DCT = {final['dwt'] / final['dct']:.4f})")
    print("\n## Final objective per P (DCT init), summed over x, y, z\n")
    print("| P | objective cm² | iterations (x, y, z) | train s |")
    print("|---:|---:|---|---:|")
    for p in COMMITTED_SPARSITIES:
        _, results, seconds = runs[("dct", p)]
        print(f"| {p} | {sum(r.objective[-1] for r in results):.6g} | {[r.iterations for r in results]} | {seconds:.1f} |")
    print(f"\nwrote {plot_convergence(runs, out_dir, positions.shape[0])} and {write_objective_csv(runs, out_dir)}")
    if args.write_model:
        write_model(runs, clips, int(positions.shape[0]), args.max_iterations, args.tol)


if __name__ == "__main__":
    from mocapbench.benchmarks.entry import run_script

    raise SystemExit(run_script(main))
