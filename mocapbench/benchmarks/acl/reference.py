"""Why two of the independent ACL reference points differ from ours: the settings grid and the measurement variants.

    python -m mocapbench.benchmarks.acl.rd --fmt bvh --grid       # shell x precision grid, best match per reference row
    python -m mocapbench.benchmarks.acl.rd --fmt bvh --variants   # other ways the reference could have run or measured
    python -m mocapbench.benchmarks.acl.rd --fmt bvh --jitter 5   # ACL's spread under float32-ulp changes of the input
    python -m mocapbench.benchmarks.acl.rd --fmt bvh --neighbourhood  # ... and under +-2 % changes of the precision
    python -m mocapbench.benchmarks.acl.rd --fmt bvh --why        # ACL's own per-bone summary (a patched temp copy)

The reference (:data:`ISSUE_REFERENCE`) is ACL 2.1.0 run independently on the 12
``cmu_test`` BVH clips. Each hypothesis is measured on the same 4 numbers the reference gives (ratio = 12·J·F /
ACL's buffer bytes; joint L∞, mean and p99 in cm, pooled over every joint of every frame of every clip), and a
point's distance to a reference row is the largest relative deviation of those 4 numbers.

- **grid**: every (shell distance, precision) of ``--grid-shells`` x ``--grid-precisions``.
- **variants**: at the issue's precisions, shell 3 cm: the BVH reference frame 0 kept (compressed and
  measured, or compressed and left out of the measurement); end sites added to the measured points; the root
  left out; the reference positions from the float32 quaternions ACL was given; the clip given to ACL in BVH
  units (precision and shell divided by 5.6444, or only the precision, i.e. a shell of 3 units = 16.9 cm; or
  neither, i.e. a precision of p units); a sample rate of 30 fps or 1/0.008333 s; the full-precision rotation
  or translation format; CMU's two hand leaves (constant rotations) left out of what ACL compresses, measured
  or not; compression levels automatic/high/medium; trivial-keyframe stripping and loop
  optimisation off. Error metrics are not a variant: without scale, ACL's three transform metrics
  (``qvvf_transform_error_metric``, ``qvvf_matrix3x4f_transform_error_metric``, ``additive_qvvf_...`` on a
  non-additive clip) run the same ``calculate_error_no_scale`` code.
- **jitter**: each local rotation turned by a random angle of about ``1e-7`` rad and each root coordinate
  scaled by ``1 + 1e-7`` noise (float32 rounding, what a different BVH reader or Euler conversion produces),
  ``--jitter`` seeds.
- **neighbourhood**: each reference precision times 0.98 .. 1.02 (shells 3 and 0): how far one setting's
  numbers move, the L∞ (a maximum over 5587 x 31 errors) most of all.
- **why**: ACL's own account of its bit-rate search. The ACL headers are copied to a temporary folder with one
  line changed (``ACL_IMPL_DEBUG_VARIABLE_QUANTIZATION`` set to ``ACL_IMPL_DEBUG_LEVEL_SUMMARY_ONLY``, plus
  ``#include <cstdio>`` which that debug path needs), the shim is built against the copy, and ACL's summary is
  parsed: per (segment, bone), the final rotation bit-rate index and whether the bone's object-space error is
  still over its precision after ACL's search (ACL's "!"; then ACL raises the bit rates of the bone's whole
  chain, "this should be rare" in ``quantize.transform.h``). The copy and its build live in a temporary folder
  and the build cache; nothing of ACL enters the repository.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import re
import shutil
import sys
import tempfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from mocapbench import metrics
from mocapbench.codecs import create
from mocapbench.datasets.cmu import CMU_CM_PER_UNIT, clip_names, cmu_data_dir
from mocapbench.io.bvh import read_bvh
from mocapbench.motion import Motion, Skeleton

__all__ = ["ISSUE_REFERENCE", "ISSUE_SHELL0",
           "Variant", "VARIANTS", "measure", "deviation", "grid", "run_variants", "run_jitter", "closest",
           "parse_quantization_summary", "main_grid", "main_variants", "main_jitter", "main_neighbourhood", "main_why"]

# The reference: ACL 2.1.0 built and run independently on the cmu_test BVH files, level highest, shell 3 cm.
# precision cm -> (ratio, bits/joint/frame, L-inf cm, mean cm, p99 cm)
ISSUE_REFERENCE = {
    0.01: (4.43, 21.67, 0.0127, 0.0029, 0.0081),
    0.1: (7.18, 13.36, 0.120, 0.029, 0.080),
    0.5: (13.54, 7.09, 0.552, 0.134, 0.392),
    1.0: (17.89, 5.37, 1.26, 0.241, 0.741),
}
# Shell distance 0 (two points quoted): ratio -> L-inf cm.
ISSUE_SHELL0 = ((15.6, 0.68), (20.3, 1.51))


HAND_LEAVES = ("LeftHandIndex1", "RightHandIndex1")
"""CMU's two hand leaf joints: constant rotations, 3-4 cm past a zero-length finger-base bone; in ACL's own summary
(``--why``) the bones most often still over their precision after ACL's bit-rate search."""
GRID_SHELLS = (0.0, 0.5, 1.0, 2.0, 3.0, 5.0)
GRID_PRECISIONS = (0.4, 0.45, 0.5, 0.55, 0.6, 0.8, 0.9, 1.0, 1.1, 1.2)


