"""Every codec on the users' rigs, and what a T-pose frame or a cut costs each clip codec.

    python -m mocapbench.benchmarks.own_data [--codecs a,b,...] [--bound-cm 1.0] [--long] [--cuts-only]
        [--data-dir D] [--out FILE]

Prints, as markdown (and writes to ``--out`` if given):

1. **codec x case**: the compression ratio (float32 positions / stream bytes) at L-inf <= ``bound`` (1 cm) on each
   synthetic case of :func:`mocapbench.synthetic.rigs.user_cases` (15-70 joints, Y/Z-up, mm/m/inch/CMU units, every
   Euler order, 2 frames, a T-pose first frame, two takes; ``--long`` adds the 20,000-frame case), found by the rate
   search (:mod:`mocapbench.ratesearch`); or the one-line reason a codec cannot. Learned codecs appear twice: as
   shipped (no fit: ``mcb-linf`` then runs untrained on other skeletons, the LSDT codecs say they need a model) and
   ``+fit``, fit on the clip itself (in-sample; the model's bytes are not in the ratio). The neural codecs run with
   the reduced training of their smoke settings (200 iterations a round; ``fourier-mlp-int`` at its default K = 10,
   no search), to keep the table to minutes: their ratios are lower bounds of what full training gives.
2. **T-pose and cut losses** of every clip codec: the ratio of the whole motion over the ratio of its parts coded
   apart (same settings: those the rate search found for the whole), with cut detection on and off:
   ``loss = 1 - ratio(whole) / ratio(parts apart)``; the target is a loss of at most 10 %. Cases: the
   synthetic T-pose-first and two-takes cases, the real CMU walk 02_01 from BVH (its frame 0 is the T-pose
   reference frame; at eps 0.5 and 1 cm, with the issue's figure of 76:1 -> 28:1 before cut detection), and CMU
   02_01 + 02_02 (frames 0 dropped) concatenated. The ratio of the longest part alone (e.g. the walk without its
   T-pose frame) is given beside them.

Timing columns are wall seconds of the whole search on this machine (shared CPUs: load average printed), not speed
figures.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import time
from collections.abc import Sequence
from typing import Any

import numpy as np
import pandas as pd

from mocapbench import metrics
from mocapbench.codecs import CODECS, UNAVAILABLE, Codec, create
from mocapbench.experiments.document import markdown_table
from mocapbench.motion import Motion
from mocapbench.ratesearch import KNOBS, search, with_config

__all__ = ["CLIP_CODECS", "case_table", "cut_losses", "main"]

#: Codecs that code clips with a transform along time (the ones that must code around cuts).
CLIP_CODECS = ("mcb-linf", "mcb-rot", "lsdt-clip", "dct-spatial-clip", "dwt-spatial-clip")

_NEURAL = ("fourier-mlp-dct", "fourier-mlp-int")


def _one_line(error: BaseException) -> str:
    text = error.args[0] if isinstance(error, KeyError) and error.args else str(error)
    return " ".join(f"{type(error).__name__}: {text}".split())


def _learns(name: str) -> bool:
    return CODECS[name].fit is not Codec.fit


def _variants(names: Sequence[str]) -> list[tuple[str, str, bool]]:
    """``(label, codec, fit on the clip)`` for every codec; learned codecs twice (as shipped, and ``+fit``)."""
    out = []
    for name in names:
        out.append((name, name, False))
        if name in CODECS and _learns(name):
            out.append((f"{name}+fit", name, True))
    return out


def _settings(name: str) -> dict[str, Any]:
    """Extra config fields for the table: the neural codecs' reduced training."""
    if name not in _NEURAL:
        return {}
    return {key: value for key, value in CODECS[name].smoke_params.items()
            if key in ("iterations_per_round", "learning_rate", "K_max")}


def _search(name: str, motion: Motion, bound_cm: float, fit: bool):
    fitted = create(name, **_settings(name)).fit([motion]) if fit else None
    prepare = (lambda codec: with_config(fitted, codec)) if fitted is not None else None
    if name == "fourier-mlp-int":  # no search: one training at the default K (a search would train 5-8 times)
        knob = dataclasses.replace(KNOBS[name], low=CODECS[name].Config().K, high=CODECS[name].Config().K)
        return search(name, motion, bound_cm, _settings(name), prepare=prepare, knob=knob)
    return search(name, motion, bound_cm, _settings(name), prepare=prepare)


