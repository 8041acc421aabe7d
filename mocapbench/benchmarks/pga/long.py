"""``pga-ik`` on long captures: error, ratio and the per-window L-inf, with and without the encoder's closed loop.

    python -m mocapbench.benchmarks.pga.long [--frames 1000,10000,100000] [--captures synthetic,cmu118]
                                             [--refine 0,1.5] [--data-dir D] [--json out.jsonl]

Two captures, cut to each frame count:

* ``synthetic``: the long-captures benchmark's capture,
  :func:`mocapbench.benchmarks.long_captures.synthetic_capture` (seed 7, its root on a 3 m circle taken in 30 s).
* ``cmu118``: CMU subject 118's 30 takes (``118_01`` .. ``118_30``, ASF/AMC, 19,449 frames at 120 fps) joined end to
  end, each take's root moved horizontally to start where the take before it ended (no jump of the root at a cut;
  the poses and the heading still jump there, as between any two takes). Longer captures play the 30 takes
  forwards, then backwards, then forwards again (no new discontinuity where two passes meet, and the root stays
  within 28 m, inside ``pga-ik``'s 50 m range).

For every (capture, frames, ``refine_ratio``) the table gives the mean and L-inf joint error over the whole capture
(cm), the ratio (float32 joint positions ``12 J F`` bytes over the stream's bytes), the median, 90th percentile and
largest L-inf of its windows (captures over 7,680 frames are coded in windows, ``pga-ik``'s ``window_frames``; the
overlap of the last window is counted once), the windows the closed loop coded again, and the CPU time of the
process per frame for encode and decode (one thread). ``--refine`` lists the ``refine_ratio`` values to compare
(0: the open-loop encoder). The load average is printed beside the table.
"""

from __future__ import annotations

import argparse
import json
import os
import time

import numpy as np

from mocapbench.benchmarks.long_captures import synthetic_capture
from mocapbench.codecs import create
from mocapbench.codecs.pga.codec import _long_extents
from mocapbench.codecs.windows import WINDOW_FRAMES
from mocapbench.datasets.cmu import load_clip
from mocapbench.motion import Motion

__all__ = ["synthetic_capture", "joined_takes", "window_linf", "measure_capture", "main"]

#: The takes of the joined CMU capture.
CMU_118_TAKES = tuple(f"118_{i:02d}" for i in range(1, 31))


def joined_takes(takes: list[Motion], num_frames: int, name: str = "joined") -> tuple[Motion, np.ndarray]:
    """Takes of one skeleton joined into a capture of ``num_frames`` frames, played forwards and backwards in turn.

    Parameters
    ----------
    takes : list of Motion
        Same skeleton and fps. Each take's root is moved horizontally (x and z; y is up) to start where the one
        before it ended.
    num_frames : int
        F. One pass holds every take once; the passes alternate forwards and backwards, each starting on the frame
        after the one the pass before ended on.

    Returns
    -------
    motion : Motion
        F frames.
    cuts : ndarray of int, shape (c,)
        The frames where a take meets the next one (the first frame after the cut), in order.
    """
    roots, rotations, starts, count = [], [], [], 0
    for take in takes:
        root = np.array(take.root_positions)
        if roots:
            root[:, [0, 2]] += roots[-1][-1, [0, 2]] - root[0, [0, 2]]
        starts.append(count)
        roots.append(root)
        rotations.append(np.asarray(take.rotations))
        count += take.num_frames
    one_root, one_rotations = np.concatenate(roots), np.concatenate(rotations)
    pass_frames, starts = len(one_root), np.array(starts[1:])
    order, cuts, total, forward = [np.arange(pass_frames)], [starts], pass_frames, False
    while total < num_frames:
        if forward:
            order.append(np.arange(1, pass_frames))
            cuts.append(total + starts - 1)
        else:
            order.append(np.arange(pass_frames - 2, -1, -1))
            cuts.append(total + (pass_frames - 1 - starts))  # frame j - 1 meets j: reversed, at P - 1 - j
        total += pass_frames - 1
        forward = not forward
    index = np.concatenate(order)[:num_frames]
    cuts = np.concatenate([np.sort(c) for c in cuts])
    motion = Motion(takes[0].skeleton, takes[0].fps, one_root[index], one_rotations[index], name=name)
    return motion, cuts[cuts < num_frames]