@dataclass(frozen=True)
class Variant:
    """One way the reference could have been run or measured.

    Attributes
    ----------
    name : str
    keep_frame0 : bool
        Compress the BVH reference frame 0 too (5,599 frames instead of 5,587).
    measure_frame0 : bool
        With ``keep_frame0``, measure it too (else frames 1: only).
    points : str
        ``"joints"`` (the 31 joints), ``"joints+ends"`` (and the end sites), ``"no-root"`` (joints 1..30).
    reference_float32 : bool
        Reference positions by FK of the float32 quaternions ACL was given, not the float64 ones.
    unit_cm : float
        Length unit of the clip given to ACL, cm (1: cm; 5.6444: BVH units). Errors are reported in cm.
    precision_in_units, shell_in_units : bool
        With ``unit_cm != 1``: the precision (shell) is converted to that unit (True) or passed as the cm number.
    drop_leaves : tuple of str
        Leaf joints left out of what ACL compresses (their raw rotations are put back before FK; for joints whose
        rotation is constant, as CMU's hand leaves, that is exact).
    measure_dropped : bool
        With ``drop_leaves``, measure those joints too (else only the joints ACL got).
    fps : float
        Sample rate given to ACL (0: the clip's 120 fps); the clip is decoded at the same rate.
    codec : tuple of (str, Any)
        Other ``acl`` config fields.
    """

    name: str
    keep_frame0: bool = False
    measure_frame0: bool = False
    points: str = "joints"
    reference_float32: bool = False
    unit_cm: float = 1.0
    precision_in_units: bool = True
    shell_in_units: bool = True
    drop_leaves: tuple[str, ...] = ()
    measure_dropped: bool = True
    fps: float = 0.0
    codec: tuple[tuple[str, Any], ...] = ()


VARIANTS = (
    Variant("ours (frame 0 dropped, 31 joints, cm)"),
    Variant("frame 0 compressed and measured", keep_frame0=True, measure_frame0=True),
    Variant("frame 0 compressed, not measured", keep_frame0=True),
    Variant("+ end sites measured", points="joints+ends"),
    Variant("root not measured", points="no-root"),
    Variant("reference = float32 quaternions", reference_float32=True),
    Variant("BVH units, precision and shell converted", unit_cm=CMU_CM_PER_UNIT),
    Variant("BVH units, shell 3 units (16.9 cm)", unit_cm=CMU_CM_PER_UNIT, shell_in_units=False),
    Variant("BVH units, precision p units (5.64p cm)", unit_cm=CMU_CM_PER_UNIT, precision_in_units=False),
    Variant("hand leaves not given to ACL, 31 joints measured", drop_leaves=HAND_LEAVES),
    Variant("hand leaves not given to ACL, 29 joints measured", drop_leaves=HAND_LEAVES, measure_dropped=False),
    Variant("sample rate 30 fps", fps=30.0),
    Variant("sample rate 1/0.008333 s (120.0048 fps)", fps=1 / 0.008333),
    Variant("rotation format quatf_drop_w_full", codec=(("rotation_format", "quatf_drop_w_full"),)),
    Variant("translation format vector3f_full", codec=(("translation_format", "vector3f_full"),)),
    Variant("level automatic", codec=(("level", "automatic"),)),
    Variant("level high", codec=(("level", "high"),)),
    Variant("level medium", codec=(("level", "medium"),)),
    Variant("strip trivial keyframes off", codec=(("strip_trivial_keyframes", False),)),
    Variant("loop optimisation off", codec=(("optimize_loops", False),)),
)


