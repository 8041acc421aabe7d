"""Long captures: peak memory and CPU per frame of every codec's encode and decode at 10k, 100k and 500k frames.

    python -m mocapbench.benchmarks.long_captures [--frames 10000,100000,500000] [--codecs a,b] [--tree DIR]
                                                  [--timeout 900] [--json out.jsonl] [--set KEY=VALUE]

Each (codec, frame count) runs in its own subprocess with the codec's default config (the neural Fourier codecs
only with ``--neural``: they train a network per clip, tens of ms of CPU per frame). The subprocess builds a
synthetic capture (:func:`mocapbench.synthetic.sinusoidal_motion` on the 31-joint CMU-like skeleton, seed 7, its
root moved on a bounded path, a 3 m circle taken in 30 s, as a capture volume holds it: the synthetic root walks
straight on at 1.2 m/s, 5 km away after 70 minutes, which no studio records), frees what building it
left behind, resets the kernel's peak-RSS mark (``/proc/self/clear_refs``), then encodes (CPU time of the process
and wall time), resets the mark again and decodes. Peak memory is the high-water mark of the resident set
(``VmHWM``) above the resident set before the step, so it counts every allocation of the step (numpy, zstd,
torch, Python objects), not the motion itself; it is printed in MB and as a multiple of the float64 positions
array (``F * J * 3 * 8`` bytes, 372 MB at 500k frames), the bound the benchmark asks of every non-neural codec.
The table gives the L-inf and mean error over the whole capture beside the ratio; ``--set KEY=VALUE`` sets a config
field of every codec run (e.g. ``--codecs pga-ik --set window_frames=7681``).

``--tree DIR`` runs the subprocesses on another checkout (``PYTHONPATH=DIR``), e.g. the commit before a change,
so one command prints before and after. ``--cache DIR`` keeps each synthetic capture in DIR (``.npz``) and later
subprocesses read it back (the same arrays up to a last-bit renormalization; building the 500k-frame capture
costs 32 CPU-s, more than most codecs' encode). Load average is printed beside the table (CPU time does not depend on
it much, wall time does). A subprocess that runs past ``--timeout`` seconds or fails is reported as such.
"""

from __future__ import annotations

import argparse
import inspect
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

from mocapbench.motion import Motion
from mocapbench.synthetic import sinusoidal_motion

__all__ = ["main", "CHILD", "synthetic_capture"]

NEURAL = ("fourier-mlp-dct", "fourier-mlp-int")

# The measurement, run with ``python -c`` so that it works on any checkout of the package (``--tree``); the
# capture is built by the source of :func:`synthetic_capture`, written into it.
_CHILD_HEAD = r"""
import ctypes, gc, json, os, sys, time
import numpy as np

def status(key):
    with open("/proc/self/status") as handle:
        for line in handle:
            if line.startswith(key):
                return int(line.split()[1]) * 1024
    return 0

def trim():
    gc.collect()
    try:
        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except OSError:
        pass

def reset_peak():
    with open("/proc/self/clear_refs", "w") as handle:
        handle.write("5")

name, frames = sys.argv[1], int(sys.argv[2])
params = json.loads(sys.argv[3]) if len(sys.argv) > 3 else {}
from mocapbench.codecs import create
from mocapbench.motion import Motion
from mocapbench.synthetic import sinusoidal_motion
"""

_CHILD_MEASURE = r"""

cache = os.environ.get("MOCAPBENCH_LONG_CAPTURES_CACHE")
cached = os.path.join(cache, f"sinusoidal-seed7-{frames}.npz") if cache else None
if cached and os.path.exists(cached):  # the same capture, read back instead of rebuilt (32 CPU-s at 500k frames)
    source = sinusoidal_motion(num_frames=1, seed=7)  # the skeleton and fps (they do not depend on F)
    with np.load(cached) as data:
        root, rotations = data["root"], data["rotations"]
    motion = Motion(source.skeleton, source.fps, root, rotations, name=f"synthetic-seed7-{frames}")
    del source, root, rotations
else:
    motion = synthetic_capture(frames)
    if cached:
        os.makedirs(cache, exist_ok=True)
        np.savez(cached + ".tmp.npz", root=motion.root_positions, rotations=motion.rotations)
        os.replace(cached + ".tmp.npz", cached)
codec = create(name, **params)
codec.decode(codec.encode(motion.slice(0, min(frames, 64))))  # lazy imports and caches, not the capture's cost
trim()
positions_bytes = frames * motion.num_joints * 3 * 8
out = {"codec": name, "frames": frames, "positions_mb": positions_bytes / 1e6}
reset_peak(); base = status("VmRSS")
cpu, wall = time.process_time(), time.perf_counter()
stream = codec.encode(motion)
out["encode_cpu_s"] = time.process_time() - cpu
out["encode_wall_s"] = time.perf_counter() - wall
out["encode_peak_mb"] = (status("VmHWM") - base) / 1e6
out["bytes"] = len(stream)
trim(); reset_peak(); base = status("VmRSS")
cpu, wall = time.process_time(), time.perf_counter()
decoded = codec.decode(stream).positions
out["decode_cpu_s"] = time.process_time() - cpu
out["decode_wall_s"] = time.perf_counter() - wall
out["decode_peak_mb"] = (status("VmHWM") - base) / 1e6
# The error over the whole capture, in blocks (the reference positions are computed block by block).
worst, total, block = 0.0, 0.0, 8192
for start in range(0, frames, block):
    stop = min(frames, start + block)
    error = np.linalg.norm(decoded[start:stop] - motion.slice(start, stop).positions(), axis=-1)
    worst, total = max(worst, float(error.max())), total + float(error.sum())
out["max_err_cm"] = worst
out["mean_err_cm"] = total / (frames * motion.num_joints)
print("RESULT " + json.dumps(out))
"""


