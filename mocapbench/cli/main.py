"""``mocapbench`` command line: compress, decompress, inspect, codecs, plot, fit, compare, view.

Errors are one line on stderr and exit code 2; an existing output file is never overwritten without ``--force``.

Start-up is kept short (``mocapbench --help`` imports nothing beyond the standard library, ``codecs`` no scipy,
torch, pandas, matplotlib or Hydra): every command is a module of this package with ``add_parser(commands)`` and
``run(args)``, which imports only the standard library at the top and what it needs when it runs
(``tests/test_cli_startup.py`` checks which modules each command loads; ``mocapbench.benchmarks.cli_startup``
measures it). A new command is a new module here and one line in :func:`_parser`.
"""

from __future__ import annotations

import argparse
import sys

from mocapbench.cli import codecs, compare, compress, decompress, fit, inspect, view
from mocapbench.cli.arguments import CliError

__all__ = ["main"]


def _version() -> str:
    from mocapbench import __version__

    return f"mocapbench {__version__} (Python {sys.version.split()[0]})"


def _parser() -> argparse.ArgumentParser:
    from mocapbench.experiments.plot_command import add_parser as add_plot_parser  # argparse only; plots load later

    parser = argparse.ArgumentParser(prog="mocapbench", description=__doc__.splitlines()[0])
    parser.add_argument("--version", action="version", version=_version())
    commands = parser.add_subparsers(dest="command", required=True)
    for command in (compress, decompress, inspect, codecs):
        command.add_parser(commands)
    add_plot_parser(commands)
    for command in (fit, compare, view):
        command.add_parser(commands)
    return parser


def _user_error_message(error: Exception) -> str | None:
    """The one line to print for an error the user can fix (bad file, bad setting, codec unavailable), else None.

    The error classes are imported here, after the failure, so that a successful command never pays for them.
    """
    from mocapbench.codecs.base import NotFittedError
    from mocapbench.codecs.registry import CodecUnavailableError
    from mocapbench.entropy.errors import BitstreamError
    from mocapbench.motion import MotionFormatError

    if isinstance(error, KeyError) and error.args:
        return str(error.args[0])
    # OSError: the safe-output refusals (an existing path or link, a missing folder) and the system's own
    # (a full disk, no permission), whose str() is one line naming the file.
    one_line = (CliError, BitstreamError, MotionFormatError, CodecUnavailableError, NotFittedError, OSError, KeyError,
                TypeError, ValueError)  # fmt: skip
    return str(error) if isinstance(error, one_line) else None


def _out_of_memory_message(args: argparse.Namespace) -> str:
    """The "out of memory" line, naming the limit that applies to the command (``--limit``), or none where none does."""
    if not hasattr(args, "limit"):
        return "out of memory"
    from mocapbench.cli.arguments import limits_of

    try:
        allowed = limits_of(args).max_output_bytes
    except ValueError:
        return "out of memory"
    return (f"out of memory under the limit output_bytes={allowed:,} bytes of arrays; lower it "
            f"(--limit output_bytes=N) to refuse such inputs up front")


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``mocapbench`` command; returns the exit code."""
    args = _parser().parse_args(argv)
    try:
        args.run(args)
    except MemoryError:
        print(f"mocapbench: error: {_out_of_memory_message(args)}", file=sys.stderr)
        return 2
    except Exception as error:
        message = _user_error_message(error)
        if message is None:
            raise
        print(f"mocapbench: error: {message}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