def _scaled(motion: Motion, factor: float) -> Motion:
    """``motion`` with every length multiplied by ``factor`` (a unit change)."""
    skeleton = dataclasses.replace(motion.skeleton, offsets=motion.skeleton.offsets * factor,
                                   end_site_offsets=motion.skeleton.end_site_offsets * factor)
    return dataclasses.replace(motion, skeleton=skeleton, root_positions=motion.root_positions * factor)


def _without_leaves(motion: Motion, leaves: Sequence[str]) -> tuple[Motion, list[int]]:
    """``motion`` without the leaf joints ``leaves`` (end sites dropped too), and the indices of the joints kept."""
    skeleton = motion.skeleton
    drop = {skeleton.index(name) for name in leaves}
    for joint in drop:
        if skeleton.children(joint):
            raise ValueError(f"{skeleton.names[joint]!r} is not a leaf joint.")
    keep = [j for j in range(skeleton.num_joints) if j not in drop]
    new_index = {old: new for new, old in enumerate(keep)}
    reduced = Skeleton(names=tuple(skeleton.names[j] for j in keep),
                       parents=np.array([new_index.get(int(skeleton.parents[j]), -1) for j in keep]),
                       offsets=skeleton.offsets[keep],
                       channel_orders=tuple(skeleton.channel_orders[j] for j in keep) if skeleton.channel_orders else ())
    return dataclasses.replace(motion, skeleton=reduced, rotations=motion.rotations[:, keep]), keep


def _points(motion: Motion, which: str) -> np.ndarray:
    """Measured points of ``motion``, (F, P, 3) cm."""
    positions = motion.positions()
    if which == "joints":
        return positions
    if which == "no-root":
        return positions[:, 1:]
    if which == "joints+ends":
        return np.concatenate([positions, motion.end_site_positions()], axis=1)
    raise ValueError(f"Unknown point set {which!r}; expected 'joints', 'no-root' or 'joints+ends'.")


def load_bvh(keep_frame0: bool, data_dir: str | None = None) -> list[Motion]:
    """The ``cmu_test`` BVH clips in cm, with or without their reference frame 0."""
    root = cmu_data_dir(data_dir)
    return [read_bvh(root / "bvh" / f"{name}.bvh", length_unit_cm=CMU_CM_PER_UNIT, drop_first_frame=not keep_frame0,
                     name=name) for name in clip_names("cmu_test", data_dir=root)]


def measure(motions: Sequence[Motion], precision_cm: float, shell_cm: float, variant: Variant = VARIANTS[0]
            ) -> dict[str, float]:
    """ACL at one setting under one variant: ratio (12·J·F of the measured frames / ACL buffer bytes) and the
    pooled joint errors (cm) of the measured points."""
    factor = 1.0 / variant.unit_cm
    precision = precision_cm * (factor if variant.precision_in_units else 1.0)
    shell = shell_cm * (factor if variant.shell_in_units else 1.0)
    codec = create("acl", precision_cm=precision, shell_cm=shell, **dict(variant.codec))
    errors = []
    buffer_bytes = raw_bytes = 0
    for motion in motions:
        given = _scaled(motion, factor) if factor != 1.0 else motion
        if variant.fps:
            given = dataclasses.replace(given, fps=variant.fps)
        keep = list(range(motion.num_joints))
        if variant.drop_leaves:
            given, keep = _without_leaves(given, variant.drop_leaves)
        decoded = codec.decode(codec.encode(given)).motion
        if factor != 1.0:
            decoded = _scaled(decoded, 1.0 / factor)
        if variant.drop_leaves:
            rotations = motion.rotations.copy()
            rotations[:, keep] = decoded.rotations
            decoded = dataclasses.replace(motion, root_positions=decoded.root_positions, rotations=rotations)
        reference = motion
        if variant.reference_float32:
            reference = dataclasses.replace(motion, rotations=motion.rotations.astype(np.float32).astype(np.float64))
        first = 1 if variant.keep_frame0 and not variant.measure_frame0 else 0
        measured = slice(None) if variant.measure_dropped else keep
        error = metrics.joint_errors(_points(reference, variant.points)[first:, measured],
                                     _points(decoded, variant.points)[first:, measured])
        errors.append(error.ravel())
        buffer_bytes += codec.last_encode_stats["acl_buffer_bytes"]
        raw_bytes += metrics.raw_position_bytes(motion.num_joints, motion.num_frames - first)
    pooled = np.concatenate(errors)
    return {"ratio": raw_bytes / buffer_bytes, "linf_cm": float(pooled.max()), "mean_cm": float(pooled.mean()),
            "p99_cm": float(np.percentile(pooled, 99))}


