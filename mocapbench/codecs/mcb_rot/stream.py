"""The ``mcb-rot`` payload: its header, its chunks, and the decoder's path from bytes to rotations.

Layout (after the container header), format 5 (format 4's, with chunks of 256 frames by default instead of 128)::

    u8 format | f32 eps | f32 bound | varint flags | u8 multiplier code (or f32) | the settings that differ from
    the defaults (:class:`Settings`)
    skeleton (compact blob: offsets on a grid of 2^e cm that follows eps, bit-packed) | cuts (varint gaps) |
    re-referenced (segment, joint) pairs, f32 rotation vectors
    principal axes: J flag bits, int16 x 3 per flagged joint
    classes: channel scales and band tilts bit-packed (:func:`write_small_ints`), u8 tilts of the segment means
    and significance counts, u8 classes of correction gaps and values
    one ANS stream: the segment means (S x C, differences along the segments), then the significance counts (per
    segment and channel, the number of AC coefficients up to the last nonzero one, differences along the segments)
    varint size of every chunk | chunks

    chunk: varint correction count | ANS stream of the significant coefficients (segment by segment,
    channel-major), then the correction gaps and values.

Formats 2 and 3 (still read) wrote every setting (the bound as f64), the skeleton's offsets on a fixed 2^-16 cm
grid as varints, the classes one byte each, the segment means alone in their stream, and each chunk's
significance counts in an ANS stream of its own (differences from the previous segment of the chunk). Format 4
saves 2-3 % of a 24 fps stream, and a full decode reads one count stream instead of one per chunk. Format 5 only
changes the default chunk length (:data:`_DEFAULTS`) to 256 frames: a 120 fps cmu_test clip is half as many chunks,
so half as many ANS streams to start, class groups to decode and per-chunk bytes (0.15-0.7 % smaller at 120 fps,
24 fps streams unchanged: their clips are one chunk either way), and a batched decode is 4-8 % faster; random
access still synthesizes only the segment (128 frames) holding the frames asked for, so one frame costs the
entropy decoding of its chunk more, not its synthesis.

Format 6 (written today) is the layout of the native runtime (``runtime/``, C): everything a sampler needs is
readable without zstd and without a float-dependent choice. The skeleton's offsets and parents come first in plain
bits and only the names stay zstd-compressed (:mod:`.skeleton6`); a varint after the classes gives the most values
a chunk holds (the runtime sizes its cache by it before decoding anything); the segment means and counts and every
chunk are *rANS units* (:mod:`mocapbench.entropy.rans6`): two interleaved states, values in natural order (no sort
by class to undo), static tables fixed by the format (the AC tables of rounding 0.45 whatever the stream's rounding);
chunks default to 128 frames (one segment), and the bands are computed in integers (:func:`.classes.band_of`).
The cost in bytes against format 5 is in the README. Format 6's optional sections sit behind flag bits that older
streams never set: a game rig's translation tracks (bit 10, :mod:`.tracks`), a bound over the end sites too (bit 11,
:mod:`.budgets`), a still root joint 0 kept apart from the coded skeleton (bit 12, :mod:`.static_root`: its
section follows the skeleton part), scale tracks (bit 13, :mod:`.scales`: their header after the translation
tracks', a unit per chunk after theirs), and a rig named in a prior fit on training clips (bit 15, :mod:`.prior`: a
reference in place of the skeleton part and the still root section; a u8 before the segment means says whether the
first segment's means are coded as differences from the rig's mean signal, :func:`.prior.first_means`).

Coding only the coefficients up to each channel's last nonzero one (as JPEG's end-of-block) skips the runs of
zeros at high frequencies: at ε = 1 cm 85 % of the AC coefficients of cmu_test are never coded, so decoding reads a
seventh of the symbols. Every count is checked before use; a corrupt stream raises :class:`BitstreamError`.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from mocapbench.codecs.base import Header
from mocapbench.codecs.mcb_rot import classes as model
from mocapbench.codecs.mcb_rot import quaternions as quat
from mocapbench.codecs.mcb_rot.axes import axes_from_codes
from mocapbench.codecs.mcb_rot.budgets import Budgets, joint_budgets
from mocapbench.codecs.mcb_rot.scratch import Scratch
from mocapbench.codecs.mcb_rot.segments import SegmentLayout, inverse, segment_starts
from mocapbench.codecs.segments import read_cuts, write_cuts
from mocapbench.codecs.skeleton_blob import STEP_EXPONENTS, unpack_skeleton_compact
from mocapbench.codecs.mcb_rot.skeleton6 import unpack_skeleton_runtime
from mocapbench.codecs.mcb_rot.tracks import KIND_SCALE, Tracks, read_tracks
from mocapbench.codecs.mcb_rot.scales import SCALES, frame_factors, stretched_lengths
from mocapbench.codecs.mcb_rot.static_root import StaticRoot, read_static_root
from mocapbench.codecs.mcb_rot.prior import Prior, first_means, read_reference
from mocapbench.entropy.ans import ClassTables, decode_classed, encode_classed
from mocapbench.entropy.rans6 import RansTables, decode_unit, encode_unit, quantize_counts
from mocapbench.entropy.bitio import ByteReader, ByteWriter
from mocapbench.entropy.errors import BitstreamError
from mocapbench.motion import Skeleton

__all__ = ["Settings", "StreamInfo", "steps_of", "base_signal", "assemble", "apply_corrections", "write_payload",
           "read_info", "segment_signal", "tables", "skeleton_step_exponent", "write_small_ints", "read_small_ints"]

FORMAT = 6  # payload layout version; BE CAREFUL WHEN CHANGING: append only
# 3 appended the shell distance (f32, cm) to the settings; a format 2 stream has none. 4 leaned the header: settings
# that equal the defaults are left out, the skeleton's offsets are on a grid that follows eps, the class offsets
# are bit-packed.
# are bit-packed. 6: the runtime layout (:mod:`.skeleton6`, :mod:`mocapbench.entropy.rans6`, chunks of 128 frames).
_READABLE = (2, 3, 4, 5, 6)
_SQRT3 = np.sqrt(3.0)
_SIDE = model.NUM_CLASSES  # classes >= this are coded with the nearest-rounding tables


def _f32(value: float) -> float:
    return float(np.float32(value))


def _f32_below(value: float) -> float:
    """The largest float32 not above ``value``."""
    rounded = np.float32(value)
    if float(rounded) > value:
        rounded = np.nextafter(rounded, np.float32(-np.inf))
    return float(rounded)


#: Formats 4 and 5 write a setting only where it differs from these (the codec's defaults; part of the format: BE
#: CAREFUL WHEN CHANGING): (field, value, how it is written), in the order of their flag bits 2, 3, ... Format 6's
#: chunks default to 128 frames (one segment: the random-access unit of a native sampler), as format 4's; format
#: 5's to 256 (:data:`_DEFAULTS_5`).
_DEFAULTS = (
    ("shell_cm", 0.0, "f32"),
    ("segment_frames", 128, "varint"),
    ("chunk_frames", 128, "varint"),
    ("slope", 1.0, "f32"),
    ("rounding", _f32(0.45), "f32"),
    ("root_share", _f32(0.05), "f32"),
    ("free_angle_rad", _f32(np.deg2rad(1.0)), "f32"),
    ("allocation_power", 0.0, "f32"),
)
_DEFAULTS_4 = _DEFAULTS
_DEFAULTS_5 = tuple((name, 256 if name == "chunk_frames" else value, kind) for name, value, kind in _DEFAULTS)
_MULTIPLIER_F32, _FLAT, _DEFAULT_BIT = 1, 2, 2  # flags: 1 multiplier as f32 (else a grid code), 2 slope 0; bit 2.. a default
# Format 6 flags after the defaults' bits: the stream carries translation tracks (:mod:`.tracks`; their header after
# the classes, a unit per chunk after its rotations), its budgets cover the end sites (:mod:`.budgets`), and it
# codes a still root's one child as its root (:mod:`.static_root`; the still root right after the skeleton part).
_TRACKS, _ENDS, _STATIC_ROOT = 1 << 10, 1 << 11, 1 << 12  # scale tracks: SCALES, bit 13 (:mod:`.scales`)
# Flag bit 15: the skeleton part and the still root are a reference to a rig of a prior (:mod:`.prior`).
PRIOR = 1 << 15
_GRID_ZERO = 64  # multiplier code k stands for 2^((k - 64) / 2)


def _multiplier_code(multiplier: float) -> int | None:
    """The code ``k`` in [0, 256) with ``multiplier == f32(2^((k - 64) / 2))``, or None (then written as f32)."""
    if not multiplier > 0:
        return None
    k = int(np.round(2 * np.log2(multiplier))) + _GRID_ZERO
    return k if 0 <= k < 256 and _f32(2.0 ** ((k - _GRID_ZERO) / 2)) == multiplier else None


@dataclass(frozen=True)
class Settings:
    """The stream's coding settings, exactly as written (floats rounded to float32; ``bound_cm`` rounded down)."""

    eps_cm: float  # nominal bound (for display; the decoder does not use it)
    bound_cm: float  # bound the budgets are computed for: eps less the safety margins
    multiplier: float  # base step over the channel's relative step
    slope: float
    rounding: float
    root_share: float
    free_angle_rad: float
    allocation_power: float
    segment_frames: int
    chunk_frames: int
    shell_cm: float = 0.0  # the bound also holds on the virtual vertices at this distance (0: joints only)
    tracks: bool = False  # format 6: the stream carries translation tracks (flags bit 10)
    ends: bool = False  # format 6: the budgets and the bound cover the end sites (flags bit 11)
    static_root: bool = False  # format 6: the stream's skeleton lacks a still root joint 0 (flags bit 12)
    scales: bool = False  # format 6: the stream carries scale tracks (flags bit 13)
    prior: bool = False  # format 6: the skeleton and still root are a prior's rig (flags bit 15, :mod:`.prior`)

    @classmethod
    def create(cls, eps_cm, bound_cm, multiplier, slope, rounding, root_share, free_angle_rad, power, segment, chunk,
               shell_cm=0.0, tracks=False, ends=False, static_root=False, scales=False,
               prior=False):
        """Settings with every field rounded as it will be read back (the bound down, so it never grows)."""
        return cls(_f32(eps_cm), _f32_below(bound_cm), _f32(multiplier), _f32(slope), _f32(rounding), _f32(root_share),
                   _f32(free_angle_rad), _f32(power), int(segment), int(chunk), _f32(shell_cm), bool(tracks),
                   bool(ends), bool(static_root), bool(scales), bool(prior))

    def write(self, writer: ByteWriter) -> None:
        """Format 6 (as 5): u8 format | f32 eps | f32 bound | varint flags | multiplier (u8 grid code or f32) | the
        settings that differ from :data:`_DEFAULTS` (flag bits 2, 3, ...; a flat slope is flag bit 1)."""
        writer.write_u8(FORMAT)
        writer.write_f32(self.eps_cm)
        writer.write_f32(self.bound_cm)
        code = _multiplier_code(self.multiplier)
        flags = (code is None) * _MULTIPLIER_F32 | (self.slope == 0.0) * _FLAT
        flags |= self.tracks * _TRACKS | self.ends * _ENDS | self.static_root * _STATIC_ROOT | self.scales * SCALES
        flags |= self.prior * PRIOR
        differing = []
        for bit, (name, default, kind) in enumerate(_DEFAULTS, start=_DEFAULT_BIT):
            value = getattr(self, name)
            if value != default and not (name == "slope" and value == 0.0):
                flags |= 1 << bit
                differing.append((value, kind))
        writer.write_varint(flags)
        if code is None:
            writer.write_f32(self.multiplier)
        else:
            writer.write_u8(code)
        for value, kind in differing:
            writer.write_f32(value) if kind == "f32" else writer.write_varint(value)

    @classmethod
    def read(cls, reader: ByteReader, version: int) -> "Settings":
        """The settings of a payload of format ``version`` (its format byte already read)."""
        eps = reader.read_f32("eps")
        fields = _read_flagged_settings(reader, version) if version >= 4 else _read_listed_settings(reader, version)
        _check_settings_range(eps, *fields[:10])
        return cls(eps, *fields)


