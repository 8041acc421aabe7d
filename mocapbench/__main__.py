"""``python -m mocapbench``: the ``mocapbench`` command (see :mod:`mocapbench.cli`)."""

import sys

from mocapbench.cli import main

sys.exit(main())