def _reference_rows() -> list[tuple[str, dict[str, float]]]:
    """The issue's rows as (label, the 4 numbers); the shell-0 points give only ratio and L∞."""
    rows = [(f"shell 3, p {p:g}", {"ratio": r[0], "linf_cm": r[2], "mean_cm": r[3], "p99_cm": r[4]})
            for p, r in ISSUE_REFERENCE.items()]
    rows += [(f"shell 0, p {p:g}", {"ratio": ratio, "linf_cm": linf})
             for p, (ratio, linf) in zip((0.5, 1.0), ISSUE_SHELL0)]
    return rows


def _relative(point: dict[str, float], key: str, value: float) -> float:
    """``point[key]`` relative to the reference ``value``; for the ratio, our bytes relative to the reference's
    (``reference ratio / ratio - 1``, the issue's "bytes vs issue")."""
    return value / point[key] - 1 if key == "ratio" else point[key] / value - 1


def deviation(point: dict[str, float], reference: dict[str, float]) -> float:
    """Largest relative deviation of ``point`` from ``reference`` over the numbers ``reference`` gives."""
    return max(abs(_relative(point, key, value)) for key, value in reference.items())


def closest(points: Sequence[dict[str, Any]], reference: dict[str, float], count: int = 3) -> list[dict[str, Any]]:
    """The ``count`` points nearest ``reference`` by :func:`deviation`."""
    return sorted(points, key=lambda point: deviation(point, reference))[:count]


def _row(point: dict[str, Any], reference: dict[str, float] | None = None) -> str:
    cells = [f"{point['ratio']:.2f}", f"{point['linf_cm']:.3f}", f"{point['mean_cm']:.3f}", f"{point['p99_cm']:.3f}"]
    if reference is not None:
        names = {"ratio": "bytes", "linf_cm": "L-inf", "mean_cm": "mean", "p99_cm": "p99"}
        cells += [", ".join(f"{names[key]} {_relative(point, key, value):+.1%}" for key, value in reference.items())]
    return " | ".join(cells)


def grid(motions: Sequence[Motion], shells: Sequence[float], precisions: Sequence[float],
         progress: Callable[[dict[str, Any]], None] | None = None) -> list[dict[str, Any]]:
    """:func:`measure` at every (shell, precision)."""
    points = []
    for shell in shells:
        for precision in precisions:
            point = {"shell_cm": shell, "precision_cm": precision, **measure(motions, precision, shell)}
            points.append(point)
            if progress:
                progress(point)
    return points


def main_grid(shells: Sequence[float], precisions: Sequence[float], data_dir: str | None = None) -> None:
    """Print the grid and, per reference row, its 3 nearest grid points."""
    motions = load_bvh(False, data_dir)
    print(f"\nGrid: ACL 2.1.0, level highest, cmu_test BVH ({sum(m.num_frames for m in motions)} frames); cm")
    print("| shell | precision | ratio | L-inf | mean | p99 |\n|---:|---:|---:|---:|---:|---:|")
    points = grid(motions, shells, precisions,
                  lambda p: print(f"| {p['shell_cm']:g} | {p['precision_cm']:g} | {_row(p)} |", flush=True))
    print("\nNearest grid points to each reference row (deviation = largest relative deviation of its numbers)")
    print("| reference row | shell | precision | ratio | L-inf | mean | p99 | vs reference |\n"
          "|---|---:|---:|---:|---:|---:|---:|---|")
    for label, reference in _reference_rows():
        for point in closest(points, reference):
            print(f"| {label} | {point['shell_cm']:g} | {point['precision_cm']:g} | {_row(point, reference)} |")


