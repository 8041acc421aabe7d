"""The native ``mcb-rot`` runtime beside ACL 2.1's own decoder, measured as ACL measures itself.

One C++ harness (``runtime/bench/bench_vs_acl.cpp``) links ACL 2.1 (header-only, ``../shared/third_party``) and the
runtime (``runtime/src/mcbrot.c``), both compiled here with the same compiler and flags (``-O2``, ACL's SSE4.1
minimum on x86-64); it samples every clip one pose at a time through each library's native API (ACL:
``decompression_context::seek`` + ``decompress_tracks``; mcb-rot: ``mcbrot_sample``, both nearest frame), in forward
playback, backward playback and random access, each with a warm and a cold cache, and reports microseconds of thread
CPU time per pose, the resident bytes (stream plus context) and the time to open a clip. The streams are made here
from the clips: mcb-rot at each ε (``eps_cm``), ACL with ``precision_cm = ε`` (its other settings the codec's
defaults); both decoded by Python once for their L∞ error (cm, max over joints and frames) and their ratio.

    python -m mocapbench.benchmarks.runtime [--dataset cmu_test] [--eps 0.1 0.5 1] [--every 1 5] [--repeats 3]
        [--set KEY=VALUE]

``--set`` sets an ``mcb-rot`` config field (e.g. ``--set segment_frames=64 --set chunk_frames=64``: shorter random
access units), so that the speed of a setting is measured beside its bytes.

Every figure is the decoder's native code (never Python); the decode-speed columns of the other benchmarks time
decoders through Python, and say so.
"""

from __future__ import annotations

import argparse
import hashlib
import os
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

from mocapbench import metrics

__all__ = ["main", "build_harness"]

_RUNTIME = Path(__file__).resolve().parents[2] / "runtime"
_HARNESS = _RUNTIME / "bench" / "bench_vs_acl.cpp"
_FLAGS = ["-O2", "-DNDEBUG"] + (["-msse4.1"] if os.uname().machine in ("x86_64", "amd64") else [])
_MODES = ("fwd_warm", "fwd_cold", "bwd_warm", "bwd_cold", "rnd_warm", "rnd_cold")


def build_harness() -> Path:
    """The harness, compiled once into the build cache (keyed by its sources, ACL's folder and the flags)."""
    from mocapbench.codecs.acl.build import find_acl_headers, find_compiler
    from mocapbench.codecs.native_build import cache_root
    from mocapbench.codecs.mcb_rot.native import _compiler

    headers = find_acl_headers()
    cxx, cc = find_compiler(), _compiler()
    if cc is None:
        raise RuntimeError("no C compiler found (set $CC or install gcc)")
    sources = [_HARNESS, _RUNTIME / "src" / "mcbrot.c", _RUNTIME / "src" / "mcbrot_tables.h",
               _RUNTIME / "include" / "mcbrot.h"]
    key = hashlib.sha256(b"".join(path.read_bytes() for path in sources) + str(headers.root).encode()
                         + " ".join(_FLAGS + [cc, cxx]).encode()).hexdigest()[:16]
    folder = cache_root() / f"runtime-bench-{key}"
    program = folder / "bench_vs_acl"
    if program.is_file():
        return program
    folder.mkdir(parents=True, exist_ok=True)
    include = ["-I", str(_RUNTIME / "include")]
    subprocess.run([cc, *_FLAGS, "-std=c99", *include, "-c", str(sources[1]), "-o", str(folder / "mcbrot.o")],
                   check=True)
    subprocess.run([cxx, *_FLAGS, "-std=c++17", *include, "-I", str(headers.acl_include), "-I",
                    str(headers.rtm_include), str(_HARNESS), str(folder / "mcbrot.o"), "-o", str(program), "-lm"],
                   check=True)
    return program


def _streams(motions, eps: float, folder: Path, tag: str, settings: dict) -> tuple[list[str], dict]:
    """Write each clip's mcb-rot stream and ACL buffer; manifest lines and the pooled ratios and errors."""
    from mocapbench.codecs import create
    from mocapbench.codecs.acl.codec import AclCodec  # noqa: F401 (the registry's ACL must be available)
    from mocapbench.entropy.bitio import ByteReader
    from mocapbench.codecs import container
    from mocapbench.codecs.skeleton_blob import unpack_skeleton

    lines, raw, sizes, errors = [], 0, {"mcb-rot": 0, "acl": 0}, {"mcb-rot": 0.0, "acl": 0.0}
    for index, motion in enumerate(motions):
        raw += 12 * motion.num_frames * motion.num_joints
        streams = {}
        for name, codec in (("mcb-rot", create("mcb-rot", **settings, eps_cm=eps)),
                            ("acl", create("acl", precision_cm=eps))):
            data = codec.encode(motion)
            streams[name] = data
            sizes[name] += len(data)
            decoded = create(name).decode(data)
            errors[name] = max(errors[name], metrics.max_joint_error(motion.positions(), decoded.positions))
        mcb = folder / f"{tag}-{index:02d}.mcb"
        mcb.write_bytes(streams["mcb-rot"])
        _, payload = container.unpack(streams["acl"], "acl")
        reader = ByteReader(payload)
        unpack_skeleton(reader)  # the payload: skeleton blob, then ACL's buffer (varint length + bytes)
        acl = folder / f"{tag}-{index:02d}.acl"
        acl.write_bytes(bytes(reader.read_blob("ACL buffer")))
        lines.append(f"{mcb} {acl}")
    pooled = {name: {"ratio": raw / sizes[name], "bytes": sizes[name], "linf_cm": errors[name]} for name in sizes}
    return lines, pooled


