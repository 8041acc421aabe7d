"""``mocapbench inspect IN``: a bitstream's header, sizes and codec parameters, or a motion file's unit and up axis."""

from __future__ import annotations

from pathlib import Path

from mocapbench.cli.arguments import add_limit_argument, add_motion_arguments, codec_for_stream, limits_of, load_motion

__all__ = ["add_parser", "run"]


def inspect_motion(args) -> None:
    """``inspect`` of a motion file: size, unit, up axis (and why), rest height."""
    from mocapbench.io.units import body_shape, detect_up_axis, rest_up_axis, unit_label

    motion = load_motion(args)
    axis, reason = detect_up_axis(motion)
    from_file = Path(args.input).suffix.lower() in (".gltf", ".glb", ".fbx")  # these formats say their up axis
    facts = {
        "frames": motion.num_frames,
        "joints": motion.num_joints,
        "fps": motion.fps,
        "source unit": unit_label(motion.source_unit_cm) + ("" if args.units else f" ({_unit_source(args.input)})"),
        "up axis": f"{motion.up_axis} (given)" if args.up else f"{motion.up_axis} (from the file)" if from_file
        else f"{axis} (detected: {reason})",
    }
    rest_axis = rest_up_axis(motion)
    shape = body_shape(motion.skeleton, rest_axis)
    turned = "" if rest_axis == motion.up_axis else f", along the rest pose's {rest_axis} (its root turns it up)"
    facts["rest height"] = f"{shape.stature_cm:.1f} cm{turned}"
    if shape.legs == 2:
        facts["hips"] = f"{shape.hip_fraction:.0%} of the rest height" + (" (an adult's proportions)"
                                                                          if shape.adult_human else "")
    width = max(len(key) for key in facts)
    for key, value in facts.items():
        print(f"{key:<{width}}  {value}")


def _unit_source(path: str) -> str:
    """Where the unit of a file read without ``--units`` came from: its sidecar, or what its format declares."""
    from mocapbench.io.formats import default_unit_source
    from mocapbench.io.unit_choice import read_sidecar, sidecar_path

    if "units" in read_sidecar(path):
        return f"sidecar {sidecar_path(path).name}"
    return default_unit_source(path)


def run(args) -> None:
    """Print the facts of a stream, or of a motion file (by its suffix)."""
    from mocapbench.codecs.limits import using_limits
    from mocapbench.io.formats import READ_SUFFIXES
    from mocapbench.io.units import unit_label
    from mocapbench.metrics import bits_per_joint_frame, compression_ratio, raw_position_bytes

    limits = limits_of(args)
    if Path(args.input).suffix.lower() in READ_SUFFIXES:
        with using_limits(limits):
            inspect_motion(args)
        return
    data = Path(args.input).read_bytes()
    codec, _ = codec_for_stream(data)
    # The header is checked against the limits before the payload is described, as decompress checks it.
    header, described = codec.describe(data, limits=limits)
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
    facts.update(described)
    width = max(len(key) for key in facts)
    for key, value in facts.items():
        print(f"{key:<{width}}  {value}")


def add_parser(commands) -> None:
    """Register ``inspect`` on the CLI's sub-parsers."""
    inspect = commands.add_parser(
        "inspect", help="print a bitstream's header, sizes and codec parameters, or a motion file's unit and up axis"
    )
    inspect.add_argument("input", help="IN.mcb, or a motion file (.bvh, .amc, .gltf, .glb, .fbx)")
    add_motion_arguments(inspect)
    inspect.add_argument("--asf", help="skeleton of an AMC input (default: the .asf beside it)")
    add_limit_argument(inspect, reading="the stream or the motion file read")
    inspect.set_defaults(run=run)