def _read_flagged_settings(reader: ByteReader, version: int) -> tuple:
    """Formats 4 to 6: f32 bound | varint flags | multiplier | the settings that differ from the defaults.

    Returns ``(bound, multiplier, slope, rounding, root_share, free_angle_rad, allocation_power, segment_frames,
    chunk_frames, shell_cm, tracks, ends, static_root, scales, prior)``, the fields of :class:`Settings` after ``eps_cm``.
    """
    defaults = _DEFAULTS_5 if version == 5 else _DEFAULTS
    bound = reader.read_f32("bound")
    flags = reader.read_varint("settings flags", max_bytes=3)
    known = _DEFAULT_BIT + len(defaults) + (4 if version >= 6 else 0)  # format 6: bits 10, 11, 12, 13
    if flags & ~((1 << known) - 1 | (PRIOR if version >= 6 else 0)):
        raise BitstreamError(f"mcb-rot: unknown settings flags {flags:#x}.")
    prior = bool(flags & PRIOR)
    tracks, ends = bool(flags & _TRACKS) and version >= 6, bool(flags & _ENDS) and version >= 6
    static_root = bool(flags & _STATIC_ROOT) and version >= 6
    scales = bool(flags & SCALES) and version >= 6
    if flags & _MULTIPLIER_F32:
        multiplier = reader.read_f32("multiplier")
    else:
        multiplier = _f32(2.0 ** ((reader.read_u8("multiplier code") - _GRID_ZERO) / 2))
    values = {}
    for bit, (name, default, kind) in enumerate(defaults, start=_DEFAULT_BIT):
        if flags & (1 << bit):
            values[name] = reader.read_f32(name) if kind == "f32" else reader.read_varint(name)
        else:
            values[name] = 0.0 if name == "slope" and flags & _FLAT else default
    listed = (values[n] for n in ("slope", "rounding", "root_share", "free_angle_rad", "allocation_power",
                                  "segment_frames", "chunk_frames", "shell_cm"))
    return (bound, multiplier, *listed, tracks, ends, static_root, scales, prior)