def _ratio(motion: Motion, data_bytes: int) -> float:
    return metrics.compression_ratio(metrics.raw_position_bytes(motion.num_joints, motion.num_frames), data_bytes)


def case_table(cases, codecs: Sequence[str], bound_cm: float, log=print) -> list[dict[str, Any]]:
    """One row per codec variant: the ratio (or reason) on each case, and the seconds spent."""
    rows = []
    for label, name, fit in _variants(codecs):
        row: dict[str, Any] = {"codec": label}
        start = time.perf_counter()
        for case in cases:
            if name in UNAVAILABLE and name not in CODECS:
                row[case.name] = f"unavailable: {UNAVAILABLE[name]}"
                continue
            try:
                result = _search(name, case.motion, bound_cm, fit)
                if result.met:
                    cell = f"{_ratio(case.motion, len(result.data)):.1f}"
                    mode = result.codec.last_encode_stats.get("model_mode", "")
                    cell += " (untrained)" if mode.startswith("untrained") else ""
                else:
                    cell = f"not reached: best L-inf {result.max_error_cm:.3g} cm"
            except Exception as error:  # noqa: BLE001 - the table records why a codec cannot
                cell = _one_line(error).split(";")[0]  # the reason; the remedy is in the full message
            row[case.name] = cell
        row["seconds"] = f"{time.perf_counter() - start:.0f}"
        log(f"  {label}: {row['seconds']} s")
        rows.append(row)
    return rows


def _slice(motion: Motion, start: int, stop: int) -> Motion:
    return dataclasses.replace(motion, root_positions=motion.root_positions[start:stop],
                               rotations=motion.rotations[start:stop], name=f"{motion.name}[{start}:{stop}]")


def _concatenate(first: Motion, second: Motion) -> Motion:
    return dataclasses.replace(first, root_positions=np.concatenate([first.root_positions, second.root_positions]),
                               rotations=np.concatenate([first.rotations, second.rotations]),
                               name=f"{first.name}|{second.name}")


def cut_losses(motion: Motion, parts: Sequence[tuple[int, int]], codecs: Sequence[str], bound_cm: float,
               label: str) -> list[dict[str, Any]]:
    """Per clip codec: ratio of ``motion`` whole, of its ``parts`` coded apart, and the loss, cut detection on/off."""
    rows = []
    pieces = [_slice(motion, start, stop) for start, stop in parts]
    raw = metrics.raw_position_bytes(motion.num_joints, motion.num_frames)
    for name in codecs:
        row: dict[str, Any] = {"case": label, "codec": name}
        try:
            result = _search(name, motion, bound_cm, fit=False)
            settings = {**_settings(name), **result.settings}
            sizes = [len(create(name, **settings).encode(piece)) for piece in pieces]
            apart = sum(sizes)
            longest = max(range(len(pieces)), key=lambda index: pieces[index].num_frames)
            whole = len(result.data)
            blind = len(create(name, **settings, **_no_cuts(name)).encode(motion))
            row.update({
                "setting": ", ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}"
                                     for k, v in result.settings.items()),
                "ratio whole": f"{raw / whole:.1f}", "ratio parts apart": f"{raw / apart:.1f}",
                "loss": f"{100 * (1 - apart / whole):.1f} %",
                "ratio of the longest part alone": f"{_ratio(pieces[longest], sizes[longest]):.1f}",
                "ratio whole, no cut detection": f"{raw / blind:.1f}",
                "loss, no cut detection": f"{100 * (1 - apart / blind):.1f} %",
                "L-inf cm": f"{result.max_error_cm:.3f}",
                "cuts found": result.codec.last_encode_stats.get("cuts", "-"),
            })
        except Exception as error:  # noqa: BLE001
            row["setting"] = _one_line(error)
        rows.append(row)
    return rows


