"""The ``--units`` and ``--up`` options of every command that reads or writes motion (one definition, no heavy imports).

The values are parsed by :mod:`mocapbench.io.units` (``parse_units``, ``parse_up_axis``) when the command runs,
so that building the parser stays cheap.
"""

from __future__ import annotations

import argparse

__all__ = ["add_motion_arguments"]


def add_motion_arguments(parser: argparse.ArgumentParser, *, writing: bool = False) -> None:
    """Add ``--units`` (alias ``--length-unit-cm``) and, when reading, ``--up`` to a sub-command.

    Parameters
    ----------
    writing : bool
        The command writes motion (``decompress``): ``--units`` is the unit to write, default the stream's.
    """
    what = "to write (default: the source unit recorded in the stream)" if writing else (
        "of the input (default: cm for BVH, m for glTF, the file's own for AMC and FBX)"
    )
    parser.add_argument(
        "--units",
        "--length-unit-cm",
        dest="units",
        default=None,
        metavar="UNIT",
        help=f"length unit {what}: cm, mm, m, inch, cmu (CMU, 5.6444 cm) or a number of cm per unit",
    )
    if not writing:
        parser.add_argument("--up", default=None, choices=("y", "z", "x"), help="up axis (default: detected)")