def run_variants(precisions: Sequence[float], shell_cm: float, data_dir: str | None = None,
                 progress: Callable[[dict[str, Any]], None] | None = None) -> list[dict[str, Any]]:
    """:func:`measure` of every :data:`VARIANTS` entry at each precision."""
    loaded = {keep: load_bvh(keep, data_dir) for keep in (False, True)}
    points = []
    for variant in VARIANTS:
        for precision in precisions:
            point = {"variant": variant.name, "precision_cm": precision, "shell_cm": shell_cm,
                     **measure(loaded[variant.keep_frame0], precision, shell_cm, variant)}
            points.append(point)
            if progress:
                progress(point)
    return points


def main_variants(precisions: Sequence[float], data_dir: str | None = None) -> None:
    """Print every variant at the issue's precisions (shell 3 cm) against the reference rows."""
    print("\nVariants at shell 3 cm, level highest unless named; vs the issue's row at that precision")
    print("| variant | precision | ratio | L-inf | mean | p99 | vs reference |\n|---|---:|---:|---:|---:|---:|---|")

    def show(point: dict[str, Any]) -> None:
        ref = ISSUE_REFERENCE.get(point["precision_cm"])
        reference = {"ratio": ref[0], "linf_cm": ref[2], "mean_cm": ref[3], "p99_cm": ref[4]} if ref else None
        print(f"| {point['variant']} | {point['precision_cm']:g} | {_row(point, reference)} |", flush=True)

    run_variants(precisions, 3.0, data_dir, show)


def _jittered(motion: Motion, seed: int, scale: float = 1e-7) -> Motion:
    """``motion`` with each rotation turned by ~``scale`` rad and the root scaled by ``1 + scale`` noise."""
    rng = np.random.default_rng(seed)
    frames, joints, _ = motion.rotations.shape
    turn = Rotation.from_rotvec(rng.normal(scale=scale, size=(frames * joints, 3)))
    rotations = (Rotation.from_quat(motion.rotations.reshape(-1, 4)) * turn).as_quat().reshape(frames, joints, 4)
    rotations *= np.sign(np.sum(rotations * motion.rotations, axis=-1, keepdims=True))  # keep the input's signs
    root = motion.root_positions * (1 + rng.normal(scale=scale, size=motion.root_positions.shape))
    return dataclasses.replace(motion, rotations=rotations, root_positions=root)


def run_jitter(seeds: int, settings: Sequence[tuple[float, float]], data_dir: str | None = None
               ) -> dict[tuple[float, float], list[dict[str, float]]]:
    """:func:`measure` at each (precision, shell) of ``settings`` on ``seeds`` jittered copies of the clips."""
    motions = load_bvh(False, data_dir)
    results: dict[tuple[float, float], list[dict[str, float]]] = {s: [] for s in settings}
    for seed in range(seeds):
        jittered = [_jittered(m, seed) for m in motions]
        for precision, shell in settings:
            results[(precision, shell)].append(measure(jittered, precision, shell))
    return results


def main_jitter(seeds: int, data_dir: str | None = None) -> None:
    """Print the min..max of each number over the jittered copies beside the reference."""
    settings = [(p, 3.0) for p in ISSUE_REFERENCE] + [(0.5, 0.0), (1.0, 0.0)]
    results = run_jitter(seeds, settings, data_dir)
    print(f"\nJitter: {seeds} copies of the clips, rotations turned ~1e-7 rad, root x (1 + 1e-7 noise); min..max")
    print("| precision | shell | ratio | L-inf | mean | p99 | reference ratio / L-inf |\n"
          "|---:|---:|---|---|---|---|---|")
    shell0 = dict(zip((0.5, 1.0), ISSUE_SHELL0))
    for (precision, shell), points in results.items():
        spans = [f"{min(p[k] for p in points):.4g}..{max(p[k] for p in points):.4g}"
                 for k in ("ratio", "linf_cm", "mean_cm", "p99_cm")]
        ref = ISSUE_REFERENCE[precision][0:3:2] if shell == 3.0 else shell0[precision]
        print(f"| {precision:g} | {shell:g} | {' | '.join(spans)} | {ref[0]:g} / {ref[1]:g} |")


