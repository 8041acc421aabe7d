"""The ``mocapbench`` command line: one module per command, the shared helpers in :mod:`.arguments` below them.

:mod:`.main` builds the parser from the command modules and turns a user's error into one line.
"""

from mocapbench.cli.main import main

__all__ = ["main"]
