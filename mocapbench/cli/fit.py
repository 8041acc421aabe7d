"""``mocapbench fit CLIPS... -o MODEL``: fit a learned codec's model on the user's clips and write it.

The clips are files or folders of motion files (an unreadable file is skipped with one line naming it); one model
is fit for their skeleton and written (:mod:`mocapbench.codecs.model_file`). ``compress --model MODEL`` codes
with it; ``decompress --model MODEL`` decodes with it.
"""

from __future__ import annotations

from mocapbench.cli.arguments import add_motion_options, read_clips, settings_of

__all__ = ["add_parser", "run"]


def run(args) -> None:
    """Fit ``args.codec`` on ``args.clips`` and write the model to ``args.output``."""
    from mocapbench.codecs.model_file import fit_codec, save_model

    motions = read_clips(args, args.clips)
    codec = fit_codec(args.codec, settings_of(args), motions)
    path = save_model(codec, args.output, force=args.force)
    frames = sum(motion.num_frames for motion in motions)
    print(
        f"{path}: {args.codec} model for {motions[0].num_joints} joints, fit on {len(motions)} clip(s), "
        f"{frames} frames; {codec.model_bytes} bytes of learned state"
    )


def add_parser(commands) -> None:
    """Register ``fit`` on the CLI's sub-parsers."""
    fit = commands.add_parser("fit", help="fit a learned codec's model on your clips (one skeleton)")
    fit.add_argument("clips", nargs="+", help="motion files, or folders of them (.bvh, .amc, ...)")
    fit.add_argument("-o", "--output", required=True, help="MODEL.npz to write")
    fit.add_argument("--codec", default="mcb-linf", help="codec to fit (mcb-linf, lsdt-clip, lsdt-frame)")
    fit.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="a codec config field")
    fit.add_argument("--force", action="store_true", help="overwrite MODEL if it exists")
    add_motion_options(fit)
    fit.set_defaults(run=run)
