"""The claims of ``mcb-rot`` on ``cmu_test`` (or ``--dataset bandai_test``, a game rig at 30 fps: ``--every 1``),
measured in one run beside ACL 2.1 and the other codecs.

    python -m mocapbench.benchmarks.mcb_rot.rd [--dataset D] [--every 1 5] [--speed] [--discontinuities] [--ablation]
        [--sweep DIR ...] [--data-dir D] [--prior TRAIN_SPLIT]

Prints, as markdown (ratio = 12·J·F / stream bytes over all clips pooled; errors over every joint of every frame):

1. mcb-rot at ε = 0.05, 0.1, 0.25, 0.5, 1, 2 cm at 120 fps and at 24 fps (every 5th frame): ratio, L∞, mean error,
   ACL's shell error at 3 cm, and the bound check (max over clips of L∞ − ε, which must be <= 0); with ``--prior``
   mcb-rot is fit on that split first (its prior of rigs, :mod:`mocapbench.codecs.mcb_rot.prior`) and the table
   gives the prior's bytes (held out of every ratio) and the ratio with them paid once;
2. ACL 2.1 run in the same process (``acl`` codec; the issue's table when ACL cannot run here), precision grid at
   shell 3 cm and 0 cm, each with and without ACL's pre-processing: mcb-rot's ratio over ACL's at mcb-rot's L∞ (ACL
   interpolated log-log on the Pareto front of all its settings together: ACL at its best), against ACL's whole
   stream and against ACL's bare buffer;
3. on ACL's own metric (shell error at 3 cm): mcb-rot's ratio over ACL's (shell 3 cm) at equal max shell error,
   for the default mcb-rot (joints bounded) and for ``shell_cm=3`` (the bound also on ACL's vertices);
4. every other codec run here (``quant-rot-zstd``, ``quant-pred-zstd``, ``quant-delta-zstd``, ``mcb-linf``) and any
   ``--sweep`` folders: ratio over theirs at equal L∞; BD-rate (L∞ axis) of mcb-rot against ACL and the others;
5. ``--speed``: encode, batched decode and one-frame random access (``decode_frames(t, t + 1)`` at random t,
   garbage collector off during the picks as in :mod:`timeit`), process CPU time beside wall time, median of
   repeats, load average;
6. ``--discontinuities``: the T-pose frame of the CMU BVH files and cuts between takes of one subject, joined vs
   coded apart;
7. ``--ablation``: each design choice switched off or changed, ratio at ε = 0.1 and 1 cm.
"""

from __future__ import annotations

import argparse
import gc
import os
import statistics
import time

import numpy as np

from mocapbench import metrics
from mocapbench.codecs import CODECS, UNAVAILABLE, create
from mocapbench.experiments.bdrate import bd_rate_percent, pareto_front
from mocapbench.motion import Motion

__all__ = ["main", "rd_points", "ratio_at"]

EPSILONS_CM = (0.05, 0.1, 0.25, 0.5, 1.0, 2.0)
TARGETS_CM = (0.05, 0.1, 0.5, 1.0)
TARGET_X = 2.5  # the target of mcb-rot's ratio over ACL's at its best, at equal L-inf on cmu_test
SHELL_CM = 3.0  # ACL's default shell distance: mcb-rot's shell_cm on ACL's own metric
ACL_PRECISIONS_CM = (0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0)
# A reference run of ACL 2.1 on the cmu_test BVH files, 120 fps: (shell cm, ratio, L-inf cm), used without ACL.
ISSUE_ACL = ((3.0, 4.43, 0.013), (3.0, 7.18, 0.120), (3.0, 13.54, 0.552), (3.0, 17.89, 1.26),
             (0.0, 15.6, 0.68), (0.0, 20.3, 1.51))
OTHERS = {
    "quant-rot-zstd": ("rotation_bits", (8, 10, 12, 14, 16)),
    "quant-pred-zstd": ("step_cm", (0.05, 0.1, 0.2, 0.5, 1.0, 2.0)),
    "quant-delta-zstd": ("step_cm", (0.05, 0.1, 0.2, 0.5, 1.0, 2.0)),
    "mcb-linf": ("eps_cm", (0.05, 0.1, 0.25, 0.5, 1.0, 2.0)),
}


def every(motions: list[Motion], step: int) -> list[Motion]:
    """Every ``step``-th frame of each motion (24 fps from 120 fps with step 5)."""
    return [m.every(step) for m in motions]