NEIGHBOURHOOD = (0.98, 0.99, 0.995, 1.0, 1.005, 1.01, 1.02)


def main_neighbourhood(data_dir: str | None = None) -> None:
    """Print each number's min..max over precisions p x :data:`NEIGHBOURHOOD` for p = 0.5 and 1 cm."""
    motions = load_bvh(False, data_dir)
    print(f"\nNeighbourhood: precision p x {NEIGHBOURHOOD[0]:g}..{NEIGHBOURHOOD[-1]:g} ({len(NEIGHBOURHOOD)} values); "
          "min..max, and the value at p")
    print("| p | shell | ratio | L-inf | mean | p99 | reference ratio / L-inf |\n|---:|---:|---|---|---|---|---|")
    shell0 = dict(zip((0.5, 1.0), ISSUE_SHELL0))
    for shell in (3.0, 0.0):
        for precision in (0.5, 1.0):
            points = [measure(motions, precision * k, shell) for k in NEIGHBOURHOOD]
            at = points[NEIGHBOURHOOD.index(1.0)]
            spans = [f"{min(p[k] for p in points):.4g}..{max(p[k] for p in points):.4g} ({at[k]:.4g})"
                     for k in ("ratio", "linf_cm", "mean_cm", "p99_cm")]
            ref = ISSUE_REFERENCE[precision][0:3:2] if shell == 3.0 else shell0[precision]
            print(f"| {precision:g} | {shell:g} | {' | '.join(spans)} | {ref[0]:g} / {ref[1]:g} |", flush=True)


_DEBUG_DEFINE = re.compile(r"(#define ACL_IMPL_DEBUG_VARIABLE_QUANTIZATION\s+)ACL_IMPL_DEBUG_LEVEL_NONE")
_SUMMARY_LINE = re.compile(r"^(\d+): (\d+) \| (\d+) \| (\d+) => [-+.\deE]+ ?(!?)\s*$")


def debug_acl_copy(destination: str | os.PathLike, acl_dir: str | None = None) -> str:
    """Copy ACL's headers into ``destination`` with ACL's quantization summary switched on; returns the copy's root.

    Raises
    ------
    RuntimeError
        If the define to change is not in this ACL's ``quantize.transform.h`` (another ACL version).
    """
    from mocapbench.codecs.acl.build import find_acl_headers

    headers = find_acl_headers(acl_dir)
    root = os.path.join(os.fspath(destination), "acl-debug")
    shutil.copytree(headers.acl_include, os.path.join(root, "acl", "includes"))
    shutil.copytree(headers.rtm_include, os.path.join(root, "rtm", "includes"))
    path = os.path.join(root, "acl", "includes", "acl", "compression", "impl", "quantize.transform.h")
    with open(path, encoding="utf-8") as handle:
        text = handle.read()
    patched, count = _DEBUG_DEFINE.subn(r"\1ACL_IMPL_DEBUG_LEVEL_SUMMARY_ONLY", text)
    if count != 1:
        raise RuntimeError(f"{path}: ACL_IMPL_DEBUG_VARIABLE_QUANTIZATION define not found (not ACL 2.1?)")
    with open(path, "w", encoding="utf-8") as handle:
        handle.write("#include <cstdio>\n" + patched)
    return root


def parse_quantization_summary(text: str, num_bones: int) -> dict[str, np.ndarray]:
    """Per bone, from ACL's "Variable quantization optimization results" blocks (one per segment):
    ``segments`` (blocks seen), ``over`` (segments whose final error is still over the precision, ACL's "!")
    and ``mean_rotation_rate`` (mean rotation bit-rate index over the segments where the rotation is animated)."""
    over = np.zeros(num_bones, dtype=np.int64)
    rate_sum = np.zeros(num_bones)
    rate_count = np.zeros(num_bones, dtype=np.int64)
    segments = 0
    for line in text.splitlines():
        if line.startswith("Variable quantization optimization results"):
            segments += 1
            continue
        match = _SUMMARY_LINE.match(line)
        if not match or int(match[1]) >= num_bones:
            continue
        bone, rate = int(match[1]), int(match[2])
        if rate <= 24:  # 255 marks a constant/default rotation
            rate_sum[bone] += rate
            rate_count[bone] += 1
        over[bone] += match[5] == "!"
    return {"segments": np.full(num_bones, segments), "over": over,
            "mean_rotation_rate": np.divide(rate_sum, rate_count, out=np.zeros(num_bones), where=rate_count > 0)}


