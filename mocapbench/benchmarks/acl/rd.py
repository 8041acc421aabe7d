"""ACL 2.1 on ``cmu_test``: its rate-distortion points beside an independent reference run, and its speed.

    python -m mocapbench.benchmarks.acl.rd                 # RD points, ASF/AMC clips (what cmu_test reads)
    python -m mocapbench.benchmarks.acl.rd --fmt bvh       # the same on the BVH release (what the issue measured)
    python -m mocapbench.benchmarks.acl.rd --speed         # + encode/decode frames/s on one core, single-pose decode
    python -m mocapbench.benchmarks.acl.rd --grid --variants --jitter 5   # why the issue's 0.5 and 1 cm points differ
                                                        # (BVH; see mocapbench.benchmarks.acl.reference)

RD points at precision 0.01 / 0.1 / 0.5 / 1 cm, shell distance 3 cm (ACL's default) and 0 cm, compression level
highest, every other setting ACL's default. ``ratio`` is the issue's definition, 12·J·F / ACL's compressed
buffer bytes (the float32 joint positions over ACL's own buffer); ``ratio (stream)`` divides by the whole
mocapbench stream (container + skeleton blob + ACL buffer). Errors pool every joint of every frame of the 12
clips (cm): joint L∞, mean, p99, and ACL's shell error at 3 cm (max, p99).

Speed: process CPU time beside wall time, median of ``--repeats`` runs, the load average printed (the machine
is shared). Encode: ``AclCodec.encode`` over the 12 clips. Decode: ``AclCodec.decode`` (ACL decompression of
every frame + mocapbench's forward kinematics), and ACL's decompression alone. Single pose: a C loop in the shim
that seeks a pseudo-random frame and decompresses one pose, context initialized once, as an engine samples a clip.
"""

from __future__ import annotations

import argparse
import os
import statistics
from collections.abc import Callable
from typing import Any

import numpy as np

from mocapbench import metrics
from mocapbench.benchmarks.acl import reference
from mocapbench.benchmarks.acl.reference import ISSUE_REFERENCE, ISSUE_SHELL0
from mocapbench.codecs import container, create
from mocapbench.codecs.acl.binding import load_library
from mocapbench.codecs.skeleton_blob import unpack_skeleton
from mocapbench.entropy.bitio import ByteReader
from mocapbench.motion import Motion

__all__ = ["rd_point", "main"]

PRECISIONS = (0.01, 0.1, 0.5, 1.0)


def _acl_buffer(data: bytes) -> bytes:
    """ACL's own compressed buffer inside an ``acl`` stream."""
    _, payload = container.unpack(data, "acl")
    reader = ByteReader(payload)
    unpack_skeleton(reader)
    return bytes(reader.read_blob("ACL buffer"))


def rd_point(motions: list[Motion], precision_cm: float, shell_cm: float) -> dict[str, Any]:
    """Encode and decode every motion at one setting; pooled rate and errors (see the module docstring)."""
    codec = create("acl", precision_cm=precision_cm, shell_cm=shell_cm)
    joint_errors, shell_errors = [], []
    stream_bytes = buffer_bytes = raw_bytes = joint_frames = 0
    for motion in motions:
        data = codec.encode(motion)
        decoded = codec.decode(data)
        joint_errors.append(metrics.joint_errors(motion.positions(), decoded.positions).ravel())
        shell_errors.append(metrics.motion_shell_errors(motion, decoded.motion, metrics.ACL_SHELL_DISTANCE_CM).ravel())
        stream_bytes += len(data)
        buffer_bytes += codec.last_encode_stats["acl_buffer_bytes"]
        raw_bytes += metrics.raw_position_bytes(motion.num_joints, motion.num_frames)
        joint_frames += motion.num_joints * motion.num_frames
    joint = np.concatenate(joint_errors)
    shell = np.concatenate(shell_errors)
    return {
        "precision_cm": precision_cm,
        "shell_cm": shell_cm,
        "buffer_bytes": buffer_bytes,
        "stream_bytes": stream_bytes,
        "ratio": raw_bytes / buffer_bytes,
        "ratio_stream": raw_bytes / stream_bytes,
        "bits_per_joint_frame": 8 * buffer_bytes / joint_frames,
        "linf_cm": float(joint.max()),
        "mean_cm": float(joint.mean()),
        "p99_cm": float(np.percentile(joint, 99)),
        "shell_max_cm": float(shell.max()),
        "shell_p99_cm": float(np.percentile(shell, 99)),
    }


