"""Fit the model that ``mcb-linf`` ships with (PCA basis + trained entropy model), on the ``cmu_train`` split.

    python -m mocapbench.benchmarks.mcb_linf.train [--data-dir D] [--force]

Writes ``mocapbench/models/mcb_linf_model_v2.npz`` (float32 ``basis`` (90, 90), ``mean`` (90,) cm, ``band_scale``
(21, 93) cm, float64 ``class_edges`` (79,), uint32 ``token_counts`` (80, 52)) with the codec's default settings
and prints the variance the leading PCA components explain. An existing file is kept unless ``--force`` is given.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from mocapbench.codecs import create
from mocapbench.codecs.mcb_linf.layers import root_relative
from mocapbench.codecs.mcb_linf.model import MODEL_FILE
from mocapbench.datasets.cmu import load_split


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data-dir", default=None, help="CMU data folder (default: ../shared/data/cmu)")
    parser.add_argument("--force", action="store_true", help="overwrite the shipped model")
    args = parser.parse_args(argv)
    target = Path(__file__).resolve().parents[2] / MODEL_FILE
    if target.exists() and not args.force:
        parser.error(f"{target} exists; pass --force to overwrite it")
    motions = load_split("cmu_train", data_dir=args.data_dir)
    model = create("mcb-linf").fit(motions)._model
    data = np.concatenate([root_relative(m.positions()) for m in motions]) - model.mean
    variance = np.sum((data @ model.basis.T) ** 2, axis=0)
    explained = np.cumsum(variance) / variance.sum()
    np.savez(target, **model.arrays())
    print(f"fit on {sum(m.num_frames for m in motions)} frames of {len(motions)} cmu_train clips")
    for k in (1, 5, 10, 20, 40):
        print(f"  {k:>2} components explain {100 * explained[k - 1]:.2f} % of the root-relative variance")
    print(f"wrote {target} ({target.stat().st_size} bytes, {model.stored_bytes} bytes of arrays, tag {model.tag:#010x})")
    return 0


if __name__ == "__main__":
    from mocapbench.benchmarks.entry import run_script

    raise SystemExit(run_script(main))