def window_linf(error: np.ndarray, window_frames: int, grid: int) -> np.ndarray:
    """L-inf (cm) of every window of ``pga-ik``'s layout, from the per-frame worst joint error ``error`` (F,), cm.

    One window for a capture up to :data:`WINDOW_FRAMES` frames; the frames the last window shares with the one
    before it count for the one before.
    """
    num_frames = len(error)
    if num_frames <= WINDOW_FRAMES:
        return np.array([error.max()])
    worst, done = [], 0
    for start, stop in _long_extents(num_frames, window_frames, grid):
        worst.append(error[max(start, done) : stop].max())
        done = stop
    return np.array(worst)


def measure_capture(motion: Motion, refine_ratio: float) -> dict:
    """Encode and decode ``motion`` with ``pga-ik`` at its defaults but ``refine_ratio``; errors in cm."""
    codec = create("pga-ik", refine_ratio=refine_ratio)
    cpu = time.process_time()
    stream = codec.encode(motion)
    encode_cpu = time.process_time() - cpu
    stats = dict(codec.last_encode_stats)
    cpu = time.process_time()
    decoded = codec.decode(stream).positions
    decode_cpu = time.process_time() - cpu
    error = np.linalg.norm(decoded - motion.positions(), axis=-1)
    config = codec.config
    windows = window_linf(error.max(axis=1), config.window_frames,
                          1 << max(config.root_levels_dropped, config.end_levels_dropped))
    return {
        "capture": motion.name, "frames": motion.num_frames, "refine_ratio": refine_ratio,
        "mean_cm": float(error.mean()), "linf_cm": float(error.max()),
        "ratio": 12 * motion.num_joints * motion.num_frames / len(stream), "bytes": len(stream),
        "windows": len(windows), "window_linf_median_cm": float(np.median(windows)),
        "window_linf_p90_cm": float(np.percentile(windows, 90)), "window_linf_max_cm": float(windows.max()),
        "refined_windows": int(stats.get("refined_windows", 0)),
        "encode_cpu_us_per_frame": 1e6 * encode_cpu / motion.num_frames,
        "decode_cpu_us_per_frame": 1e6 * decode_cpu / motion.num_frames,
    }


def _row(r: dict) -> str:
    return (
        f"| {r['capture']} | {r['frames']:,} | {r['refine_ratio']:g} | {r['mean_cm']:.3g} | {r['linf_cm']:.3g} "
        f"| {r['ratio']:.1f} | {r['windows']} | {r['window_linf_median_cm']:.3g} / {r['window_linf_p90_cm']:.3g} / "
        f"{r['window_linf_max_cm']:.3g} | {r['refined_windows']} | {r['encode_cpu_us_per_frame']:.0f} "
        f"| {r['decode_cpu_us_per_frame']:.0f} |"
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", default="1000,10000", help="comma-separated frame counts")
    parser.add_argument("--captures", default="synthetic,cmu118", help="synthetic and/or cmu118")
    parser.add_argument("--refine", default="0,1.5", help="comma-separated refine_ratio values (0: open loop)")
    parser.add_argument("--data-dir", default=None, help="CMU data folder (default: ../shared/data/cmu)")
    parser.add_argument("--json", default=None, help="append every result as a JSON line to this file")
    args = parser.parse_args(argv)
    frames = [int(f) for f in args.frames.split(",")]
    ratios = [float(r) for r in args.refine.split(",")]
    captures = args.captures.split(",")
    unknown = set(captures) - {"synthetic", "cmu118"}
    if unknown:
        parser.error(f"--captures: expected synthetic and/or cmu118, got {sorted(unknown)}")
    takes = [load_clip(name, data_dir=args.data_dir) for name in CMU_118_TAKES] if "cmu118" in captures else []
    print(f"Load average at start: {os.getloadavg()[0]:.1f}")
    print("| capture | frames | refine_ratio | mean cm | L-inf cm | ratio | windows | window L-inf median / p90 / max "
          "cm | refined | encode µs/frame | decode µs/frame |")
    print("|---|---:|---:|---:|---:|---:|---:|---|---:|---:|---:|")
    for capture in captures:
        for num_frames in frames:
            if capture == "synthetic":
                motion = synthetic_capture(num_frames)
            else:
                motion = joined_takes(takes, num_frames, name=f"cmu118-joined-{num_frames}")[0]
            for ratio in ratios:
                result = measure_capture(motion, ratio)
                print(_row(result), flush=True)
                if args.json:
                    with open(args.json, "a") as handle:
                        handle.write(json.dumps(result) + "\n")
    print(f"Load average at end: {os.getloadavg()[0]:.1f}")
    return 0


if __name__ == "__main__":
    from mocapbench.benchmarks.entry import run_script

    raise SystemExit(run_script(main))
