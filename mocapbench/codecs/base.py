"""The one codec interface: ``fit`` (optional), ``encode(motion) -> bytes``, ``decode(bytes) -> Decoded``.

A codec writes only its payload; :meth:`Codec.encode` wraps it in the self-describing container
(:mod:`mocapbench.codecs.container`) and :meth:`Codec.decode` checks the container before the payload is read.
The rate of a codec is ``len(encode(motion))``. Learned state shared across clips is reported by
:attr:`Codec.model_bytes`, never hidden.

Configs are frozen dataclasses derived from :class:`CodecConfig`; declare fields with :func:`param` so that
range, unit and meaning live beside the default and are checked on construction::

    @dataclass(frozen=True)
    class Config(CodecConfig):
        step_cm: float = param(0.5, low=1e-6, high=100.0, unit="cm", doc="quantization step")
"""

from __future__ import annotations

import abc
import dataclasses
import hashlib
import json
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from mocapbench.codecs import container
from mocapbench.codecs.container import BitstreamError, Header
from mocapbench.codecs.limits import DecodeLimits, using_limits
from mocapbench.motion import Motion

__all__ = [
    "Codec", "CodecConfig", "Decoded", "param", "BitstreamError", "Header", "NotFittedError", "single_threaded_blas",
]


class NotFittedError(RuntimeError):
    """A codec that needs training state was used before :meth:`Codec.fit`."""


def single_threaded_blas():
    """A context in which BLAS runs one thread: a fit inside gives the same model whatever the machine's threads.

    BLAS splits a product or a decomposition into blocks by its thread count, and the order of the sums changes
    with them: an SVD of the same data then differs in the last bits at 1 and 2 threads, and a model rounded to
    float32 (or a model tag, a CRC of its bytes) differs with it. Fitting with one thread makes the model a
    function of the clips alone. Encoding and decoding are unaffected (they check their own streams).
    """
    from threadpoolctl import threadpool_limits

    return threadpool_limits(limits=1, user_api="blas")


def param(
    default: Any,
    *,
    low: float | None = None,
    high: float | None = None,
    choices: Sequence[Any] | None = None,
    unit: str = "",
    doc: str = "",
) -> Any:
    """A config field with its allowed range (inclusive) or choices, unit and meaning."""
    metadata = {"low": low, "high": high, "choices": tuple(choices) if choices else None, "unit": unit, "doc": doc}
    return dataclasses.field(default=default, metadata=metadata)


@dataclass(frozen=True)
class CodecConfig:
    """Base of every codec's frozen config: validates types and ranges of :func:`param` fields."""

    def __post_init__(self) -> None:
        owner = type(self).__qualname__.split(".")[0]
        for field in dataclasses.fields(self):
            value = getattr(self, field.name)
            meta = field.metadata
            kind = type(field.default) if field.default is not dataclasses.MISSING else None
            if kind is float and isinstance(value, int) and not isinstance(value, bool):
                value = float(value)
                object.__setattr__(self, field.name, value)
            if kind is tuple and isinstance(value, list):
                value = tuple(value)
                object.__setattr__(self, field.name, value)
            if kind is not None and not isinstance(value, kind) or isinstance(value, bool) and kind is not bool:
                raise ValueError(
                    f"{owner}.{field.name} must be of type {kind.__name__}, got {value!r} ({type(value).__name__})."
                )
            unit = f" {meta.get('unit')}" if meta.get("unit") else ""
            if meta.get("choices") is not None and value not in meta["choices"]:
                raise ValueError(f"{owner}.{field.name} must be one of {list(meta['choices'])}, got {value!r}.")
            low, high = meta.get("low"), meta.get("high")
            if isinstance(value, (int, float)) and not isinstance(value, bool):
                if not np.isfinite(value):
                    raise ValueError(f"{owner}.{field.name} must be finite, got {value!r}.")
                if (low is not None and value < low) or (high is not None and value > high):
                    lo = "-inf" if low is None else low
                    hi = "inf" if high is None else high
                    raise ValueError(f"{owner}.{field.name} must be in [{lo}, {hi}]{unit}, got {value!r}.")

    def as_dict(self) -> dict[str, Any]:
        """Field values, for the results row."""
        return dataclasses.asdict(self)

    def config_hash(self) -> str:
        """Short stable hash of the field values (ACL's ``get_hash``), for grouping results."""
        text = json.dumps(self.as_dict(), sort_keys=True, default=str)
        return hashlib.sha1(text.encode()).hexdigest()[:12]

    @classmethod
    def describe_fields(cls) -> str:
        """One line per field: name, type, default, range or choices, unit, meaning.

        ``eps_cm (float, default 1.0, in [0.001, 100] cm): ...``; a boolean says ``true or false``, a bound that is
        not set is left out (``>= 1``), a field without either says nothing about its range.
        """
        lines = []
        for field in dataclasses.fields(cls):
            meta = field.metadata
            kind = type(field.default).__name__ if field.default is not dataclasses.MISSING else "value"
            low, high = meta.get("low"), meta.get("high")
            if meta.get("choices") is not None:
                allowed = f", one of {list(meta['choices'])}"
            elif isinstance(field.default, bool):
                allowed = ", true or false"
            elif low is not None and high is not None:
                allowed = f", in [{low:g}, {high:g}]"
            elif low is not None or high is not None:
                allowed = f", >= {low:g}" if low is not None else f", <= {high:g}"
            else:
                allowed = ""
            unit = f" {meta['unit']}" if meta.get("unit") and allowed else (f", {meta['unit']}" if meta.get("unit") else "")
            lines.append(f"{field.name} ({kind}, default {field.default!r}{allowed}{unit}): {meta.get('doc', '')}")
        return "\n".join(lines)


