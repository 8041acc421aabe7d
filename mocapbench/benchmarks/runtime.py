"""The native ``mcb-rot`` runtime beside ACL 2.1's own decoder, measured as ACL measures itself.

One C++ harness (``runtime/bench/bench_vs_acl.cpp``) links ACL 2.1 (header-only, ``../shared/third_party``) and the
runtime (``runtime/src/mcbrot.c``), both compiled here with the same compiler and flags (``-O2``) for the same
instruction set (``--isa``, x86-64: ``avx2`` with FMA, the default where the CPU has them, or ``sse4.1``, ACL's
minimum; mcb-rot's runtime, which picks its AVX2 sums at open from the CPU, is built without them for ``sse4.1``, so
neither decoder runs wider instructions than the other); it samples every clip one whole pose at a time through each library's native API, both nearest
frame: ACL's ``decompression_context::seek`` + ``decompress_tracks`` writes every joint's rotation and translation,
and so does mcb-rot's ``mcbrot_sample_pose`` (rotations J x 4, translations J x 3: a game rig's translation tracks,
the skeleton offsets elsewhere), in forward playback, backward playback and random access, each with a warm and a
cold cache, and reports microseconds of thread CPU time per pose, the resident bytes (stream plus context) and the
time to open a clip. The streams are made here from the clips: mcb-rot at each ε (``eps_cm``), ACL with
``precision_cm = ε`` (its other settings the codec's defaults); both decoded by Python once for their L∞ error (cm,
max over joints and frames) and their ratio. Each case ends with a check that both harness decoders give the pose
Python decodes (one frame of every clip) and that ACL's translations are the clip's within ε.

    python -m mocapbench.benchmarks.runtime [--dataset cmu_test] [--eps 0.1 0.5 1] [--every 1 5] [--repeats 3]
        [--runs 1] [--sample] [--set KEY=VALUE] [--isa avx2 sse4.1] [--keep DIR [--force]]

``--dataset`` is a CMU split (``cmu_test``, ..., 120 fps: ``--every 1 5`` gives 120 and 24 fps) or a Bandai Namco
one (``bandai_test``, ``bandai_train``, ``bandai_all``: a 22-joint game rig at its native 30 fps, ``--every 1``
by default). ``--runs N`` runs the harness N times on the same streams and takes each clip's median over the runs
(each run itself the median of ``--repeats``). ``--sample`` also times ``mcbrot_sample`` (rotations and the root
only, what the harness timed before it took whole poses) on the same contexts: the cost of the joints' translations.
A clip that mcb-rot's encoder or a native decoder refuses is named in one line and left out of both decoders'
figures (the exit status is then 1).

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
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from mocapbench import metrics
from mocapbench.io.safe_output import write_bytes, write_text

__all__ = ["main", "build_harness", "harness_poses", "HarnessError"]

_RUNTIME = Path(__file__).resolve().parents[2] / "runtime"
_HARNESS = _RUNTIME / "bench" / "bench_vs_acl.cpp"
_FLAGS = ["-O2", "-DNDEBUG"]
_X86 = os.uname().machine in ("x86_64", "amd64")
# The instruction set both decoders are built for on x86-64 (--isa): (flags of both, flags of mcb-rot's runtime only).
# ACL and rtm choose their SSE4.1 or AVX code from the compiler's target; mcb-rot's runtime chooses its AVX2 + FMA
# sums at open from the CPU, so an SSE4.1 build leaves them out (MCBROT_NO_AVX2): either way both decoders run the
# same instruction set.
ISA_FLAGS = {"sse4.1": (["-msse4.1"], ["-DMCBROT_NO_AVX2"]), "avx2": (["-mavx2", "-mfma"], [])}
_MODES = ("fwd_warm", "fwd_cold", "bwd_warm", "bwd_cold", "rnd_warm", "rnd_cold")


class HarnessError(RuntimeError):
    """The harness refused its manifest or its arguments (exit status 2); the message is its one line."""


def cpu_isas() -> list[str]:
    """The ``--isa`` values this CPU runs (``avx2`` where /proc/cpuinfo lists avx2 and fma); none off x86-64."""
    if not _X86:
        return []
    try:
        flags = next((line.split(":", 1)[1].split() for line in Path("/proc/cpuinfo").read_text().splitlines()
                      if line.startswith("flags")), [])
    except OSError:
        flags = []
    return ["sse4.1"] + (["avx2"] if {"avx2", "fma"} <= set(flags) else [])


def harness_flags(isa: str | None) -> tuple[list[str], list[str]]:
    """(flags of both decoders, flags of mcb-rot's runtime only) for ``isa`` (None: no ISA flag, off x86-64)."""
    if isa is None:
        return list(_FLAGS), []
    common, runtime_only = ISA_FLAGS[isa]
    return _FLAGS + common, list(runtime_only)


def build_harness(isa: str | None = None) -> Path:
    """The harness for ``isa`` (an :data:`ISA_FLAGS` key; None: the best this CPU runs), compiled once into the build
    cache (keyed by its sources, ACL's folder and the flags)."""
    from mocapbench.codecs.acl.build import find_acl_headers, find_compiler
    from mocapbench.codecs.native_build import cache_root
    from mocapbench.codecs.mcb_rot.native import _compiler

    if isa is None:
        isa = (cpu_isas() or [None])[-1]
    flags, runtime_flags = harness_flags(isa)
    headers = find_acl_headers()
    cxx, cc = find_compiler(), _compiler()
    if cc is None:
        raise RuntimeError("no C compiler found (set $CC or install gcc)")
    sources = [_HARNESS, _RUNTIME / "src" / "mcbrot.c", _RUNTIME / "src" / "mcbrot_tables.h",
               _RUNTIME / "include" / "mcbrot.h"]
    key = hashlib.sha256(b"".join(path.read_bytes() for path in sources) + str(headers.root).encode()
                         + " ".join(flags + runtime_flags + [cc, cxx]).encode()).hexdigest()[:16]
    folder = cache_root() / f"runtime-bench-{key}"
    program = folder / "bench_vs_acl"
    if program.is_file():
        return program
    folder.mkdir(parents=True, exist_ok=True)
    include = ["-I", str(_RUNTIME / "include")]
    subprocess.run([cc, *flags, *runtime_flags, "-std=c99", *include, "-c", str(sources[1]), "-o",
                    str(folder / "mcbrot.o")], check=True)
    subprocess.run([cxx, *flags, "-std=c++17", *include, "-I", str(headers.acl_include), "-I",
                    str(headers.rtm_include), str(_HARNESS), str(folder / "mcbrot.o"), "-o", str(program), "-lm"],
                   check=True)
    return program


def _streams(motions, eps: float, folder: Path, tag: str, settings: dict, frame: int = 0):
    """Write each clip's mcb-rot stream and ACL buffer: the manifest lines, the pooled ratios and errors, each written
    clip's pose at ``frame`` as each decoder's Python decode gives it (rotations (J, 4), translations (J, 3), the
    source's beside them, by manifest stream path) and one line per clip that mcb-rot's encoder or decoder refused
    (that clip is left out of both decoders' figures)."""
    from mocapbench.codecs import create
    from mocapbench.codecs.acl.codec import AclCodec  # noqa: F401 (the registry's ACL must be available)
    from mocapbench.entropy.bitio import ByteReader
    from mocapbench.codecs import container
    from mocapbench.codecs.skeleton_blob import unpack_skeleton

    lines, raw, sizes, errors = [], 0, {"mcb-rot": 0, "acl": 0}, {"mcb-rot": 0.0, "acl": 0.0}
    poses, refused = {}, []
    for index, motion in enumerate(motions):
        streams, decoded, pose_frame = {}, {}, min(frame, motion.num_frames - 1)
        for name, codec in (("mcb-rot", create("mcb-rot", **settings, eps_cm=eps)),
                            ("acl", create("acl", precision_cm=eps))):
            try:
                streams[name] = codec.encode(motion)
                decoded[name] = create(name).decode(streams[name])
            except Exception as error:  # a finding to report with the clip's name, not a reason to stop the table
                refused.append(f"{name} refused clip {index} ({motion.name or 'unnamed'}, {motion.num_frames} frames)"
                               f": {type(error).__name__}: {' '.join(str(error).split())}")
                break
        if len(decoded) < 2:
            continue
        raw += 12 * motion.num_frames * motion.num_joints
        for name, data in streams.items():
            sizes[name] += len(data)
            errors[name] = max(errors[name], metrics.max_joint_error(motion.positions(), decoded[name].positions))
        mcb = folder / f"{tag}-{index:02d}.mcb"
        write_bytes(mcb, streams["mcb-rot"], force=True)  # the folder was checked (main): a link is replaced
        _, payload = container.unpack(streams["acl"], "acl")
        reader = ByteReader(payload)
        unpack_skeleton(reader)  # the payload: skeleton blob, then ACL's buffer (varint length + bytes)
        acl = folder / f"{tag}-{index:02d}.acl"
        write_bytes(acl, bytes(reader.read_blob("ACL buffer")), force=True)
        lines.append(f"{mcb} {acl}")
        poses[str(mcb)] = {name: (d.motion.rotations[pose_frame], d.motion.local_translations()[pose_frame])
                           for name, d in decoded.items()}
        poses[str(mcb)]["source"] = (motion.rotations[pose_frame], motion.local_translations()[pose_frame])
    pooled = {name: {"ratio": raw / max(sizes[name], 1), "bytes": sizes[name], "linf_cm": errors[name]}
              for name in sizes}
    return lines, pooled, poses, refused


def _harness(program: Path, manifest: Path, *options: str) -> subprocess.CompletedProcess:
    """Run the harness; its refusal of the manifest or its arguments (exit 2) is a :class:`HarnessError`."""
    result = subprocess.run([str(program), str(manifest), *options], capture_output=True, text=True)
    if result.returncode == 2 or (result.returncode != 0 and not result.stdout.strip()):
        lines = result.stderr.strip().splitlines() or [f"exit status {result.returncode}"]
        raise HarnessError(f"{program.name}: {lines[0]}")
    return result


def _run(program: Path, lines: list[str], manifest: Path, repeats: int, *, runs: int = 1, sample: bool = False,
         failures: list[str] | None = None) -> list[dict]:
    """The harness's rows, one per clip and decoder (``mcb-rot``, ``acl``, with ``sample`` ``mcb-rot-sample``):
    over ``runs`` runs each figure is the clip's median. A clip a native decoder refused is one line of the harness's
    stderr, appended to ``failures``; the other clips' rows come back."""
    write_text(manifest, "\n".join(lines) + "\n", force=True)
    per_run = []
    for _ in range(runs):
        result = _harness(program, manifest, str(repeats), *(["--sample"] if sample else []))
        if failures is not None and result.returncode != 0:
            failures.extend(line for line in result.stderr.splitlines() if line.strip())
        rows = []
        for line in result.stdout.splitlines():
            fields = line.split()
            row = {"decoder": fields[0], "clip": fields[1], "frames": int(fields[2]), "joints": int(fields[3]),
                   "stream_bytes": int(fields[4]), "resident_bytes": int(fields[5]), "open_us": float(fields[6])}
            row.update({mode: float(value) for mode, value in zip(_MODES, fields[7:13])})
            rows.append(row)
        per_run.append(rows)
    rows = per_run[0]
    for row in rows:
        same = [other for rows_of_run in per_run for other in rows_of_run
                if (other["decoder"], other["clip"]) == (row["decoder"], row["clip"])]
        for key in ("open_us", *_MODES):
            row[key] = statistics.median(other[key] for other in same)
    return rows


def harness_poses(program: Path, manifest: Path, frame: int) -> dict:
    """Each clip's pose at ``frame`` (clamped to the clip) as the harness's two decoders give it: ``{(decoder,
    stream path): (rotations (J, 4) x, y, z, w, translations (J, 3) cm)}`` (``mcb-rot``: ``mcbrot_sample_pose``;
    ``acl``: ``decompress_tracks``, float32 widened)."""
    result = _harness(program, manifest, "--pose", str(frame))
    if result.returncode != 0:
        raise HarnessError(f"{program.name}: {result.stderr.strip().splitlines()[0]}")
    joints: dict = {}
    for line in result.stdout.splitlines():
        fields = line.split()
        joints.setdefault((fields[1], fields[2]), []).append([float(value) for value in fields[5:12]])
    return {key: (np.array(rows)[:, :4], np.array(rows)[:, 4:]) for key, rows in joints.items()}


def _rotation_gap(a: np.ndarray, b: np.ndarray) -> float:
    """Largest difference between two sets of unit quaternions (J, 4), q and -q being one rotation."""
    return float(np.minimum(np.abs(a - b).max(axis=1), np.abs(a + b).max(axis=1)).max())


def _pose_check(program: Path, manifest: Path, frame: int, poses: dict, eps: float) -> str:
    """One line: how far the harness's poses are from Python's decodes, and ACL's translations from the clip's."""
    from mocapbench.codecs.mcb_rot import native

    native_pose = harness_poses(program, manifest, frame)
    gaps = {"mcb-rot": [0.0, 0.0], "acl": [0.0, 0.0]}
    from_source = {"mcb-rot": 0.0, "acl": 0.0}
    for clip, python in poses.items():
        if ("mcb-rot", clip) not in native_pose:  # a clip the harness refused (named above the check)
            continue
        for decoder, gap in gaps.items():
            rotations, translations = native_pose[(decoder, clip)]
            gap[0] = max(gap[0], _rotation_gap(rotations, python[decoder][0]))
            gap[1] = max(gap[1], float(np.abs(translations - python[decoder][1]).max()))
            from_source[decoder] = max(from_source[decoder], float(np.abs(translations - python["source"][1]).max()))
    path = "numpy" if native.library() is None else "the runtime through ctypes"
    return (f"(pose check, frame {frame} of every clip: harness mcb-rot (mcbrot_sample_pose) vs Python's mcb-rot "
            f"decode ({path}): |Δq| ≤ {gaps['mcb-rot'][0]:.1e}, |Δt| ≤ {gaps['mcb-rot'][1]:.1e} cm; harness ACL vs "
            f"Python's ACL decode: |Δq| ≤ {gaps['acl'][0]:.1e}, |Δt| ≤ {gaps['acl'][1]:.1e} cm; every joint's "
            f"translation from the clip's: mcb-rot ≤ {from_source['mcb-rot']:.3f} cm, ACL ≤ {from_source['acl']:.3f} "
            f"cm at ε = {eps:g})")


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
    sampled = {row["clip"]: row for row in rows if row["decoder"] == "mcb-rot-sample"}
    if sampled:
        whole = {row["clip"]: row for row in rows if row["decoder"] == "mcb-rot"}
        print("| mcb-rot, mcbrot_sample (rotations + root) | | | | "
              + " | ".join(f"{statistics.median(row[mode] for row in sampled.values()):.3f}" for mode in _MODES)
              + " | | | |")
        print("| sample_pose − sample, µs (median over clips) | | | | "
              + " | ".join(f"{statistics.median(whole[clip][mode] - row[mode] for clip, row in sampled.items()):+.3f}"
                           for mode in _MODES) + " | | | |")


def _label(dataset: str, native_fps: float, step: int, eps: float) -> str:
    rate = (f"{native_fps / step:g} fps (every {step}th frame of its {native_fps:g} fps)" if step > 1
            else f"{native_fps:g} fps (its native rate, every frame)")
    return f"{dataset} at {rate}, ε = {eps:g} cm"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dataset", default="cmu_test", help="a CMU split (cmu_test, ...) or a Bandai Namco one "
                        "(bandai_test, bandai_train, bandai_all)")
    parser.add_argument("--data-dir", default=None)
    parser.add_argument("--eps", type=float, nargs="+", default=[0.1, 0.5, 1.0])
    parser.add_argument("--every", type=int, nargs="+", default=None,
                        help="frame steps (CMU default 1 5: 120 and 24 fps; Bandai Namco default 1: 30 fps)")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--runs", type=int, default=1, help="harness runs on the same streams (median per clip)")
    parser.add_argument("--sample", action="store_true",
                        help="also time mcbrot_sample (rotations and root only) beside mcbrot_sample_pose")
    parser.add_argument("--keep", default=None, help="folder to keep the streams and manifests in (else a temporary "
                        "one): rerun the harness on them with `<harness> <folder>/<case>.txt REPEATS`")
    parser.add_argument("--force", action="store_true", help="with --keep: replace what a folder already holds")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="an mcb-rot config field (Python literal), e.g. --set segment_frames=64")
    parser.add_argument("--isa", nargs="+", default=None, choices=sorted(ISA_FLAGS),
                        help="x86-64: the instruction sets to build both decoders for, one table each (default: the "
                             "widest this CPU runs, avx2 where it has AVX2 and FMA)")
    args = parser.parse_args(argv)
    from mocapbench.benchmarks.mcb_rot.rd import _load
    from mocapbench.cli.arguments import CliError, parse_settings

    from mocapbench.codecs import create

    try:
        settings = parse_settings(args.set)
        if "eps_cm" in settings:
            raise CliError("--set eps_cm: give the bounds with --eps")
        if min(args.every or [1]) < 1 or args.repeats < 1 or args.runs < 1:
            raise CliError("--every, --repeats and --runs take positive integers")
        create("mcb-rot", **settings)  # a field or value it refuses is one line here, not a traceback later
        if args.keep:
            _check_keep(Path(args.keep), args.force)
        isas = _isas(args.isa)
    except (CliError, TypeError, ValueError) as error:
        parser.error(str(error))

    programs = {isa: build_harness(isa) for isa in isas}
    motions = _load(args.dataset, args.data_dir)
    try:
        return _measure(programs, motions, args, settings)
    except HarnessError as error:  # the harness refused what this script gave it: a bug here, said in one line
        print(f"mocapbench.benchmarks.runtime: {error}", file=sys.stderr)
        return 2


