"""Quick start (the README shows this file; tests/test_readme_example.py runs it): one clip, three codecs, a table."""

import pandas as pd

from mocapbench.codecs import create
from mocapbench.experiments.evaluate import evaluate
from mocapbench.io import read_motion

# read_motion reads BVH, AMC, glTF/GLB and FBX, records the unit and the up axis, and warns (or, strict=True,
# refuses) when the body's size says the unit is wrong: CMU's BVH release is in CMU units.
motion, warnings = read_motion("tests/fixtures/cmu/bvh/09_06.bvh", units="cmu", drop_first_frame=True)
print(motion, *warnings, sep="\n")
rows = [evaluate(create(name, **params), motion) for name, params in
        [("quant-delta-zstd", {"step_cm": 0.5}), ("quant-rot-zstd", {}), ("mcb-linf", {"eps_cm": 1.0})]]
columns = ["codec", "bitstream_bytes", "compression_ratio", "max_err_cm", "mean_err_cm"]
print(pd.DataFrame(rows)[columns].to_string(index=False))
