"""``mocapbench`` command line: compress, decompress, inspect, codecs.

Errors are one line on stderr and exit code 2; an existing output file is never overwritten without ``--force``.

Start-up is kept short (``mocapbench --help`` imports nothing beyond the standard library, ``codecs`` no scipy,
torch, pandas, matplotlib or Hydra): this module imports only the standard library at the top, and each command
imports what it needs when it runs. A new subcommand keeps its code in its own module and registers here with
``set_defaults(run=_lazy("package.module", "function"))``, so its imports cost nothing to the other commands
(``tests/test_cli_startup.py`` checks which modules each command loads; ``mocapbench.benchmarks.cli_startup``
measures it).
"""

from __future__ import annotations

import argparse
import ast
import importlib
import sys
from collections.abc import Callable
from pathlib import Path

__all__ = ["main"]


class CliError(Exception):
    """A user-facing error: printed as one line, no traceback."""


def _parse_value(text: str):
    """``--set`` values: Python/YAML-like literals (``12``, ``0.5``, ``true``, ``bone``)."""
    lowered = text.strip().lower()
    if lowered in ("true", "false"):
        return lowered == "true"
    try:
        return ast.literal_eval(text)
    except (ValueError, SyntaxError):
        return text


def _parse_settings(pairs: list[str]) -> dict:
    settings = {}
    for pair in pairs:
        key, sep, value = pair.partition("=")
        if not sep or not key:
            raise CliError(f"--set expects key=value, got {pair!r}")
        settings[key.strip()] = _parse_value(value)
    return settings


def _load_motion(args, path: str | None = None) -> "Motion":  # noqa: F821
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


def _codec_for_stream(data: bytes):
    from mocapbench.codecs import create
    from mocapbench.codecs.container import read_header

    header, _ = read_header(data)
    return create(header.codec), header


def _compress(args) -> None:
    from mocapbench.cli_fit import compress_motion
    from mocapbench.io.safe_output import check_output, write_bytes
    from mocapbench.io.units import unit_label
    from mocapbench.metrics import compression_ratio, raw_position_bytes

    output = check_output(args.output, force=args.force)
    motion = _load_motion(args)
    codec, data, worst, mean, note = compress_motion(args, motion)
    write_bytes(output, data, force=args.force)
    raw = raw_position_bytes(motion.num_joints, motion.num_frames)
    print(
        f"{output}: {len(data)} bytes, {motion.num_frames} frames x {motion.num_joints} joints, "
        f"{compression_ratio(raw, len(data)):.1f}:1 against float32 positions ({args.codec}); "
        f"source unit {unit_label(motion.source_unit_cm)}, {motion.up_axis} up; "
        f"L-inf {worst:.3f} cm, mean {mean:.3f} cm{note}"
    )


def _decompress(args) -> None:
    import dataclasses

    from mocapbench.io.formats import WRITE_SUFFIXES, write_motion
    from mocapbench.codecs import DecodeLimits
    from mocapbench.io.safe_output import check_output, save_npy
    from mocapbench.io.units import canonical_unit_cm, parse_units, unit_label

    output = check_output(args.output, force=args.force)
    suffix = output.suffix.lower()
    if suffix not in (".npy", *WRITE_SUFFIXES):
        expected = ", ".join((*WRITE_SUFFIXES, ".npy"))
        raise CliError(f"{output}: expected a {expected} output, got {suffix or 'no extension'}")
    limits = DecodeLimits.from_settings(args.limit)
    data = Path(args.input).read_bytes()
    codec, header = _codec_for_stream(data)
    if args.model:
        from mocapbench.cli_fit import decoding_codec

        codec = decoding_codec(args, header)
    decoded = codec.decode(data, limits=limits)
    # Written in the source unit recorded in the stream unless --units says otherwise.
    unit_cm = parse_units(args.units) if args.units is not None else canonical_unit_cm(header.source_unit_cm)
    if suffix == ".npy":
        save_npy(output, decoded.positions / unit_cm, force=args.force)
        unit = unit_label(unit_cm)
    else:
        if decoded.motion is None:
            raise CliError(f"codec {codec.name!r} codes joint positions only; write positions with a .npy output")
        up_axis = header.up_axis if header.up_axis != "?" else "y"
        motion = dataclasses.replace(decoded.motion, source_unit_cm=unit_cm, up_axis=up_axis)
        write_motion(motion, output, units=args.units, force=args.force)
        unit = "m, Y-up (glTF)" if suffix in (".gltf", ".glb") and args.units is None else unit_label(unit_cm)
    print(f"{output}: {decoded.positions.shape[0]} frames x {decoded.positions.shape[1]} joints, lengths in {unit}")