def rd_points(name: str, motions: list[Motion], key: str, values, *, shell: bool = False,
              training: list[Motion] | None = None, **fixed) -> list[dict]:
    """Encode and decode every motion at each setting; pooled ratio and errors (one dict per setting). With
    ``training`` the codec is fit on those motions first (mcb-rot: its prior); ``model_bytes`` is the largest
    model a stream needed, held out of ``ratio`` and paid once in ``ratio_model_paid``."""
    points = []
    for value in values:
        codec = create(name, **{key: value}, **fixed)
        if training is not None:
            codec.fit(training)
        raw = stream = model = 0
        linf = mean_sum = count = shell_max = slack = 0.0
        slack = -np.inf
        buffer = 0
        for motion in motions:
            data = codec.encode(motion)
            decoded = codec.decode(data)
            errors = metrics.joint_errors(motion.positions(), decoded.positions)
            raw += metrics.raw_position_bytes(motion.num_joints, motion.num_frames)
            stream += len(data)
            model = max(model, int(codec.model_bytes))
            buffer += codec.last_encode_stats.get("acl_buffer_bytes", len(data))
            linf = max(linf, float(errors.max()))
            mean_sum += float(errors.sum())
            count += errors.size
            if key == "eps_cm":
                slack = max(slack, float(errors.max()) - value)
            if shell and decoded.motion is not None:
                shell_max = max(shell_max, float(metrics.motion_shell_errors(motion, decoded.motion).max()))
        points.append({"codec": name, key: value, **fixed, "ratio": raw / stream, "ratio_buffer": raw / buffer,
                       "linf_cm": linf, "mean_cm": mean_sum / count, "shell_max_cm": shell_max,
                       "bound_margin_cm": slack, "model_bytes": model, "ratio_model_paid": raw / (stream + model)})
    return points


def ratio_at(points: list[dict], error: str, target: float, ratio: str = "ratio") -> float:
    """A curve's ratio at ``target`` error, interpolated log-log on its Pareto front (NaN outside its range)."""
    rates = np.array([96.0 / p[ratio] for p in points])
    errors = np.array([p[error] for p in points])
    bits, errs = pareto_front(rates, errors)
    if len(bits) == 0 or not errs.min() <= target <= errs.max():
        return float("nan")
    if len(bits) == 1:
        return float(96.0 / bits[0])
    order = np.argsort(errs)
    return float(96.0 / np.exp(np.interp(np.log(target), np.log(errs[order]), np.log(bits[order]))))


def _table(header: list[str], rows: list[list]) -> None:
    print("| " + " | ".join(header) + " |")
    print("|" + "---:|" * len(header))
    for row in rows:
        print("| " + " | ".join(f"{v:.4g}" if isinstance(v, float) else str(v) for v in row) + " |")


def _acl_points(motions: list[Motion], fps: float) -> tuple[list[dict], str]:
    if "acl" not in CODECS:
        if fps < 100:
            return [], f"ACL unavailable ({UNAVAILABLE.get('acl', 'not registered')}); no 24 fps reference"
        return ([{"codec": "acl", "shell_cm": s, "ratio": r, "ratio_buffer": r, "linf_cm": e, "shell_max_cm": np.nan}
                 for s, r, e in ISSUE_ACL], "ACL: the reference run's table (BVH, not measured here)")
    points = []
    for shell in (3.0, 0.0):
        for pre_process in (False, True):
            points += rd_points("acl", motions, "precision_cm", ACL_PRECISIONS_CM, shell=True, shell_cm=shell,
                                pre_process=pre_process)
    return points, "ACL 2.1 measured in this run (level highest, with and without its pre-processing)"


