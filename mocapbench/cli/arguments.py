"""What the commands share: the motion reader's options, ``--set`` values, reading clips, the codec a command uses.

Lowest module of :mod:`mocapbench.cli`: the command modules import it, it imports no command. Only the standard
library is imported at the top (building the parser stays cheap); each helper imports what it needs when it runs.
The values of ``--units`` and ``--up`` are parsed by :mod:`mocapbench.io.units` when a command runs.
"""

from __future__ import annotations

import argparse
import ast
import sys
from typing import Any

__all__ = [
    "CliError",
    "add_motion_arguments",
    "add_motion_options",
    "codec_for_stream",
    "codec_of",
    "decoding_codec",
    "load_motion",
    "parse_settings",
    "read_clips",
    "settings_of",
]

class CliError(Exception):
    """A user-facing error: printed as one line, no traceback."""


def parse_value(text: str):
    """``--set`` values: Python/YAML-like literals (``12``, ``0.5``, ``true``, ``bone``)."""
    lowered = text.strip().lower()
    if lowered in ("true", "false"):
        return lowered == "true"
    try:
        return ast.literal_eval(text)
    except (ValueError, SyntaxError):
        return text


def parse_settings(pairs: list[str]) -> dict:
    """``--set key=value`` pairs as a dict of parsed values; a pair without ``=`` is a :class:`CliError`."""
    settings = {}
    for pair in pairs:
        key, sep, value = pair.partition("=")
        if not sep or not key:
            raise CliError(f"--set expects key=value, got {pair!r}")
        settings[key.strip()] = parse_value(value)
    return settings


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


def add_motion_options(parser: argparse.ArgumentParser) -> None:
    """The motion reader's options (as on ``compress``), for sub-commands that read many clips."""
    parser.add_argument("--asf", help="skeleton of AMC inputs (default: the .asf beside each)")
    add_motion_arguments(parser)
    parser.add_argument("--fps", type=float, help="sampling rate of glTF animations / frame rate of AMC files")
    parser.add_argument("--drop-first-frame", action="store_true", help="drop BVH frame 0 (CMU reference pose)")


def load_motion(args, path: str | None = None) -> "Motion":  # noqa: F821
    """Read the input motion with ``--units``/``--up`` (mocapbench.io.formats); warnings go to stderr, one line each."""
    from mocapbench.io.formats import read_motion

    motion, warnings = read_motion(
        path or args.input,
        units=args.units,
        up=args.up,
        asf=getattr(args, "asf", None),
        drop_first_frame=getattr(args, "drop_first_frame", False),
        fps=getattr(args, "fps", None),
    )
    for warning in warnings:
        print(f"mocapbench: warning: {warning}", file=sys.stderr)
    return motion


def read_clips(args: argparse.Namespace, paths: list[str]) -> list:
    """The motions of ``paths`` (files, or folders whose motion files are read in name order).

    A file that cannot be read is skipped with one line on stderr naming it and why. Each file is read by
    :func:`load_motion` with the command's reader options.

    Raises
    ------
    ValueError
        No readable motion at all.
    """
    from mocapbench.io.format_table import motion_files

    files = motion_files(paths)
    motions = []
    for file in files:
        one = argparse.Namespace(**{**vars(args), "input": str(file)})
        try:
            motion = load_motion(one)
        except Exception as error:  # noqa: BLE001 - any file a reader refuses is skipped, named, and the rest read
            message = error.args[0] if isinstance(error, KeyError) and error.args else error
            print(f"mocapbench: skipped {file}: {message}", file=sys.stderr)
            continue
        if not motion.name:
            import dataclasses

            motion = dataclasses.replace(motion, name=file.stem)
        motions.append(motion)
    if not motions:
        raise ValueError(f"no readable motion in {', '.join(paths)}")
    return motions


def settings_of(args) -> dict[str, Any]:
    """The codec config fields of ``--set``."""
    return parse_settings(getattr(args, "set", []) or [])


def codec_of(args, settings: dict[str, Any]):
    """The codec of ``args.codec`` with ``settings``, holding ``args.model`` if given."""
    from mocapbench.codecs import create
    from mocapbench.codecs.model_file import load_model

    if getattr(args, "model", None):
        return load_model(args.model, settings, codec_name=args.codec)
    return create(args.codec, **settings)


def decoding_codec(args, header):
    """The codec that decodes a stream of ``header``: the registered one, or the one of ``--model``."""
    from mocapbench.codecs import create
    from mocapbench.codecs.model_file import load_model

    if getattr(args, "model", None):
        return load_model(args.model, codec_name=header.codec)
    return create(header.codec)


def codec_for_stream(data: bytes):
    """The registered codec named in the header of stream ``data``, and the header."""
    from mocapbench.codecs import create
    from mocapbench.codecs.container import read_header

    header, _ = read_header(data)
    return create(header.codec), header