def _inspect_motion(args) -> None:
    """``inspect`` of a motion file: size, unit, up axis (and why), rest height."""
    from mocapbench.io.units import detect_up_axis, rest_height_cm, unit_label

    motion = _load_motion(args)
    axis, reason = detect_up_axis(motion)
    from_file = Path(args.input).suffix.lower() in (".gltf", ".glb", ".fbx")  # these formats say their up axis
    facts = {
        "frames": motion.num_frames,
        "joints": motion.num_joints,
        "fps": motion.fps,
        "source unit": unit_label(motion.source_unit_cm) + ("" if args.units else " (default; --units to change)"),
        "up axis": f"{motion.up_axis} (given)" if args.up else f"{motion.up_axis} (from the file)" if from_file
        else f"{axis} (detected: {reason})",
        "rest height": f"{rest_height_cm(motion.skeleton, motion.up_axis):.1f} cm",
    }
    width = max(len(key) for key in facts)
    for key, value in facts.items():
        print(f"{key:<{width}}  {value}")


def _inspect(args) -> None:
    from mocapbench.codecs.container import read_header
    from mocapbench.io.formats import READ_SUFFIXES
    from mocapbench.io.units import unit_label
    from mocapbench.metrics import bits_per_joint_frame, compression_ratio, raw_position_bytes

    if Path(args.input).suffix.lower() in READ_SUFFIXES:
        _inspect_motion(args)
        return
    data = Path(args.input).read_bytes()
    header, payload = read_header(data)
    codec, _ = _codec_for_stream(data)
    raw = raw_position_bytes(header.num_joints, header.num_frames)
    facts = {
        "codec": header.codec,
        "format version": header.version,
        "frames": header.num_frames,
        "joints": header.num_joints,
        "fps": header.fps,
        "source unit": unit_label(header.source_unit_cm) if header.version > 1 else "cm (format version 1)",
        "up axis": {"?": "unknown"}.get(header.up_axis, header.up_axis),
        "bytes": len(data),
        "header bytes": header.header_bytes,
        "payload bytes": header.payload_bytes,
        "compression ratio (float32 positions)": f"{compression_ratio(raw, len(data)):.2f}",
        "bits per joint per frame": f"{bits_per_joint_frame(len(data), header.num_joints, header.num_frames):.3f}",
    }
    facts.update(codec.describe_payload(header, payload))
    width = max(len(key) for key in facts)
    for key, value in facts.items():
        print(f"{key:<{width}}  {value}")


def _list_codecs(args) -> None:
    from mocapbench.codecs import CODECS, UNAVAILABLE

    for name in sorted(CODECS):
        cls = CODECS[name]
        print(f"{name}: {(cls.__doc__ or '').strip().splitlines()[0]}")
        for line in cls.Config.describe_fields().splitlines():
            print(f"    {line}")
    for name in sorted(set(UNAVAILABLE) - set(CODECS)):
        print(f"{name}: unavailable here: {UNAVAILABLE[name]}")


def _lazy(module: str, function: str) -> Callable[[argparse.Namespace], None]:
    """A command handler that imports ``module`` only when the command runs, then calls ``module.function(args)``."""

    def run(args: argparse.Namespace) -> None:
        getattr(importlib.import_module(module), function)(args)

    run.__qualname__ = f"{module}.{function}"
    return run


def _version() -> str:
    from mocapbench import __version__

    return f"mocapbench {__version__} (Python {sys.version.split()[0]})"