def _rd_section(motions: list[Motion], label: str, sweep_points: list[dict], epsilons=EPSILONS_CM,
                others_too: bool = True, training: list[Motion] | None = None) -> None:
    """Sections 1-4 of the report for one frame rate: mcb-rot's curve, then ACL, then every other codec."""
    print(f"\n## {label}: {len(motions)} clips, {sum(m.num_frames for m in motions)} frames at {motions[0].fps:g} fps")
    ours = rd_points("mcb-rot", motions, "eps_cm", epsilons, shell=True, training=training)
    _print_bound(ours)
    acl, source = _acl_points(motions, motions[0].fps)
    print(f"\n### Against ACL ({source})")
    if acl:
        _print_against_acl(ours, acl)
        shell3 = [a for a in acl if a["shell_cm"] == 3.0 and np.isfinite(a["shell_max_cm"])]
        if shell3:
            _print_on_acl_metric(ours, shell3)
        if shell3 and others_too:  # mcb-rot's shell variant: a second mcb-rot curve
            _print_shelled_on_acl_metric(rd_points("mcb-rot", motions, "eps_cm", epsilons, shell=True,
                                                   shell_cm=SHELL_CM), shell3)
        _print_acl_points(acl)
    others = _other_curves(motions, sweep_points, acl, others_too)
    _print_ratio_over_others(ours, others)
    _print_bd_rates(ours, others)


def _print_bound(ours: list[dict]) -> None:
    """Section 1: mcb-rot's ratio and errors at each bound, and the bound check."""
    print("\n### mcb-rot: rate and the bound (margin = max over clips of L-inf - eps, must be <= 0; ratio: model "
          "bytes held out, as in every table below; the last column pays them once for the whole set)")
    _table(["eps cm", "ratio", "L-inf cm", "mean cm", "shell max cm (3 cm)", "bound margin cm", "model bytes",
            "ratio, model paid"],
           [[p["eps_cm"], p["ratio"], p["linf_cm"], p["mean_cm"], p["shell_max_cm"], p["bound_margin_cm"],
             p["model_bytes"], p["ratio_model_paid"]] for p in ours])


def _print_against_acl(ours: list[dict], acl: list[dict]) -> None:
    """Section 2: mcb-rot's ratio over ACL's at mcb-rot's L-inf, per ACL shell and at ACL's best (its Pareto front)."""
    rows = []
    for p in ours:
        if p["eps_cm"] not in TARGETS_CM:
            continue
        by_shell = {s: ratio_at([a for a in acl if a["shell_cm"] == s], "linf_cm", p["linf_cm"]) for s in (3.0, 0.0)}
        # ACL at its best: the Pareto front of every setting (shell, pre-processing) together.
        acl_best = ratio_at(acl, "linf_cm", p["linf_cm"])
        acl_buffer = ratio_at(acl, "linf_cm", p["linf_cm"], "ratio_buffer")
        rows.append([p["eps_cm"], p["ratio"], p["linf_cm"], by_shell[3.0], by_shell[0.0], p["ratio"] / acl_best,
                     p["ratio"] / acl_buffer, "met" if p["ratio"] / acl_best >= TARGET_X else "not met"])
    _table(["eps cm", "mcb-rot ratio", "L-inf cm", "ACL shell 3", "ACL shell 0", "x ACL best (stream)",
            "x ACL best (buffer only)", f"target {TARGET_X:g}x"], rows)


def _shell_verdict(ratio: float, other: float) -> str:
    """The 1.5x target on ACL's metric: met, not met, or '-' where ACL's curve does not reach that error."""
    return "met" if ratio / other >= 1.5 else ("not met" if np.isfinite(other) else "-")


def _print_on_acl_metric(ours: list[dict], shell3: list[dict]) -> None:
    """Section 3: the default mcb-rot (joints bounded) against ACL at shell 3 cm, at equal max shell error."""
    print("\n### On ACL's metric (max shell error at 3 cm), ACL at shell 3 cm")
    rows = []
    for p in ours:
        other = ratio_at(shell3, "shell_max_cm", p["shell_max_cm"])
        rows.append([p["eps_cm"], p["ratio"], p["shell_max_cm"], other, p["ratio"] / other,
                     _shell_verdict(p["ratio"], other)])
    _table(["eps cm", "mcb-rot ratio", "shell max cm", "ACL ratio at that shell error", "x ACL", "target 1.5x"], rows)


def _print_shelled_on_acl_metric(shelled: list[dict], shell3: list[dict]) -> None:
    """Section 3, second table: mcb-rot with ``shell_cm`` (bound also on ACL's vertices) against ACL at shell 3 cm."""
    print(f"\n### On ACL's metric, mcb-rot with shell_cm={SHELL_CM:g} (the bound also on the vertices)")
    rows = []
    for p in shelled:
        other = ratio_at(shell3, "shell_max_cm", p["shell_max_cm"])
        rows.append([p["eps_cm"], p["ratio"], p["shell_max_cm"], p["linf_cm"], other, p["ratio"] / other,
                     _shell_verdict(p["ratio"], other)])
    _table(["eps cm", "mcb-rot ratio", "shell max cm", "L-inf cm", "ACL ratio at that shell error", "x ACL",
            "target 1.5x"], rows)