def _read_listed_settings(reader: ByteReader, version: int) -> tuple:
    """Formats 2 and 3: f64 bound, then every setting in turn (the shell distance from format 3); no tracks, no end
    sites. Returns the fields of :class:`Settings` after ``eps_cm``, as :func:`_read_flagged_settings`."""
    bound = reader.read_f64("bound")
    multiplier, slope, rounding, root_share, free, power = (reader.read_f32("setting") for _ in range(6))
    segment_frames = reader.read_varint("segment frames")
    chunk_frames = reader.read_varint("chunk frames")
    shell = reader.read_f32("shell distance") if version >= 3 else 0.0
    return (bound, multiplier, slope, rounding, root_share, free, power, segment_frames, chunk_frames, shell,
            False, False, False, False, False)


def _check_settings_range(eps, bound, multiplier, slope, rounding, root_share, free, power, segment_frames,
                          chunk_frames, shell) -> None:
    """Refuse settings no encoder writes (a hostile stream), in one line naming every value."""
    if not (
        0 < bound <= 100 and 0 < eps <= 101 and 0 < multiplier <= 1e6 and 0 <= slope <= 64
        and 0 <= rounding <= 0.5 and 0 < root_share < 1 and 0 < free <= np.pi and 0 <= power <= 64
        and 1 <= segment_frames <= 4096 and 1 <= chunk_frames <= 1 << 20 and 0 <= shell <= 100
    ):
        raise BitstreamError(
            f"mcb-rot: settings out of range: eps {eps}, bound {bound}, multiplier {multiplier}, slope {slope}, "
            f"rounding {rounding}, root share {root_share}, free angle {free}, allocation power {power}, "
            f"segment frames {segment_frames}, chunk frames {chunk_frames}, shell distance {shell}."
        )


@dataclass(frozen=True, eq=False)
class StreamInfo:
    """What a decoder knows after the payload header: everything but the chunks' own contents."""

    settings: Settings
    skeleton: Skeleton
    budgets: Budgets
    layout: SegmentLayout
    cuts: np.ndarray  # (N,) frames where a take starts
    overrides: dict  # (segment, joint) -> reference quaternion (4,)
    axis_codes: np.ndarray  # (J, 3) int codes of each joint's principal axes (:mod:`.axes`)
    scale: np.ndarray  # (C,) class offsets of the channels
    tilt: np.ndarray  # (NUM_BANDS,) class offsets of the bands
    dc_tilt: int = 0  # class offset of the segment means over the channel scales
    count_tilt: int = 0  # class offset of the significance counts over the channel scales
    gap_class: int = 0
    value_class: int = 0
    dc: np.ndarray | None = None  # (S, C) quantized segment means
    chunk_offsets: np.ndarray | None = None  # (K + 1,) byte offsets of the chunks in the payload
    counts: np.ndarray | None = None  # (S, C) significance counts (format 4; earlier formats have them in the chunks)
    version: int = FORMAT  # payload format the stream was read from (the encoder writes FORMAT)
    unit_values: int = 0  # format 6: most values in one chunk's rANS unit (a native decoder sizes its cache by it)
    tracks: Tracks | None = None  # format 6, flags bit 10: the translation tracks' header (and q at the encoder)
    static_root: StaticRoot | None = None  # format 6, flags bit 12: the still root joint 0 the skeleton lacks
    scales: Tracks | None = None  # format 6, flags bit 13: the scale tracks' header (and q at the encoder)
    prior_mean: np.ndarray | None = None  # format 6, flags bit 15: the named rig's mean signal (:mod:`.prior`)
    prior_data: bytes | None = None  # format 6, flags bit 15: the prior's bytes (the native runtime reads the rig there)
    _cache: dict = field(default_factory=dict, repr=False)

    def replace(self, **changes) -> "StreamInfo":
        """A copy with ``changes`` (and an empty cache: the classes may have changed)."""
        return dataclasses.replace(self, _cache={}, **changes)

    @property
    def axes(self) -> np.ndarray:
        """(J, 3, 3) each joint's principal axes."""
        if "axes" not in self._cache:
            self._cache["axes"] = axes_from_codes(self.axis_codes)
        return self._cache["axes"]

    @property
    def turned_axes(self) -> np.ndarray:
        """(T, 3, 3) the principal axes of the :attr:`turned` joints (:attr:`axes` of those rows, computed alone)."""
        if "turned axes" not in self._cache:
            self._cache["turned axes"] = axes_from_codes(self.axis_codes[self.turned])
        return self._cache["turned axes"]

    @property
    def turned(self) -> np.ndarray:
        """Indices of the joints whose channels are on principal axes (the others' axes are the identity)."""
        if "turned" not in self._cache:
            self._cache["turned"] = np.flatnonzero(np.any(self.axis_codes != 0, axis=1))
        return self._cache["turned"]

    @property
    def channels(self) -> int:
        return 3 + 3 * self.skeleton.num_joints

    @property
    def channel_steps(self) -> np.ndarray:
        """(C,) relative base step of each channel: root translation cm, then 3 per joint rotation, rad."""
        return np.concatenate([np.full(3, self.budgets.root_cm), np.repeat(self.budgets.base_rad, 3)])

    @property
    def correction_steps(self) -> np.ndarray:
        """(J + 1,) step of the corrections: root translation cm, then each joint's rotation, rad (cube of side s
        fits in the ball of radius s sqrt(3) / 2 = the budget; cached)."""
        if "correction steps" not in self._cache:
            steps = np.concatenate([[self.budgets.root_cm], self.budgets.rotation_rad]) * (2.0 / _SQRT3)
            steps.setflags(write=False)
            self._cache["correction steps"] = steps
        return self._cache["correction steps"]

    def class_matrix(self, length: int) -> np.ndarray:
        """(n - 1, C) classes of the AC coefficients of a segment of ``length`` frames (cached)."""
        key = ("classes", length)
        if key not in self._cache:
            bands = model.band_of(np.arange(1, length), length, self.settings.segment_frames)
            self._cache[key] = model.classes_of(
                np.arange(self.channels)[None, :], bands[:, None], self.scale, self.tilt
            ).reshape(length - 1, self.channels)
        return self._cache[key]

    def count_classes(self, num_segments: int) -> np.ndarray:
        return _tilted(self.scale, self.count_tilt, num_segments)


