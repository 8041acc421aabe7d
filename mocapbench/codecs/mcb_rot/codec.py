"""``mcb-rot``: local joint rotations + root translation, with every joint and end site guaranteed within ε.

``mcb-linf`` bounds joint positions but codes positions, which cannot drive a rig. This codec codes what an engine
plays back (the local rotation of every joint and the root translation, with the skeleton in the stream), decodes to
a full :class:`~mocapbench.motion.Motion` (so ``mocapbench decompress x.mcb out.bvh`` writes BVH), and guarantees
that forward kinematics of the decoded motion puts every joint of every frame within ``eps_cm`` of the original:
the encoder decodes its own stream and refuses to return one that breaks the bound (the pattern of ``mcb-linf``).
Neither the three papers nor ACL guarantee a bound in the rotation domain (ACL measures its error after the fact).

Design::

    rotations (F, J) unit quaternions, root (F, 3) cm
      └─ signs made continuous along time (``q`` and ``-q`` are one rotation: input sign flips and Euler wraps
         cost nothing), then rotation vectors (log map) taken without forcing the short way, so a joint turning
         through a half turn stays continuous; where a segment of a joint strays beyond 1.5 pi from the identity,
         that segment is coded relative to its own middle rotation (a float32 rotation vector in the stream)
      └─ segments: a grid of ``segment_frames`` frames, restarted at every detected cut (a T-pose first frame, a
         seam between takes) so that no transform straddles a jump; each segment is a random-access unit. At 60 fps
         and above, segments and chunks are at most ``high_rate_segment_frames`` long: a random pose decodes its
         whole chunk, so a shorter chunk buys the native runtime's random access time for a few percent of bytes
         (a segment's means and significance counts are paid more often; they weigh most at large ε, where few
         coefficients are coded); the README has the curve of bytes against µs per segment length
      └─ base layer: orthonormal DCT-II along time per segment and channel (3 root + 3 J rotation-vector channels);
         the step of channel ``c`` is ``m β_c (1 + slope k / n)``: ``β_c`` is the channel's error budget from its lever
         arm (:mod:`.budgets`: an error at the hips moves every joint, one at the wrist only the fingers) and ``m`` a
         multiplier chosen per stream by a rate search (the smallest stream wins; it also tries slope 0, a
         flat step over frequency, which wins at small ε: +1-2 % at 24 fps), then at the step it chose wider dead
         zones (``rounding_search``: fewer small coefficients, more corrections; kept where smaller). Each attempt is quantized and
         refined (below) but not entropy coded: attempts are ranked by their estimated size (:mod:`.rate`, ideal
         code lengths; on cmu_test its pick is at most 0.03 % larger than the real sizes' pick) and only the winner is
         written. An attempt gives up as soon as its estimate exceeds the best so far (its base layer alone, or
         its corrections after a round of the closed loop), and the walk goes first towards finer steps when the
         start's corrections are over 12 % of its size (:data:`_FINER_FIRST_SHARE`): 4-6 attempts per stream, of
         which 2-3 stop early (cmu_test). A short clip (up to 200 frames: a capture at 24 fps) is dominated by
         numpy's per-call costs, not by arithmetic, so it first evaluates the six attempts the walk most often
         needs side by side (:data:`_PREFETCH`; :meth:`_Encoder.attempts_of`: one compensated quantization and one
         closed loop over the attempts' frames laid end to end, those over the start's size given up once the start
         has finished, as the walk would); the walk then reads them (the same streams; 6.3-6.8 attempts per clip
         at 24 fps instead of 4.2-5.5 one by one, in 1-2 passes); the batched closed loop gives an attempt up once it
         exceeds the budget the walk would give it next (:func:`_walk_limit`). Speeds: ``python -m
         mocapbench.benchmarks.mcb_rot.rd --no-rd --speed`` (the README quotes a run). Segment means (DC) and the
         significance counts are coded as differences along the segments
         in one small track that random access reads whole.
      └─ compensated quantization (:mod:`.compensate`, encoder only): joints are quantized level by level down the
         tree, each coding the local rotation that puts its *global* rotation on the original's given its parent as
         the decoder rebuilds it, so the errors of the hips and spine do not add up down to the hands and feet
         (+5-7 % at 24 fps, +6-15 % at 120 fps on cmu_test); the decoder is unchanged.
      └─ refinement (closed loop, :mod:`.refine`): the encoder decodes the base layer, runs forward kinematics and, on
         every frame where a joint misses ε, replaces the rotation of the over-budget ancestors of the missing joints
         (and the root translation) by a correction quantized finely enough to bring it within its budget, repeating
         until no joint misses. A frame whose every joint is within budget is within ε in any pose (:mod:`.budgets`),
         so the loop always ends. Greedy: each round corrects one joint per missing frame, the one whose correction
         most reduces a missing joint's error (to first order); a miss is usually small and one correction ends it
         (+7 % at 24 fps, +11-17 % at 120 fps on cmu_test). The loop runs forward kinematics once; after that each
         correction turns its joint's subtree (positions and global rotations updated in place, float rounding apart),
         and the loop works on the frames still missing only.
      └─ shell (``shell_cm`` = d > 0): the bound also holds on ACL's virtual vertices at distance d along every
         joint's axes (:mod:`mocapbench.metrics.shell`). Each vertex is a virtual child bone of length d in the
         budgets, so every joint (leaves too) gets a budget from its lever plus d instead of a fixed angle; the
         closed loop checks the larger of the joint and vertex errors (:mod:`.checks`) and the encoder refuses a
         stream whose decoded shell error exceeds ε.
      └─ entropy coding: ANS with per-stream parametric classes (:mod:`.classes`): no trained model, any skeleton.

The decoder (:mod:`.decoder`) is vectorized numpy over blocks of chunks written into preallocated outputs: ANS
decoding (constriction, one call per class and chunk), a batched inverse DCT, the exponential map, one multiply per
correction, then forward kinematics compiled with numba (:mod:`.kinematics`: one loop over joints and frames, bit
for bit the closed loop's numpy arithmetic). Everything else is numpy call overhead on a few thousand values, so its
speed is the number of calls. Hence: chunks of 256 frames (payload format 5: half the ANS streams per clip), SIMD
tan instead of sin and cos in the exponential map, entropy sort keys built per chunk from cached class rows, signs
and raw bits read without N-long index arithmetic, the motion built without re-validating the decoder's own arrays
(``Motion.from_decoder``), and the compiled forward kinematics, which also writes the output rotations (the README
quotes the speeds). Random access (``decode_frames(data, t, t + 1)``)
entropy decodes its chunk and sends only the frames asked for through the exponential map, the corrections and
forward kinematics; the first frame of a clip also parses its header. Speeds: ``python -m
mocapbench.benchmarks.mcb_rot.rd --no-rd --speed`` (the README quotes a run).

Long captures (:mod:`.windowed`): a capture of more than 7,680 frames is coded as independent, about equal windows
of at most that many frames, each a self-contained payload with its own rate search, closed loop and check of the
bound, so the encoder holds one window's arrays (it needs about 20 times the positions array of what it codes at
once) and the decoder decodes each window straight into its outputs; random access decodes only the windows, and in
them the chunks, holding the frames. Clips up to a window keep their bytes. The windows cost -2.0 % / +0.6 % in bytes at
eps 0.1 / 1 cm on the 63 CMU clips joined on one skeleton (44,842 frames, 6 windows; the same L-inf, and 25 % less
encoding CPU than the whole capture in one window).

Game rigs (:mod:`.tracks`): a joint that moves relative to its parent (a pelvis under a ground-level root) has a
translation track on a uniform grid whose error along the worst chain (``track_share`` of eps) comes off the bound,
each translated joint's longest translation is its bone in the budgets, and forward kinematics, in the closed loop
and in the decoder, steps from the parent by the decoded translation of the frame; a motion whose joints do not move
writes no track. A rig whose root never moves (a ground root at the origin above a pelvis that carries the whole
trajectory) keeps that root apart instead (:mod:`.static_root`, ``static_root``): the pelvis is coded as the root,
its trajectory in the root channels with a DCT, the rate search and the closed loop behind them, rather than on the
lossless grid of a track. The bound covers the end sites too (the head, finger and toe tips a viewer draws): each is a virtual
child of its joint in the budgets and a checked point of the closed loop, so a leaf with an end site is budgeted by
its lever instead of ``free_angle_deg`` (``end_sites=false``: the joints only, as before; the bytes the end sites cost are
measured by the benchmark). A scaled joint has a scale track on a uniform grid too (:mod:`.scales`): the budgets
take every length stretched by the most the scales above it stretch it, the scale error comes off the bound, and the
closed loop places the joints with the decoded scales (matrix forward kinematics, in the decoder too); a scaled
rig has no shell bound and keeps a still root in the coded skeleton.

Departures from the issue's sketch: no trained prior (the stream needs no model, ``model_bytes`` is 0). Leaves
(joints whose rotation moves no joint) get the fixed budget ``free_angle_deg`` unless ``shell_cm`` > 0.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from mocapbench.codecs import container
from mocapbench.codecs.base import Codec, CodecConfig, Decoded, Header, NotFittedError, TrackRefusal, param
from mocapbench.codecs.limits import DecodeLimits, using_limits
from mocapbench.codecs.mcb_rot import windowed
from mocapbench.codecs.mcb_rot.decoder import decode_range
from mocapbench.codecs.mcb_rot import quaternions as quat
from mocapbench.codecs.mcb_rot.axes import axes_from_codes, principal_axes, to_axes
from mocapbench.codecs.mcb_rot.budgets import offset_discrepancy_cm
from mocapbench.codecs.mcb_rot.checks import PointTargets
from mocapbench.codecs.mcb_rot.compensate import Compensator, quantize
from mocapbench.codecs.mcb_rot.refine import refine
from mocapbench.codecs.mcb_rot.prior import Prior
from mocapbench.codecs.mcb_rot.static_root import split_static_root
from mocapbench.codecs.mcb_rot.tracks import plan_tracks
from mocapbench.codecs.mcb_rot.scales import plan_scales, scale_error_cm, scales_of
from mocapbench.codecs.mcb_rot.rate import base_bytes, base_bytes_many, corrections_bytes
from mocapbench.codecs.mcb_rot.classes import NUM_BANDS, fit_single
from mocapbench.codecs.mcb_rot.segments import SegmentLayout, forward, segment_starts
from mocapbench.codecs.segments import CUT_MIN_JUMP_CM, CUT_RATIO, find_cuts
from mocapbench.codecs.mcb_rot.stream import (
    Settings,
    StreamInfo,
    assemble,
    base_signal,
    end_site_reach,
    stretch_of,
    _f32,
    read_info,
    skeleton_step_exponent,
    stream_budgets,
    write_payload,
)
from mocapbench.codecs.registry import register_codec
from mocapbench.codecs.mcb_rot.skeleton6 import pack_skeleton_runtime, unpack_skeleton_runtime
from mocapbench.entropy.bitio import ByteReader, ByteWriter
from mocapbench.entropy.errors import BitstreamError
from mocapbench.metrics.shell import motion_shell_errors
from mocapbench.motion import Motion

__all__ = ["McbRotCodec"]

# Corrections work to eps (1 - margin) so that float rounding in any decoder can never cross eps.
_SAFETY_MARGIN = 1e-6
# A segment of a joint is re-referenced when it strays this far (radians) from the identity.
_OVERRIDE_ANGLE = 1.5 * np.pi
# The rate search: step multipliers on a half-octave grid from 1 to 32, started at 11.3 and walked downhill (the
# stream size is unimodal in the multiplier on every clip tried; 3-5 attempts instead of 11). A quarter-octave grid
# gained 0.2 % at 24 fps for 40 % more encoding time.
_SEARCH_GRID = tuple(2.0 ** (i / 2) for i in range(0, 11))
_SEARCH_START = 7
# Where the start's corrections take more than this share of its estimated size, the walk tries finer steps first.
# On cmu_test (12 clips x eps 0.05, 0.1, 0.5, 1 cm x 120 and 24 fps) the best multiplier is the start or finer in 54
# of the 56 cases above this share and the start or coarser in all 40 below it (the share grows about 2.5x per
# half octave of the multiplier). It only orders the walk: any order ends on the same minimum of a unimodal size.
_FINER_FIRST_SHARE = 0.12
# Short clips (up to _PREFETCH_FRAMES frames: a clip at 24 fps) evaluate the attempts the walk most often needs side
# by side first (grid indices of the config's slope, of a flat slope), where numpy's per-call costs outweigh the
# arithmetic.
_PREFETCH_FRAMES = 200
# StreamInfo cache entries that depend on the axis codes only (shared by every attempt of a stream).
_AXES_CACHE = ("axes", "turned", "turned axes")
_PREFETCH = ((6, 7, 8), (7, 8, 9))
# Below this frame rate the encoder also tries segments of half ``segment_frames`` and keeps the smaller stream (a
# second encode): a segment of 128 frames spans 4.3 s at 30 fps, and which length codes a clip of a game capture
# smaller depends on the clip and on eps (the README has the figures). At or above it (a segment of 128 frames is
# 1.1 s at 120 fps) no length is searched, and segments and chunks are at most ``high_rate_segment_frames`` long:
# a random pose entropy-decodes its whole chunk, so the runtime's random access costs about the chunk's values.
_HIGH_RATE_FPS = 60.0
_MIN_SEARCHED_SEGMENT = 16
# The other segment lengths are screened by one attempt each at the config's length's pick; the rate search runs on
# the two whose screens are smallest, where within 3 % of the best stream so far (a length whose screen is further
# off rarely wins after its own search; the README has the bytes and CPU this screen saves and costs).
_SCREENED_SEARCHES = 2
_SCREEN_MARGIN = 0.03
# A short clip (up to this many times ``segment_frames``) also tries even splits (:func:`_segment_lengths`): a game
# clip of 130 frames on the grid of 128 ends in a segment of 2 frames, whose means and significance counts cost as
# much as a full segment's.
_EVEN_SPLIT_CLIPS = 4
# Wider dead zones the rate search tries at the step it chose (``rounding_search``), and what a rounding other than
# the default costs in the settings (an f32).
_WIDER_ROUNDINGS = (0.40, 0.35)
_DEFAULT_ROUNDING = _f32(0.45)  # the settings' default (stream.py), written in no stream
_ROUNDING_BYTES = 4.0


@register_codec
class McbRotCodec(Codec):
    """Guaranteed-L∞ rotation codec: per-segment DCT of rotation vectors + closed-loop refinement (module docstring)."""

    name = "mcb-rot"
    codes_rotations = True
    carries_tracks = ("translations", "scales")
    family = "mocapbench"
    random_access = True
    smoke_params = {"eps_cm": 0.5}
    smoke_max_error_cm = 0.5

    @dataclass(frozen=True)
    class Config(CodecConfig):
        eps_cm: float = param(1.0, low=1e-3, high=100.0, unit="cm", doc="guaranteed L-inf bound on every joint and end site")
        segment_frames: int = param(128, low=1, high=4096, unit="frames", doc="DCT segment length")
        chunk_frames: int = param(
            128, low=1, high=1 << 20, unit="frames", doc="random-access unit: segments are coded in chunks this long"
        )
        step_rel: float = param(
            0.0, low=0.0, high=1e4, unit="x budget", doc="base step over the error budget (0: rate search per stream)"
        )
        frequency_slope: float = param(1.0, low=0.0, high=64.0, doc="step of DCT frequency k is (1 + slope k / n) x")
        slope_search: bool = param(
            True, doc="the rate search also tries a flat step over frequency (slope 0) at its best multipliers"
        )
        rounding: float = param(0.45, low=0.0, high=0.5, doc="rounding offset of the base quantizer (0.5: nearest)")
        root_share: float = param(0.05, low=0.01, high=0.9, doc="share of eps budgeted to the root translation")
        allocation_power: float = param(
            0.0, low=0.0, high=64.0, doc="p of the p-norm lever arm setting each joint's base step (0: max lever)"
        )
        free_angle_deg: float = param(
            1.0, low=1e-3, high=30.0, unit="deg", doc="budget of joints whose rotation moves no joint (leaves)"
        )
        principal_axes: bool = param(True, doc="turn the channels of joints with < 3 degrees of freedom onto their axes")
        cut_ratio: float = param(
            CUT_RATIO, low=0.0, high=1e6, doc="a jump this many times the median frame move starts a segment (0: off)"
        )
        cut_min_cm: float = param(
            CUT_MIN_JUMP_CM, low=0.0, high=1e4, unit="cm", doc="smallest jump (RMS over joints) treated as a cut"
        )
        compensate: bool = param(True, doc="each joint's target compensates its ancestors' decoded errors")
        greedy_corrections: bool = param(
            True, doc="correct one joint per missing frame and round (the one helping the miss most), not all"
        )
        shell_cm: float = param(
            0.0, low=0.0, high=100.0, unit="cm",
            doc="the bound also holds on ACL's virtual vertices at this distance from every joint (0: joints only)",
        )
        end_sites: bool = param(
            True, doc="the bound also covers the end sites (head, finger and toe tips); false: joints only"
        )
        track_share: float = param(
            0.1, low=0.01, high=0.5, doc="share of eps given to a game rig's translation tracks (their grid's error)"
        )
        static_root: bool = param(
            True, doc="a still root joint 0 is kept apart and its moving child coded as the root (game rigs)"
        )
        rounding_search: bool = param(
            True, doc="the rate search also tries a wider dead zone (rounding 0.40, 0.35) at the step it chose"
        )
        segment_search: bool = param(
            True, doc="below 60 fps, also try segments of half segment_frames (and a short clip even splits of it), "
                      "each screened by one attempt, the closest two searched: the smallest stream is kept"
        )
        high_rate_segment_frames: int = param(
            80, low=0, high=4096, unit="frames",
            doc="at >= 60 fps, segments and chunks of at most this many frames (the unit a random pose decodes; "
                "0: segment_frames and chunk_frames at every rate)",
        )

    # The prior (:mod:`.prior`) a fit or a model file gave this codec, and whether the last encode named one of its rigs.
    _prior: Prior | None = None
    _used_prior: bool = False

    @property
    def latency_frames(self) -> int:
        """The whole clip (-1): the encoder sees every frame before it writes one. The rate search picks one step
        multiplier for the stream, the entropy classes (channel scales, band tilts) are fitted on all of its values,
        and a still root is a property of the whole clip; a segment bounds what a random pose decodes, not what
        the encoder waits for."""
        return -1

    # -- learned state: the prior ---------------------------------------------------------------------
    def fit(self, motions: Sequence[Motion]) -> "McbRotCodec":
        """Hold a prior of the distinct rigs of ``motions`` (:mod:`.prior`): a stream of one of them names it
        (flag bit 15) instead of carrying its skeleton. The coding of the motion itself learns nothing."""
        self._prior = Prior.fit(motions, self.config.static_root)
        self._last_info = None
        return self

    def model_arrays(self, num_joints: int) -> dict:
        """The arrays of a model file (:mod:`mocapbench.codecs.model_file`): the prior's bytes, any length."""
        from mocapbench.codecs.model_file import ModelArray

        return {"prior": ModelArray("|u1", (-1,)), "num_joints": ModelArray("<i8", ())}

    def model_state(self) -> dict[str, np.ndarray]:
        """The prior as arrays (its bytes, and the joint count of its first rig)."""
        if self._prior is None:
            raise NotFittedError("mcb-rot: no prior to save; fit one on clips first "
                                 "(`mocapbench fit CLIPS... -o MODEL.npz --codec mcb-rot`).")
        return {"prior": np.frombuffer(self._prior.data, np.uint8).copy(),
                "num_joints": np.array(self._prior.main_joints, dtype=np.int64)}

    def load_model_state(self, arrays) -> "McbRotCodec":
        """Hold the prior stored by :meth:`model_state` (ValueError naming what is wrong)."""
        prior = Prior.from_bytes(np.asarray(arrays["prior"], dtype=np.uint8).tobytes())
        if int(arrays["num_joints"]) != prior.main_joints:
            raise ValueError(f"mcb-rot: num_joints says {int(arrays['num_joints'])}, the prior's first rig has "
                             f"{prior.main_joints} joints.")
        self._prior = prior
        self._last_info = None
        return self

    @property
    def model_bytes(self) -> int:
        """Bytes of the prior the last encode named a rig of (0 when it carried its own rig or none is held)."""
        return len(self._prior.data) if self._prior is not None and self._used_prior else 0

    # -- encoding --------------------------------------------------------------------------------------
    def encode_payload(self, motion: Motion) -> bytes:
        """One window (every clip up to :data:`.windowed.WINDOW_FRAMES` frames: the bytes it always had), else a
        sequence of windows, each coded and checked on its own (:mod:`.windowed`), so that the encoder holds one
        window's arrays whatever the length of the capture."""
        if motion.num_frames <= windowed.WINDOW_FRAMES:
            return self._encode_window(motion)

        def encode_window(start: int, stop: int) -> tuple[bytes, dict]:
            payload = self._encode_window(motion.slice(start, stop))
            return payload, self.last_encode_stats

        segment_frames = self._config_at(motion.fps).segment_frames
        payload, stats = windowed.encode(motion.num_frames, segment_frames, encode_window)
        self.last_encode_stats = windowed.merged_stats(stats)
        return payload

    def _encode_window(self, motion: Motion) -> bytes:
        """The one-window payload of ``motion`` (a whole clip, or one window of a long capture), checked; below
        :data:`_HIGH_RATE_FPS` with ``segment_search``, the smallest stream over the segment lengths of
        :func:`_segment_lengths`.

        The config's length gets the whole rate search; every other length is first screened by one attempt at the
        step, slope and rounding the config's length chose, written (real bytes: the estimates of two segment
        lengths differ by header and chunk costs they leave out); only the :data:`_SCREENED_SEARCHES` smallest
        screens within :data:`_SCREEN_MARGIN` of the best stream so far get a rate search of their own. Every
        stream written (the screens too: each is refined in closed loop) is a candidate; only the one returned is
        decoded and checked (the check guards what leaves the encoder)."""
        if not (self.config.segment_search and motion.fps < _HIGH_RATE_FPS):
            return self._encode_segments(motion)
        lengths = _segment_lengths(motion.num_frames, self.config.segment_frames)
        common = self._common(motion, self.config)
        prepared = self._prepare(motion, self.config, common)
        chosen = self._search_of(prepared)
        best = (prepared.encoder.write(chosen), prepared, chosen, lengths[0])  # payload, prepared, attempt, frames
        screened = []
        settings = chosen.info.settings
        for order, frames in enumerate(lengths[1:]):
            prepared = self._prepare(motion, dataclasses.replace(self.config, segment_frames=frames), common)
            trial = prepared.encoder.attempt(chosen.multiplier, settings.slope, rounding=settings.rounding)
            payload = prepared.encoder.write(trial)
            if len(payload) < len(best[0]):  # ties keep the earlier length (the config's first)
                best = (payload, prepared, trial, frames)
            # Only the screens that may be searched keep their encoders (memory: at most that many at once).
            screened = sorted(screened + [(len(payload), order, prepared, frames, trial)], key=lambda s: s[:2])
            del screened[_SCREENED_SEARCHES:]
        for size, _, prepared, frames, seed in screened:
            if size > len(best[0]) * (1.0 + _SCREEN_MARGIN):
                break
            searched = self._search_of(prepared, seed)
            payload = prepared.encoder.write(searched)
            if len(payload) < len(best[0]):
                best = (payload, prepared, searched, frames)
        payload, prepared, chosen, frames = best
        payload = self._finish(prepared, chosen, payload)
        self.last_encode_stats["segment_frames"] = frames
        return payload

    def _encode_segments(self, full: Motion) -> bytes:
        """The one-window payload of ``full`` with the config's segments (at most ``high_rate_segment_frames`` at
        :data:`_HIGH_RATE_FPS` and above), checked."""
        prepared = self._prepare(full, self._config_at(full.fps))
        return self._finish(prepared, self._search_of(prepared))

    def _config_at(self, fps: float):
        """The config a clip at ``fps`` is coded with: at :data:`_HIGH_RATE_FPS` and above, segments and chunks of
        at most ``high_rate_segment_frames`` (when > 0); below it, the config itself (its segment search)."""
        limit = self.config.high_rate_segment_frames
        if fps < _HIGH_RATE_FPS or limit == 0:
            return self.config
        return dataclasses.replace(self.config, segment_frames=min(self.config.segment_frames, limit),
                                   chunk_frames=min(self.config.chunk_frames, limit))

    def _common(self, full: Motion, config) -> "_Common":
        """What every segment length of ``full`` shares: the rig, its tracks, the bound left, targets and cuts.

        A still root (:mod:`.static_root`) is kept apart: ``motion`` is then the motion of the other joints, and the
        check of :meth:`_finish` decodes the whole rig against ``full``."""
        if full.num_joints > container.MAX_JOINTS:
            raise ValueError(
                f"mcb-rot: the stream holds at most {container.MAX_JOINTS} joints, the motion has {full.num_joints}."
            )
        if full.scales is not None and config.shell_cm > 0:
            joint = full.skeleton.names[int(full.scaled_joints()[0])]
            raise TrackRefusal(f"mcb-rot: joint {joint!r} is scaled (a scale track); the shell bound (shell_cm > 0) "
                               "is defined on unscaled joint frames: set shell_cm=0 for a scaled rig.")
        split = split_static_root(full) if config.static_root else None
        still, motion = (None, full) if split is None else split
        exponent = skeleton_step_exponent(config.eps_cm, motion.skeleton)
        skeleton_blob = pack_skeleton_runtime(motion.skeleton, exponent)
        stored = unpack_skeleton_runtime(ByteReader(skeleton_blob))
        rig = None if self._prior is None else self._prior.match(motion.skeleton, still, exponent)
        if rig is not None:  # the prior holds this rig: the stream names it (flag bit 15), the same skeleton decoded
            reference = ByteWriter()
            self._prior.write_reference(reference, exponent, rig)
            skeleton_blob = reference.getvalue()
        # A game rig's translation tracks, on a grid whose error (along the worst chain) comes off the bound.
        tracks = plan_tracks(motion, config.track_share * config.eps_cm, lambda values: fit_single(values, 0.5))
        # Its scale tracks (:mod:`.scales`): their error, and the lengths they stretch, come off the bound too.
        bones = np.sqrt(np.sum(stored.offsets**2, axis=1)) if tracks is None else tracks.bones_cm(stored)
        scales = plan_scales(motion, stored, bones, end_site_reach(stored) if config.end_sites else None,
                             config.track_share * config.eps_cm, lambda values: fit_single(values, 0.5))
        stretch = stretch_of(stored, scales)
        discrepancy = offset_discrepancy_cm(motion.skeleton, stored, config.end_sites, stretch)
        track_error = 0.0 if tracks is None else tracks.error_cm(stored, None if stretch is None else stretch[0])
        scale_error = 0.0 if scales is None else scale_error_cm(
            stored, scales, bones, end_site_reach(stored) if config.end_sites else None)
        bound = config.eps_cm * (1.0 - 2 * _SAFETY_MARGIN) - 2.0 * discrepancy - track_error - scale_error
        if bound <= 0.25 * config.eps_cm:  # defensive: skeleton_step_exponent keeps 2 x discrepancy below eps / 3
            raise ValueError(
                f"mcb-rot: eps {config.eps_cm} cm is too small for this skeleton's stored offsets "
                f"(their grid moves joints by up to {discrepancy:.3g} cm"
                f"{'' if scales is None else f', its scale tracks by {scale_error:.3g} cm'})."
            )
        target = motion.positions()
        ends = motion.end_site_positions() if config.end_sites and len(motion.skeleton.end_site_parents) else None
        cuts = find_cuts(target, ratio=config.cut_ratio, min_jump_cm=config.cut_min_cm) if config.cut_ratio > 0 else np.zeros(0, np.int64)
        quats = quat.sign_continuous(motion.rotations)
        steps = None if tracks is None else tracks.steps_of(stored, tracks.q)
        points = PointTargets(target, motion.rotations, stored, _f32(config.shell_cm), ends=ends, translations=steps,
                              scales=None if scales is None else scales_of(scales, motion.num_joints, scales.q))
        return _Common(full, motion, still, skeleton_blob, stored, rig, tracks, scales, bound, target, ends, cuts,
                       quats, points)

    def _prepare(self, full: Motion, config, common: "_Common | None" = None) -> "_Prepared":
        """Everything the rate search of ``full`` under ``config`` needs, up to its :class:`_Encoder`; ``common``
        (:meth:`_common` of ``full`` under a config that differs at most in ``segment_frames``) is not rebuilt."""
        if common is None:
            common = self._common(full, config)
        c = common
        motion, still, stored, tracks, scales, rig, cuts = (c.motion, c.still, c.stored, c.tracks, c.scales, c.rig,
                                                            c.cuts)
        starts = segment_starts(motion.num_frames, cuts, config.segment_frames)
        layout = SegmentLayout(motion.num_frames, starts, config.chunk_frames)
        signal, overrides = _signal(c.quats, motion.root_positions, layout)
        rotvecs = signal[:, 3:].reshape(motion.num_frames, motion.num_joints, 3)
        axis_codes = principal_axes(rotvecs) if config.principal_axes else np.zeros((motion.num_joints, 3), np.int64)
        signal[:, 3:] = to_axes(rotvecs, axes_from_codes(axis_codes)).reshape(motion.num_frames, -1)
        spectra = forward(signal, layout)
        settings = Settings.create(config.eps_cm, c.bound, 1.0, config.frequency_slope, config.rounding,
                                   config.root_share, np.deg2rad(config.free_angle_deg), config.allocation_power,
                                   config.segment_frames, config.chunk_frames, config.shell_cm,
                                   tracks=tracks is not None, ends=config.end_sites, static_root=still is not None,
                                   scales=scales is not None, prior=rig is not None)
        budgets = stream_budgets(settings, stored, tracks, scales)
        channels = 3 + 3 * motion.num_joints
        info = StreamInfo(settings, stored, budgets, layout, cuts, overrides, axis_codes,
                          np.zeros(channels, np.int64), np.zeros(NUM_BANDS, np.int64), tracks=tracks,
                          static_root=still, scales=scales,
                          prior_mean=None if rig is None else self._prior.rigs[rig].mean)
        encoder = _Encoder(config, motion, info, c.skeleton_blob, spectra, c.points, c.quats)
        return _Prepared(encoder, full, still, c.target, c.ends, rig, cuts)

    @staticmethod
    def _search_of(prepared: "_Prepared", seed: "_Attempt | None" = None) -> "_Attempt":
        """The attempt the rate search (and the rounding search) of ``prepared`` picks, not yet written; with
        ``seed`` (an attempt of this stream at a grid multiplier) the walk starts at its multiplier and reads it."""
        encoder = prepared.encoder
        config, motion = encoder.config, encoder.motion
        if config.step_rel > 0:
            return encoder.attempt(config.step_rel)
        flat_too = config.slope_search and config.frequency_slope > 0
        if seed is not None:
            start = int(np.argmin(np.abs(np.log(np.array(_SEARCH_GRID) / seed.multiplier))))
            settings = seed.info.settings
            key = (start, flat_too and settings.slope == 0.0)
            known = {key: seed} if settings.rounding == _f32(config.rounding) and np.isfinite(seed.size) else {}
            chosen = _search(encoder.attempt, flat_too, start=start, known=known)
        else:
            prefetch = _PREFETCH if motion.num_frames <= _PREFETCH_FRAMES else ((), ())
            chosen = _search(encoder.attempt, flat_too, encoder.attempts_of, prefetch)
        if config.rounding_search:
            chosen = _search_rounding(encoder, chosen, config.rounding)
        return chosen

    def _finish(self, prepared: "_Prepared", chosen: "_Attempt", payload: bytes | None = None) -> bytes:
        """The payload of ``chosen`` (``payload`` when already written), decoded and checked against the bound:
        every joint and end site (and shell vertex) of the whole rig within eps, else RuntimeError."""
        encoder, still, target, ends, rig = (prepared.encoder, prepared.still, prepared.target, prepared.ends,
                                             prepared.rig)
        config, motion, layout = encoder.config, encoder.motion, encoder.layout
        if payload is None:
            payload = encoder.write(chosen)
        # The guarantee: decode what we are about to return and check it (the whole rig, a still root included).
        if still is not None:
            full = prepared.full
            target = full.positions()
            ends = full.end_site_positions() if ends is not None else None
            motion = full
        header = Header(self.name, motion.num_frames, motion.num_joints, motion.fps)
        decoded, decoded_motion = self.decode_payload(header, memoryview(payload))
        worst = float(np.sqrt(np.sum((decoded - target) ** 2, axis=-1)).max())
        if not worst <= config.eps_cm:
            raise RuntimeError(f"mcb-rot: decoded L-inf {worst} cm exceeds eps {config.eps_cm} cm; not writing.")
        if ends is not None:
            end_worst = float(np.sqrt(np.sum((decoded_motion.end_site_positions() - ends) ** 2, axis=-1)).max())
            if not end_worst <= config.eps_cm:
                raise RuntimeError(f"mcb-rot: decoded end-site L-inf {end_worst} cm exceeds eps {config.eps_cm} cm; "
                                   "not writing.")
            worst = max(worst, end_worst)
        if config.shell_cm > 0:
            shell = float(motion_shell_errors(motion, decoded_motion, config.shell_cm).max())
            if not shell <= config.eps_cm:
                raise RuntimeError(f"mcb-rot: decoded shell error {shell} cm at {config.shell_cm} cm exceeds eps "
                                   f"{config.eps_cm} cm; not writing.")
            worst = max(worst, shell)
        self._used_prior = rig is not None
        self.last_encode_stats = {"step_multiplier": chosen.multiplier, "frequency_slope": chosen.info.settings.slope,
                                  "corrections": int(len(chosen.corrections[0])), "attempts": encoder.attempts,
                                  "attempts_given_up": encoder.given_up,
                                  "estimated_bytes": chosen.size,
                                  "bound_slack_cm": config.eps_cm - worst, "segments": layout.num_segments,
                                  "cuts": len(prepared.cuts)}
        return payload

    # -- decoding --------------------------------------------------------------------------------------
    def decode_payload(self, header: Header, payload: memoryview):
        if windowed.is_windowed(payload):
            return self._frames_of_windows(header, payload, 0, header.num_frames)
        return self._decode_window(header, payload)

    def _decode_window(self, header: Header, payload: memoryview):
        """Positions (F, J, 3) cm and the motion of a one-window payload."""
        return _decode_frames(read_info(header, payload, self._prior), payload, 0, header.num_frames, header.fps)

    def _stream_info(self, header: Header, payload: memoryview) -> StreamInfo:
        """The parsed payload header, kept for the last stream seen: an engine sampling one clip at many times
        parses the skeleton, budgets and segment means once (the container header and the payload are compared,
        the payload byte for byte: the same payload under another frame or joint count must be checked against
        it again, not decoded into outputs sized by the new header)."""
        cached = getattr(self, "_last_info", None)
        if cached is not None and cached[0] == header and cached[1] == payload:
            return cached[2]
        info = read_info(header, payload, self._prior)
        self._last_info = (header, bytes(payload), info)
        return info

    def decode_frames(self, data: bytes, start: int, stop: int, *, limits: DecodeLimits | None = None) -> Decoded:
        """Frames ``start:stop`` of a stream, decoding only the chunks (groups of segments) that hold them.

        Returns a :class:`Decoded` whose positions (``stop - start``, J, 3) and motion cover those frames only (the
        header still describes the whole stream). ``limits`` as in :meth:`decode`, applied to the frames asked for.

        Raises
        ------
        ValueError
            If ``start:stop`` is empty or outside the stream's frames.
        BitstreamError
            If the stream is corrupt.
        """
        header, payload = self._unpack_frame_range(data, start, stop)
        with using_limits(limits) as active:
            active.check_header(stop - start, header.num_joints, self.codes_rotations)
        try:
            with np.errstate(all="ignore"):  # as in decode: what a hostile payload overflows is refused below
                if windowed.is_windowed(payload):
                    positions, motion = self._frames_of_windows(header, payload, start, stop)
                else:
                    positions, motion = _decode_frames(self._stream_info(header, payload), payload, start, stop,
                                                       header.fps)
        except BitstreamError:
            raise
        except (ValueError, IndexError, KeyError, OverflowError, EOFError, TypeError) as error:
            raise BitstreamError(f"{self.name}: payload is inconsistent with its header: {error}") from error
        if not np.all(np.isfinite(positions)):
            raise BitstreamError(f"{self.name}: decoded positions hold non-finite values.")
        return Decoded(positions=positions, motion=motion, header=header)

    def _frames_of_windows(self, header: Header, payload: memoryview, start: int,
                           stop: int) -> tuple[np.ndarray, Motion]:
        """Positions (n, J, 3) cm and the motion of frames ``start:stop`` (n of them) of a windowed payload.

        Decodes only the windows holding those frames, and in each only the chunks holding them, into the outputs
        (memory: the outputs and one decoder block's temporaries: each window is decoded straight into them). The last window's parsed header is kept, as for a one-window
        stream, so that sampling one window at many times parses it once.
        """
        _, parts = windowed.read_windows(payload, header.num_frames)  # every extent checked before decoding
        count = stop - start
        positions = np.empty((count, header.num_joints, 3))
        roots = np.empty((count, 3))
        quats = np.empty((count, header.num_joints, 4))
        translations = None  # allocated at the first window with tracks (a window without any: the offsets)
        scales = None  # allocated at the first window with scale tracks (a window without any: 1)
        skeleton = None
        for first, end, part in windowed.windows_of_range(parts, start, stop):
            info = self._stream_info(windowed.window_header(header, first, end), part)
            skeleton = _skeleton_of(info) if skeleton is None else skeleton
            low, high = max(start, first), min(stop, end)
            out = slice(low - start, high - start)
            if (info.tracks is not None or info.static_root is not None) and translations is None:
                translations = np.empty((count, header.num_joints, 3))
                translations[:] = skeleton.offsets
            if info.scales is not None and scales is None:
                scales = np.ones((count, header.num_joints, 3))
            if info.static_root is not None or info.scales is not None:  # decoded apart, then put in place
                window_positions, window_motion = _decode_frames(info, part, low - first, high - first, header.fps)
                positions[out], roots[out], quats[out] = window_positions, window_motion.root_positions, \
                    window_motion.rotations
                if window_motion.translations is not None:
                    if translations is None:
                        translations = np.empty((count, header.num_joints, 3))
                        translations[:] = skeleton.offsets
                    translations[out] = window_motion.translations
                if window_motion.scales is not None:
                    scales[out] = window_motion.scales
                continue
            window_out = (positions[out], roots[out], quats[out])
            if translations is not None:
                window_out += (translations[out],)
                translations[out] = skeleton.offsets  # a window without tracks keeps the offsets
            decode_range(info, part, low - first, high - first, window_out)
        if translations is not None:
            translations[:, 0] = roots
        return positions, Motion.from_decoder(skeleton, header.fps, roots, quats, translations, scales)

    def describe_payload(self, header: Header, payload: memoryview):
        if windowed.is_windowed(payload):
            window_frames, parts = windowed.read_windows(payload, header.num_frames)
            first = windowed.window_header(header, *parts[0][:2])
            return {"windows of frames": f"{len(parts)} x {window_frames} (first shown)",
                    **self._describe_window(first, parts[0][2])}
        return self._describe_window(header, payload)

    def _describe_window(self, header: Header, payload: memoryview):
        info = read_info(header, payload, self._prior)
        settings = info.settings
        return {"eps_cm (guaranteed L-inf)": settings.eps_cm, "step multiplier (x budget)": settings.multiplier,
                "shell distance cm (bound also on vertices)": settings.shell_cm,
                "segment frames": settings.segment_frames, "chunk frames": settings.chunk_frames,
                "segments": info.layout.num_segments, "cuts": len(info.cuts),
                "re-referenced joint segments": len(info.overrides),
                "joints on principal axes": int((info.axis_codes != 0).any(axis=1).sum())}