@contextlib.contextmanager
def _captured_stdout(path: str):
    """Redirect the process's file descriptor 1 (C ``printf`` included) into ``path``."""
    sys.stdout.flush()
    saved = os.dup(1)
    with open(path, "wb") as sink:
        os.dup2(sink.fileno(), 1)
        try:
            yield
        finally:
            import ctypes

            ctypes.CDLL(None).fflush(None)  # flush C's stdio buffer before fd 1 goes back
            os.dup2(saved, 1)
            os.close(saved)


def main_why(settings: Sequence[tuple[float, float]], data_dir: str | None = None) -> None:
    """Print ACL's own per-bone summary at each (precision, shell): segments over precision after the search and
    the mean rotation bit-rate index of the chain bones."""
    motions = load_bvh(False, data_dir)
    names = motions[0].skeleton.names
    cache = os.environ.get("MOCAPBENCH_CACHE_DIR")
    with tempfile.TemporaryDirectory(prefix="mcb-acl-why-") as folder:
        acl_dir = debug_acl_copy(folder)
        os.environ["MOCAPBENCH_CACHE_DIR"] = folder  # the debug build goes with the copy, not into the user's cache
        try:
            results = {}
            for precision, shell in settings:
                codec = create("acl", precision_cm=precision, shell_cm=shell, acl_dir=acl_dir)
                log = os.path.join(folder, "summary.txt")
                buffer_bytes = 0
                with _captured_stdout(log):
                    for motion in motions:
                        codec.encode(motion)
                        buffer_bytes += codec.last_encode_stats["acl_buffer_bytes"]
                with open(log, encoding="utf-8", errors="replace") as handle:
                    results[(precision, shell)] = (parse_quantization_summary(handle.read(), len(names)), buffer_bytes)
        finally:
            if cache is None:
                os.environ.pop("MOCAPBENCH_CACHE_DIR", None)
            else:
                os.environ["MOCAPBENCH_CACHE_DIR"] = cache
    worst = np.max([r[0]["over"] for r in results.values()], axis=0)
    shown = sorted(np.argsort(worst)[::-1][:5].tolist())  # the 5 bones most often over their precision
    chain = [names.index(n) for n in ("Hips", "LowerBack", "Spine", "Spine1", "LeftArm", "LeftForeArm", "LeftHand")
             if n in names]
    print("\nACL's own summary (level highest; segments of the 12 clips): per bone, the segments still over "
          "its precision after ACL's search; then the mean rotation bit-rate index of some chain bones")
    print("| precision | shell | ACL bytes | segments | over, all bones | " + " | ".join(f"over: {names[j]}" for j in shown)
          + " | " + " | ".join(f"rate: {names[j]}" for j in chain) + " |")
    print("|" + "---:|" * (5 + len(shown) + len(chain)))
    for (precision, shell), (summary, buffer_bytes) in results.items():
        cells = [f"{summary['over'].sum()}"] + [f"{summary['over'][j]}" for j in shown]
        cells += [f"{summary['mean_rotation_rate'][j]:.1f}" for j in chain]
        print(f"| {precision:g} | {shell:g} | {buffer_bytes} | {summary['segments'][0]} | " + " | ".join(cells) + " |")


WHY_SETTINGS = ((0.4, 3.0), (0.5, 3.0), (0.6, 3.0), (1.0, 3.0), (0.5, 2.0), (0.5, 5.0), (0.8, 5.0), (0.5, 0.0))
"""(precision, shell) cm where ``--why`` reads ACL's summary: the 0.5 cm reference point, its neighbours, and
the other places the grid shows ACL over-spending (shell 3 at 0.4, shell 5 at 0.8)."""
