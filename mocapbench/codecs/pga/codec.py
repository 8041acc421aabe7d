"""``pga-ik``: principal geodesic pose model + IK from end-joint trajectories + multiscale trajectories.

Paper: M. Tournier, X. Wu, N. Courty, E. Arnaud, L. Reveret, "Motion Compression using Principal Geodesics
Analysis", INRIA research report RR-6648, 2008 (https://inria.hal.science/inria-00321983).

Data flow (paper Fig. 1)::

    encoder: inner-joint rotations (F, n) --Karcher mean + tangent PCA--> mu, v_1..v_k          (§3.3)
             root position (F, 3), root orientation (F,), d end-joint global positions (F, d, 3)
                 --lifting scheme, finest levels dropped, kept details quantized--> coarse + details (§3.5)
    stream:  skeleton | k, end joints, settings | mu, v quantized | trajectory coefficients, Huffman-coded
    decoder: trajectories --> end joints in the root frame y0 --LM on the geodesic coordinates--> x (F, k)
             --> h(x) = mu · prod_j exp(x_j v_j) + root --> Motion --FK--> positions             (§3.4, §3.6)

What is the paper's and what is ours
------------------------------------
* As the paper: pose model on the inner joints (root excluded), Karcher mean, PGA by PCA of the tangent
  vectors, product of exponentials; IK on d = 5 end joints (hands, feet, head) in the root frame with the
  analytic Jacobian and Levenberg–Marquardt minimizing ``||f(x) - y0||^2 + lambda ||x - x_prev||^2``,
  lambda = 1, warm-started; root position, root orientation and end-joint global positions coded by the
  lifting scheme with the tangent-space cubic prediction for rotations; the finest levels dropped.
* Departures, and why:
  - **Quantization.** The paper counts stored *numbers* and leaves quantization as future work (§4, §5); a
    real bitstream needs bits, so mu (rotation vectors), v (unit-vector entries) and the trajectory
    coefficients are uniformly quantized (``model_bits``, ``trajectory_bits``; a symmetric mid-tread quantizer
    whose step is stored per trajectory level) and Huffman-coded. The trajectory details are computed
    closed-loop (predicted from already quantized samples) so the quantization error does not accumulate
    across levels. The paper's own ratio (numbers vs ``3(m + 1) n``) is reported beside the real one.
  - **Levels.** The knob is the number of *finest levels dropped*, not the number kept: the paper's total
    (#LOD = ceil(log2 F) + 1) depends on the clip length, so "kept" means a different time resolution on
    every clip; dropped levels D mean one sample per 2^D frames everywhere. The paper's "4/9" for the 141
    frames of 09_06 is D = 5; the stats give the paper's kept/total notation.
  - **Lifting boundaries** (not given in the paper): shorter stencils at the ends, linear extrapolation of a
    last odd sample (see :mod:`mocapbench.codecs.pga.lifting`).
  - **Jacobian.** The paper writes ``dh/dx_j = v_j``; for the product of exponentials we use the exact body
    velocity ``S_j^T v_j`` (v_j carried through the later factors), which equals v_j when the later
    coordinates are 0 and makes the LM steps exact Gauss–Newton steps (see :mod:`mocapbench.codecs.pga.ik`).
  - **Units of lambda.** The objective mixes cm^2 with squared coordinates, so lambda = 1 means nothing
    without a length unit. The paper worked on the CMU ASF/AMC data, whose native length unit is 1/0.45 inch
    = 5.6444 cm; lambda = 1 in that unit is 31.9 in cm^2 (``ik_length_unit_cm``). Measured on cmu_test, this
    reading is the one that works: with lambda = 1 cm^2 the IK drifts along the directions that move no end
    joint (a knee swinging about the hip-ankle axis: 40 cm errors on 05_01 with lossless trajectories),
    with 31.9 cm^2 it does not (4.5 cm).
  - **First frame.** It has no previous frame: LM starts from the mean pose (x = 0), anchored there by the
    same lambda term, with ten times the iterations; nothing extra is stored.
  - **k by variance** (optional): ``variance_fraction`` > 0 picks the smallest k reaching that share of the
    tangent variance (the paper's Fig. 3 measure), capped by ``num_geodesics``.
  - The skeleton travels in the stream (needed for FK); the paper does not count it.
  - **Long captures** (more than 7,680 frames; the paper codes every clip whole and suggests "a segment-based
    approach" for long motions, §4): windows of ``window_frames`` frames (default 1,025), each a stream of its own
    with its own pose model, the last one lengthened backwards so that it too ends on a kept trajectory sample.
    Clips up to 7,680 frames are coded whole, as the paper does, and their streams are unchanged. Why (measured
    with ``python -m mocapbench.benchmarks.long_captures --codecs pga-ik --frames 1000,10000,100000`` and on
    CMU subject 118's 30 takes joined into one capture):
    the error of k geodesics grows with the span of poses they must hold (12 geodesics hold 62 % of the tangent
    variance of 1,024 synthetic frames, 33 % of 7,680; on the joined CMU takes the mean error is 0.50 cm for the
    first 1,000 frames and 1.04 cm over 10,000 in 7,680-frame windows, 0.47 cm in 1,025-frame windows), so a
    capture coded in W-frame windows has the error of a W-frame clip whatever its length. More geodesics per
    window instead (as many as leave the pose variance a 1,024-frame model leaves: 16-30) halved the error on the
    synthetic capture but raised it on the CMU one (1.62 cm at 10,000 frames against 1.04): with more geodesics
    than the 15 end-joint coordinates constrain, the IK drifts. The price is the rate: a pose model per 1,025
    frames (CR about 84 on the joined CMU takes against 173 with 7,680-frame windows); ``window_frames=7681``
    gives the rate back. Windows of 7,680 frames (the earlier layout, which still decodes: a long capture's
    payload now starts with a marker) also ended 15 frames off the trajectory grid, so those frames were
    extrapolated (62 cm at a toe at a window's end on the synthetic capture).
  - **The encoder's closed loop on long captures** (``refine_ratio``, default 1.5; ours). The paper picks k and
    the kept levels per motion by hand (Table 2: 6-17 geodesics, 4-12 of 9-16 levels) and notes that what the
    trajectories need "highly depends on the dynamics" (§4); a long capture's windows differ the same way. The
    encoder decodes every window, and a window whose L-inf is over ``refine_ratio`` x the capture's median window
    L-inf is coded again with the refinements of :data:`_REFINEMENTS` in turn, cheapest first: end-joint
    trajectory corrections, 4 more geodesics, both, one end-joint level more, ... (the first under the limit is
    kept, else the lowest L-inf: never worse than the first coding). Why: a capture's L-inf is its worst
    window's, and the per-window L-inf has a tail, so more windows draw more of it. On the synthetic capture
    (1,025-frame windows, 100k frames: median 17.3 cm, 90th percentile 25.2, worst 32.6 of 98) the tail is toes,
    below the feet the IK constrains, in windows whose poses 12 geodesics hold badly (4 more bring them to
    15 cm); on CMU subject 118's takes joined it is end-joint trajectories smoothed across a cut between takes
    (the dropped levels interpolate over the pose jump: 19 cm at a hand), and IK solutions that turn an elbow.
  - **End-joint corrections** (the paper's closing remark, §4: "quantization may be used to compress the
    trajectories reconstruction errors while controlling additional overhead"): a refined window may end with
    the end-joint samples its trajectories miss by over half the limit, quantized and Huffman-coded
    (:func:`_write_corrections`); the decoder adds them before the IK. A capture with any is written in long
    layout 2 (every window ends with its section); one without stays layout 1, byte for byte as before.
  - Measured with ``python -m mocapbench.benchmarks.pga.long`` (``--refine 0`` is the open loop): 100,000
    synthetic frames 32.6 -> 25.7 cm (1k frames: 17.5) at 1 % less ratio (69.9 against 70.6); 10,000 frames of
    the joined CMU takes 13.1 -> 11.8 cm (1k: 8.2) at 84.3 against 84.4. Short clips are coded whole and keep their
    bytes. The cost: the encoder runs the decoder's IK once per window and once per trial (about 0.6 ms of CPU
    per frame against 0.05 open loop).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np
from mocapbench.lazy_imports import Rotation

from mocapbench.codecs.base import Codec, CodecConfig, Header, param
from mocapbench.codecs.limits import current_limits, using_limits
from mocapbench.codecs.registry import register_codec
from mocapbench.codecs.skeleton_blob import pack_skeleton, unpack_skeleton
from mocapbench.codecs.windows import WINDOW_FRAMES, encode_frame_windows, split_windows
from mocapbench.entropy.bitio import ByteReader, ByteWriter
from mocapbench.entropy.errors import BitstreamError
from mocapbench.entropy.huffman import decode_symbols, encode_symbols
from mocapbench.entropy.quantize import quantize
from mocapbench.codecs.pga.ik import GeodesicIK, to_root_frame
from mocapbench.io.asf_amc import CMU_CM_PER_UNIT
from mocapbench.codecs.pga.lifting import (
    EUCLIDEAN,
    ROTATIONS,
    level_sizes,
    lifting_decompose,
    lifting_reconstruct,
    num_lifting_levels,
)
from mocapbench.codecs.pga.geodesics import fit_pga, geodesic_poses, variance_count
from mocapbench.metrics.rate import pga_raw_numbers
from mocapbench.motion import Motion, OwnedQuaternions, Skeleton

__all__ = ["PgaIkCodec", "select_end_joints", "END_JOINT_NAMES"]

#: Candidate names of the five end joints (case-insensitive), first match wins: CMU ASF/AMC bone names, then the
#: BVH / synthetic names. Order: left hand, right hand, left foot, right foot, head.
END_JOINT_NAMES: tuple[tuple[str, ...], ...] = (
    ("lhand", "LeftHand", "lwrist", "LeftWrist", "LHand", "L_Hand", "left_hand"),
    ("rhand", "RightHand", "rwrist", "RightWrist", "RHand", "R_Hand", "right_hand"),
    ("lfoot", "LeftFoot", "ltoes", "LeftToeBase", "LFoot", "L_Foot", "left_foot"),
    ("rfoot", "RightFoot", "rtoes", "RightToeBase", "RFoot", "R_Foot", "right_foot"),
    ("head", "Head"),
)

# Part of the stream format: a decoder runs F x iterations LM steps (~0.5 ms each on 31 joints), so the stream may
# not ask for more than 20 per frame (1-5 give the same errors on cmu_test); DecodeLimits.max_ik_iterations bounds F x it.
_MAX_LM_ITERATIONS = 20

#: Frames per block of the decoder's pose model (:func:`geodesic_poses`): bounds its rotation temporaries.
_POSE_BLOCK_FRAMES = 1024

# A long capture's payload starts with this varint (0: no window is empty, so a stream written before the marker,
# whose first varint is its first window's length, is told apart), then the layout version, the window length and
# the trajectory grid (see _long_extents).
_LONG_MARKER, _LONG_VERSION = 0, 1
# Layout 2: as 1, and every window's payload ends with its end-joint trajectory corrections (_write_corrections). A
# capture whose windows carry none is written as layout 1, byte for byte as before the corrections existed.
_LONG_VERSION_CORRECTED = 2
#: Step of the corrections' quantizer as a fraction of the threshold they are made over (cm / cm).
_CORRECTION_STEP = 1 / 8

#: The encoder's closed loop (``refine_ratio``): what a window over the limit tries, cheapest first, as (extra
#: geodesics, end-joint trajectory levels dropped fewer, corrections of the end-joint samples missed by over half
#: the limit). Measured on 1,025-frame windows of the long captures: corrections (+1-2 % of a window's bytes) take a
#: window whose worst frame is an end-joint trajectory smoothed over a cut between takes from 19.1 to 11.7 cm (CMU
#: 118 joined; one end-joint level more: 18.0 cm for +20 %); 4 more geodesics (+14 %) bring the synthetic
#: capture's worst windows, toes below feet whose poses 12 geodesics hold badly, from 1.5-1.9x the median window's
#: L-inf to under it.
_REFINEMENTS = ((0, 0, True), (4, 0, False), (4, 0, True), (0, 1, False), (4, 1, False), (4, 1, True), (8, 1, True))


def select_end_joints(skeleton: Skeleton) -> list[int]:
    """The IK end joints: hands, feet and head by name (:data:`END_JOINT_NAMES`), else the tree's leaves.

    Returns
    -------
    list of int
        Joint indices (never the root). If any of the five is not found by name, every leaf of the tree
        (joints without children, the root excepted) is used instead.
    """
    lower = {name.lower(): j for j, name in enumerate(skeleton.names)}
    chosen = []
    for candidates in END_JOINT_NAMES:
        found = next((lower[c.lower()] for c in candidates if c.lower() in lower), None)
        if found is None or found == 0 or found in chosen:
            break
        chosen.append(found)
    else:
        return chosen
    has_child = np.zeros(skeleton.num_joints, dtype=bool)
    has_child[skeleton.parents[1:]] = True
    leaves = [j for j in range(1, skeleton.num_joints) if not has_child[j]]
    if not leaves:
        raise ValueError(f"pga-ik: the skeleton {list(skeleton.names)} has no joint besides the root to constrain.")
    return leaves


def _symmetric_quantize(values: np.ndarray, bits: int) -> tuple[np.ndarray, float]:
    """Mid-tread quantizer with ``2^(bits-1) - 1`` levels each side of 0 over ``max |values|``.

    Returns the int64 indices and the step (float32-representable, so the decoder uses exactly the same one;
    0.0 when every value is 0).
    """
    amax = float(np.max(np.abs(values))) if values.size else 0.0
    if amax == 0.0:
        return np.zeros(values.shape, dtype=np.int64), 0.0
    step = float(np.float32(amax / ((1 << (bits - 1)) - 1)))
    return quantize(values, step), step


#: A window coded with the configured settings (extra geodesics, end-joint levels dropped fewer, corrections).
_NO_REFINEMENT = (0, 0, False)
#: The corrections section of a layout-2 window that has none (a varint 0).
_NO_CORRECTIONS = b"\x00"


def _write_corrections(writer: ByteWriter, misses: np.ndarray, over_cm: float) -> int:
    """Write the end-joint trajectory corrections of one window: every sample the decoder misses by over ``over_cm``.

    The paper's closing remark (§4): "quantization may be used to compress the trajectories reconstruction errors
    while controlling additional overhead". Layout: a varint count n; if n > 0, the quantizer step (f32, cm:
    ``over_cm`` x :data:`_CORRECTION_STEP`) and, Huffman-coded, the n frame gaps (from the previous corrected
    sample's frame, the first from 0), the n end-joint indices and the 3n quantized components, frame by frame.

    Parameters
    ----------
    misses : ndarray, shape (F, d, 3), cm
        Original minus decoded end-joint positions (global).
    over_cm : float
        Threshold: samples whose miss is longer are corrected (to within half a step per component).

    Returns
    -------
    int
        n, the corrected samples.
    """
    frames, joints = np.nonzero(np.linalg.norm(misses, axis=-1) > over_cm)  # frame-major order
    writer.write_varint(len(frames))
    if len(frames):
        step = float(np.float32(over_cm * _CORRECTION_STEP))
        writer.write_f32(step)
        gaps = np.diff(frames, prepend=0)
        writer.write_bytes(encode_symbols(np.concatenate([gaps, joints, quantize(misses[frames, joints], step).ravel()])))
    return len(frames)


def _read_corrections(payload: memoryview, reader: ByteReader, num_frames: int, num_ends: int):
    """The corrections section written by :func:`_write_corrections` at ``reader``, checked: ``(frames (n,),
    end-joint indices (n,), corrections (n, 3) cm)`` and the offset after the section."""
    count = reader.read_varint("number of end-joint corrections")
    if count > num_frames * num_ends:
        raise BitstreamError(f"pga-ik: at most {num_frames} x {num_ends} end-joint corrections, found {count}.")
    if count == 0:
        return (np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros((0, 3))), reader.offset
    step = reader.read_f32("end-joint correction step")
    if not (np.isfinite(step) and step > 0):
        raise BitstreamError(f"pga-ik: expected a finite correction step > 0 cm, found {step}.")
    symbols, offset = decode_symbols(payload, reader.offset, expected_count=5 * count)
    gaps, joints = symbols[:count], symbols[count : 2 * count]
    frames = np.cumsum(gaps)
    if np.any(gaps < 0) or frames[-1] >= num_frames or np.any(joints < 0) or np.any(joints >= num_ends):
        raise BitstreamError(f"pga-ik: end-joint corrections must fall on frames 0..{num_frames - 1} and end joints "
                             f"0..{num_ends - 1}.")
    return (frames, joints, symbols[2 * count :].reshape(count, 3) * float(step)), offset


def _long_extents(num_frames: int, window_frames: int, grid: int) -> list[tuple[int, int]]:
    """``(start, stop)`` of the windows of a capture of more than :data:`WINDOW_FRAMES` frames.

    Back-to-back windows of ``window_frames``; the last one ends at the capture's end and is lengthened backwards
    (over the end of the one before, which it decodes again) to ``1 + a multiple of grid`` frames (at least
    ``grid + 1``, at most ``window_frames`` or the capture), so that, like every full window when ``grid`` divides
    ``window_frames - 1``, its last frame is a kept trajectory sample (``grid`` = 2^dropped levels): interpolated,
    not extrapolated from the last kept samples.
    """
    extents = [(start, min(num_frames, start + window_frames)) for start in range(0, num_frames, window_frames)]
    start, stop = extents[-1]
    length = 1 + max(1, -(-(stop - start - 1) // grid)) * grid
    length = max(stop - start, min(length, window_frames, num_frames))
    extents[-1] = (stop - length, stop)
    return extents


def _kept_levels(num_frames: int, dropped: int) -> int:
    """Detail levels actually coded for an F-sample track with ``dropped`` finest levels omitted."""
    return max(num_lifting_levels(num_frames) - dropped, 0)


def _kept_samples(num_frames: int, dropped: int) -> int:
    """Samples of a track at its finest kept level (the numbers the paper counts per coordinate)."""
    return level_sizes(num_frames)[_kept_levels(num_frames, dropped)]


@register_codec
class PgaIkCodec(Codec):
    """Tournier et al. 2008: PGA pose model, end-joint IK, lifting-scheme trajectories (module docstring)."""

    name = "pga-ik"
    # Trajectories are quantized to `trajectory_bits` over their largest |value|: the root's step grows with its
    # distance from the origin (L-inf on the 48-frame synthetic clip: 0.8 cm at 10 m, 6.9 cm at 100 m, 249 cm at
    # 10 km), so the range is 50 m: beyond it the error is the quantizer's, not the model's.
    max_coordinate_cm = 5e3
    min_joints = 2  # the PGA pose model needs a joint below the root
    codes_rotations = True
    # k = 12 holds 99.99 % of the synthetic clip's tangent variance (measured L-inf 1.71 cm); no level dropped.
    smoke_params = {"num_geodesics": 12, "root_levels_dropped": 0, "end_levels_dropped": 0}
    smoke_max_error_cm = 2.5

    @dataclass(frozen=True)
    class Config(CodecConfig):
        num_geodesics: int = param(
            12, low=1, high=300, doc="k, principal geodesics kept (capped at 3 x inner joints); the paper uses 6-17"
        )
        variance_fraction: float = param(
            0.0,
            low=0.0,
            high=1.0,
            doc="if > 0, k = fewest geodesics reaching this share of tangent variance, at most num_geodesics",
        )
        root_levels_dropped: int = param(
            4, low=0, high=40, doc="finest lifting levels omitted for the root position and orientation"
        )
        end_levels_dropped: int = param(4, low=0, high=40, doc="finest lifting levels omitted for the end joints")
        trajectory_bits: int = param(
            12, low=2, high=24, unit="bits", doc="quantizer of each kept trajectory level (over its max |value|)"
        )
        model_bits: int = param(14, low=2, high=24, unit="bits", doc="quantizer of the mean and the geodesics")
        ik_lambda: float = param(
            1.0, low=0.0, high=1e6, doc="smoothness weight lambda of the IK (paper: 1), in ik_length_unit^2"
        )
        ik_length_unit_cm: float = param(
            CMU_CM_PER_UNIT,
            low=1e-3,
            high=1e3,
            unit="cm",
            doc="length unit of the IK objective (default: the CMU ASF unit, 5.6444 cm, the paper's data)",
        )
        lm_iterations: int = param(2, low=1, high=_MAX_LM_ITERATIONS, doc="Levenberg-Marquardt iterations per frame")
        window_frames: int = param(
            1025,
            low=2,
            high=WINDOW_FRAMES + 1,
            unit="frames",
            doc="window of a capture over 7,680 frames, each with its own pose model (1 + a multiple of 2^dropped "
            "levels ends each window on a kept trajectory sample); clips up to 7,680 frames are coded whole",
        )
        refine_ratio: float = param(
            1.5,
            low=0.0,
            high=1e3,
            doc="captures over 7,680 frames: a window whose decoded L-inf exceeds this x the median window's is "
            "coded again with more geodesics / trajectory samples (closed loop, see encode_payload); 0: off",
        )

        def __post_init__(self) -> None:
            super().__post_init__()
            if 0.0 < self.refine_ratio < 1.0:
                raise ValueError(
                    f"PgaIkCodec.refine_ratio must be 0 (off) or >= 1 (a multiple of the median window's L-inf), "
                    f"got {self.refine_ratio!r}."
                )

    # -- encoder ---------------------------------------------------------------------------------------------
    def encode_payload(self, motion: Motion) -> bytes:
        """One window (every clip up to :data:`WINDOW_FRAMES` frames), else a marked sequence of windows.

        A long capture is coded window by window (``window_frames``, :func:`_long_extents`), each with its own
        pose model, and the coder holds one window's arrays. Why windows of about 1,000 frames (see the module
        docstring, "Long captures"): the error of a pose model grows with the span of poses it must hold, so a
        capture coded in windows of W frames has the error of a W-frame clip, whatever its length.

        Closed loop (``refine_ratio`` > 0, long captures only): every window is decoded as the decoder will and
        its L-inf measured; a window over ``refine_ratio`` x the median window L-inf of the capture is coded
        again with the refinements of :data:`_REFINEMENTS` in turn (end-joint corrections, more geodesics, one
        end-joint trajectory level more), keeping the first that brings it under that limit, else the one with the
        lowest L-inf (the original included, so no window gets worse). A window's k and levels are in its own
        stream; corrections make the capture long layout 2 (:func:`_write_corrections`). Why: the capture's
        L-inf is the worst of its windows', and the per-window L-inf has a tail (synthetic, 100k frames: median
        17 cm, worst 33 cm) made of windows whose poses 12 geodesics hold badly or whose end-joint trajectories
        cross a cut; more windows draw more of the tail. The cost: the encoder decodes every window once (the IK:
        about 10x the open-loop encode time).
        """
        if motion.num_frames <= WINDOW_FRAMES:
            return self._encode_window(motion)
        config = self.config
        grid = 1 << max(config.root_levels_dropped, config.end_levels_dropped)
        extents = _long_extents(motion.num_frames, config.window_frames, grid)
        windows = self._encode_long_windows(motion, extents)
        # Layout 2 when a window carries corrections: then every window ends with its (maybe empty) section.
        corrected = any(stats["refinement"][2] for _, stats in windows.values())
        if corrected:
            windows = {key: (payload if stats["refinement"][2] else payload + _NO_CORRECTIONS, stats)
                       for key, (payload, stats) in windows.items()}
        payload, stats = encode_frame_windows(
            motion.num_frames, config.window_frames, lambda start, stop: windows.pop((start, stop)), extents
        )
        head = ByteWriter()
        version = _LONG_VERSION_CORRECTED if corrected else _LONG_VERSION
        head.write_varints([_LONG_MARKER, version, config.window_frames, grid])
        payload = head.getvalue() + payload
        errors = [w["window_linf_cm"] for w in stats if "window_linf_cm" in w]
        self.last_encode_stats = {
            "windows": len(stats),
            "K": stats[0]["K"],
            "num_end_joints": stats[0]["num_end_joints"],
            "explained_variance": float(np.mean([w["explained_variance"] for w in stats])),
            "paper_numbers_stored": sum(w["paper_numbers_stored"] for w in stats),
            "paper_compression_ratio": pga_raw_numbers(motion.num_joints - 1, motion.num_frames)
            / sum(w["paper_numbers_stored"] for w in stats),
            "refined_windows": sum(1 for w in stats if w["refinement"] != _NO_REFINEMENT),
            "corrections": sum(w.get("corrections", 0) for w in stats),
            **({"window_linf_median_cm": float(np.median(errors)), "window_linf_max_cm": max(errors)} if errors else {}),
        }
        return payload

    def _encode_long_windows(self, motion: Motion, extents: list[tuple[int, int]]) -> dict:
        """``{(start, stop): (payload, stats)}`` of every window, through the closed loop when ``refine_ratio`` > 0.

        Holds the windows' payloads (a few KB each) and one window's arrays at a time. Each window's stats carry
        its decoded L-inf (``window_linf_cm``, cm) and the refinement it was coded with (``refinement``: extra
        geodesics, end-joint levels dropped fewer, corrections or not; :data:`_NO_REFINEMENT` for the configured
        settings). Corrections are made over half the limit, so a corrected end joint's trajectory error leaves
        at least half of the limit to the IK.
        """
        ratio = self.config.refine_ratio
        windows = {}
        for start, stop in extents:
            part = motion.slice(start, stop)
            payload = self._encode_window(part)
            stats = {**self.last_encode_stats, "refinement": _NO_REFINEMENT}
            if ratio > 0:
                stats["window_linf_cm"] = self._window_linf(part, payload)
            windows[(start, stop)] = (payload, stats)
        if ratio == 0:
            return windows
        limit = ratio * float(np.median([stats["window_linf_cm"] for _, stats in windows.values()]))
        for (start, stop), (payload, stats) in list(windows.items()):
            if stats["window_linf_cm"] <= limit:
                continue
            part = motion.slice(start, stop)
            best = (payload, stats)
            for refinement in _REFINEMENTS:
                extra_geodesics, fewer_levels, correct = refinement
                trial = self._encode_window(part, extra_geodesics, fewer_levels, limit / 2 if correct else None)
                trial_stats = {**self.last_encode_stats, "refinement": refinement,
                               "window_linf_cm": self._window_linf(part, trial, correct)}
                if trial_stats["window_linf_cm"] < best[1]["window_linf_cm"]:
                    best = (trial, trial_stats)
                if trial_stats["window_linf_cm"] <= limit:
                    break
            windows[(start, stop)] = best
        return windows

    def _window_linf(self, part: Motion, payload: bytes, corrections: bool = False) -> float:
        """L-inf (cm) of one window's payload (ending with corrections or not) decoded as the decoder does,
        against the window's positions."""
        header = Header(self.name, part.num_frames, part.num_joints, part.fps)
        positions, _ = self._decode_parsed(header, self._read(header, memoryview(payload), corrections))
        return float(np.max(np.linalg.norm(positions - part.positions(), axis=-1)))

    def _encode_window(self, motion: Motion, extra_geodesics: int = 0, fewer_end_levels: int = 0,
                       correct_over_cm: float | None = None) -> bytes:
        """The stream of one clip or window; ``extra_geodesics`` above the configured k (at most 3 x inner joints),
        ``fewer_end_levels`` end-joint levels dropped below ``end_levels_dropped`` (at least 0) and end-joint
        trajectory corrections over ``correct_over_cm`` (a section at the end of the stream, layout 2 only; None:
        no section) are the closed loop's refinements (:meth:`_encode_long_windows`). Stats in
        ``last_encode_stats`` (``corrections``: how many end-joint samples were corrected)."""
        config = self.config
        end_dropped = max(0, config.end_levels_dropped - fewer_end_levels)
        skeleton = motion.skeleton
        num_frames, num_inner = motion.num_frames, motion.num_joints - 1
        if num_inner < 1:
            raise ValueError(f"pga-ik: the motion {motion.name!r} has only a root joint; there is no pose to model.")
        ends = select_end_joints(skeleton)
        max_k = min(config.num_geodesics, 3 * num_inner)
        model = fit_pga(motion.rotations[:, 1:], min(max_k + extra_geodesics, 3 * num_inner))  # §3.3
        k = max_k
        if config.variance_fraction > 0:
            k = max(1, min(max_k, variance_count(model.variances, config.variance_fraction)))
        k = min(k + extra_geodesics, 3 * num_inner)
        mean_rotvec = Rotation.from_quat(model.mean).as_rotvec()  # (n, 3), |.| <= pi
        model_values = np.concatenate([mean_rotvec.ravel() / np.pi, model.directions[:k].ravel()])
        model_step = 1.0 / ((1 << (config.model_bits - 1)) - 1)  # fixed range [-1, 1]: nothing to store
        model_indices = quantize(model_values, model_step)

        # Trajectories (§3.5-3.6): global end-joint positions, root position, root orientation.
        positions = motion.positions()
        tracks = [
            ("root position", motion.root_positions, EUCLIDEAN, config.root_levels_dropped),
            ("root orientation", motion.rotations[:, 0], ROTATIONS, config.root_levels_dropped),
            ("end-joint positions", positions[:, ends].reshape(num_frames, -1), EUCLIDEAN, end_dropped),
        ]
        steps: list[float] = []
        indices: list[np.ndarray] = []

        def quantize_details(level: int, vectors: np.ndarray) -> np.ndarray:
            q, step = _symmetric_quantize(vectors, config.trajectory_bits)
            steps.append(step)
            indices.append(q.ravel())
            return q * step

        end_track = None
        for name, samples, space, dropped in tracks:
            reconstruction = lifting_decompose(samples, space, dropped, quantize_details)[2]
            if name == "end-joint positions":
                end_track = (samples - reconstruction).reshape(num_frames, len(ends), 3)  # what the decoder misses

        writer = ByteWriter()
        writer.write_bytes(pack_skeleton(skeleton))
        writer.write_varints(
            [k, len(ends), *ends, config.model_bits, config.trajectory_bits]
            + [config.root_levels_dropped, end_dropped, config.lm_iterations]
        )
        # The decoder works in cm: ||f - y0||^2 / u^2 + lambda ||dx||^2 = (||f - y0||^2 + lambda u^2 ||dx||^2) / u^2.
        writer.write_f32(config.ik_lambda * config.ik_length_unit_cm**2)
        writer.write_bytes(encode_symbols(model_indices))
        writer.write_array(np.array(steps), np.float32)
        writer.write_bytes(encode_symbols(np.concatenate(indices)))
        corrections = 0 if correct_over_cm is None else _write_corrections(writer, end_track, correct_over_cm)

        kept_root = _kept_samples(num_frames, config.root_levels_dropped)
        kept_end = _kept_samples(num_frames, end_dropped)
        stored = (k + 1) * 3 * num_inner + 3 * (2 * kept_root + len(ends) * kept_end)  # §3.6
        total_lod = num_lifting_levels(num_frames) + 1
        self.last_encode_stats = {
            "K": k,
            "num_end_joints": len(ends),
            "explained_variance": model.explained_variance(k),
            "k_95": variance_count(model.variances, 0.95),
            "k_99": variance_count(model.variances, 0.99),
            "root_lod": f"{_kept_levels(num_frames, config.root_levels_dropped) + 1}/{total_lod}",
            "end_lod": f"{_kept_levels(num_frames, end_dropped) + 1}/{total_lod}",
            "paper_numbers_stored": stored,
            "paper_compression_ratio": pga_raw_numbers(num_inner, num_frames) / stored,
            "corrections": corrections,
        }
        return writer.getvalue()

    # -- decoder ---------------------------------------------------------------------------------------------
    def _read(self, header: Header, payload: memoryview, corrections: bool = False) -> dict[str, Any]:
        """Parse and check a payload; returns the model, settings and dequantized trajectory coefficients, and the
        end-joint corrections (``corrections``: the payload ends with their section, a window of layout 2)."""
        reader = ByteReader(payload)
        skeleton = unpack_skeleton(reader)
        if skeleton.num_joints != header.num_joints or skeleton.num_joints < 2:
            raise BitstreamError(
                f"pga-ik: header says {header.num_joints} joints, the skeleton has {skeleton.num_joints} (need >= 2)."
            )
        num_inner, num_frames = skeleton.num_joints - 1, header.num_frames
        settings = _read_settings(reader, num_inner, num_frames)
        k, ends = settings["k"], settings["ends"]
        model_bits, trajectory_bits, root_dropped, end_dropped = settings["bits_and_levels"]
        mean, directions, offset = _read_pose_model(payload, reader.offset, num_inner, k, model_bits)
        reader = ByteReader(payload, offset)
        layout = _trajectory_layout(num_frames, root_dropped, end_dropped, len(ends))
        num_steps = sum(len(counts) for _, counts in layout)
        steps = reader.read_array(num_steps, np.float32, "trajectory steps").astype(np.float64)
        if not np.all(np.isfinite(steps)) or np.any(steps < 0):
            raise BitstreamError("pga-ik: trajectory quantizer steps must be finite and >= 0.")
        total = sum(channels * sum(counts) for channels, counts in layout)
        symbols, offset = decode_symbols(payload, reader.offset, expected_count=total)
        fixes = None
        if corrections:
            fixes, offset = _read_corrections(payload, ByteReader(payload, offset), num_frames, len(ends))
        ByteReader(payload, offset).expect_end()
        return {
            "skeleton": skeleton,
            "k": k,
            "ends": ends,
            "mean": mean,
            "directions": directions,
            "lambda": settings["lambda"],
            "iterations": settings["iterations"],
            "coefficients": _dequantized_levels(symbols, layout, steps),
            "corrections": fixes,
            "settings": (model_bits, trajectory_bits, root_dropped, end_dropped),
        }

    def decode_payload(self, header: Header, payload: memoryview):
        num_frames = header.num_frames
        if num_frames <= WINDOW_FRAMES:
            return self._decode_window(header, payload)
        windows, corrections = self._windows(payload, num_frames)  # every extent checked before decoding
        positions = np.empty((num_frames, header.num_joints, 3))
        roots = np.empty((num_frames, 3))
        rotations = np.empty((num_frames, header.num_joints, 4))
        skeleton = None
        limits = current_limits()
        work = 0  # IK iterations of the windows decoded so far: the limit holds for the whole stream
        for start, stop, part in windows:
            window = Header(header.codec, stop - start, header.num_joints, header.fps)
            left = dataclasses.replace(limits, max_ik_iterations=max(0, limits.max_ik_iterations - work))
            with using_limits(left):
                parsed = self._read(window, part, corrections)
                # Each window's rotations and root go straight into the motion's arrays (views of them).
                part_positions, part = self._decode_parsed(window, parsed, roots[start:stop], rotations[start:stop])
            work += (stop - start) * parsed["iterations"]
            positions[start:stop] = part_positions
            skeleton = skeleton or part.skeleton
            del part_positions, part, parsed
        motion = Motion(skeleton=skeleton, fps=header.fps, root_positions=roots, rotations=OwnedQuaternions(rotations))
        return positions, motion

    @staticmethod
    def _windows(payload: memoryview, num_frames: int) -> tuple[list[tuple[int, int, memoryview]], bool]:
        """The windows of a long capture's payload: after the marker, as its header says (:func:`_long_extents`);
        without it (a stream written before the marker), back-to-back windows of :data:`WINDOW_FRAMES`. Also
        whether each window ends with its corrections (layout 2)."""
        reader = ByteReader(payload)
        if reader.read_varint("first window length or long-capture marker") != _LONG_MARKER:
            return split_windows(payload, num_frames, WINDOW_FRAMES), False
        version = reader.read_varint("long-capture layout version")
        if version not in (_LONG_VERSION, _LONG_VERSION_CORRECTED):
            raise BitstreamError(f"pga-ik: long-capture layout version {version} is not known (this decoder reads "
                                 f"{_LONG_VERSION} and {_LONG_VERSION_CORRECTED}).")
        window_frames, grid = reader.read_varints(2, "window frames and trajectory grid")
        if not (2 <= window_frames <= WINDOW_FRAMES + 1 and 1 <= grid <= 1 << 40):
            raise BitstreamError(f"pga-ik: expected a window of 2..{WINDOW_FRAMES + 1} frames and a grid in "
                                 f"1..2^40, found {window_frames} and {grid}.")
        extents = _long_extents(num_frames, int(window_frames), int(grid))
        windows = split_windows(payload[reader.offset :], num_frames, int(window_frames), extents)
        return windows, version == _LONG_VERSION_CORRECTED

    def _decode_window(self, header: Header, payload: memoryview):
        return self._decode_parsed(header, self._read(header, payload))

    def _decode_parsed(self, header: Header, parsed: dict[str, Any], roots: np.ndarray | None = None,
                       rotations: np.ndarray | None = None):
        """Positions and motion of one window; its root positions (F, 3) and quaternions (F, J, 4) are written into
        ``roots`` and ``rotations`` (new arrays when not given), which the returned motion then holds."""
        num_frames = header.num_frames
        spaces = (EUCLIDEAN, ROTATIONS, EUCLIDEAN)
        tracks = []
        for space, levels in zip(spaces, parsed["coefficients"]):
            def details(level, predicted, levels=levels):
                return levels[level] if level < len(levels) else None  # None: a dropped level

            tracks.append(lifting_reconstruct(num_frames, levels[0], details, space))
        root_positions, root_quats, end_positions = tracks
        del tracks
        if parsed.get("corrections") is not None:
            frames, joints, values = parsed["corrections"]
            end_positions = end_positions.reshape(num_frames, len(parsed["ends"]), 3)
            np.add.at(end_positions, (frames, joints), values)
        root_quats = root_quats / np.linalg.norm(root_quats, axis=1, keepdims=True)
        ends = parsed["ends"]
        targets = to_root_frame(root_quats, root_positions, end_positions.reshape(num_frames, len(ends), 3))
        del end_positions
        ik = GeodesicIK(parsed["skeleton"], parsed["mean"], parsed["directions"], ends)
        coordinates = ik.solve_sequence(targets, parsed["lambda"], parsed["iterations"])  # §3.4, §3.6
        del targets
        roots = np.empty((num_frames, 3)) if roots is None else roots
        rotations = np.empty((num_frames, parsed["skeleton"].num_joints, 4)) if rotations is None else rotations
        roots[:] = root_positions
        rotations[:, 0] = root_quats
        del root_positions, root_quats
        # The pose model per block of frames: its rotation temporaries stay one block long.
        for start in range(0, num_frames, _POSE_BLOCK_FRAMES):
            block = slice(start, start + _POSE_BLOCK_FRAMES)
            rotations[block, 1:] = geodesic_poses(parsed["mean"], parsed["directions"], coordinates[block]).as_quat()
        motion = Motion(
            skeleton=parsed["skeleton"],
            fps=header.fps,
            root_positions=roots,
            rotations=OwnedQuaternions(rotations),  # normalized in place, not copied
        )
        return motion.positions(), motion

    def describe_payload(self, header: Header, payload: memoryview) -> dict[str, Any]:
        windows = {}
        if header.num_frames > WINDOW_FRAMES:  # a sequence of windows: describe the first
            parts, corrections = self._windows(payload, header.num_frames)
            start, stop, payload = parts[0]
            windows = {"windows of frames": f"{len(parts)} x {stop - start} (first shown)"}
            header = Header(header.codec, stop - start, header.num_joints, header.fps)
        else:
            corrections = False
        parsed = self._read(header, payload, corrections)
        model_bits, trajectory_bits, root_dropped, end_dropped = parsed["settings"]
        names = parsed["skeleton"].names
        return {
            **windows,
            "num_geodesics": parsed["k"],
            "end_joints": [names[e] for e in parsed["ends"]],
            "model_bits": model_bits,
            "trajectory_bits": trajectory_bits,
            "root_levels_dropped": root_dropped,
            "end_levels_dropped": end_dropped,
            "ik_lambda_cm2": parsed["lambda"],
            "lm_iterations": parsed["iterations"],
            **({"end_joint_corrections": len(parsed["corrections"][0])} if corrections else {}),
        }