def _parser() -> argparse.ArgumentParser:
    from mocapbench.cli_units import add_motion_arguments

    parser = argparse.ArgumentParser(prog="mocapbench", description=__doc__.splitlines()[0])
    parser.add_argument("--version", action="version", version=_version())
    commands = parser.add_subparsers(dest="command", required=True)

    compress = commands.add_parser("compress", help="encode a BVH, AMC, glTF or FBX file into a .mcb bitstream")
    compress.add_argument("input", help="IN.bvh, IN.amc, IN.gltf, IN.glb or IN.fbx")
    compress.add_argument("output", help="OUT.mcb")
    compress.add_argument("--codec", required=True, help="registry name (see `mocapbench codecs`)")
    compress.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="a codec config field")
    compress.add_argument("--asf", help="skeleton of an AMC input (default: the .asf beside it)")
    add_motion_arguments(compress)
    compress.add_argument("--fps", type=float, help="sampling rate of a glTF animation / frame rate of an AMC file")
    compress.add_argument("--drop-first-frame", action="store_true", help="drop BVH frame 0 (CMU reference pose)")
    compress.add_argument("--force", action="store_true", help="overwrite OUT if it exists")
    compress.add_argument("--model", help="MODEL.npz written by `mocapbench fit` (learned codecs)")
    compress.add_argument("--max-error-cm", type=float, help="smallest stream with L-inf <= this (a rate search)")
    compress.set_defaults(run=_compress)

    decompress = commands.add_parser(
        "decompress", help="decode a .mcb into BVH/glTF (rotation codecs) or .npy positions"
    )
    decompress.add_argument("input", help="IN.mcb")
    decompress.add_argument("output", help="OUT.bvh, OUT.gltf, OUT.glb (rotation codecs) or OUT.npy (positions)")
    add_motion_arguments(decompress, writing=True)
    decompress.add_argument("--force", action="store_true", help="overwrite OUT if it exists")
    decompress.add_argument(
        "--limit",
        action="append",
        default=[],
        metavar="NAME=N",
        help="raise or lower a decode limit: frames, joints, output_bytes (default 2 GiB), ik_iterations",
    )
    decompress.add_argument("--model", help="MODEL.npz the stream was coded with (`compress --model`)")
    decompress.set_defaults(run=_decompress)

    inspect = commands.add_parser(
        "inspect", help="print a bitstream's header, sizes and codec parameters, or a motion file's unit and up axis"
    )
    inspect.add_argument("input", help="IN.mcb, or a motion file (.bvh, .amc, .gltf, .glb, .fbx)")
    add_motion_arguments(inspect)
    inspect.add_argument("--asf", help="skeleton of an AMC input (default: the .asf beside it)")
    inspect.set_defaults(run=_inspect)

    listing = commands.add_parser("codecs", help="list the registered codecs and their parameters")
    listing.set_defaults(run=_list_codecs)

    from mocapbench.experiments.plot_command import add_parser as add_plot_parser  # argparse only; plots load later

    add_plot_parser(commands)
    from mocapbench.cli_fit import add_fit_parser  # argparse only; codecs load when the command runs
    from mocapbench.compare import add_compare_parser

    add_fit_parser(commands, _motion_options)
    add_compare_parser(commands, _motion_options)
    return parser


def _motion_options(parser: argparse.ArgumentParser) -> None:
    """The motion reader's options (as on ``compress``), for sub-commands that read many clips."""
    from mocapbench.cli_units import add_motion_arguments

    parser.add_argument("--asf", help="skeleton of AMC inputs (default: the .asf beside each)")
    add_motion_arguments(parser)
    parser.add_argument("--fps", type=float, help="sampling rate of glTF animations / frame rate of AMC files")
    parser.add_argument("--drop-first-frame", action="store_true", help="drop BVH frame 0 (CMU reference pose)")


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


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``mocapbench`` command; returns the exit code."""
    args = _parser().parse_args(argv)
    try:
        args.run(args)
    except MemoryError:
        print("mocapbench: error: out of memory; lower the decode limits (--limit output_bytes=N)", file=sys.stderr)
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
