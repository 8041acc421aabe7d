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
    "add_limit_argument",
    "add_motion_arguments",
    "add_motion_options",
    "codec_for_stream",
    "codec_of",
    "decoding_codec",
    "limits_of",
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


def add_motion_arguments(parser: argparse.ArgumentParser, *, writing: bool = False, many: bool = False) -> None:
    """Add ``--units`` (alias ``--length-unit-cm``) and, when reading, ``--up`` and ``--strict`` to a sub-command.

    Parameters
    ----------
    writing : bool
        The command writes motion (``decompress``): ``--units`` is the unit to write, default the stream's.
    many : bool
        The command reads many files (``fit``, ``compare``): ``--units`` may be repeated and name a file
        (``--units walk.bvh:inch``), see :mod:`mocapbench.io.unit_choice`.
    """
    what = "to write (default: the source unit recorded in the stream)" if writing else (
        "of the input (default: the file's FILE.units sidecar, else cm for BVH, m for glTF, the file's own for AMC "
        "and FBX)"
    )
    per_file = "; FILE:UNIT for one file (repeatable)" if many else ""
    parser.add_argument(
        "--units",
        "--length-unit-cm",
        dest="units",
        default=None,
        action="append" if many else "store",
        metavar="UNIT",
        help=f"length unit {what}: cm, mm, m, inch, cmu (CMU, 5.6444 cm) or a number of cm per unit{per_file}",
    )
    if not writing:
        parser.add_argument("--up", default=None, choices=("y", "z", "x"),
                            help="up axis (default: the sidecar's, else detected from the frames)")
        parser.add_argument("--strict", action="store_true",
                            help="a unit warning (a body that is not a body's size in the unit read) is an error")


def add_limit_argument(parser: argparse.ArgumentParser, *, reading: str) -> None:
    """Add ``--limit NAME=N`` (repeatable): the :class:`~mocapbench.codecs.limits.DecodeLimits` of the command.

    Parameters
    ----------
    reading : str
        What the limits bound in this command, for the help (``"the input file and the stream written"``).
    """
    parser.add_argument(
        "--limit",
        action="append",
        default=[],
        metavar="NAME=N",
        help=f"raise or lower a limit on {reading}: frames, joints, output_bytes (default 2 GiB of arrays), "
             f"ik_iterations",
    )


def limits_of(args) -> "DecodeLimits":  # noqa: F821
    """The command's limits from its ``--limit`` values (the defaults without any)."""
    from mocapbench.codecs.limits import DecodeLimits

    return DecodeLimits.from_settings(getattr(args, "limit", None) or [])


def add_motion_options(parser: argparse.ArgumentParser) -> None:
    """The motion reader's options (as on ``compress``), for sub-commands that read many clips."""
    parser.add_argument("--asf", help="skeleton of AMC inputs (default: the .asf beside each)")
    add_motion_arguments(parser, many=True)
    parser.add_argument("--fps", type=float, help="sampling rate of glTF animations / frame rate of AMC files")
    parser.add_argument("--drop-first-frame", action="store_true", help="drop BVH frame 0 (CMU reference pose)")
    parser.add_argument("--no-recurse", action="store_true", help="read a folder's own files only, not its subfolders")


def _read(args, path: str, units=None) -> tuple["Motion", list[str]]:  # noqa: F821
    from mocapbench.io.formats import read_motion

    return read_motion(
        path,
        units=units,
        up=args.up,
        asf=getattr(args, "asf", None),
        drop_first_frame=getattr(args, "drop_first_frame", False),
        fps=getattr(args, "fps", None),
        strict=getattr(args, "strict", False),
    )


def load_motion(args, path: str | None = None) -> "Motion":  # noqa: F821
    """Read the input motion with ``--units``/``--up`` (mocapbench.io.formats); warnings go to stderr, one line each.

    Under ``--strict`` a warning is an error (:class:`mocapbench.io.formats.UnitCheckError`, exit 2).
    """
    motion, warnings = _read(args, path or args.input, args.units)
    for warning in warnings:
        print(f"mocapbench: warning: {warning}", file=sys.stderr)
    return motion


def read_clips(args: argparse.Namespace, paths: list[str], *, verdicts: bool = False):
    """The motions of ``paths`` (files, or folders of motion files of every format, searched recursively unless
    ``--no-recurse``), each read with its own unit (``--units FILE:UNIT``, its sidecar, ``--units``;
    :class:`mocapbench.io.unit_choice.UnitChoice`).

    A file that cannot be read is skipped with one line on stderr naming it and why; under ``--strict`` a unit
    warning is an error for the whole command, not a skipped file.

    Returns
    -------
    list of Motion, or (motions, verdicts) with ``verdicts``
        ``verdicts``: one line per file read (:func:`mocapbench.io.unit_choice.verdict`).

    Raises
    ------
    ValueError
        No readable motion at all, or a ``--units FILE:UNIT`` that names no file read.
    """
    import dataclasses

    from mocapbench.io.format_table import motion_files
    from mocapbench.io.formats import UnitCheckError
    from mocapbench.io.unit_choice import UnitChoice, read_sidecar, verdict

    choice = UnitChoice.parse(args.units, args.up)
    files = motion_files(paths, recurse=not getattr(args, "no_recurse", False))
    unmatched = choice.unmatched(files)
    if unmatched:
        raise CliError(f"--units {unmatched[0]}:...: no file of {', '.join(paths)} is named {unmatched[0]}")
    motions, lines = [], []
    for file in files:
        units, unit_source = choice.units_for(file)
        try:
            motion, warnings = _read(args, str(file), units)
        except UnitCheckError:
            raise
        except Exception as error:  # noqa: BLE001 - any file a reader refuses is skipped, named, and the rest read
            message = error.args[0] if isinstance(error, KeyError) and error.args else error
            print(f"mocapbench: skipped {file}: {message}", file=sys.stderr)
            continue
        for warning in warnings if not verdicts else []:
            print(f"mocapbench: warning: {warning}", file=sys.stderr)
        if not motion.name:
            motion = dataclasses.replace(motion, name=file.stem)
        motions.append(motion)
        if verdicts:
            up_source = ("--up" if args.up else "sidecar" if "up" in read_sidecar(file) else
                         "the file" if file.suffix.lower() in (".gltf", ".glb", ".fbx") else None)
            lines.append(verdict(file, motion, unit_source, up_source, warnings))
    if not motions:
        raise ValueError(f"no readable motion in {', '.join(paths)} (formats read: .bvh, .amc, .gltf, .glb, .fbx)")
    return (motions, lines) if verdicts else motions


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