def _read_settings(reader: ByteReader, num_inner: int, num_frames: int) -> dict[str, Any]:
    """The payload's counts and settings after the skeleton, each checked against its range (and the IK work
    against the decode limits): ``k``, ``ends``, ``bits_and_levels``, ``iterations``, ``lambda``."""
    k = reader.read_varint("number of geodesics")
    num_ends = reader.read_varint("number of end joints")
    if not 1 <= k <= 3 * num_inner or not 1 <= num_ends <= num_inner:
        raise BitstreamError(
            f"pga-ik: expected 1..{3 * num_inner} geodesics and 1..{num_inner} end joints, "
            f"found {k} and {num_ends}."
        )
    values = reader.read_varints(num_ends + 5, "end joints and settings")
    ends = [int(e) for e in values[:num_ends]]
    model_bits, trajectory_bits, root_dropped, end_dropped, iterations = (int(v) for v in values[num_ends:])
    if len(set(ends)) != num_ends or min(ends) < 1 or max(ends) > num_inner:
        raise BitstreamError(f"pga-ik: end joints must be distinct indices in 1..{num_inner}, found {ends}.")
    if not (2 <= model_bits <= 24 and 2 <= trajectory_bits <= 24 and 1 <= iterations <= _MAX_LM_ITERATIONS):
        raise BitstreamError(
            f"pga-ik: expected bits in 2..24 and 1..{_MAX_LM_ITERATIONS} LM iterations, found "
            f"{model_bits}, {trajectory_bits}, {iterations}."
        )
    if root_dropped > 40 or end_dropped > 40:
        raise BitstreamError(f"pga-ik: at most 40 dropped levels, found {root_dropped} and {end_dropped}.")
    current_limits().check("max_ik_iterations", num_frames * iterations, f"{num_frames} frames x {iterations}")
    lam = reader.read_f32("IK lambda")
    if not (np.isfinite(lam) and 0.0 <= lam <= 1e12):
        raise BitstreamError(f"pga-ik: expected an IK lambda in [0, 1e12] cm^2, found {lam}.")
    return {"k": k, "ends": ends, "bits_and_levels": (model_bits, trajectory_bits, root_dropped, end_dropped),
            "iterations": iterations, "lambda": float(lam)}