def synthetic_capture(num_frames: int) -> Motion:
    """The benchmark's synthetic capture: :func:`~mocapbench.synthetic.sinusoidal_motion` (seed 7) on the CMU-like
    skeleton, its root moved on a 3 m circle taken in 30 s (a capture volume holds it), ``num_frames`` frames.

    Self-contained (the subprocess runs its source on any checkout): it needs only ``np``, ``Motion`` and
    ``sinusoidal_motion`` in scope.
    """
    source = sinusoidal_motion(num_frames=num_frames, seed=7)
    angle = 2 * np.pi * (np.arange(num_frames) / source.fps) / 30.0
    root = np.array(source.root_positions)
    root[:, 0] = 300.0 * np.cos(angle)
    root[:, 2] = 300.0 * np.sin(angle)
    return Motion(source.skeleton, source.fps, root, np.array(source.rotations), name=f"synthetic-seed7-{num_frames}")


CHILD = _CHILD_HEAD + "\n" + inspect.getsource(synthetic_capture) + "\n" + _CHILD_MEASURE


def _run_one(name: str, frames: int, tree: Path, timeout: float, cache: str | None = None,
             params: dict | None = None) -> dict:
    env = dict(os.environ, PYTHONPATH=str(tree), OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1")
    if cache:
        env["MOCAPBENCH_LONG_CAPTURES_CACHE"] = str(Path(cache).resolve())
    try:
        done = subprocess.run([sys.executable, "-c", CHILD, name, str(frames), json.dumps(params or {})], env=env,
                              capture_output=True, text=True, timeout=timeout, cwd=tree)
    except subprocess.TimeoutExpired:
        return {"codec": name, "frames": frames, "status": f"over {timeout:.0f} s"}
    for line in done.stdout.splitlines():
        if line.startswith("RESULT "):
            return {**json.loads(line[len("RESULT "):]), "status": "ok"}
    last = (done.stderr.strip().splitlines() or ["no output"])[-1]
    return {"codec": name, "frames": frames, "status": f"failed: {last[:160]}"}


def _row(result: dict) -> str:
    if result.get("status") != "ok":
        return f"| {result['codec']} | {result['frames']:,} | {result['status']} | | | | | | |"
    frames, positions = result["frames"], result["positions_mb"]
    return (
        f"| {result['codec']} | {frames:,} | {result['encode_peak_mb']:.0f} ({result['encode_peak_mb'] / positions:.1f}x) "
        f"| {result['decode_peak_mb']:.0f} ({result['decode_peak_mb'] / positions:.1f}x) "
        f"| {1e6 * result['encode_cpu_s'] / frames:.1f} | {1e6 * result['decode_cpu_s'] / frames:.1f} "
        f"| {result['max_err_cm']:.3g} | {positions * 1e6 / 2 / result['bytes']:.1f} | {result['mean_err_cm']:.3g} |"
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", default="10000,100000,500000", help="comma-separated frame counts")
    parser.add_argument("--codecs", default=None, help="comma-separated codec names (default: every registered one)")
    parser.add_argument("--neural", action="store_true", help="include the neural Fourier codecs")
    parser.add_argument("--tree", default=str(Path(__file__).resolve().parents[2]),
                        help="checkout whose package the subprocesses import (default: this one)")
    parser.add_argument("--timeout", type=float, default=900.0, help="seconds per (codec, frames) subprocess")
    parser.add_argument("--json", default=None, help="append every result as a JSON line to this file")
    parser.add_argument("--cache", default=None,
                        help="folder keeping each synthetic capture (.npz, 0.5 GB at 500k frames) so that later "
                             "subprocesses read it back instead of rebuilding it (32 CPU-s at 500k frames)")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="a codec config field for every codec run (JSON value), e.g. --set window_frames=7681")
    args = parser.parse_args(argv)
    tree = Path(args.tree).resolve()
    if args.codecs:
        names = args.codecs.split(",")
    else:
        listing = subprocess.run([sys.executable, "-c", "from mocapbench.codecs import codec_names; "
                                  "print(','.join(codec_names()))"], env=dict(os.environ, PYTHONPATH=str(tree)),
                                 capture_output=True, text=True, check=True, cwd=tree)
        names = [n for n in listing.stdout.strip().split(",") if args.neural or n not in NEURAL]
    frame_counts = [int(f) for f in args.frames.split(",")]
    params = {}
    for item in args.set:
        key, _, value = item.partition("=")
        try:
            params[key] = json.loads(value)
        except json.JSONDecodeError:
            params[key] = value
    if params:
        print(f"codec config: {params}")
    print(f"tree {tree}; load average {os.getloadavg()[0]:.1f} at start")
    print("| codec | frames | encode peak MB (x positions) | decode peak MB (x positions) | encode CPU us/frame "
          "| decode CPU us/frame | L-inf cm | CR | mean cm |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for frames in frame_counts:
        for name in names:
            result = _run_one(name, frames, tree, args.timeout, args.cache, params)
            print(_row(result), flush=True)
            if args.json:
                with open(args.json, "a") as handle:
                    handle.write(json.dumps({**result, "tree": str(tree)}) + "\n")
    print(f"load average {os.getloadavg()[0]:.1f} at end")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
