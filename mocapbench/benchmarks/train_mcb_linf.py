"""Fit the PCA spatial basis that ``mcb-linf`` ships with, on the ``cmu_train`` split.

    python -m mocapbench.benchmarks.train_mcb_linf [--data-dir D] [--force]

Writes ``mocapbench/models/mcb_linf_pca_v1.npz`` (float32 ``basis`` (90, 90) and ``mean`` (90,), cm) and prints
the variance the leading components explain. An existing file is kept unless ``--force`` is given.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from mocapbench.codecs.mcb_linf import BASIS_FILE, _root_relative, fit_spatial_basis
from mocapbench.datasets.cmu import load_split


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data-dir", default=None, help="CMU data folder (default: ../shared/data/cmu)")
    parser.add_argument("--force", action="store_true", help="overwrite the shipped basis")
    args = parser.parse_args(argv)
    target = Path(__file__).resolve().parents[1] / BASIS_FILE
    if target.exists() and not args.force:
        parser.error(f"{target} exists; pass --force to overwrite it")
    motions = load_split("cmu_train", data_dir=args.data_dir)
    basis = fit_spatial_basis(motions)
    data = np.concatenate([_root_relative(m.positions()) for m in motions]) - basis.mean
    variance = np.sum((data @ basis.basis.T) ** 2, axis=0)
    explained = np.cumsum(variance) / variance.sum()
    np.savez(target, basis=basis.basis.astype(np.float32), mean=basis.mean.astype(np.float32))
    print(f"fit on {sum(m.num_frames for m in motions)} frames of {len(motions)} cmu_train clips")
    for k in (1, 5, 10, 20, 40):
        print(f"  {k:>2} components explain {100 * explained[k - 1]:.2f} % of the root-relative variance")
    print(f"wrote {target} ({target.stat().st_size} bytes, tag {basis.tag:#010x})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
