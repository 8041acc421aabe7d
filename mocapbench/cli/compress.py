"""``mocapbench compress IN OUT.mcb --codec NAME``: encode a motion file into a bitstream.

``--model MODEL`` codes with a model written by ``fit``; ``--max-error-cm E`` runs the rate search
(:mod:`mocapbench.ratesearch`) over the codec's main knob.

``--limit NAME=N`` sets the limits the input is read under (frames x joints checked before the reader
allocates, as ``decompress`` checks a stream's header). The stream written is decoded back to measure its
errors under these limits raised to what the motion just read needs: a capture that was read is never thrown
away after encoding for want of a limit.
"""

from __future__ import annotations

from typing import Any

from mocapbench.cli.arguments import (
    CliError,
    add_limit_argument,
    add_motion_arguments,
    codec_of,
    limits_of,
    load_motion,
    settings_of,
)

__all__ = ["add_parser", "compress_motion", "run"]


def run(args) -> None:
    """Encode ``args.input`` into ``args.output``; print the sizes, the ratio and the errors."""
    from mocapbench.codecs.limits import using_limits
    from mocapbench.io.safe_output import check_output, write_bytes
    from mocapbench.io.units import unit_label
    from mocapbench.metrics import compression_ratio, raw_position_bytes

    _refuse_motion_suffix(args.output)
    output = check_output(args.output, force=args.force)
    limits = limits_of(args)
    with using_limits(limits):
        motion = load_motion(args)
    # Decoding back what was just encoded: the motion is in memory, so its own size is admitted.
    with using_limits(limits.admitting(motion.num_frames, motion.num_joints, codes_rotations=True)):
        codec, data, worst, mean, note = compress_motion(args, motion)
    write_bytes(output, data, force=args.force)
    raw = raw_position_bytes(motion.num_joints, motion.num_frames)
    print(
        f"{output}: {len(data)} bytes, {motion.num_frames} frames x {motion.num_joints} joints, "
        f"{compression_ratio(raw, len(data)):.1f}:1 against float32 positions ({args.codec}"
        f"{_model_text(args, codec, raw, len(data))}); "
        f"source unit {unit_label(motion.source_unit_cm)}, {motion.up_axis} up; "
        f"L-inf {worst:.3f} cm, mean {mean:.3f} cm{note}"
    )


def _refuse_motion_suffix(output: str) -> None:
    """``compress`` writes a bitstream: an output named like a motion file would hide it under a lie."""
    from pathlib import Path

    from mocapbench.io.formats import READ_SUFFIXES

    suffix = Path(output).suffix.lower()
    if suffix in READ_SUFFIXES:
        raise CliError(f"{output}: compress writes a bitstream, not a {suffix} motion file; name the output "
                       f"{Path(output).with_suffix('.mcb').name} (`mocapbench decompress` writes {suffix})")


def _model_text(args, codec, raw_bytes: int, stream_bytes: int) -> str:
    """What the ratio leaves out: the model a decoder needs beside the stream, its bytes and the ratio with it."""
    from mocapbench.metrics import compression_ratio

    model_bytes = int(codec.model_bytes)
    if model_bytes <= 0:
        return ""
    where = (f"model {args.model}, fit elsewhere" if getattr(args, "model", None)
             else "the model shipped with the package")
    with_model = compression_ratio(raw_bytes, stream_bytes + model_bytes)
    return f"; the decoder also needs {where}: {model_bytes:,} bytes, {with_model:.1f}:1 with them"


def compress_motion(args, motion) -> tuple[Any, bytes, float, float, str]:
    """Encode ``motion`` as ``compress`` asks: ``(codec, stream, L-inf cm, mean cm, note)``.

    With ``--max-error-cm`` the rate search picks the codec's main knob; the note says what it chose. The errors
    are those of the stream written (decoded and measured here).
    """
    from mocapbench import metrics
    from mocapbench.ratesearch import search

    settings = settings_of(args)
    codec = codec_of(args, settings)
    bound = getattr(args, "max_error_cm", None)
    if bound is None:
        data = codec.encode(motion)
        decoded = codec.decode(data).positions
        worst = metrics.max_joint_error(motion.positions(), decoded)
        mean = metrics.mean_joint_error(motion.positions(), decoded)
        note = ""
    else:
        prepare = None
        if getattr(args, "model", None):
            state = codec.model_state()
            settings = codec.config.as_dict()
            prepare = lambda fresh: fresh.load_model_state(state)  # noqa: E731
        result = search(args.codec, motion, bound, settings, prepare=prepare)
        if not result.met:
            chosen = ", ".join(f"{key}={value}" for key, value in result.settings.items())
            raise ValueError(
                f"{args.codec} cannot reach L-inf <= {bound:g} cm on {motion.name or args.input}: the closest "
                f"setting ({chosen}) gives {result.max_error_cm:.3f} cm"
            )
        codec, data, worst, mean = result.codec, result.data, result.max_error_cm, result.mean_error_cm
        how = "guaranteed" if result.exact else f"rate search, {result.tries} tries"
        note = f"; {', '.join(f'{k}={v:.6g}' if isinstance(v, float) else f'{k}={v}' for k, v in result.settings.items())} ({how})"
    mode = codec.last_encode_stats.get("model_mode", "")
    if mode.startswith("untrained"):
        note += f"; {mode}"
    return codec, data, worst, mean, note


def add_parser(commands) -> None:
    """Register ``compress`` on the CLI's sub-parsers."""
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
    add_limit_argument(compress, reading="the input file")
    compress.set_defaults(run=run)