def _time(function: Callable[[], Any], repeats: int) -> tuple[float, float]:
    """Median wall and median process-CPU seconds of ``function()`` over ``repeats`` runs after one warm-up
    (:func:`mocapbench.metrics.timing.measure`, the helper every benchmark times with)."""
    from mocapbench.metrics.timing import measure

    timing, _ = measure(function, repeats=repeats, warmup=1)
    return timing.wall_s, timing.cpu_s


def _print_rd(points: list[dict[str, Any]], fmt: str) -> None:
    print(f"\nACL 2.1.0 on cmu_test ({fmt}), level highest; ratio = 12*J*F / ACL buffer bytes; errors in cm")
    print("| precision | shell | ratio | (issue) | bytes vs issue | ratio (stream) | bits/joint/frame | L-inf | (issue) "
          "| L-inf vs issue | mean | (issue) | p99 | (issue) | shell max | shell p99 |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for p in points:
        ref = ISSUE_REFERENCE.get(p["precision_cm"]) if p["shell_cm"] == 3.0 else None
        if ref:
            issue_cols = [f"{ref[0]:.2f}", f"{ref[0] / p['ratio'] - 1:+.1%}"]
            linf_cols = [f"{ref[2]:.4g}", f"{p['linf_cm'] / ref[2] - 1:+.1%}"]
            mean_ref, p99_ref = f"{ref[3]:.4g}", f"{ref[4]:.4g}"
        else:
            issue_cols, linf_cols, mean_ref, p99_ref = ["", ""], ["", ""], "", ""
        print(
            f"| {p['precision_cm']:g} | {p['shell_cm']:g} | {p['ratio']:.2f} | {issue_cols[0]} | {issue_cols[1]} "
            f"| {p['ratio_stream']:.2f} | {p['bits_per_joint_frame']:.2f} | {p['linf_cm']:.4g} | {linf_cols[0]} "
            f"| {linf_cols[1]} | {p['mean_cm']:.4g} | {mean_ref} | {p['p99_cm']:.4g} | {p99_ref} "
            f"| {p['shell_max_cm']:.4g} | {p['shell_p99_cm']:.4g} |"
        )
    print("Issue, shell 0: " + ", ".join(f"{r}:1 at L-inf {e} cm" for r, e in ISSUE_SHELL0))


def _speed(motions: list[Motion], repeats: int) -> None:
    frames = sum(m.num_frames for m in motions)
    library = load_library()
    print(f"\nSpeed, one core (precision 0.01 cm, shell 3 cm, level highest), {frames} frames, "
          f"median of {repeats}; load average before: {os.getloadavg()[0]:.2f}")
    codec = create("acl", precision_cm=0.01, shell_cm=3.0)
    streams = [codec.encode(m) for m in motions]
    buffers = [_acl_buffer(s) for s in streams]
    rows = []
    wall, cpu = _time(lambda: [codec.encode(m) for m in motions], repeats)
    rows.append(("encode (AclCodec.encode)", wall, cpu))
    wall, cpu = _time(lambda: [codec.decode(s) for s in streams], repeats)
    rows.append(("decode (AclCodec.decode: ACL + FK)", wall, cpu))
    wall, cpu = _time(lambda: [library.decompress(b, m.num_joints, 0, m.num_frames) for b, m in zip(buffers, motions)],
                      repeats)
    rows.append(("decode (ACL decompression only)", wall, cpu))
    print("| what | frames/s (wall) | frames/s (CPU) | wall s | CPU s |")
    print("|---|---:|---:|---:|---:|")
    for what, wall, cpu in rows:
        print(f"| {what} | {frames / wall:,.0f} | {frames / cpu:,.0f} | {wall:.3f} | {cpu:.3f} |")
    poses = 200_000
    walls, cpus = [], []
    for _ in range(repeats):
        totals = [library.time_single_pose(b, m.num_frames, poses // len(motions)) for b, m in zip(buffers, motions)]
        walls.append(sum(t[0] for t in totals))
        cpus.append(sum(t[1] for t in totals))
    count = (poses // len(motions)) * len(motions)
    print(f"Single pose (seek + decompress_tracks of {motions[0].num_joints} joints, C loop, {count} poses): "
          f"{1e6 * statistics.median(walls) / count:.2f} us wall, {1e6 * statistics.median(cpus) / count:.2f} us CPU "
          f"per pose; load average after: {os.getloadavg()[0]:.2f}")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--fmt", choices=("amc", "bvh"), default="amc", help="clip format (cmu_test reads amc)")
    parser.add_argument("--speed", action="store_true", help="also time encode, decode and single poses")
    parser.add_argument("--repeats", type=int, default=3, help="timing repeats (median)")
    parser.add_argument("--data-dir", default=None, help="CMU data folder (default: $MOCAPBENCH_CMU_DIR, ../shared)")
    parser.add_argument("--grid", action="store_true", help="shell x precision grid on the BVH clips, nearest points "
                        "to each reference row (no RD table)")
    parser.add_argument("--grid-shells", type=float, nargs="+", default=reference.GRID_SHELLS, metavar="CM")
    parser.add_argument("--grid-precisions", type=float, nargs="+", default=reference.GRID_PRECISIONS, metavar="CM")
    parser.add_argument("--variants", action="store_true", help="measurement and setting variants at the issue's "
                        "precisions on the BVH clips (no RD table)")
    parser.add_argument("--jitter", type=int, default=0, metavar="SEEDS",
                        help="spread over SEEDS float32-ulp jittered copies of the BVH clips (no RD table)")
    parser.add_argument("--neighbourhood", action="store_true",
                        help="spread over precisions p x 0.98..1.02 at 0.5 and 1 cm on the BVH clips (no RD table)")
    parser.add_argument("--why", action="store_true", help="ACL's own per-bone bit-rate summary from a patched "
                        "temporary copy of its headers, on the BVH clips (no RD table)")
    args = parser.parse_args(argv)
    if args.grid or args.variants or args.jitter or args.neighbourhood or args.why:
        if args.grid:
            reference.main_grid(args.grid_shells, args.grid_precisions, args.data_dir)
        if args.variants:
            reference.main_variants(PRECISIONS, args.data_dir)
        if args.jitter:
            reference.main_jitter(args.jitter, args.data_dir)
        if args.neighbourhood:
            reference.main_neighbourhood(args.data_dir)
        if args.why:
            reference.main_why(reference.WHY_SETTINGS, args.data_dir)
        return
    from mocapbench.datasets.cmu import load_split

    motions = load_split("cmu_test", fmt=args.fmt, data_dir=args.data_dir)
    frames = sum(m.num_frames for m in motions)
    print(f"cmu_test: {len(motions)} clips, {frames} frames, {motions[0].num_joints} joints, {motions[0].fps:g} fps "
          f"({args.fmt}); ACL {load_library().acl_version} from {load_library().path}")
    points = [rd_point(motions, p, shell) for shell in (3.0, 0.0) for p in PRECISIONS]
    _print_rd(points, args.fmt)
    if args.speed:
        _speed(motions, args.repeats)


if __name__ == "__main__":
    from mocapbench.benchmarks.entry import run_script

    raise SystemExit(run_script(main))
