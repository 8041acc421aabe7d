"""``python -m mocapbench.cli``: the ``mocapbench`` command."""

import sys

from mocapbench.cli.main import main

sys.exit(main())