def _print_acl_points(acl: list[dict]) -> None:
    """Every ACL point of the run on one line: precision, shell, pre-processing, ratios and L-inf."""
    print("\nACL points: " + "; ".join(f"p {a.get('precision_cm', '-')}/s {a['shell_cm']:g}"
                                      f"{'/pre' if a.get('pre_process') else ''}: {a['ratio']:.2f} "
                                      f"(buffer {a['ratio_buffer']:.2f}) at {a['linf_cm']:.3g} cm" for a in acl))


def _other_curves(motions: list[Motion], sweep_points: list[dict], acl: list[dict],
                  others_too: bool) -> dict[str, list[dict]]:
    """Section 4's curves by codec name: the ``OTHERS`` run here, the sweep folders' points, and ACL at its best."""
    others = {name: rd_points(name, motions, key, values) for name, (key, values) in OTHERS.items()
              if name in CODECS and others_too}
    for point in sweep_points:
        others.setdefault(point["codec"], []).append(point)
    if acl:
        others["acl (best shell)"] = acl
    return others


def _print_ratio_over_others(ours: list[dict], others: dict[str, list[dict]]) -> None:
    """Section 4: mcb-rot's ratio over each other codec's at equal L-inf."""
    print("\n### mcb-rot's ratio over each codec's at equal L-inf ('-': the other curve does not reach that error)")
    names = sorted(others)
    rows = []
    for p in ours:
        row = [p["eps_cm"], p["ratio"]]
        for name in names:
            other = ratio_at(others[name], "linf_cm", p["linf_cm"])
            row.append(p["ratio"] / other if np.isfinite(other) else "-")
        rows.append(row)
    _table(["eps cm", "mcb-rot ratio"] + names, rows)


def _print_bd_rates(ours: list[dict], others: dict[str, list[dict]]) -> None:
    """Section 4: BD-rate of mcb-rot against each other codec as the anchor (L-inf axis)."""
    print("\n### BD-rate of mcb-rot (L-inf axis; negative: fewer bits than the anchor at equal L-inf)")
    rows = []
    our_rate = np.array([96.0 / p["ratio"] for p in ours])
    our_err = np.array([p["linf_cm"] for p in ours])
    for name in sorted(others):
        anchor = others[name]
        try:
            value, method = bd_rate_percent(np.array([96.0 / a["ratio"] for a in anchor]),
                                            np.array([a["linf_cm"] for a in anchor]), our_rate, our_err)
            rows.append([name, value, method])
        except ValueError as error:
            rows.append([name, "-", str(error)[:80]])
    _table(["anchor", "BD-rate %", "method"], rows)


def _speed(motions: list[Motion], repeats: int) -> None:
    from mocapbench.metrics.timing import measure
    from mocapbench.synthetic import sinusoidal_motion

    frames = sum(m.num_frames for m in motions)
    print(f"\n## Speed, one thread, {frames} frames, median of {repeats} (load average {os.getloadavg()[0]:.1f})")
    print("Encode: every repeat codes fresh copies of the motions (nothing computed on them survives a repeat), "
          "after one warm-up encode of an unrelated synthetic clip (imports, coder tables).")
    rows = []
    for eps in TARGETS_CM:  # the decode speed at every target bound
        codec = create("mcb-rot", eps_cm=eps)
        copies = iter([[_fresh(m) for m in motions] for _ in range(repeats + 1)])
        codec.encode(sinusoidal_motion(num_frames=60, seed=1))
        timing, streams = measure(lambda: [codec.encode(m) for m in next(copies)], repeats=repeats, warmup=0)
        rows.append([eps, "encode", frames / timing.cpu_s, frames / timing.wall_s, 2000])
        slow = iter([[_fresh(m.every(5)) for m in motions] for _ in range(repeats + 1)])
        slow_frames = sum(len(range(0, m.num_frames, 5)) for m in motions)
        timing_24, _ = measure(lambda: [codec.encode(m) for m in next(slow)], repeats=repeats, warmup=0)
        rows.append([eps, "encode, 24 fps (every 5th frame)", slow_frames / timing_24.cpu_s,
                     slow_frames / timing_24.wall_s, 2000])
        timing, _ = measure(lambda: [codec.decode(s) for s in streams], repeats=repeats, warmup=1)
        rows.append([eps, "decode (batched, + FK)", frames / timing.cpu_s, frames / timing.wall_s, 100_000])
        rng = np.random.default_rng(0)
        picks = [(s, int(rng.integers(m.num_frames))) for s, m in zip(streams, motions) for _ in range(20)]
        cpu, wall = _one_frame_picks(codec, picks)
        rows.append([eps, "one frame at random t (ms, median; max)",
                     f"{1e3 * statistics.median(cpu):.2f}; {1e3 * max(cpu):.2f}",
                     f"{1e3 * statistics.median(wall):.2f}; {1e3 * max(wall):.2f}", "<= 5 ms"])
    _table(["eps cm", "what", "frames/s CPU", "frames/s wall", "target"], rows)
    print(f"Load average after: {os.getloadavg()[0]:.1f}")


