"""``mocapbench decompress IN.mcb OUT``: decode a bitstream into BVH/glTF (rotation codecs) or ``.npy`` positions."""

from __future__ import annotations

from pathlib import Path

from mocapbench.cli.arguments import (
    CliError,
    add_limit_argument,
    add_motion_arguments,
    codec_for_stream,
    decoding_codec,
    limits_of,
)

__all__ = ["add_parser", "run"]


def run(args) -> None:
    """Decode ``args.input`` into ``args.output`` (the unit recorded in the stream unless ``--units``)."""
    import dataclasses

    from mocapbench.io.formats import WRITE_SUFFIXES, write_motion
    from mocapbench.io.safe_output import check_output, save_npy
    from mocapbench.io.units import canonical_unit_cm, parse_units, unit_label

    output = check_output(args.output, force=args.force)
    suffix = output.suffix.lower()
    if suffix not in (".npy", *WRITE_SUFFIXES):
        expected = ", ".join((*WRITE_SUFFIXES, ".npy"))
        raise CliError(f"{output}: expected a {expected} output, got {suffix or 'no extension'}")
    limits = limits_of(args)
    data = Path(args.input).read_bytes()
    codec, header = codec_for_stream(data)
    if args.model:
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


def add_parser(commands) -> None:
    """Register ``decompress`` on the CLI's sub-parsers."""
    decompress = commands.add_parser(
        "decompress", help="decode a .mcb into BVH/glTF (rotation codecs) or .npy positions"
    )
    decompress.add_argument("input", help="IN.mcb")
    decompress.add_argument("output", help="OUT.bvh, OUT.gltf, OUT.glb (rotation codecs) or OUT.npy (positions)")
    add_motion_arguments(decompress, writing=True)
    decompress.add_argument("--force", action="store_true", help="overwrite OUT if it exists")
    add_limit_argument(decompress, reading="the decode")
    decompress.add_argument("--model", help="MODEL.npz the stream was coded with (`compress --model`)")
    decompress.set_defaults(run=run)
