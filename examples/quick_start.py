"""Quick start (the README shows this file; tests/test_readme_example.py runs it): one clip, three codecs, a table."""

import pandas as pd

from mocapbench.codecs import create
from mocapbench.experiments.evaluate import evaluate
from mocapbench.io import read_bvh

motion = read_bvh("tests/fixtures/cmu/bvh/09_06.bvh", length_unit_cm=5.6444, drop_first_frame=True)
print(motion)
rows = [evaluate(create(name, **params), motion) for name, params in
        [("quant-delta-zstd", {"step_cm": 0.5}), ("quant-rot-zstd", {}), ("mcb-linf", {"eps_cm": 1.0})]]
columns = ["codec", "bitstream_bytes", "compression_ratio", "max_err_cm", "mean_err_cm"]
print(pd.DataFrame(rows)[columns].to_string(index=False))
