"""The claims of ``mcb-linf`` on a sweep that ran it beside the other codecs (e.g. ``make bench`` on cmu_test).

    python -m mocapbench.benchmarks.mcb_linf.rd SWEEP_DIR... [--dataset cmu_test] [--speed] [--ablation]
        [--mean-targets] [--data-dir D]

Prints, as markdown:

1. at eps = 0.1, 0.5, 1, 2, 3 cm: mcb-linf's ratio (and its model bytes) over every other codec's ratio at the same L-inf
   (the other curve interpolated log-log along its Pareto front; "-" where its curve does not reach that error);
2. the same at equal mean error;
3. BD-rate against ``quant-delta-zstd`` on both error axes;
4. the bound: max over clips and frames of (measured L-inf − eps), which must be <= 0;
5. with ``--speed``: encode and decode frames/s on one core over the cmu_test clips;
6. with ``--ablation``: what each design choice buys, every variant fit on cmu_train and run on cmu_test side by
   side (compression ratio at each eps);
7. with ``--mean-targets``: the ``mean_cm`` knob at a loose bound (eps = 3 cm): ratio, mean error, L-inf, and the
   ratio over quant-delta-zstd at the same mean error.
"""

from __future__ import annotations

import argparse

import numpy as np
import pandas as pd

from mocapbench.experiments.aggregate import aggregate, curve_points
from mocapbench.experiments.bdrate import bd_rate_percent, pareto_front
from mocapbench.experiments.document import markdown_table

CODEC = "mcb-linf"
ANCHOR = "quant-delta-zstd"
EPSILONS_CM = (0.5, 1.0, 2.0, 3.0)
COMPARED_EPSILONS_CM = (0.1, *EPSILONS_CM)  # the comparison tables also show the finest bound of the sweep


def ratio_at_error(points: pd.DataFrame, error: str, target: float) -> float:
    """A codec's compression ratio at ``target`` error, interpolated log-log on its Pareto front (NaN outside)."""
    bits, errors = pareto_front(points["bits_per_joint_frame"].to_numpy(), points[error].to_numpy())
    if len(bits) == 0 or not errors.min() <= target <= errors.max():
        return float("nan")
    if len(bits) == 1:
        return float(96.0 / bits[0])
    order = np.argsort(errors)
    log_bits = np.interp(np.log(target), np.log(errors[order]), np.log(bits[order]))
    return float(96.0 / np.exp(log_bits))


def comparison_table(points: pd.DataFrame, error: str) -> pd.DataFrame:
    """mcb-linf's ratio over each codec's ratio at mcb-linf's own error, for each eps."""
    ours = points[points["codec"] == CODEC]
    rows = []
    for eps in COMPARED_EPSILONS_CM:
        point = ours[np.isclose(ours["param_eps_cm"].astype(float), eps)]
        if point.empty:
            continue
        point = point.iloc[0]
        row = {"eps_cm": eps, "mcb-linf ratio": point["compression_ratio"], error: point[error],
               "model_bytes": point["model_bytes"]}
        for codec in sorted(set(points["codec"]) - {CODEC}):
            other = ratio_at_error(points[points["codec"] == codec], error, float(point[error]))
            row[codec] = point["compression_ratio"] / other if np.isfinite(other) else float("nan")
        rows.append(row)
    return pd.DataFrame(rows)


def bound_check(rows: pd.DataFrame) -> float:
    """Max over clips of measured L-inf − eps for mcb-linf rows (<= 0 when the bound holds)."""
    ours = rows[rows["codec"] == CODEC]
    return float((ours["max_err_cm"] - ours["param_eps_cm"].astype(float)).max())


def speed_table(data_dir: str | None) -> pd.DataFrame:
    """Encode and decode frames per CPU second of mcb-linf at each eps over the cmu_test clips, one core
    (median of 3 timed runs after a warm-up, :func:`mocapbench.metrics.timing.measure`)."""
    from mocapbench.codecs import create
    from mocapbench.datasets.cmu import load_split
    from mocapbench.metrics import time_call

    clips = load_split("cmu_test", data_dir=data_dir)
    frames = sum(m.num_frames for m in clips)
    rows = []
    for eps in EPSILONS_CM:
        codec = create(CODEC, eps_cm=eps)
        streams = [codec.encode(m) for m in clips]
        encode_s, _ = time_call(lambda: [codec.encode(m) for m in clips], repeats=3, warmup=1)
        decode_s, _ = time_call(lambda: [codec.decode(s) for s in streams], repeats=5)
        rows.append({"eps_cm": eps, "frames": frames, "encode_fps": frames / encode_s, "decode_fps": frames / decode_s})
    return pd.DataFrame(rows)


# (label, config overrides) of the ablation: each row changes one choice of the default.
ABLATION = (
    ("default", {}),
    ("per-band Huffman/zstd instead of the trained ANS model", {"entropy": "bands"}),
    ("root step = base step (root_step_rel 1)", {"root_step_rel": 1.0}),
    ("240-frame clips", {"clip_frames": 240}),
    ("no dead zone (rounding 0.5)", {"rounding": 0.5}),
    ("flat quantization matrix (frequency_slope 0)", {"frequency_slope": 0.0}),
)
MEAN_TARGETS_CM = (0.1, 0.2, 0.3, 0.5)
LOOSE_EPS_CM = 3.0


