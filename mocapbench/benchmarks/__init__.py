"""Speed benchmarks and reproduction scripts, run as modules, e.g. ``python -m mocapbench.benchmarks.io``.

Never asserted in tests. Importing this package pins every numeric library to one thread before any benchmark
module imports numpy: the targets are per core, and a shared 2-core machine makes multi-threaded timings noise.
"""

import os

for _variable in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMEXPR_NUM_THREADS"):
    os.environ[_variable] = "1"