def _isas(asked: list[str] | None) -> list:
    """The instruction sets to measure: ``asked`` in order without repeats, each one this CPU runs (CliError
    naming one it does not); by default the widest it runs; ``[None]`` off x86-64 (no ISA flag)."""
    from mocapbench.cli.arguments import CliError

    runs = cpu_isas()
    if not runs:
        if asked:
            raise CliError(f"--isa {' '.join(asked)}: this machine is {os.uname().machine}, not x86-64")
        return [None]
    for isa in asked or []:
        if isa not in runs:
            raise CliError(f"--isa {isa}: this CPU does not run it (it runs {', '.join(runs)})")
    return list(dict.fromkeys(asked)) if asked else [runs[-1]]


def _check_keep(folder: Path, force: bool) -> None:
    """Refuse a ``--keep`` folder that is a link or not a folder, or that holds anything unless ``force``: its
    streams and manifests are replaced (each file by a new one, never written through a link)."""
    from mocapbench.cli.arguments import CliError

    if folder.is_symlink():
        raise CliError(f"--keep {folder} is a link; give a folder")
    if folder.exists() and not folder.is_dir():
        raise CliError(f"--keep {folder} is not a folder")
    if folder.is_dir() and not force and any(folder.iterdir()):
        raise CliError(f"--keep {folder} is not empty; pass --force to replace the streams and manifests in it")