def _no_cuts(name: str) -> dict[str, Any]:
    """The config fields that switch a codec's cut detection off."""
    fields = {field.name for field in dataclasses.fields(CODECS[name].Config)}
    if "cut_detection" in fields:
        return {"cut_detection": False}
    if "cut_ratio" in fields:  # mcb-rot: cut_ratio 0 switches its detection off
        return {"cut_ratio": 0.0}
    return {}


def _cmu_cases(data_dir) -> list[tuple[str, Motion, list[tuple[int, int]]]]:
    """The real CMU walk with its T-pose frame 0, and two CMU takes concatenated (their frames 0 dropped)."""
    from mocapbench.datasets.cmu import cmu_data_dir
    from mocapbench.io import read_bvh
    from mocapbench.io.asf_amc import CMU_CM_PER_UNIT

    folder = cmu_data_dir(data_dir) / "bvh"
    walk = read_bvh(folder / "02_01.bvh", length_unit_cm=CMU_CM_PER_UNIT)
    second = read_bvh(folder / "02_02.bvh", length_unit_cm=CMU_CM_PER_UNIT, drop_first_frame=True)
    takes = _concatenate(_slice(walk, 1, walk.num_frames), second)
    return [
        ("CMU 02_01 BVH, T-pose frame 0", walk, [(0, 1), (1, walk.num_frames)]),
        ("CMU 02_01 + 02_02 (cut)", takes, [(0, walk.num_frames - 1), (walk.num_frames - 1, takes.num_frames)]),
    ]


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m mocapbench.benchmarks.own_data", description=__doc__.splitlines()[0])
    parser.add_argument("--codecs", help="comma-separated codecs (default: every registered and unavailable one)")
    parser.add_argument("--bound-cm", type=float, default=1.0, help="L-inf bound of the case table (cm)")
    parser.add_argument("--long", action="store_true", help="add the 20,000-frame case")
    parser.add_argument("--cuts-only", action="store_true", help="only the T-pose / cut losses")
    parser.add_argument("--data-dir", help="CMU data folder (default: found as usual)")
    parser.add_argument("--out", help="also write the tables to this markdown file")
    args = parser.parse_args(argv)
    from mocapbench.synthetic.rigs import user_case, user_cases

    codecs = args.codecs.split(",") if args.codecs else sorted(CODECS) + sorted(UNAVAILABLE)
    lines = [f"mocapbench.benchmarks.own_data, bound {args.bound_cm:g} cm, load average at start "
             f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs", ""]
    start = time.perf_counter()
    if not args.cuts_only:
        cases = user_cases(include_long=args.long)
        lines += ["## Ratio at L-inf <= {:g} cm, codec x case".format(args.bound_cm), "",
                  "Cases: " + "; ".join(f"`{case.name}`: {case.description}" for case in cases), ""]
        rows = case_table(cases, codecs, args.bound_cm)
        lines += [markdown_table(pd.DataFrame(rows)), ""]
    clip_codecs = [name for name in CLIP_CODECS if name in codecs and name in CODECS]
    lines += ["## What a T-pose frame or a cut costs each clip codec", "",
              "loss = 1 - ratio(whole) / ratio(parts coded apart), same settings; target <= 10 %.", ""]
    loss_rows = []
    for name in ("biped-31-tpose-first", "biped-31-two-takes"):
        case = user_case(name)
        first = 1 if "tpose" in name else case.motion.num_frames // 2
        loss_rows += cut_losses(case.motion, [(0, first), (first, case.motion.num_frames)], clip_codecs,
                                args.bound_cm, name)
    for label, motion, parts in _cmu_cases(args.data_dir):
        for bound in sorted({0.5, args.bound_cm}):
            loss_rows += cut_losses(motion, parts, clip_codecs, bound, f"{label}, eps {bound:g} cm")
    lines += [markdown_table(pd.DataFrame(loss_rows)), "", f"total wall time {time.perf_counter() - start:.0f} s, load average at "
              f"end {os.getloadavg()[0]:.1f}"]
    text = "\n".join(lines)
    print(text)
    if args.out:
        from mocapbench.io.safe_output import write_text

        write_text(args.out, text + "\n", force=True)


if __name__ == "__main__":
    main()