def _pooled(codec, clips) -> dict[str, float]:
    """Encode and decode every clip: pooled compression ratio, L-inf and mean error (cm)."""
    from mocapbench.metrics import joint_errors, raw_position_bytes

    raw = coded = 0
    errors = []
    for motion in clips:
        data = codec.encode(motion)
        raw += raw_position_bytes(motion.num_joints, motion.num_frames)
        coded += len(data)
        errors.append(joint_errors(motion.positions(), codec.decode(data).positions).ravel())
    errors = np.concatenate(errors)
    return {"compression_ratio": raw / coded, "max_err_cm": float(errors.max()), "mean_err_cm": float(errors.mean())}


def ablation_table(data_dir: str | None) -> pd.DataFrame:
    """Compression ratio on cmu_test of each ablation variant at each eps (each variant fit on cmu_train)."""
    from mocapbench.codecs import create
    from mocapbench.datasets.cmu import load_split

    train, test = load_split("cmu_train", data_dir=data_dir), load_split("cmu_test", data_dir=data_dir)
    rows = []
    for label, overrides in ABLATION:
        fitted = create(CODEC, **overrides).fit(train)
        row = {"variant": label}
        for eps in EPSILONS_CM:
            codec = create(CODEC, eps_cm=eps, **overrides)
            codec._model = fitted._model  # the same learned state, fit once
            row[f"CR at eps {eps:g}"] = _pooled(codec, test)["compression_ratio"]
        rows.append(row)
    return pd.DataFrame(rows)


def mean_target_table(points: pd.DataFrame, data_dir: str | None) -> pd.DataFrame:
    """The ``mean_cm`` knob at eps = LOOSE_EPS_CM on cmu_test, against quant-delta-zstd at the same mean error."""
    from mocapbench.codecs import create
    from mocapbench.datasets.cmu import load_split

    clips = load_split("cmu_test", data_dir=data_dir)
    anchor = points[points["codec"] == ANCHOR]
    rows = []
    for target in (0.0, *MEAN_TARGETS_CM):
        row = {"eps_cm": LOOSE_EPS_CM, "mean_cm target": target or "off"}
        row.update(_pooled(create(CODEC, eps_cm=LOOSE_EPS_CM, mean_cm=target), clips))
        row[f"x {ANCHOR} at same mean error"] = row["compression_ratio"] / ratio_at_error(
            anchor, "mean_err_cm", row["mean_err_cm"]
        )
        rows.append(row)
    return pd.DataFrame(rows)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folders", nargs="+", help="sweep folders holding mcb-linf and the other codecs")
    parser.add_argument("--dataset", default="cmu_test")
    parser.add_argument("--speed", action="store_true", help="also measure single-core encode/decode speed")
    parser.add_argument("--ablation", action="store_true", help="also run the design ablation on cmu_test")
    parser.add_argument("--mean-targets", action="store_true", help="also run the mean_cm knob on cmu_test")
    parser.add_argument("--data-dir", default=None, help="CMU data folder for --speed, --ablation, --mean-targets")
    args = parser.parse_args(argv)
    rows = aggregate(args.folders)
    rows = rows[rows["dataset"] == args.dataset]
    points = curve_points(rows)
    if CODEC not in set(points["codec"]):
        parser.error(f"no {CODEC} rows for dataset {args.dataset} under {args.folders}")
    print(f"## mcb-linf on {args.dataset}: ratio over each codec at the same L-inf (x; > 1: mcb-linf smaller)\n")
    print(markdown_table(comparison_table(points, "max_err_cm")))
    print(f"\n## ... at the same mean error\n")
    print(markdown_table(comparison_table(points, "mean_err_cm")))
    print(f"\n## BD-rate of mcb-linf against {ANCHOR} (bits per joint per frame; negative: fewer bits)\n")
    ours, anchor = points[points["codec"] == CODEC], points[points["codec"] == ANCHOR]
    for error in ("max_err_cm", "mean_err_cm"):
        value, note = bd_rate_percent(
            anchor["bits_per_joint_frame"], anchor[error], ours["bits_per_joint_frame"], ours[error]
        )
        print(f"- {error}: {value:+.1f} % ({note})")
    print(f"\n## The bound\n\nmax over clips and frames of (L-inf - eps) = {bound_check(rows):+.2e} cm (must be <= 0)")
    if args.speed:
        print("\n## Speed, one core\n")
        print(markdown_table(speed_table(args.data_dir)))
    if args.ablation:
        print("\n## Ablation: compression ratio on cmu_test, one choice changed per row (each fit on cmu_train)\n")
        print(markdown_table(ablation_table(args.data_dir)))
    if args.mean_targets:
        print(f"\n## The mean_cm knob at eps = {LOOSE_EPS_CM:g} cm on cmu_test\n")
        print(markdown_table(mean_target_table(points, args.data_dir)))
    return 0


if __name__ == "__main__":
    from mocapbench.benchmarks.entry import run_script

    raise SystemExit(run_script(main))
