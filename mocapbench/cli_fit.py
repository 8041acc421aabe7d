"""``mocapbench fit CLIPS... -o MODEL``, and the codec a ``compress``/``decompress`` uses (``--model``,
``--max-error-cm``).

``fit`` reads the clips (files or folders of motion files; an unreadable file is skipped with one line naming it),
fits one model for their skeleton and writes it (:mod:`mocapbench.codecs.model_file`). ``compress --model MODEL``
codes with it; ``decompress --model MODEL`` decodes with it. ``compress --max-error-cm E`` runs the rate search
(:mod:`mocapbench.ratesearch`) over the codec's main knob.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

__all__ = ["add_fit_parser", "compress_motion", "decoding_codec", "read_clips", "MOTION_SUFFIXES"]

#: Files a folder argument contributes (other files in it are ignored).
MOTION_SUFFIXES = (".bvh", ".amc", ".gltf", ".glb")


def read_clips(args: argparse.Namespace, paths: list[str], load_motion) -> list:
    """The motions of ``paths`` (files, or folders whose motion files are read in name order).

    A file that cannot be read is skipped with one line on stderr naming it and why. ``load_motion(namespace)`` is
    the CLI's reader (``args`` with ``input`` set to one file).

    Raises
    ------
    ValueError
        No readable motion at all.
    """
    files: list[Path] = []
    for path in map(Path, paths):
        if path.is_dir():
            files += sorted(p for p in path.iterdir() if p.is_file() and p.suffix.lower() in MOTION_SUFFIXES)
        else:
            files.append(path)
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


def _settings(args) -> dict[str, Any]:
    from mocapbench.cli import _parse_settings

    return _parse_settings(getattr(args, "set", []) or [])


def _fit(args) -> None:
    from mocapbench.cli import _load_motion
    from mocapbench.codecs.model_file import fit_codec, save_model

    motions = read_clips(args, args.clips, _load_motion)
    codec = fit_codec(args.codec, _settings(args), motions)
    path = save_model(codec, args.output, force=args.force)
    frames = sum(motion.num_frames for motion in motions)
    print(
        f"{path}: {args.codec} model for {motions[0].num_joints} joints, fit on {len(motions)} clip(s), "
        f"{frames} frames; {codec.model_bytes} bytes of learned state"
    )


def _codec(args, settings: dict[str, Any]):
    """The codec of ``args.codec`` with ``settings``, holding ``args.model`` if given."""
    from mocapbench.codecs import create
    from mocapbench.codecs.model_file import load_model

    if getattr(args, "model", None):
        return load_model(args.model, settings, codec_name=args.codec)
    return create(args.codec, **settings)


def compress_motion(args, motion) -> tuple[Any, bytes, float, float, str]:
    """Encode ``motion`` as ``compress`` asks: ``(codec, stream, L-inf cm, mean cm, note)``.

    With ``--max-error-cm`` the rate search picks the codec's main knob; the note says what it chose. The errors
    are those of the stream written (decoded and measured here).
    """
    from mocapbench import metrics
    from mocapbench.ratesearch import search

    settings = _settings(args)
    codec = _codec(args, settings)
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


def decoding_codec(args, header):
    """The codec that decodes a stream of ``header``: the registered one, or the one of ``--model``."""
    from mocapbench.codecs import create
    from mocapbench.codecs.model_file import load_model

    if getattr(args, "model", None):
        return load_model(args.model, codec_name=header.codec)
    return create(header.codec)


def add_fit_parser(commands, add_motion_options) -> None:
    """Register ``fit`` on the CLI's sub-parsers; ``add_motion_options(parser)`` adds the motion reader's options."""
    fit = commands.add_parser("fit", help="fit a learned codec's model on your clips (one skeleton)")
    fit.add_argument("clips", nargs="+", help="motion files, or folders of them (.bvh, .amc, ...)")
    fit.add_argument("-o", "--output", required=True, help="MODEL.npz to write")
    fit.add_argument("--codec", default="mcb-linf", help="codec to fit (mcb-linf, lsdt-clip, lsdt-frame)")
    fit.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="a codec config field")
    fit.add_argument("--force", action="store_true", help="overwrite MODEL if it exists")
    add_motion_options(fit)
    fit.set_defaults(run=_fit)
