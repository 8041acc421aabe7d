"""``mocapbench`` command line: compress, decompress, inspect, codecs.

Errors are one line on stderr and exit code 2; an existing output file is never overwritten without ``--force``.
"""

from __future__ import annotations

import argparse
import ast
import sys
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


def _load_motion(args) -> "Motion":  # noqa: F821
    from mocapbench.io import find_asf, read_amc, read_bvh

    source = Path(args.input)
    if not source.exists():
        raise CliError(f"{source}: no such file")
    suffix = source.suffix.lower()
    if suffix == ".bvh":
        return read_bvh(source, length_unit_cm=args.length_unit_cm, drop_first_frame=args.drop_first_frame)
    if suffix == ".amc":
        asf = Path(args.asf) if args.asf else find_asf(source)
        return read_amc(source, asf)
    raise CliError(f"{source}: expected a .bvh or .amc file, got {suffix or 'no extension'}")


def _codec_for_stream(data: bytes):
    from mocapbench.codecs import create
    from mocapbench.codecs.container import read_header

    header, _ = read_header(data)
    return create(header.codec), header


def _compress(args) -> None:
    from mocapbench.codecs import create
    from mocapbench.io.safe_output import check_output, write_bytes
    from mocapbench.metrics import compression_ratio, raw_position_bytes

    output = check_output(args.output, force=args.force)
    motion = _load_motion(args)
    codec = create(args.codec, **_parse_settings(args.set))
    data = codec.encode(motion)
    write_bytes(output, data, force=args.force)
    raw = raw_position_bytes(motion.num_joints, motion.num_frames)
    print(
        f"{output}: {len(data)} bytes, {motion.num_frames} frames x {motion.num_joints} joints, "
        f"{compression_ratio(raw, len(data)):.1f}:1 against float32 positions ({args.codec})"
    )


def _decompress(args) -> None:
    from mocapbench.io import write_bvh
    from mocapbench.io.safe_output import check_output, save_npy

    output = check_output(args.output, force=args.force)
    suffix = output.suffix.lower()
    if suffix not in (".npy", ".bvh"):
        raise CliError(f"{output}: expected a .bvh or .npy output, got {suffix or 'no extension'}")
    data = Path(args.input).read_bytes()
    codec, _ = _codec_for_stream(data)
    decoded = codec.decode(data)
    if suffix == ".npy":
        save_npy(output, decoded.positions, force=args.force)
    else:
        if decoded.motion is None:
            raise CliError(f"codec {codec.name!r} codes joint positions only; write positions with a .npy output")
        write_bvh(decoded.motion, output, length_unit_cm=args.length_unit_cm, overwrite=args.force)
    print(f"{output}: {decoded.positions.shape[0]} frames x {decoded.positions.shape[1]} joints")


def _inspect(args) -> None:
    from mocapbench.codecs.container import read_header
    from mocapbench.metrics import bits_per_joint_frame, compression_ratio, raw_position_bytes

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
    from mocapbench.codecs import CODECS

    for name in sorted(CODECS):
        cls = CODECS[name]
        print(f"{name}: {(cls.__doc__ or '').strip().splitlines()[0]}")
        for line in cls.Config.describe_fields().splitlines():
            print(f"    {line}")


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="mocapbench", description=__doc__.splitlines()[0])
    commands = parser.add_subparsers(dest="command", required=True)

    compress = commands.add_parser("compress", help="encode a BVH or AMC file into a .mcb bitstream")
    compress.add_argument("input", help="IN.bvh or IN.amc")
    compress.add_argument("output", help="OUT.mcb")
    compress.add_argument("--codec", required=True, help="registry name (see `mocapbench codecs`)")
    compress.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="a codec config field")
    compress.add_argument("--asf", help="skeleton of an AMC input (default: the .asf beside it)")
    compress.add_argument("--length-unit-cm", type=float, default=1.0, help="cm per BVH length unit (CMU: 5.6444)")
    compress.add_argument("--drop-first-frame", action="store_true", help="drop BVH frame 0 (CMU reference pose)")
    compress.add_argument("--force", action="store_true", help="overwrite OUT if it exists")
    compress.set_defaults(run=_compress)

    decompress = commands.add_parser("decompress", help="decode a .mcb into BVH (rotation codecs) or .npy positions")
    decompress.add_argument("input", help="IN.mcb")
    decompress.add_argument("output", help="OUT.bvh or OUT.npy")
    decompress.add_argument("--length-unit-cm", type=float, default=1.0, help="cm per BVH length unit to write")
    decompress.add_argument("--force", action="store_true", help="overwrite OUT if it exists")
    decompress.set_defaults(run=_decompress)

    inspect = commands.add_parser("inspect", help="print a bitstream's header, sizes and codec parameters")
    inspect.add_argument("input", help="IN.mcb")
    inspect.set_defaults(run=_inspect)

    listing = commands.add_parser("codecs", help="list the registered codecs and their parameters")
    listing.set_defaults(run=_list_codecs)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``mocapbench`` command; returns the exit code."""
    args = _parser().parse_args(argv)
    from mocapbench.codecs import BitstreamError
    from mocapbench.motion import MotionFormatError

    try:
        args.run(args)
    except CliError as error:
        print(f"mocapbench: error: {error}", file=sys.stderr)
        return 2
    except (BitstreamError, MotionFormatError, OSError) as error:
        # OSError: the safe-output refusals (an existing path or link, a missing folder) and the system's own
        # (a full disk, no permission), whose str() is one line naming the file.
        print(f"mocapbench: error: {error}", file=sys.stderr)
        return 2
    except (KeyError, TypeError, ValueError) as error:
        message = error.args[0] if isinstance(error, KeyError) and error.args else error
        print(f"mocapbench: error: {message}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