def _read_pose_model(payload: memoryview, offset: int, num_inner: int, k: int, model_bits: int):
    """The PGA pose model at ``offset``: the mean pose (num_inner, 4) quaternions, the ``k`` geodesic directions
    (k, num_inner, 3) and the offset after them."""
    model_indices, offset = decode_symbols(payload, offset, expected_count=3 * num_inner * (k + 1))
    model_step = 1.0 / ((1 << (model_bits - 1)) - 1)
    model_values = model_indices * model_step
    if np.max(np.abs(model_values)) > 1.0 + model_step:
        raise BitstreamError("pga-ik: the mean and geodesics must lie in [-1, 1] before scaling; found more.")
    mean = Rotation.from_rotvec(model_values[: 3 * num_inner].reshape(num_inner, 3) * np.pi).as_quat()
    return mean, model_values[3 * num_inner :].reshape(k, num_inner, 3), offset


def _trajectory_layout(num_frames: int, root_dropped: int, end_dropped: int, num_ends: int):
    """Per track (root, root again, end joints): its channels and the samples of each coded level, coarse first."""
    sizes = level_sizes(num_frames)
    layout = []
    for channels, dropped in ((3, root_dropped), (3, root_dropped), (3 * num_ends, end_dropped)):
        coded = _kept_levels(num_frames, dropped) + 1
        counts = [1] + [sizes[level] - sizes[level - 1] for level in range(1, coded)]
        layout.append((channels, counts))
    return layout


def _dequantized_levels(symbols: np.ndarray, layout, steps: np.ndarray) -> list[list[np.ndarray]]:
    """The trajectory coefficients of each track, level by level ((count, channels) each), times their steps."""
    coefficients, position, step_index = [], 0, 0
    for channels, counts in layout:
        levels = []
        for count in counts:
            size = channels * count
            levels.append(symbols[position : position + size].reshape(count, channels) * steps[step_index])
            position += size
            step_index += 1
        coefficients.append(levels)
    return coefficients