def _run(program: Path, lines: list[str], manifest: Path, repeats: int) -> list[dict]:
    manifest.write_text("\n".join(lines) + "\n")
    result = subprocess.run([str(program), str(manifest), str(repeats)], capture_output=True, text=True, check=True)
    rows = []
    for line in result.stdout.splitlines():
        fields = line.split()
        row = {"decoder": fields[0], "clip": fields[1], "frames": int(fields[2]), "joints": int(fields[3]),
               "stream_bytes": int(fields[4]), "resident_bytes": int(fields[5]), "open_us": float(fields[6])}
        row.update({mode: float(value) for mode, value in zip(_MODES, fields[7:13])})
        rows.append(row)
    return rows


def _table(rows: list[dict], pooled: dict, label: str) -> None:
    print(f"\n## {label}: µs per pose (median over clips; thread CPU time, native decoders)")
    print("| decoder | ratio | bytes | L∞ cm | " + " | ".join(_MODES)
          + " | resident bytes (max) | stream + 64 kB? | open µs |")
    print("|---|---:|---:|---:|" + "---:|" * len(_MODES) + "---:|---|---:|")
    medians = {}
    for decoder in ("mcb-rot", "acl"):
        mine = [row for row in rows if row["decoder"] == decoder]
        medians[decoder] = {mode: statistics.median(row[mode] for row in mine) for mode in _MODES}
        within = all(row["resident_bytes"] <= row["stream_bytes"] + 65536 for row in mine)
        print(f"| {decoder} | {pooled[decoder]['ratio']:.2f} | {pooled[decoder]['bytes']:,} | "
              f"{pooled[decoder]['linf_cm']:.4f} | "
              + " | ".join(f"{medians[decoder][mode]:.3f}" for mode in _MODES)
              + f" | {max(row['resident_bytes'] for row in mine):,} | {'yes' if within else 'no'} | "
              f"{statistics.median(row['open_us'] for row in mine):.1f} |")
    print("| mcb-rot / acl | " + f"{pooled['mcb-rot']['ratio'] / pooled['acl']['ratio']:.2f} | | | "
          + " | ".join(f"{medians['mcb-rot'][mode] / medians['acl'][mode]:.2f}" for mode in _MODES) + " | | | |")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dataset", default="cmu_test")
    parser.add_argument("--data-dir", default=None)
    parser.add_argument("--eps", type=float, nargs="+", default=[0.1, 0.5, 1.0])
    parser.add_argument("--every", type=int, nargs="+", default=[1, 5], help="frame steps (1: 120 fps, 5: 24 fps)")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--keep", default=None, help="folder to keep the streams and manifests in (else a temporary "
                        "one): rerun the harness on them with `<harness> <folder>/<case>.txt REPEATS`")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="an mcb-rot config field (Python literal), e.g. --set segment_frames=64")
    args = parser.parse_args(argv)
    from mocapbench.cli.arguments import CliError, parse_settings
    from mocapbench.datasets.cmu import load_split

    from mocapbench.codecs import create

    try:
        settings = parse_settings(args.set)
        if "eps_cm" in settings:
            raise CliError("--set eps_cm: give the bounds with --eps")
        create("mcb-rot", **settings)  # a field or value it refuses is one line here, not a traceback later
    except (CliError, TypeError, ValueError) as error:
        parser.error(str(error))

    program = build_harness()
    motions = load_split(args.dataset, data_dir=args.data_dir)
    print(f"# the mcb-rot runtime beside ACL 2.1 on {args.dataset} ({len(motions)} clips; load average "
          f"{os.getloadavg()[0]:.1f}; flags {' '.join(_FLAGS)}; mcb-rot {settings or 'defaults'})")
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(args.keep or tmp)
        folder.mkdir(parents=True, exist_ok=True)
        print(f"(harness: {program})")
        for step in args.every:
            clips = [m.every(step) for m in motions] if step > 1 else motions
            fps = clips[0].fps
            for eps in args.eps:
                wall, cpu = time.perf_counter(), time.process_time()
                lines, pooled = _streams(clips, eps, folder, f"e{step}-{eps:g}", settings)
                rows = _run(program, lines, folder / f"e{step}-{eps:g}.txt", args.repeats)
                _table(rows, pooled, f"{args.dataset} at {fps:g} fps, ε = {eps:g} cm")
                print(f"({time.perf_counter() - wall:.0f} s wall, {time.process_time() - cpu:.0f} s CPU of this "
                      f"process beside the harness; load average {os.getloadavg()[0]:.1f})")


if __name__ == "__main__":
    main()
