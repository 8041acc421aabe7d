"""``python -m mocapbench.fuzz``: the fuzz campaign (see :mod:`mocapbench.fuzz.harness`)."""

import sys

from mocapbench.fuzz.harness import main

sys.exit(main())