def _segment_lengths(num_frames: int, segment_frames: int) -> list[int]:
    """The segment lengths the search below :data:`_HIGH_RATE_FPS` tries, in order (the first is
    ``segment_frames``; the smallest stream wins, ties to the earlier): ``segment_frames``, half of it, and for a
    clip of up to :data:`_EVEN_SPLIT_CLIPS` x ``segment_frames`` frames the even splits ``ceil(F / k)`` of its frames
    into k segments of half to all of ``segment_frames`` (and one split finer, down to a quarter): no segment is
    ever longer than ``segment_frames``, so the unit a random pose decodes stays the config's. Each length is any varint of the
    settings (the decoder reads the grid from the stream); the split is even when the clip has no cut."""
    lengths = [segment_frames]
    if segment_frames // 2 >= _MIN_SEARCHED_SEGMENT:
        lengths.append(segment_frames // 2)
    if num_frames <= _EVEN_SPLIT_CLIPS * segment_frames:
        first = -(-num_frames // segment_frames)
        for count in range(first, -(-2 * num_frames // segment_frames) + 2):
            frames = -(-num_frames // count)
            if frames < max(segment_frames // 4, _MIN_SEARCHED_SEGMENT):
                break
            if frames not in lengths:
                lengths.append(frames)
    return lengths


def _skeleton_of(info: StreamInfo):
    """The decoded motion's skeleton: the stream's, under its still root when it has one (cached)."""
    if info.static_root is None:
        return info.skeleton
    if "full skeleton" not in info._cache:
        info._cache["full skeleton"] = info.static_root.skeleton(info.skeleton)
    return info._cache["full skeleton"]


def _decode_frames(info: StreamInfo, payload: memoryview, start: int, stop: int, fps: float) -> tuple:
    """Positions (n, J, 3) cm and the motion of frames ``start:stop`` of a one-window payload (n of them); a still
    root (:mod:`.static_root`) is put back above the decoded joints."""
    out = _outputs(stop - start, info.skeleton.num_joints, info)
    positions, roots, quats = decode_range(info, payload, start, stop, out)
    translations = out[3] if info.tracks is not None else None
    scales = out[4] if len(out) > 4 else None
    if info.static_root is not None:
        positions, roots, quats, translations = info.static_root.expand(positions, roots, quats, translations,
                                                                        info.skeleton.offsets)
    return positions, Motion.from_decoder(_skeleton_of(info), fps, roots, quats, translations, scales)


def _outputs(count: int, num_joints: int, info: StreamInfo) -> tuple:
    """The decode's outputs of ``count`` frames: positions, roots, rotations and, when the stream has translation
    tracks, every joint's translation (its offset where it has no track), and when it has scale tracks (then with
    the translations) every joint's scale (1 where it has no track)."""
    out = (np.empty((count, num_joints, 3)), np.empty((count, 3)), np.empty((count, num_joints, 4)))
    if info.tracks is not None or info.scales is not None:
        out += (np.empty((count, num_joints, 3)),)
    if info.scales is not None:
        out += (np.empty((count, num_joints, 3)),)
    return out


def _search(attempt, flat_too: bool = False, batch=None, prefetch: tuple = ((), ()), start: int = _SEARCH_START,
            known: dict | None = None) -> "_Attempt":
    """The attempt of smallest estimated size over :data:`_SEARCH_GRID`, by walking downhill from
    :data:`_SEARCH_START`; with ``flat_too``, also a flat step over frequency (slope 0) from the next multiplier up,
    walking up while it wins. ``attempt(multiplier, slope=None, budget=inf)`` returns an :class:`_Attempt`; every
    attempt after the first gets the best size so far as its budget (it gives up, size inf, once it exceeds it).

    ``prefetch`` (grid indices of the config's slope, of the flat slope) are evaluated first, side by side, by
    ``batch(requests)`` (a list of ``(multiplier, slope)``: their attempts, run to their end); the walk then reads
    them instead of trying them. A prefetched attempt has its exact size where the walk would have given it up
    (larger than the budget: the walk's decisions are the same), so the walk ends where it would without them.

    ``start`` (a grid index) starts the walk elsewhere (then without ``prefetch``), where another stream of the motion
    found its minimum; ``known`` ((grid index, flat) -> attempt) are attempts the walk reads instead of trying."""
    tried: dict = dict(known or {})  # (grid index, flat) -> attempt
    if batch is not None and (prefetch[0] or prefetch[1]) and start == _SEARCH_START:
        # The start first: the batch gives up the others against its size (every later attempt of the walk has a
        # budget no larger than it), and tighter where the walk has gone further on the attempts finished so far.
        keys = [(_SEARCH_START, False)] + [(i, False) for i in prefetch[0] if i != _SEARCH_START]
        keys += [(i, True) for i in prefetch[1] if flat_too]

        def limit(known: dict) -> float:
            """The largest budget the walk can still give an attempt it has not read, from the batch's attempts
            known so far (request index -> attempt, size inf where given up); -inf where it reads none of them."""
            return _walk_limit({keys[k]: attempt for k, attempt in known.items()}, flat_too)

        for key, result in zip(keys, batch([(_SEARCH_GRID[i], 0.0 if flat else None) for i, flat in keys],
                                           limit=limit)):
            tried[key] = result

    def get(index: int, flat: bool, budget: float = np.inf) -> "_Attempt":
        if (index, flat) not in tried:
            tried[index, flat] = attempt(_SEARCH_GRID[index], 0.0 if flat else None, budget=budget)
        return tried[index, flat]

    return _walk(get, flat_too, start)


def _walk(get, flat_too: bool, start: int = _SEARCH_START):
    """The walk of :func:`_search` over ``get(grid index, flat, budget)`` (an attempt: ``size``, ``base``): the
    attempt chosen. Every budget it gives is the best size so far, so budgets never grow along the walk."""
    best = start
    start = get(best, False)
    # Walk first the way the start's correction share points (same minimum as any order, one attempt fewer where
    # it points right): corrections dearer than _FINER_FIRST_SHARE of the stream call for finer steps.
    finer_first = start.size - start.base > _FINER_FIRST_SHARE * start.size
    for direction in ((-1, 1) if finer_first else (1, -1)):
        while (0 <= best + direction < len(_SEARCH_GRID)
               and get(best + direction, False, get(best, False).size).size < get(best, False).size):
            best += direction
    chosen = get(best, False)
    if flat_too:  # a flat step is finer at high frequencies: its best multiplier is the next one up, or higher
        index = min(best + 1, len(_SEARCH_GRID) - 1)
        flat = get(index, True, chosen.size)
        while flat.size < chosen.size:
            chosen = flat
            if index + 1 == len(_SEARCH_GRID):
                break
            index += 1
            flat = get(index, True, chosen.size)
    return chosen


def _search_rounding(encoder: "_Encoder", chosen: "_Attempt", rounding: float) -> "_Attempt":
    """``chosen`` (the rate search's pick) or, where smaller, the attempt at its step multiplier and slope with a
    wider dead zone (:data:`_WIDER_ROUNDINGS`, tried in order while each wins): fewer small coefficients, more of
    the closed loop's corrections; which is smaller depends on the clip. A rounding other than the default costs
    :data:`_ROUNDING_BYTES` in the settings, added to its estimate (both are estimated on the format's tables)."""
    def cost(attempt: "_Attempt") -> float:
        return attempt.size + (_ROUNDING_BYTES if attempt.info.settings.rounding != _DEFAULT_ROUNDING else 0.0)

    for wider in _WIDER_ROUNDINGS:
        if not wider < rounding:
            continue
        extra = _ROUNDING_BYTES if _f32(wider) != _DEFAULT_ROUNDING else 0.0
        other = encoder.attempt(chosen.multiplier, chosen.info.settings.slope, budget=cost(chosen) - extra,
                                rounding=wider)
        if not cost(other) < cost(chosen):
            break
        chosen = other
    return chosen


class _Blocked(Exception):
    """Raised by :func:`_walk_limit`'s ``get`` at the first attempt not known yet, with the budget it would get."""

    def __init__(self, budget: float) -> None:
        super().__init__(budget)
        self.budget = budget


def _walk_limit(known: dict, flat_too: bool) -> float:
    """The walk of :func:`_search` run on the attempts ``known`` ((grid index, flat) -> attempt) until it asks for
    one it does not know: that request's budget, which bounds every later one (budgets never grow along the walk);
    -inf when the walk ends on known attempts (it reads no other). An attempt not known yet whose estimate
    exceeds this limit can be given up: the walk either never reads it or gives it a budget it exceeds."""

    def get(index: int, flat: bool, budget: float = np.inf):
        if (index, flat) not in known:
            raise _Blocked(budget)
        return known[index, flat]

    try:
        _walk(get, flat_too)
    except _Blocked as blocked:
        return blocked.budget
    return -np.inf


def _signal(quats: np.ndarray, roots: np.ndarray, layout: SegmentLayout) -> tuple[np.ndarray, dict]:
    """The (F, 3 + 3 J) signal (root cm, rotation vectors rad) and the re-referenced (segment, joint) pairs."""
    num_frames, num_joints, _ = quats.shape
    segment_of = np.repeat(np.arange(layout.num_segments), layout.lengths)
    middle = layout.starts + layout.lengths // 2
    # Each segment's signs are chosen so that its middle frame has w >= 0 (continuity is kept inside it).
    flips = np.where(quats[middle, :, 3] < 0, -1.0, 1.0)  # (S, J)
    quats = quats * flips[segment_of][..., None]
    rotvecs = quat.log_map(quats)
    angles = np.sqrt(np.sum(rotvecs**2, axis=-1))  # (F, J)
    overrides = {}
    worst = np.maximum.reduceat(angles, layout.starts, axis=0)  # (S, J)
    for segment, joint in zip(*np.nonzero(worst > _OVERRIDE_ANGLE)):
        frames = slice(layout.starts[segment], layout.starts[segment] + layout.lengths[segment])
        mid = quats[middle[segment], joint]
        reference = quat.exp_map(quat.log_map(mid).astype(np.float32).astype(np.float64))
        relative = quat.multiply(quat.conjugate(reference), quats[frames, joint])
        relative = relative * np.where(relative[len(relative) // 2, 3] < 0, -1.0, 1.0)
        rotvecs[frames, joint] = quat.log_map(relative)
        overrides[(int(segment), int(joint))] = reference
    return np.concatenate([roots, rotvecs.reshape(num_frames, 3 * num_joints)], axis=1), overrides


@dataclass(frozen=True, eq=False)
class _Common:
    """What the streams of one motion with different segment lengths share (:meth:`McbRotCodec._common`): the
    motion coded (``full`` less a still root ``still``), the skeleton as stored and its blob, the prior's ``rig``,
    translation and scale tracks, the ``bound`` (cm) left to the rotations, the targets (``target`` (F, J, 3) cm,
    ``ends`` (F, E, 3) cm or None, ``points``), the cut frames and the sign-continuous rotations (F, J, 4)."""

    full: Motion
    motion: Motion
    still: object
    skeleton_blob: bytes
    stored: object
    rig: int | None
    tracks: object
    scales: object
    bound: float
    target: np.ndarray
    ends: np.ndarray | None
    cuts: np.ndarray
    quats: np.ndarray
    points: PointTargets


@dataclass(frozen=True, eq=False)
class _Prepared:
    """One stream's encoder before its rate search, with what the check after it needs: ``full`` the whole motion
    (a still root included), ``still`` the still root kept apart (or None), ``target`` (F, J, 3) cm and ``ends``
    (F, E, 3) cm (or None) the positions the coded joints must reach, ``rig`` the prior's rig it names (or None),
    ``cuts`` the cut frames."""

    encoder: "_Encoder"
    full: Motion
    still: object
    target: np.ndarray
    ends: np.ndarray | None
    rig: int | None
    cuts: np.ndarray


@dataclass(frozen=True, eq=False)
class _Attempt:
    """One step multiplier's stream, not yet entropy coded.

    ``size`` is its estimated payload size (bytes, :func:`.rate.estimate_bytes`: comparable between attempts of one
    stream only), ``base`` the part of it that is the base layer (the rest codes the corrections); ``info`` has the attempt's settings and segment means; ``coefficients`` segment -> (n - 1, C) int64
    AC coefficients; ``corrections`` (flat indices (N,), values (N, 3)) from :func:`.refine.refine`.
    """

    size: float
    base: float
    multiplier: float
    info: StreamInfo
    coefficients: dict
    corrections: tuple


class _Encoder:
    """One motion's fixed encoding state; :meth:`attempt` quantizes and refines for one step multiplier,
    :meth:`write` entropy codes the chosen attempt."""

    def __init__(self, config, motion: Motion, info: StreamInfo, skeleton_blob: bytes, spectra,
                 points: PointTargets, quats: np.ndarray | None = None) -> None:
        self.config = config
        self.motion = motion
        self.info = info
        self.layout = info.layout
        self.skeleton_blob = skeleton_blob
        self.spectra = spectra
        self.points = points
        self.compensator = None
        if config.compensate:
            quats = quat.sign_continuous(motion.rotations) if quats is None else quats  # (F, J, 4)
            self.compensator = Compensator(info, quats, motion.root_positions)
        self.attempts = 0
        self.given_up = 0
        self._tiles: dict = {}
        for name in _AXES_CACHE:  # into info's cache, for every attempt's copy (:meth:`_with_axes`)
            getattr(info, name.replace(" ", "_"), None)

    def attempt(self, multiplier: float, slope: float | None = None, budget: float = np.inf,
                rounding: float | None = None) -> _Attempt:
        """The stream at step multiplier ``multiplier``, frequency slope ``slope`` (None: the config's) and
        quantizer rounding ``rounding`` (None: the config's).

        An attempt whose estimated size exceeds ``budget`` (bytes, the best attempt so far) is given up as soon as
        that is known (before the closed loop when its base layer alone exceeds it, else after a round of
        corrections): it is returned with size inf and nothing else.
        """
        return self.attempts_of([(multiplier, slope) + (() if rounding is None else (rounding,))], budget)[0]

    def attempts_of(self, requests: list, budget: float = np.inf, limit=None) -> list[_Attempt]:
        """:meth:`attempt` of every ``(multiplier, slope)`` of ``requests``, side by side: one compensated
        quantization for all (:meth:`.Compensator.quantize_many`) and one closed loop over their frames laid end to
        end, so that each numpy call does the work of all of them. ``budget`` applies to each; an attempt is also
        given up once its estimate exceeds the size of the first request (when that has finished), or with
        ``limit`` (``limit(known)``: a budget from the attempts finished or given up so far, request index ->
        attempt with ``size`` and ``base``; :func:`_walk_limit`) once it exceeds that instead."""
        config, layout = self.config, self.layout
        infos = []
        for multiplier, slope, *rounding in requests:
            self.attempts += 1
            settings = dataclasses.replace(self.info.settings, multiplier=_f32(multiplier))
            if slope is not None:
                settings = dataclasses.replace(settings, slope=_f32(slope))
            if rounding:  # (one rounding per call: the compensated quantization takes the first attempt's)
                settings = dataclasses.replace(settings, rounding=_f32(rounding[0]))
            infos.append(self._with_axes(self.info.replace(settings=settings)))
        if self.compensator is not None:
            quantized = self.compensator.quantize_many(infos)
        else:
            quantized = [quantize(info, self.spectra) for info in infos]
        for k, (dc, _) in enumerate(quantized):
            infos[k] = self._with_axes(infos[k].replace(dc=dc))
        if self.compensator is not None:
            estimates = base_bytes_many(infos, self.compensator.last_quantized)
        else:
            estimates = [base_bytes(info, coefficients) for info, (_, coefficients) in zip(infos, quantized)]
        results: list = [None] * len(requests)
        live, roots, quats, bases = [], [], [], []
        segments = np.arange(layout.num_segments)
        for k, (info, (dc, coefficients)) in enumerate(zip(infos, quantized)):
            base = estimates[k]
            if base > budget:
                self.given_up += 1
                results[k] = _Attempt(np.inf, base, requests[k][0], info, {}, ())
                continue
            # Decode the base layer as the decoder will, then refine in closed loop.
            root, quat_ = assemble(info, segments, base_signal(info, segments, coefficients))
            live.append((k, coefficients))
            roots.append(root)
            quats.append(quat_)
            bases.append(base)
        if not live:
            return results
        check = config.eps_cm * (1.0 - _SAFETY_MARGIN)
        num_frames = self.motion.num_frames
        if len(live) == 1:
            k = live[0][0]
            info, base = infos[k], bases[0]
            corrections = refine(info, self.motion.rotations, self.motion.root_positions, roots[0], quats[0],
                                  self.points, check, config.greedy_corrections,
                                  lambda flat, values: base + corrections_bytes(info, flat, values) > budget)
            parts = [corrections]
        else:
            true_quats, true_roots, points = self._tiled(len(live))
            prune = _Pruner([infos[k] for k, _ in live], bases, num_frames, budget, anchor=live[0][0] == 0,
                            limit=limit, requests=[k for k, _ in live],
                            known={k: results[k] for k in range(len(requests)) if results[k] is not None})
            flat, values = refine(infos[live[0][0]], true_quats, true_roots, np.concatenate(roots),
                                   np.concatenate(quats), points, check, config.greedy_corrections, prune=prune)
            slots = len(self.info.correction_steps)
            bounds = np.searchsorted(flat, np.arange(len(live) + 1) * (num_frames * slots))
            parts = [None if i in prune.dropped else
                     (flat[bounds[i] : bounds[i + 1]] - i * num_frames * slots, values[bounds[i] : bounds[i + 1]])
                     for i in range(len(live))]
        for (k, coefficients), base, corrections in zip(live, bases, parts):
            info = infos[k]
            if corrections is None:
                self.given_up += 1
                results[k] = _Attempt(np.inf, base, requests[k][0], info, {}, ())
                continue
            results[k] = _Attempt(base + corrections_bytes(info, *corrections), base, requests[k][0], info,
                                  coefficients, corrections)
        return results

    def _with_axes(self, info: StreamInfo) -> StreamInfo:
        """``info`` (a copy of the stream's with other settings) with the stream's principal axes already in its
        cache (they depend on the axis codes only; every attempt would rebuild them)."""
        for key in _AXES_CACHE:
            if key in self.info._cache:
                info._cache.setdefault(key, self.info._cache[key])
        return info

    def _tiled(self, count: int) -> tuple:
        """The original rotations (count F, J, 4), roots (count F, 3) and checked points, ``count`` times along the
        frames (cached): the targets of a closed loop over ``count`` attempts side by side."""
        if count not in self._tiles:
            motion = self.motion
            self._tiles[count] = (np.tile(motion.rotations, (count, 1, 1)), np.tile(motion.root_positions, (count, 1)),
                                  self.points.tiled(count))
        return self._tiles[count]

    def write(self, chosen: _Attempt) -> bytes:
        """The payload of an attempt (entropy classes fitted and every chunk ANS coded)."""
        return write_payload(chosen.info, self.skeleton_blob, chosen.coefficients, chosen.corrections)


@dataclass(frozen=True)
class _Size:
    """What the walk of the rate search reads of an attempt: its estimated ``size`` and the ``base`` part of it."""

    size: float
    base: float


class _Pruner:
    """The give-up rule of a closed loop over several attempts side by side (frames of attempt ``i`` at
    ``i F .. (i + 1) F``): after every round, an attempt whose estimate so far (base plus the corrections so far)
    exceeds ``budget``, or, once the anchor (attempt 0, the rate search's start: every later attempt of the
    walk has a budget no larger than its size) has finished, exceeds the anchor's size, is given up: dropped from
    the loop (the walk would have given it up too, at this round or before). ``dropped`` lists them.

    With ``limit`` (:func:`_walk_limit` over the rate search's keys), the anchor's size gives way to the budget the
    walk would give next, run on the attempts finished (or given up) so far: tighter where the walk has moved past
    the start, -inf (every attempt still running is dropped) where it ends without them. ``requests`` maps the
    loop's attempts to request indices, ``known`` holds the requests given up before the loop."""

    def __init__(self, infos: list, bases: list, num_frames: int, budget: float, anchor: bool, limit=None,
                 requests: list = (), known: dict | None = None) -> None:
        self.infos, self.bases, self.num_frames, self.budget = infos, bases, num_frames, budget
        self.anchor = anchor
        self.anchor_size = None
        self.dropped: set = set()
        self.limit, self.requests, self.known = limit, list(requests), dict(known or {})
        self.finished: dict = {}  # attempt -> its final estimate

    def _estimate(self, attempt: int, corrected: np.ndarray, values: np.ndarray) -> float:
        rows = slice(attempt * self.num_frames, (attempt + 1) * self.num_frames)
        flat = np.flatnonzero(corrected[rows].ravel())
        return self.bases[attempt] + corrections_bytes(self.infos[attempt], flat, values[rows].reshape(-1, 3)[flat])

    def _known(self, running: list, corrected: np.ndarray, values: np.ndarray) -> dict:
        """Request index -> size and base of every attempt no longer running (size inf where given up)."""
        known = dict(self.known)
        for attempt, request in enumerate(self.requests):
            if attempt in self.dropped:
                known[request] = _Size(np.inf, self.bases[attempt])
            elif attempt not in running:
                if attempt not in self.finished:
                    self.finished[attempt] = self._estimate(attempt, corrected, values)
                known[request] = _Size(self.finished[attempt], self.bases[attempt])
        return known

    def __call__(self, corrected: np.ndarray, values: np.ndarray, frames: np.ndarray) -> np.ndarray:
        """Which of the ``frames`` still missing stay in the loop (bool mask)."""
        attempt_of = frames // self.num_frames
        running = np.unique(attempt_of).tolist()
        limit = self.budget
        if self.limit is not None:
            limit = min(limit, self.limit(self._known(running, corrected, values)))
            if limit == -np.inf:  # the walk reads none of the attempts still running
                self.dropped.update(running)
                return np.zeros(len(frames), dtype=bool)
        elif self.anchor and running[0] != 0:  # the anchor has finished: its size is final
            if self.anchor_size is None:
                self.anchor_size = self._estimate(0, corrected, values)
            limit = min(limit, self.anchor_size)
        if limit == np.inf:
            return np.ones(len(frames), dtype=bool)
        for attempt in running:  # (the base alone, a part of the estimate, often settles it)
            if self.bases[attempt] > limit or self._estimate(attempt, corrected, values) > limit:
                self.dropped.add(attempt)
        return ~np.isin(attempt_of, list(self.dropped))