@dataclass(frozen=True, eq=False)
class Decoded:
    """What a decoder returns.

    Attributes
    ----------
    positions : ndarray, shape (F, J, 3), float, cm
        Decoded joint positions (always present).
    motion : Motion or None
        The full decoded motion (rotations) when the codec codes rotations, so it can be written as BVH.
    header : Header
        The container fields of the stream.
    """

    positions: np.ndarray
    motion: Motion | None
    header: Header

    def __repr__(self) -> str:
        """One line: ``Decoded('mcb-linf', 141 frames x 31 joints, positions only, 756 bytes)``; no arrays."""
        header = self.header
        what = "positions and rotations" if self.motion is not None else "positions only"
        size = header.header_bytes + header.payload_bytes
        return f"Decoded({header.codec!r}, {header.num_frames} frames x {header.num_joints} joints, {what}, {size} bytes)"


def _longest_chain_cm(skeleton, translations=None, scales=None) -> float:
    """Largest sum of bone lengths from the root to any joint (end sites included), cm: the offsets', or with a
    translation track (F, J, 3) each joint's longest translation, each times the largest scale above it."""
    if translations is None:
        lengths = np.linalg.norm(skeleton.offsets, axis=1)
    else:
        lengths = np.linalg.norm(translations, axis=2).max(axis=0)
    lengths[0] = 0.0
    stretch = np.ones(skeleton.num_joints)  # largest scale factor of each joint's frame (its own and above)
    if scales is not None:
        stretch = np.abs(scales).max(axis=(0, 2))
        for joint in range(1, skeleton.num_joints):
            stretch[joint] *= stretch[skeleton.parents[joint]]
    reach = lengths.copy()
    for joint in range(1, skeleton.num_joints):  # parents come before children
        reach[joint] = lengths[joint] * stretch[skeleton.parents[joint]] + reach[skeleton.parents[joint]]
    ends = reach[skeleton.end_site_parents] + (
        np.linalg.norm(skeleton.end_site_offsets, axis=1) * stretch[skeleton.end_site_parents]
    )
    return float(max(reach.max(), ends.max(initial=0.0)))


class TrackRefusal(ValueError):
    """A rotation codec cannot carry a game rig's translation or scale track: the message names the joint.

    A refusal, not a failure: the motion is valid and other codecs code it (the benchmark records it as the codec's
    one-line reason on that dataset)."""