def _tilted(scale: np.ndarray, tilt: int, repeats: int) -> np.ndarray:
    """Classes ``clip(scale + tilt)`` of the side tables, repeated ``repeats`` times (segment-major)."""
    row = (np.clip(scale + tilt, 0, model.NUM_CLASSES - 1) + _SIDE).astype(np.uint8)
    return np.broadcast_to(row, (repeats, len(row))).ravel()


_TABLES: dict = {}


def runtime_tables() -> RansTables:
    """Format 6's tables (fixed by the format, whatever the stream's rounding): classes 0..63 the AC mixtures of
    rounding 0.45 (the codec's default), 64..127 those of nearest rounding, quantized to 2^-15 (cached)."""
    if "runtime" not in _TABLES:
        _TABLES["runtime"] = RansTables(quantize_counts(np.concatenate(
            [model.tables(RUNTIME_ROUNDING).counts, model.tables(0.5).counts])))
    return _TABLES["runtime"]


#: Rounding offset format 6's AC tables are built for (part of the format).
RUNTIME_ROUNDING = _f32(0.45)


def tables(rounding: float) -> ClassTables:
    """Classes 0..63: AC coefficients (dead-zone rounding); 64..127: everything else (nearest rounding)."""
    if rounding not in _TABLES:
        _TABLES[rounding] = ClassTables(np.concatenate([model.tables(rounding).counts, model.tables(0.5).counts]))
    return _TABLES[rounding]


def steps_of(info: StreamInfo, length: int) -> np.ndarray:
    """(n, C) quantization steps of a segment of ``length`` frames; row 0 is the step of the mean (DC)."""
    settings = info.settings
    base = settings.multiplier * info.channel_steps
    k = np.arange(length)[:, None]
    steps = base[None, :] * (1.0 + settings.slope * k / length)
    steps[0] = base * np.sqrt(length / settings.segment_frames)
    return steps


def significance(coefficients: np.ndarray) -> np.ndarray:
    """(C,) number of AC coefficients of each channel up to its last nonzero one, of a (n - 1, C) int array."""
    nonzero = coefficients != 0
    if len(coefficients) == 0:
        return np.zeros(coefficients.shape[1], dtype=np.int64)
    return np.where(nonzero.any(axis=0), len(coefficients) - np.argmax(nonzero[::-1], axis=0), 0)


def _significant_mask(counts: np.ndarray, length: int) -> np.ndarray:
    """(C, n - 1) mask of the coded coefficients, channel-major."""
    return np.arange(length - 1)[None, :] < counts[:, None]


def _steps_by_channel(info: StreamInfo, length: int) -> np.ndarray:
    """(C, n) :func:`steps_of` channel-major, cached per segment length."""
    key = ("steps", length)
    if key not in info._cache:  # steps_of(info, length).T, element for element, without its transposed copy
        settings = info.settings
        if "base steps" not in info._cache:
            info._cache["base steps"] = settings.multiplier * info.channel_steps
        base = info._cache["base steps"]
        steps = base[:, None] * (1.0 + settings.slope * np.arange(length) / length)
        steps[:, 0] = base * np.sqrt(length / settings.segment_frames)
        info._cache[key] = steps
    return info._cache[key]


def segment_signal(info: StreamInfo, segments: np.ndarray, ac: np.ndarray, scratch: Scratch | None = None) -> np.ndarray:
    """The (C, n) base signal of consecutive ``segments``, channel-major, from their AC coefficients.

    ``ac`` (S, C, P), any real or integer dtype: the quantized AC coefficients of each segment, channel-major,
    zero-padded to ``P >= n_s - 1``; the segment means come from ``info.dc``. Dequantization and one inverse DCT
    per segment length (a batched call over the segments of that length). Encoder and decoder both go through here,
    so both see bit-identical signals. With ``scratch`` the signal is a scratch view (valid until its next use).
    """
    layout = info.layout
    lengths = layout.lengths[segments]
    offsets = layout.starts[segments] - layout.starts[segments[0]]
    channels = info.channels
    shape = (channels, int(lengths.sum()))
    signal = np.empty(shape) if scratch is None else scratch.take("signal", shape)
    for length in np.unique(lengths).tolist():
        pick = np.flatnonzero(lengths == length)
        every = len(pick) == len(segments)
        steps = _steps_by_channel(info, length)
        shape = (len(pick), channels, length)
        spectrum = np.empty(shape) if scratch is None else scratch.take("spectrum", shape)
        np.multiply(info.dc[segments[pick]], steps[:, 0], out=spectrum[:, :, 0])
        np.multiply(ac[:, :, : length - 1] if every else ac[pick, :, : length - 1], steps[:, 1:],
                    out=spectrum[:, :, 1:])
        spectrum = inverse(spectrum)
        first = int(offsets[pick[0]])
        if every or int(offsets[pick[-1]]) - first == (len(pick) - 1) * length:  # consecutive segments
            signal[:, first : first + len(pick) * length].reshape(channels, len(pick), length)[...] = (
                spectrum.transpose(1, 0, 2))
        else:
            for i, segment in enumerate(pick.tolist()):
                signal[:, offsets[segment] : offsets[segment] + length] = spectrum[i]
    return signal