def _one_frame_picks(codec, picks: list[tuple[bytes, int]]) -> tuple[list[float], list[float]]:
    """CPU and wall seconds of ``decode_frames(stream, t, t + 1)`` for every ``(stream, t)`` pick, one thread.

    As :mod:`timeit` does, garbage is collected before and the collector is off during the picks: a gen-2
    collection of the host process (21 ms measured inside one pick) is not the codec's latency.
    """
    from mocapbench.metrics.timing import single_thread

    cpu, wall = [], []
    gc.collect()
    gc.disable()
    try:
        with single_thread(1):
            for stream, t in picks:
                c0, w0 = time.process_time(), time.perf_counter()
                codec.decode_frames(stream, t, t + 1)
                cpu.append(time.process_time() - c0)
                wall.append(time.perf_counter() - w0)
    finally:
        gc.enable()
    return cpu, wall


def _fresh(motion: Motion) -> Motion:
    """A new Motion with copies of ``motion``'s arrays (no state of an earlier encode can be reused)."""
    return Motion(motion.skeleton, motion.fps, motion.root_positions.copy(), motion.rotations.copy(), motion.name,
                  source_unit_cm=motion.source_unit_cm, up_axis=motion.up_axis)


def _discontinuities(data_dir) -> None:
    from mocapbench.datasets.cmu import CMU_CM_PER_UNIT, cmu_data_dir, load_clip
    from mocapbench.io import read_bvh

    root = cmu_data_dir(data_dir)
    print("\n## Discontinuities: bytes joined / bytes of the parts coded apart (target <= 1.10)")
    rows = []
    for eps in TARGETS_CM:  # the decode speed at every target bound
        codec = create("mcb-rot", eps_cm=eps)
        for name in ("02_01", "09_06", "16_07", "64_05", "118_10"):
            motion = read_bvh(root / "bvh" / f"{name}.bvh", length_unit_cm=CMU_CM_PER_UNIT)
            joined = len(codec.encode(motion))
            apart = len(codec.encode(motion.slice(0, 1))) + len(codec.encode(motion.slice(1, motion.num_frames)))
            no_cut = len(create("mcb-rot", eps_cm=eps, cut_ratio=0.0).encode(motion))
            rows.append([eps, f"T-pose + {name} (BVH)", joined / apart, no_cut / apart])
        for first, second in (("02_01", "02_02"), ("10_01", "10_02"), ("16_01", "16_07"), ("118_01", "118_10")):
            a, b = load_clip(first, data_dir=root), load_clip(second, data_dir=root)
            both = Motion(a.skeleton, a.fps, np.concatenate([a.root_positions, b.root_positions]),
                          np.concatenate([a.rotations, b.rotations]))
            joined = len(codec.encode(both))
            apart = len(codec.encode(a)) + len(codec.encode(b))
            no_cut = len(create("mcb-rot", eps_cm=eps, cut_ratio=0.0).encode(both))
            rows.append([eps, f"{first} + {second} (one cut)", joined / apart, no_cut / apart])
    _table(["eps cm", "case", "joined / apart", "without cut detection / apart"], rows)


