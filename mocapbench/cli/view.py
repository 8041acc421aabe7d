"""``mocapbench view FILE [--against ORIGINAL] [-o OUT.html]``: a player page for a motion file or a stream.

FILE is a motion file (BVH, AMC, glTF, GLB, FBX) or a ``.mcb`` stream (told apart by the stream's magic bytes).
With ``--against ORIGINAL`` the page plays ORIGINAL (grey) under FILE (blue), every joint coloured by its error,
the worst frame marked (:mod:`mocapbench.experiments.player`, the page the report writes); without it, FILE alone.
The page stands alone (its script inside it, no network). A stream of a codec that returns joint positions only
carries no skeleton: it needs ``--against`` for the bones.
"""

from __future__ import annotations

from pathlib import Path

from mocapbench.cli.arguments import CliError, add_motion_options, decoding_codec, load_motion

__all__ = ["add_parser", "run"]


def _is_stream(path: str) -> bool:
    from mocapbench.codecs.container import MAGIC

    with open(path, "rb") as handle:
        return handle.read(len(MAGIC)) == MAGIC


def _read(args, path: str):
    """``(positions (F, J, 3) cm, Motion or None, fps, up axis or None)`` of a motion file or a stream."""
    if not _is_stream(path):
        motion = load_motion(args, path)
        return motion.positions(), motion, motion.fps, motion.up_axis
    from mocapbench.codecs import DecodeLimits
    from mocapbench.codecs.container import read_header

    data = Path(path).read_bytes()
    header, _ = read_header(data)
    decoded = decoding_codec(args, header).decode(data, limits=DecodeLimits.from_settings(args.limit))
    up = header.up_axis if header.up_axis != "?" else None
    return decoded.positions, decoded.motion, header.fps, up


def run(args) -> None:
    """Write the player page of ``args.input`` (against ``args.against`` if given) to ``args.output``."""
    from mocapbench.experiments.player import PlayerEntry, player_html
    from mocapbench.io.safe_output import check_output, write_text

    output = check_output(args.output or f"{args.input}.html", force=args.force)
    positions, motion, fps, up = _read(args, args.input)
    if args.against is None:
        if motion is None:
            raise CliError(f"{args.input}: the stream holds joint positions only (no skeleton): give "
                           "--against ORIGINAL for its bones")
        original, decoded, skeleton = positions, None, motion.skeleton
        label = f"{Path(args.input).name}, {positions.shape[0]} frames at {fps:g} fps"
    else:
        original, reference, ref_fps, ref_up = _read(args, args.against)
        if reference is None:
            raise CliError(f"{args.against}: ORIGINAL must carry a skeleton (a motion file or a rotation stream)")
        if original.shape != positions.shape:
            raise CliError(f"{args.input} has {positions.shape[0]} frames x {positions.shape[1]} joints, "
                           f"{args.against} {original.shape[0]} x {original.shape[1]}: they must match")
        decoded, skeleton, fps, up = positions, reference.skeleton, ref_fps, ref_up or up
        label = f"{Path(args.input).name} against {Path(args.against).name}, {positions.shape[0]} frames at {fps:g} fps"
    entry = PlayerEntry(label, skeleton.names, skeleton.parents, fps, up or "y", original, decoded)
    intro = ["Original (grey) and decoded (blue) overlaid, each decoded joint coloured by its error (green 0, red "
             "the largest); the right half magnifies the worst joint. Keys: space plays, arrows step."
             if decoded is not None else "One motion, no error to show. Keys: space plays, arrows step."]
    write_text(output, player_html(f"mocapbench view: {Path(args.input).name}", [entry], intro=intro),
               force=args.force)
    print(f"{output}: player page of {label}")


def add_parser(commands) -> None:
    """Register ``view`` on the CLI's sub-parsers."""
    view = commands.add_parser("view", help="write a player page (HTML) of a motion file or a .mcb stream")
    view.add_argument("input", help="FILE: a BVH, AMC, glTF, GLB or FBX file, or a .mcb stream")
    view.add_argument("--against", metavar="ORIGINAL", help="the original motion: play FILE over it, errors coloured")
    view.add_argument("-o", "--output", help="the page to write (default FILE.html)")
    view.add_argument("--force", action="store_true", help="overwrite OUT if it exists")
    view.add_argument("--model", help="model file of a codec that needs one (decoding a stream)")
    view.add_argument("--limit", action="append", default=[], metavar="NAME=N",
                      help="decode limit of a stream, as on decompress (repeatable)")
    add_motion_options(view)
    view.set_defaults(run=run)