def base_signal(info: StreamInfo, segments, coefficients: dict[int, np.ndarray]) -> np.ndarray:
    """Dequantize and inverse-transform consecutive segments (segment -> (n - 1, C) AC coefficients): (C, n)."""
    segments = np.asarray(segments, dtype=np.int64)
    lengths = info.layout.lengths[segments]
    ac = np.zeros((len(segments), info.channels, max(int(lengths.max()) - 1, 0)), dtype=np.int64)
    for i, segment in enumerate(segments.tolist()):
        ac[i, :, : lengths[i] - 1] = coefficients[segment].T
    return segment_signal(info, segments, ac)


def assemble(info: StreamInfo, segments, signal: np.ndarray, scratch: Scratch | None = None,
             skip: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Consecutive decoded segments (their (C, n) base signal) as roots (n, 3) cm and base quaternions (n, J, 4).

    ``signal`` is consumed: the rotation rows of the joints on principal axes are overwritten. With ``scratch`` the
    quaternions are a scratch view (valid until its next use). ``signal`` may hold only frames ``skip .. skip + n``
    of the segments (random access: a frame costs its own exponential maps, not its segment's); every step is
    elementwise over the frames, so those frames come out as they do from the whole segments.

    The quaternions are a view of a component-major (4, J, n) array (what forward kinematics reads fastest); the
    rotation vectors of the joints on principal axes are turned back off them (the others' axes are the identity),
    then mapped to quaternions component by component.
    """
    num_joints = info.skeleton.num_joints
    length = signal.shape[1]
    rotvec = signal[3:].reshape(num_joints, 3, length)  # [joint, component on its axes, frame]
    turned = info.turned
    if turned.size:
        axes = info.turned_axes  # (T, 3, 3)
        parts = rotvec[turned]  # (T, 3, n) copy
        for row in range(3):
            rotvec[turned, row] = (axes[:, row, 0, None] * parts[:, 0] + axes[:, row, 1, None] * parts[:, 1]
                                   + axes[:, row, 2, None] * parts[:, 2])
    x, y, z = rotvec[:, 0], rotvec[:, 1], rotvec[:, 2]
    quats = np.empty((4, num_joints, length)) if scratch is None else scratch.take("quats", (4, num_joints, length))
    angle = np.multiply(x, x, out=quats[0])
    angle += np.multiply(y, y, out=quats[1])
    angle += np.multiply(z, z, out=quats[1])
    np.sqrt(angle, out=angle)
    # sin and cos of theta / 2 from u = tan(theta / 4): sin = 2u / (1 + u^2), cos = 2 / (1 + u^2) - 1. numpy's
    # float64 tan is vectorized (SIMD) where its sin and cos are not: 6 times faster each, and the quaternions
    # agree with sin / cos to a few ulp (the encoder's closed loop runs this same function).
    u = np.multiply(angle, 0.25, out=quats[2])
    np.tan(u, out=u)
    ratio = np.multiply(u, u, out=quats[3])
    ratio += 1.0
    np.divide(2.0, ratio, out=ratio)  # 2 / (1 + u^2)
    scale = np.multiply(u, ratio, out=quats[2])  # sin(theta / 2)
    with np.errstate(divide="ignore", invalid="ignore"):
        scale /= angle
    small = angle < 1e-6  # sin(theta/2)/theta by its Taylor series near 0 (exact to float precision)
    if small.any():
        scale[small] = 0.5 - angle[small] * angle[small] / 48.0
    half = ratio
    half -= 1.0  # cos(theta / 2)
    np.multiply(x, scale, out=quats[0])
    np.multiply(y, scale, out=quats[1])
    np.multiply(z, scale, out=quats[2])
    quats = quats.transpose(2, 1, 0)  # (n, J, 4) view
    if info.overrides:
        first = int(info.layout.starts[segments[0]]) + skip
        for (segment, joint), reference in info.overrides.items():
            if segments[0] <= segment <= segments[-1]:
                start = int(info.layout.starts[segment]) - first
                frames = slice(max(start, 0), max(start + int(info.layout.lengths[segment]), 0))
                if frames.start < frames.stop:
                    quats[frames, joint] = quat.multiply(reference, quats[frames, joint])
    return np.ascontiguousarray(signal[:3].T), quats


def apply_corrections(info: StreamInfo, roots, quats, flat: np.ndarray, values: np.ndarray) -> None:
    """Add coded corrections in place: ``flat = frame * (J + 1) + slot`` (slot 0 root, 1 + j joint j), values (N, 3)."""
    if flat.size == 0:
        return
    slots = len(info.correction_steps)
    frames, slot = np.divmod(flat, slots)
    steps = info.correction_steps[slot][:, None]
    root = slot == 0
    roots[frames[root]] += values[root] * steps[root]
    joint = ~root
    quats[frames[joint], slot[joint] - 1] = quat.multiply(
        quats[frames[joint], slot[joint] - 1], quat.exp_map(values[joint] * steps[joint])
    )


# -- writing ---------------------------------------------------------------------------------------------------
def skeleton_step_exponent(eps_cm: float, skeleton: Skeleton) -> int:
    """Exponent ``e`` of the grid (2^e cm) the stream keeps the skeleton's offsets on: the coarsest power of two
    with ``3 sqrt(3) depth 2^e <= eps``.

    Rounding moves each offset by at most ``sqrt(3) / 2`` steps, so a joint ``depth`` bones down moves by at most
    ``sqrt(3) / 2 depth`` steps, and the encoder takes twice the actual change off the bound its budgets are
    computed for (:func:`~mocapbench.codecs.mcb_rot.budgets.offset_discrepancy_cm`): at most a third of eps, so
    it never refuses a skeleton for its grid (it does below half). The closed loop still checks the true error, and
    the rate search's step multiplier makes up most of the smaller budgets: on cmu_test (2D = 14 % of eps) this
    grid makes 24 fps streams 0.9 % (eps 0.05 cm) to 2.1 % (1 cm) smaller than one 16 times finer, 120 fps streams
    0.1-1.8 %: each halving of the grid saves a bit per offset coordinate (about 9 bytes on the CMU rig).
    """
    depth = np.zeros(skeleton.num_joints, dtype=np.int64)
    for joint in range(1, skeleton.num_joints):
        depth[joint] = depth[skeleton.parents[joint]] + 1
    exponent = int(np.floor(np.log2(eps_cm / (3.0 * np.sqrt(3.0) * max(int(depth.max()), 1)))))
    return int(np.clip(exponent, STEP_EXPONENTS[0], STEP_EXPONENTS[-1]))



def write_payload(info: StreamInfo, skeleton_blob: bytes, coefficients: dict, corrections) -> bytes:
    """The payload of ``info`` (whose ``dc`` is set), the AC coefficients (segment -> (n - 1, C) int) and the
    corrections (flat indices, values (N, 3)); the entropy classes are chosen here, on the whole stream."""
    settings, layout = info.settings, info.layout
    slots = len(info.correction_steps)
    flat, values = corrections
    channels = info.channels
    counts = {s: significance(c) for s, c in coefficients.items()}
    coded = {s: c.T[_significant_mask(counts[s], len(c) + 1)] for s, c in coefficients.items()}
    # Classes, chosen on the whole stream: AC by (channel, band), the rest by one tilt or one class each.
    bands, channel_of = [], []
    for segment in range(layout.num_segments):
        length = int(layout.lengths[segment])
        mask = _significant_mask(counts[segment], length)
        band = np.broadcast_to(model.band_of(np.arange(1, length), length, settings.segment_frames), mask.shape)
        bands.append(band[mask])
        channel_of.append(np.broadcast_to(np.arange(channels)[:, None], mask.shape)[mask])
    # (fitted on the tables the units code with: format 6's, whatever rounding the quantizer used)
    scale, tilt = model.fit_offsets(np.concatenate(list(coded.values())), np.concatenate(channel_of),
                                    np.concatenate(bands), channels, RUNTIME_ROUNDING)
    all_channels = np.tile(np.arange(channels), layout.num_segments)
    predicted = _first_means(info)
    dc_diff = np.diff(info.dc, axis=0, prepend=0 if predicted is None else predicted[None]).ravel()
    count_diff = np.diff(np.stack([counts[s] for s in range(layout.num_segments)]), axis=0, prepend=0).ravel()
    info = info.replace(
        scale=scale, tilt=tilt,
        dc_tilt=model.fit_tilt(dc_diff, all_channels, scale, 0.5),
        count_tilt=model.fit_tilt(count_diff, all_channels, scale, 0.5),
        gap_class=model.fit_single(np.diff(flat, prepend=-1) - 1, 0.5),
        value_class=model.fit_single(values.ravel(), 0.5),
    )
    chunks, unit_values = [], 0
    chunk_first_frame = layout.starts[layout.chunk_starts[:-1]]
    chunk_of_flat = np.searchsorted(chunk_first_frame * slots, flat, side="right") - 1
    for chunk in range(layout.num_chunks):
        segments = layout.chunk_segments(chunk)
        mine = chunk_of_flat == chunk
        gaps = np.diff(flat[mine] - chunk_first_frame[chunk] * slots, prepend=-1) - 1
        writer = ByteWriter()
        writer.write_varint(int(mine.sum()))
        unit_values = max(unit_values, sum(len(coded[s]) for s in segments) + 4 * int(mine.sum()))
        classes = [info.class_matrix(int(layout.lengths[s])).T[_significant_mask(counts[s], int(layout.lengths[s]))]
                   for s in segments]
        encode_unit(  # natural order: segment by segment, channel by channel, then the corrections
            writer,
            np.concatenate([coded[s] for s in segments] + [gaps, values[mine].ravel()]),
            np.concatenate(classes + [np.full(len(gaps), _SIDE + info.gap_class, np.uint8),
                                      np.full(3 * len(gaps), _SIDE + info.value_class, np.uint8)]),
            runtime_tables(),
        )
        if info.tracks is not None:  # the chunk's frames of every translation track, one unit (:mod:`.tracks`)
            first, length = int(chunk_first_frame[chunk]), int(layout.lengths[segments].sum())
            encode_unit(writer, info.tracks.chunk_values(first, first + length), info.tracks.unit_classes(length),
                        runtime_tables())
        if info.scales is not None:  # the chunk's frames of every scale track, one unit (:mod:`.scales`)
            first, length = int(chunk_first_frame[chunk]), int(layout.lengths[segments].sum())
            encode_unit(writer, info.scales.chunk_values(first, first + length), info.scales.unit_classes(length),
                        runtime_tables())
        chunks.append(writer.getvalue())

    writer = ByteWriter()
    settings.write(writer)
    writer.write_bytes(skeleton_blob)  # with the prior flag: the reference to its rig (:mod:`.prior`)
    if info.static_root is not None and not settings.prior:
        info.static_root.write(writer)
    write_cuts(writer, info.cuts)
    writer.write_varint(len(info.overrides))
    for (segment, joint), reference in sorted(info.overrides.items()):
        writer.write_varint(segment)
        writer.write_varint(joint)
        writer.write_array(quat.log_map(reference).astype(np.float32), np.float32)
    turned = np.any(info.axis_codes != 0, axis=1)
    writer.write_bytes(np.packbits(turned).tobytes())
    writer.write_array(info.axis_codes[turned], np.int16)
    write_small_ints(writer, scale)
    write_small_ints(writer, tilt[1:] + model.NUM_CLASSES)  # band 0 (the DC) has no AC coefficients
    writer.write_bytes(bytes([info.dc_tilt + model.NUM_CLASSES, info.count_tilt + model.NUM_CLASSES,
                              info.gap_class, info.value_class]))
    if info.tracks is not None:
        info.tracks.write(writer)
    if info.scales is not None:
        info.scales.write(writer)
    writer.write_varint(unit_values)
    if settings.prior:
        writer.write_u8(predicted is not None)
    side = layout.num_segments
    encode_unit(writer, np.concatenate([dc_diff, count_diff]),
                np.concatenate([_tilted(scale, info.dc_tilt, side), _tilted(scale, info.count_tilt, side)]),
                runtime_tables())
    writer.write_varints([len(chunk) for chunk in chunks])
    for chunk in chunks:
        writer.write_bytes(chunk)
    return writer.getvalue()


def _first_means(info: StreamInfo) -> np.ndarray | None:
    """(C,) the first segment's quantized means predicted from the prior's rig, or None (no prior, or too close
    to call: :func:`.prior.first_means`)."""
    if info.prior_mean is None:
        return None
    base = info.settings.multiplier * info.channel_steps
    return first_means(info.prior_mean, info.axes, base, info.settings.segment_frames)


_OFFSET_LIMIT = 2 * model.NUM_CLASSES  # channel scales and band tilts (+ 64) lie in [0, 128)


def write_small_ints(writer: ByteWriter, values: np.ndarray) -> None:
    """Small non-negative ints (N,), bit-packed: a bitmap of the nonzero ones, then (when any) u8 ``low``, u8
    ``width`` and ``value - low`` of each nonzero value in ``width`` bits (MSB first, byte-padded). Class offsets of
    one stream span a few octaves and many are 0: about 6 bits each instead of 8."""
    values = np.asarray(values, dtype=np.int64)
    nonzero = values[values != 0]
    writer.write_bytes(np.packbits(values != 0).tobytes())
    if nonzero.size == 0:
        return
    low = int(nonzero.min())
    width = int(nonzero.max() - low).bit_length()
    writer.write_bytes(bytes([low, width]))
    if width:
        bits = ((nonzero - low)[:, None] >> np.arange(width - 1, -1, -1)) & 1
        writer.write_bytes(np.packbits(bits.astype(np.uint8)).tobytes())


def read_small_ints(reader: ByteReader, count: int, limit: int, what: str) -> np.ndarray:
    """Inverse of :func:`write_small_ints`: ``count`` values (int64), each checked to be below ``limit``."""
    present = np.unpackbits(np.frombuffer(reader.read_bytes((count + 7) // 8, what), np.uint8), count=count)
    values = np.zeros(count, dtype=np.int64)
    nonzero = int(present.sum())
    if nonzero == 0:
        return values
    low, width = reader.read_bytes(2, what)
    if not 1 <= low < limit or width > 8:
        raise BitstreamError(f"mcb-rot: {what}: expected values below {limit}, found a low of {low}, width {width}.")
    if width:
        bits = np.unpackbits(np.frombuffer(reader.read_bytes((nonzero * width + 7) // 8, what), np.uint8),
                             count=nonzero * width).reshape(nonzero, width).astype(np.int64)
        values[present.astype(bool)] = low + bits @ (1 << np.arange(width - 1, -1, -1))
    else:
        values[present.astype(bool)] = low
    if values.max() >= limit:
        raise BitstreamError(f"mcb-rot: {what}: expected values below {limit}, found {int(values.max())}.")
    return values


# -- reading ---------------------------------------------------------------------------------------------------
def read_info(header: Header, payload: memoryview, prior: Prior | None = None) -> StreamInfo:
    """Parse and check everything before the chunks (``prior``: the one a stream with flag bit 15 names)."""
    reader = ByteReader(payload)
    version = reader.read_u8("mcb-rot format")
    if version not in _READABLE:
        raise BitstreamError(f"mcb-rot: expected payload format {' or '.join(map(str, _READABLE))}, found {version}.")
    settings = Settings.read(reader, version)
    if settings.prior:
        skeleton, static_root, prior_mean = read_reference(reader, prior)
        if (static_root is not None) != settings.static_root:
            raise BitstreamError("mcb-rot: the prior's rig and the stream's still-root flag disagree.")
    else:
        skeleton = (unpack_skeleton_runtime(reader) if version >= 6
                    else unpack_skeleton_compact(reader, stepped=version >= 4))
        static_root = read_static_root(reader) if settings.static_root else None
        prior_mean = None
    num_frames, num_joints = header.num_frames, skeleton.num_joints
    if num_joints + (static_root is not None) != header.num_joints:
        raise BitstreamError(f"mcb-rot: the skeleton has {num_joints} joints"
                             f"{' and a static root' if static_root is not None else ''}, the header says "
                             f"{header.num_joints}.")
    cuts = read_cuts(reader, num_frames, "mcb-rot")
    layout = SegmentLayout(num_frames, segment_starts(num_frames, cuts, settings.segment_frames), settings.chunk_frames)
    num_segments = layout.num_segments
    num_overrides = reader.read_varint("re-reference count")
    if num_overrides > num_segments * num_joints:
        raise BitstreamError(f"mcb-rot: expected at most {num_segments * num_joints} re-references, "
                             f"found {num_overrides}.")
    overrides = {}
    for _ in range(num_overrides):
        segment = reader.read_varint("re-referenced segment")
        joint = reader.read_varint("re-referenced joint")
        rotvec = reader.read_array(3, np.float32, "reference").astype(np.float64)
        if segment >= num_segments or joint >= num_joints or not np.all(np.abs(rotvec) <= 2 * np.pi):
            raise BitstreamError("mcb-rot: a re-reference names a segment or joint outside the motion.")
        overrides[(segment, joint)] = quat.exp_map(rotvec)
    turned = np.unpackbits(np.frombuffer(reader.read_bytes((num_joints + 7) // 8, "axis flags"), np.uint8))
    turned = turned[:num_joints].astype(bool)
    axis_codes = np.zeros((num_joints, 3), dtype=np.int64)
    axis_codes[turned] = reader.read_array(3 * int(turned.sum()), np.int16, "joint axes").reshape(-1, 3)
    channels = 3 + 3 * num_joints
    if version >= 4:
        scale = read_small_ints(reader, channels, _OFFSET_LIMIT, "channel classes")
        tilt = np.concatenate([[0], read_small_ints(reader, model.NUM_BANDS - 1, _OFFSET_LIMIT, "band classes")])
    else:
        scale = reader.read_array(channels, np.uint8, "channel classes").astype(np.int64)
        tilt = reader.read_array(model.NUM_BANDS, np.uint8, "band classes").astype(np.int64)
    tilt = tilt - model.NUM_CLASSES
    dc_tilt, count_tilt, gap_class, value_class = reader.read_bytes(4, "classes")
    dc_tilt, count_tilt = dc_tilt - model.NUM_CLASSES, count_tilt - model.NUM_CLASSES
    if max(dc_tilt, count_tilt, gap_class, value_class) >= model.NUM_CLASSES:
        raise BitstreamError(f"mcb-rot: classes must be < {model.NUM_CLASSES}.")
    coder_tables = tables(settings.rounding)
    track_header = read_tracks(reader, num_joints) if settings.tracks else None
    scale_header = read_tracks(reader, num_joints, KIND_SCALE) if settings.scales else None
    counts, unit_values = None, 0
    if version >= 6:
        unit_values = reader.read_varint("largest unit")
        most = max(int(layout.lengths.max()), settings.chunk_frames) * (channels + 4 * (num_joints + 1))
        if unit_values > most:
            raise BitstreamError(f"mcb-rot: expected at most {most} values in a chunk, the header says {unit_values}.")
    if version >= 4:  # the segment means and the significance counts, one stream
        side_classes = np.concatenate([_tilted(scale, dc_tilt, num_segments), _tilted(scale, count_tilt, num_segments)])
        what = "mcb-rot: segment means and significance counts"
        predicted = None
        if settings.prior:
            flag = reader.read_u8("first means predicted")
            if flag > 1:
                raise BitstreamError(f"mcb-rot: the first-means flag must be 0 or 1, found {flag}.")
            if flag:
                budgets = stream_budgets(settings, skeleton, track_header, scale_header)
                base = settings.multiplier * np.concatenate([np.full(3, budgets.root_cm), np.repeat(budgets.base_rad, 3)])
                predicted = first_means(prior_mean, axes_from_codes(axis_codes), base, settings.segment_frames)
                if predicted is None:
                    raise BitstreamError("mcb-rot: the stream predicts its first segment's means where a rounding is "
                                         "too close to call.")
        side = (decode_unit(reader, side_classes, runtime_tables(), what) if version >= 6
                else decode_classed(reader, side_classes, coder_tables, what))
        dc = side[: num_segments * channels].reshape(num_segments, channels)
        if predicted is not None:
            dc = dc.copy()
            dc[0] += predicted
        dc = np.cumsum(dc, axis=0)
        counts = np.cumsum(side[num_segments * channels :].reshape(num_segments, channels), axis=0)
        bad = (counts < 0) | (counts > (layout.lengths - 1)[:, None])
        if bad.any():
            raise BitstreamError(f"mcb-rot: segment {int(np.argmax(bad.any(axis=1)))}: significance counts outside "
                                 "the segment.")
    else:
        dc_diff = decode_classed(reader, _tilted(scale, dc_tilt, num_segments), coder_tables, "mcb-rot: segment means")
        dc = np.cumsum(dc_diff.reshape(num_segments, channels), axis=0)
    if layout.num_chunks <= 16:  # one varint at a time: cheaper than the vectorized read for a few
        sizes = np.array([reader.read_varint("chunk size") for _ in range(layout.num_chunks)], dtype=np.int64)
    else:
        sizes = reader.read_varints(layout.num_chunks, "chunk sizes").astype(np.int64)
    offsets = reader.offset + np.concatenate([[0], np.cumsum(sizes)])
    if offsets[-1] != len(payload):
        raise BitstreamError(f"mcb-rot: the chunks end at byte {offsets[-1]}, the payload has {len(payload)}.")
    if settings.scales and (settings.shell_cm > 0 or static_root is not None):
        raise BitstreamError("mcb-rot: scale tracks with a shell distance or a still root kept apart (the encoder "
                             "writes neither).")
    budgets = stream_budgets(settings, skeleton, track_header, scale_header)
    return StreamInfo(settings, skeleton, budgets, layout, cuts, overrides, axis_codes, scale, tilt, dc_tilt,
                      count_tilt, gap_class, value_class, dc, offsets, counts, version, unit_values, track_header,
                      static_root, scale_header, prior_mean, prior.data if settings.prior else None)


def end_site_reach(skeleton: Skeleton) -> np.ndarray:
    """(J,) cm each joint's longest end-site offset (0 where it has none)."""
    reach = np.zeros(skeleton.num_joints)
    if len(skeleton.end_site_parents):
        np.maximum.at(reach, skeleton.end_site_parents, np.sqrt(np.sum(skeleton.end_site_offsets**2, axis=1)))
    return reach


def stream_budgets(settings: Settings, skeleton: Skeleton, tracks: Tracks | None, scales: Tracks | None = None) -> Budgets:
    """The budgets of a stream (encoder and decoder alike): its settings' bound and shares, with the end sites as
    virtual children when the stream covers them, each translated joint's reach as its bone, and with scale tracks
    every length stretched by the most the scales above it stretch it (:func:`.scales.stretched_lengths`)."""
    ends = end_site_reach(skeleton) if settings.ends else None
    bones = None if tracks is None else tracks.bones_cm(skeleton)
    if scales is not None:
        bones = np.sqrt(np.sum(skeleton.offsets**2, axis=1)) if bones is None else bones
        bones, ends = stretched_lengths(skeleton, bones, ends, scales)
    return joint_budgets(skeleton, settings.bound_cm, settings.root_share, settings.free_angle_rad,
                         settings.allocation_power, settings.shell_cm, ends_cm=ends, bones_cm=bones)


def stretch_of(skeleton: Skeleton, scales: Tracks | None) -> tuple[np.ndarray, np.ndarray] | None:
    """(frame factors, peaks) (J,) each of a stream's scale tracks (:mod:`.scales`), or None without them."""
    if scales is None:
        return None
    peaks = np.ones(skeleton.num_joints)
    peaks[scales.joints] = scales.reach
    return frame_factors(skeleton, scales), peaks