ABLATIONS = {
    "default": {},
    "no principal axes": {"principal_axes": False},
    "no compensation (each joint quantized alone)": {"compensate": False},
    "all over-budget joints corrected (not greedy)": {"greedy_corrections": False},
    "no flat-slope trial in the rate search": {"slope_search": False},
    "fixed step (4x budget, no rate search)": {"step_rel": 4.0},
    "root share 0.2 (was 0.05)": {"root_share": 0.2},
    "allocation p = 2 (was max lever)": {"allocation_power": 2.0},
    "segments of 64 frames (was 128)": {"segment_frames": 64},
    "segments of 256 frames": {"segment_frames": 256},
    "chunks of 512 frames (was 256)": {"chunk_frames": 512},
    "chunks of 128 frames": {"chunk_frames": 128},
    "flat step over frequency (slope 0, was 1)": {"frequency_slope": 0.0},
    "nearest rounding (0.5, was 0.45)": {"rounding": 0.5},
    "shell_cm 3 (bound also on ACL's vertices)": {"shell_cm": 3.0},
}


def _ablation(motions: list[Motion]) -> None:
    print("\n## Ablation: ratio at eps = 0.1 and 1 cm (the bound holds in every variant)")
    rows = []
    for label, params in ABLATIONS.items():
        points = rd_points("mcb-rot", motions, "eps_cm", (0.1, 1.0), **params)
        rows.append([label] + [p["ratio"] for p in points] + [max(p["bound_margin_cm"] for p in points)])
    _table(["variant", "ratio at 0.1 cm", "ratio at 1 cm", "bound margin cm"], rows)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dataset", default="cmu_test")
    parser.add_argument("--data-dir", default=None)
    parser.add_argument("--every", type=int, nargs="+", default=[1, 5], help="frame steps (1: 120 fps, 5: 24 fps)")
    parser.add_argument("--sweep", nargs="*", default=[], help="sweep folders whose other codecs join the tables")
    parser.add_argument("--speed", action="store_true")
    parser.add_argument("--discontinuities", action="store_true")
    parser.add_argument("--ablation", action="store_true")
    parser.add_argument("--no-rd", action="store_true", help="skip the rate-distortion sections")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--eps", type=float, nargs="+", default=list(EPSILONS_CM), help="mcb-rot's bounds, cm")
    parser.add_argument("--prior", default=None, metavar="SPLIT",
                        help="fit mcb-rot's prior (its rigs, format 6 flag bit 15) on this split first, e.g. "
                             "bandai_train; its bytes are reported as model bytes, held out of the ratio")
    parser.add_argument("--no-others", action="store_true",
                        help="mcb-rot and ACL only (not quant-*, mcb-linf: the sweep's headline has those)")
    args = parser.parse_args(argv)
    motions = _load(args.dataset, args.data_dir)
    print(f"# mcb-rot on {args.dataset} (load average {os.getloadavg()[0]:.1f})")
    sweep_points = _sweep_points(args.sweep)
    training = None if args.prior is None else _load(args.prior, args.data_dir)
    if training is not None:
        print(f"mcb-rot fit on {args.prior} ({len(training)} clips): a stream of a rig the prior holds names it")
    if not args.no_rd:
        for step in args.every:
            _rd_section(every(motions, step), f"{args.dataset}, every {step}. frame", sweep_points if step == 1 else [],
                        tuple(args.eps), not args.no_others, None if training is None else every(training, step))
    if args.speed:
        _speed(motions, args.repeats)
    if args.discontinuities:
        _discontinuities(args.data_dir)
    if args.ablation:
        _ablation(motions)


def _load(dataset: str, data_dir: str | None) -> list[Motion]:
    """The clips of ``dataset``: a CMU split (``cmu_test``, ...) or a Bandai Namco one (``bandai_test``, ...)."""
    if dataset.startswith("bandai_"):
        from mocapbench.experiments.datasets import load_clips

        return load_clips({"name": dataset, "kind": "bandai", "split": dataset, "data_dir": data_dir})
    from mocapbench.datasets.cmu import load_split

    return load_split(dataset, data_dir=data_dir)


def _sweep_points(folders: list[str]) -> list[dict]:
    """Pooled RD points of every codec (but mcb-rot) in sweep folders, as :func:`rd_points` dicts."""
    if not folders:
        return []
    from mocapbench.experiments.aggregate import aggregate, curve_points

    points = curve_points(aggregate(folders))
    return [{"codec": row["codec"], "ratio": row["compression_ratio"], "linf_cm": row["max_err_cm"]}
            for _, row in points.iterrows() if row["codec"] != "mcb-rot"]


if __name__ == "__main__":
    from mocapbench.benchmarks.entry import run_script

    raise SystemExit(run_script(main))