class Codec(abc.ABC):
    """Base class of every codec. Subclasses set ``name`` and ``Config`` and implement the payload methods.

    Subclasses implement :meth:`encode_payload` (motion → payload bytes) and :meth:`decode_payload`
    (header + payload → ``(positions, motion_or_None)``); this class adds the container, the checks and the
    conversion of every low-level failure on corrupt input into :class:`BitstreamError`.
    """

    name: ClassVar[str]
    Config: ClassVar[type[CodecConfig]]
    codes_rotations: ClassVar[bool] = False
    # What a user choosing a codec needs to know beside rate and error (the report's headline columns):
    # - family: "paper" (a published method), "generic" (what a user would do with off-the-shelf tools),
    #   "production" (a shipped engine codec such as ACL) or "mocapbench" (this project's own);
    # - needs_model: decoding needs learned state fit for the skeleton (see ``model_bytes``);
    # - random_access: a frame range can be decoded without decoding the whole stream.
    family: ClassVar[str] = "paper"
    needs_model: ClassVar[bool] = False
    random_access: ClassVar[bool] = False
    # A fast configuration and the L-inf bound (cm) it must meet on the synthetic fixture
    # (tests/codecs/test_registry.py runs every registered codec with them).
    smoke_params: ClassVar[dict[str, Any]] = {}
    smoke_max_error_cm: ClassVar[float] = 1.0
    # The numeric range of the codec's format: every joint of a motion it encodes lies within this distance of
    # the origin, cm (default 1e6 cm = 10 km; codecs whose format is coarser set less and say why). Beyond it a
    # codec would overflow or lose its precision silently, so :meth:`encode` refuses the motion in one line.
    max_coordinate_cm: ClassVar[float] = 1e6
    # Fewest joints the codec can code (a codec that models a pose below the root needs 2).
    min_joints: ClassVar[int] = 1
    # The per-joint tracks of a game rig a rotation codec carries besides local rotations and the root translation:
    # "translations" (a joint that moves relative to its parent) and "scales". A rotation codec refuses a motion with
    # a track it does not carry, in one line naming the joint, never dropping it; a codec that codes joint positions
    # codes what the tracks do to them and needs none.
    carries_tracks: ClassVar[tuple[str, ...]] = ()

    def __init__(self, config: CodecConfig | None = None) -> None:
        if config is None:
            config = self.Config()
        if not isinstance(config, self.Config):
            raise TypeError(f"{self.name}: expected a {self.Config.__qualname__}, got {type(config).__name__}.")
        self.config = config
        # Extra columns for the results row from the last encode (e.g. the paper's own ratio, a training time).
        self.last_encode_stats: dict[str, Any] = {}

    # -- learned state ---------------------------------------------------------------------------------
    def fit(self, motions: Sequence[Motion]) -> "Codec":
        """Learn shared state from training motions. Default: nothing to learn."""
        return self

    @property
    def model_bytes(self) -> int:
        """Bytes of learned state shared across clips that a decoder needs beside the stream (0 if none)."""
        return 0

    @property
    def latency_frames(self) -> int:
        """Frames of look-ahead the encoder needs before it can emit a frame (0: frame by frame).

        Default: the whole clip (-1 stands for "the whole clip"); clip and frame codecs override it.
        """
        return -1

    # -- coding ----------------------------------------------------------------------------------------
    def encode(self, motion: Motion) -> bytes:
        """Encode ``motion`` into a self-describing bitstream; ``len()`` of the result is the rate."""
        if not isinstance(motion, Motion):
            raise TypeError(f"{self.name}: encode expects a Motion, got {type(motion).__name__}.")
        self.last_encode_stats = {}
        self.check_motion_fits(motion)
        return self.pack_stream(motion, self.encode_payload(motion))

    def pack_stream(self, motion: Motion, payload: bytes) -> bytes:
        """The self-describing stream of ``payload`` (the container header of ``motion``'s facts around it)."""
        return container.pack(
            self.name,
            motion.num_frames,
            motion.num_joints,
            motion.fps,
            payload,
            source_unit_cm=motion.source_unit_cm,
            up_axis=motion.up_axis,
        )

    #: True when :meth:`encode_many` does work shared by its clips (the neural Fourier codecs train the clips'
    #: networks side by side), so that a caller holding several clips should hand them over together.
    encodes_many: ClassVar[bool] = False

    def encode_many(self, motions: Sequence[Motion]) -> list[tuple[bytes | Exception, dict[str, Any]]]:
        """Encode several motions; per motion its stream (or the error that refused it) and its encode stats.

        Default: :meth:`encode` one motion at a time. A codec with ``encodes_many`` overrides it; its streams are
        the ones :meth:`encode` writes for each motion alone (up to the order of floating-point sums). One motion's
        error never stops the others.
        """
        out: list[tuple[bytes | Exception, dict[str, Any]]] = []
        for motion in motions:
            try:
                out.append((self.encode(motion), dict(self.last_encode_stats)))
            except Exception as error:  # noqa: BLE001 - handed back per motion, as encode would raise it
                out.append((error, {}))
        return out

    def check_motion_fits(self, motion: Motion) -> None:
        """Refuse, in one ``ValueError`` line, a motion outside the codec's range or with too few joints.

        The reach of a motion is bounded without forward kinematics: the largest root coordinate plus the longest
        chain of bone offsets from the root (no joint can be farther from the origin).
        """
        if motion.num_joints < self.min_joints:
            raise ValueError(
                f"{self.name}: needs a skeleton of at least {self.min_joints} joints, the motion {motion.name!r} has "
                f"{motion.num_joints}."
            )
        self.check_tracks(motion)
        reach = float(np.abs(motion.root_positions).max()) + _longest_chain_cm(
            motion.skeleton, motion.translations, motion.scales
        )
        if not reach <= self.max_coordinate_cm:
            raise ValueError(
                f"{self.name}: the motion {motion.name!r} reaches {reach:.3g} cm from the origin; this codec's "
                f"numeric range is ±{self.max_coordinate_cm:g} cm (re-centre the motion, check its length unit, or "
                "pick another codec)."
            )

    def check_tracks(self, motion: Motion) -> None:
        """Refuse, in one :class:`TrackRefusal` line naming the joint, a rotation codec's motion with a translation or
        scale track the codec does not carry (:attr:`carries_tracks`)."""
        if not self.codes_rotations:
            return
        names = motion.skeleton.names
        if motion.translations is not None and "translations" not in self.carries_tracks:
            joint = int(motion.moving_joints()[0])
            raise TrackRefusal(
                f"{self.name}: joint {names[joint]!r} moves relative to its parent "
                f"(a translation track, as a game rig's pelvis); {self.name} codes rotations on fixed bones and "
                "cannot carry it (acl, mcb-rot and quant-rot-zstd can, as can every codec of joint positions)."
            )
        if motion.scales is not None and "scales" not in self.carries_tracks:
            joint = int(motion.scaled_joints()[0])
            raise TrackRefusal(
                f"{self.name}: joint {names[joint]!r} is scaled (a scale track); "
                f"{self.name} codes rotations of unscaled bones and cannot carry it (acl and quant-rot-zstd can, as "
                "can every codec of joint positions)."
            )

    def decode(self, data: bytes, *, limits: DecodeLimits | None = None) -> Decoded:
        """Decode a stream written by this codec from its bytes alone.

        Parameters
        ----------
        data : bytes
            The whole stream.
        limits : DecodeLimits, optional, keyword-only
            Bounds on frames, joints, decoded bytes and CPU work (default: the current limits,
            :data:`~mocapbench.codecs.limits.DEFAULT_LIMITS` unless a caller set others with
            :func:`~mocapbench.codecs.limits.using_limits`). Checked before anything F- or J-sized is allocated.

        Raises
        ------
        BitstreamError
            If the stream is malformed, truncated, corrupted or written by another codec;
            :class:`~mocapbench.codecs.limits.DecodeLimitError` (a subclass) if it asks for more than ``limits``.
        """
        header, payload = container.unpack(data, self.name)
        with using_limits(limits) as active:
            active.check_header(header.num_frames, header.num_joints, self.codes_rotations)
            return self._decode_checked(header, payload)

    def _decode_checked(self, header: Header, payload: memoryview) -> Decoded:
        try:
            # A hostile payload may overflow or hold NaN: numpy's warnings would print lines that say nothing to
            # the user, and the non-finite result is refused below with one BitstreamError.
            with np.errstate(all="ignore"):
                positions, motion = self.decode_payload(header, payload)
        except BitstreamError:
            raise
        except (ValueError, IndexError, KeyError, OverflowError, EOFError, TypeError) as error:
            # The CRC passed, so this is a stream that is well-formed outside but inconsistent inside.
            raise BitstreamError(f"{self.name}: payload is inconsistent with its header: {error}") from error
        positions = np.asarray(positions, dtype=np.float64)
        expected = (header.num_frames, header.num_joints, 3)
        if positions.shape != expected:
            raise BitstreamError(f"{self.name}: decoded positions have shape {positions.shape}, expected {expected}.")
        if not np.all(np.isfinite(positions)):
            raise BitstreamError(f"{self.name}: decoded positions hold non-finite values.")
        return Decoded(positions=positions, motion=motion, header=header)

    def decode_frames(self, data: bytes, start: int, stop: int, *, limits: DecodeLimits | None = None) -> Decoded:
        """Frames ``start:stop`` of a stream: positions (``stop - start``, J, 3) cm and, for a rotation codec, the
        motion of those frames (the header still describes the whole stream).

        The default decodes the whole clip and keeps the frames asked for, so it costs a whole :meth:`decode`;
        a codec with ``random_access`` overrides it to decode only what holds those frames. ``limits`` as in
        :meth:`decode`.

        Raises
        ------
        ValueError
            If ``start:stop`` is empty or outside the stream's frames.
        BitstreamError
            If the stream is corrupt.
        """
        self._unpack_frame_range(data, start, stop)
        decoded = self.decode(data, limits=limits)
        motion = decoded.motion.slice(start, stop) if decoded.motion is not None else None
        return Decoded(positions=decoded.positions[start:stop].copy(), motion=motion, header=decoded.header)

    def _unpack_frame_range(self, data: bytes, start: int, stop: int) -> tuple[Header, memoryview]:
        """The container of a random-access stream and a check that ``start:stop`` is a non-empty frame range in it.

        Every ``decode_frames(data, start, stop)`` starts here.

        Raises
        ------
        ValueError
            If ``start:stop`` is empty or outside the stream's frames.
        BitstreamError
            If the container is corrupt.
        """
        header, payload = container.unpack(data, self.name)
        if not 0 <= start < stop <= header.num_frames:
            raise ValueError(f"{self.name}: frame range {start}:{stop} is outside 0:{header.num_frames} or empty.")
        return header, payload

    @abc.abstractmethod
    def encode_payload(self, motion: Motion) -> bytes:
        """The codec's payload for ``motion`` (the container header is added by :meth:`encode`)."""

    @abc.abstractmethod
    def decode_payload(self, header: Header, payload: memoryview) -> tuple[np.ndarray, Motion | None]:
        """Positions ``(F, J, 3)`` cm and, for rotation codecs, the decoded motion."""

    def describe_payload(self, header: Header, payload: memoryview) -> dict[str, Any]:
        """Human-readable facts about a payload for ``mocapbench inspect`` (default: none)."""
        return {}

    def describe(self, data: bytes, *, limits: DecodeLimits | None = None) -> tuple[Header, dict[str, Any]]:
        """The header and :meth:`describe_payload`'s facts of a stream, checked as :meth:`decode` checks it.

        The header is checked against ``limits`` (default: the current ones) before the payload is looked at, so
        that ``inspect`` refuses what ``decompress`` refuses instead of building what the header asks for.

        Raises
        ------
        BitstreamError
            As :meth:`decode`: a malformed stream, or one that asks for more than ``limits``.
        """
        header, payload = container.unpack(data, self.name)
        with using_limits(limits) as active:
            active.check_header(header.num_frames, header.num_joints, self.codes_rotations)
            try:
                with np.errstate(all="ignore"):
                    return header, self.describe_payload(header, payload)
            except BitstreamError:
                raise
            except (ValueError, IndexError, KeyError, OverflowError, EOFError, TypeError) as error:
                raise BitstreamError(f"{self.name}: payload is inconsistent with its header: {error}") from error

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.config!r})"