def _isa_text(isa: str | None) -> str:
    """The flags a harness was built with, said in words."""
    flags, runtime_only = harness_flags(isa)
    return (f"{isa or 'no ISA flag'}: {' '.join(flags)} for both decoders"
            + (f", {' '.join(runtime_only)} for mcb-rot's runtime" if runtime_only else ""))


def _measure(programs: dict, motions: list, args: argparse.Namespace, settings: dict) -> int:
    """Every case (frame step x ε): streams, then for each instruction set (``programs``: ISA -> harness) the
    harness's table and the pose check; 1 if a clip was refused."""
    steps = args.every or ([1] if args.dataset.startswith("bandai_") else [1, 5])
    print(f"# the mcb-rot runtime beside ACL 2.1 on {args.dataset} ({len(motions)} clips, {motions[0].num_joints} "
          f"joints; load average {os.getloadavg()[0]:.1f}; mcb-rot {settings or 'defaults'}; "
          f"whole poses: mcbrot_sample_pose beside ACL's decompress_tracks)")
    refused_any = False
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(args.keep or tmp)
        folder.mkdir(parents=True, exist_ok=True)
        for isa, program in programs.items():
            print(f"(harness for {_isa_text(isa)}: {program}; {args.runs} run(s) of {args.repeats} repeats per clip "
                  f"and mode)")
        for step in steps:
            clips = [m.every(step) for m in motions] if step > 1 else motions
            frame = min(clip.num_frames for clip in clips) // 2
            for eps in args.eps:
                wall, cpu = time.perf_counter(), time.process_time()
                case = f"e{step}-{eps:g}"
                lines, pooled, poses, refused = _streams(clips, eps, folder, case, settings, frame)
                label = _label(args.dataset, motions[0].fps, step, eps)
                for line in refused:
                    print(f"({label}: {line})")
                refused_any |= bool(refused)
                if not lines:
                    continue
                for isa, program in programs.items():
                    title = f"{label}, {isa}" if len(programs) > 1 else label
                    failures: list[str] = []
                    rows = _run(program, lines, folder / f"{case}.txt", args.repeats, runs=args.runs,
                                sample=args.sample, failures=failures)
                    if {row["decoder"] for row in rows} >= {"mcb-rot", "acl"}:
                        _table(rows, pooled, title)
                    for line in dict.fromkeys(failures):  # a clip refused in every run: named once
                        print(f"({title}: the harness refused {line})")
                    refused_any |= bool(failures)
                    print(_pose_check(program, folder / f"{case}.txt", frame, poses, eps))
                print(f"({time.perf_counter() - wall:.0f} s wall, {time.process_time() - cpu:.0f} s CPU of this "
                      f"process beside the harness; load average {os.getloadavg()[0]:.1f})")
    return 1 if refused_any else 0


if __name__ == "__main__":
    from mocapbench.benchmarks.entry import run_script

    raise SystemExit(run_script(main))
