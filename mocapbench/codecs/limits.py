"""Decode limits: what one stream may make a decoder allocate or compute, checked before the work is done.

A stream is 28 bytes of header plus a payload, and its header says how many frames and joints it decodes to.
Without limits a stream of a few kB can ask for gigabytes (a header F of 1e7) or minutes of CPU (an IK
solver asked for thousands of iterations per frame). :class:`DecodeLimits` bounds every decode:

* ``max_frames``, ``max_joints``: F and J from the header;
* ``max_output_bytes``: the decoded arrays (float64 positions, ``F·J·3·8`` bytes, plus for rotation codecs the
  quaternions and root positions, ``F·(J·4 + 3)·8`` bytes); every other array a decoder builds is a bounded
  multiple of these;
* ``max_ik_iterations``: CPU work of decoders that solve (``pga-ik``: F × Levenberg–Marquardt iterations).

:meth:`mocapbench.codecs.Codec.decode` checks the first three against the header before the payload is read,
and makes the limits current (:func:`current_limits`) so that a decoder can check its own work and its inner
sizes (a zstd frame, a coefficient count) against them before allocating. Exceeding a limit raises
:class:`DecodeLimitError`, a :class:`~mocapbench.entropy.errors.BitstreamError` that names the limit, the
value asked for and the value allowed.

Every decoder also checks its payload against the header before any F- or J-sized allocation (a payload
that cannot hold F frames is refused while it is still a few bytes); :func:`check_payload_holds` is the helper.
"""

from __future__ import annotations

import contextlib
import contextvars
import dataclasses
from collections.abc import Iterator
from dataclasses import dataclass

from mocapbench.entropy.errors import BitstreamError

__all__ = [
    "DecodeLimits",
    "DecodeLimitError",
    "DEFAULT_LIMITS",
    "current_limits",
    "using_limits",
    "output_bytes",
    "check_payload_holds",
]

GIB = 1 << 30


class DecodeLimitError(BitstreamError):
    """A stream asks for more than a decode limit allows.

    Attributes
    ----------
    limit : str
        The :class:`DecodeLimits` field, e.g. ``"max_output_bytes"``.
    value, allowed : int
        What the stream asks for and what the limit allows.
    """

    def __init__(self, limit: str, value: int, allowed: int, what: str = "") -> None:
        self.limit, self.value, self.allowed = limit, int(value), int(allowed)
        detail = f" ({what})" if what else ""
        super().__init__(
            f"decode limit {limit} exceeded: the stream asks for {int(value):,}{detail}, the limit is {int(allowed):,}; "
            f"raise it with --limit {limit.removeprefix('max_')}=N (or DecodeLimits({limit}=N)) if the stream is trusted."
        )


@dataclass(frozen=True)
class DecodeLimits:
    """Bounds on one decode (generous defaults: a 2 GiB decoded motion, ~23 h at 120 fps).

    Attributes
    ----------
    max_frames : int
        Largest F, frames. Default 10,000,000.
    max_joints : int
        Largest J, joints. Default 4096 (the container's own bound).
    max_output_bytes : int
        Largest decoded output, bytes: float64 positions ``F·J·3·8``, plus ``F·(J·4 + 3)·8`` for codecs that
        decode rotations. Default 2 GiB.
    max_ik_iterations : int
        Largest total of inverse-kinematics iterations (F × iterations per frame) a decoder may run. Default
        2,000,000 (about 10 CPU-minutes of ``pga-ik`` on a 31-joint skeleton).
    """

    max_frames: int = 10_000_000
    max_joints: int = 4096
    max_output_bytes: int = 2 * GIB
    max_ik_iterations: int = 2_000_000

    def __post_init__(self) -> None:
        for field in dataclasses.fields(self):
            value = getattr(self, field.name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"DecodeLimits.{field.name} must be an int >= 1, got {value!r}.")

    def replace(self, **changes: int) -> "DecodeLimits":
        """A copy with some limits changed; names are the fields with or without ``max_``."""
        fields = {f.name for f in dataclasses.fields(self)}
        named = {}
        for key, value in changes.items():
            name = key if key in fields else f"max_{key}"
            if name not in fields:
                short = sorted(f.removeprefix("max_") for f in fields)
                raise ValueError(f"unknown decode limit {key!r}; known: {short}.")
            named[name] = value
        return dataclasses.replace(self, **named)

    @classmethod
    def from_settings(cls, pairs: list[str]) -> "DecodeLimits":
        """Limits from ``NAME=VALUE`` strings (the CLI's ``--limit``), e.g. ``output_bytes=8e9``, ``frames=1e6``."""
        changes: dict[str, int] = {}
        for pair in pairs:
            key, sep, text = pair.partition("=")
            try:
                value = float(text)
            except ValueError:
                value = float("nan")
            if not sep or not key or not (value == value and 1 <= value < 2**63) or value != int(value):
                raise ValueError(f"--limit expects NAME=INTEGER (e.g. output_bytes=8e9), got {pair!r}.")
            changes[key.strip()] = int(value)
        return cls().replace(**changes)

    def admitting(self, num_frames: int, num_joints: int, codes_rotations: bool) -> "DecodeLimits":
        """These limits, raised where needed to admit a motion of ``num_frames`` x ``num_joints`` (never lowered).

        For an encoder checking its own stream: the motion it coded is already in memory, so decoding it back must
        not be refused by a limit meant for streams of unknown origin.
        """
        return dataclasses.replace(
            self,
            max_frames=max(self.max_frames, num_frames),
            max_joints=max(self.max_joints, num_joints),
            max_output_bytes=max(self.max_output_bytes, output_bytes(num_frames, num_joints, codes_rotations)),
        )

    def check(self, limit: str, value: int, what: str = "") -> None:
        """Raise :class:`DecodeLimitError` if ``value`` exceeds the field ``limit``."""
        allowed = getattr(self, limit)
        if value > allowed:
            raise DecodeLimitError(limit, value, allowed, what)

    def check_header(self, num_frames: int, num_joints: int, codes_rotations: bool) -> None:
        """Check F, J and the decoded output size implied by a container header."""
        self.check("max_frames", num_frames, "frames")
        self.check("max_joints", num_joints, "joints")
        self.check("max_output_bytes", output_bytes(num_frames, num_joints, codes_rotations), "bytes of decoded arrays")


DEFAULT_LIMITS = DecodeLimits()
_CURRENT: contextvars.ContextVar[DecodeLimits] = contextvars.ContextVar("mocapbench_decode_limits", default=DEFAULT_LIMITS)


def current_limits() -> DecodeLimits:
    """The limits of the decode in progress (:data:`DEFAULT_LIMITS` outside one)."""
    return _CURRENT.get()


@contextlib.contextmanager
def using_limits(limits: DecodeLimits | None) -> Iterator[DecodeLimits]:
    """Make ``limits`` current inside the block (``None``: keep the current ones)."""
    if limits is None:
        yield current_limits()
        return
    if not isinstance(limits, DecodeLimits):
        raise TypeError(f"limits must be a DecodeLimits, got {type(limits).__name__}.")
    token = _CURRENT.set(limits)
    try:
        yield limits
    finally:
        _CURRENT.reset(token)


def output_bytes(num_frames: int, num_joints: int, codes_rotations: bool) -> int:
    """Bytes of the decoded arrays: float64 positions, plus quaternions and root positions for rotation codecs."""
    size = num_frames * num_joints * 3 * 8
    if codes_rotations:
        size += num_frames * (num_joints * 4 + 3) * 8
    return size


def check_payload_holds(available: int, needed: int, what: str, codec: str) -> None:
    """Refuse a payload with fewer than ``needed`` bytes left for ``what`` (before allocating for it).

    Parameters
    ----------
    available : int
        Payload bytes left to read.
    needed : int
        The fewest bytes that can hold ``what`` for the header's F and J.
    """
    if needed > available:
        raise BitstreamError(
            f"{codec}: the payload cannot hold {what}: it needs at least {needed:,} bytes for the header's frames "
            f"and joints, {available:,} are left."
        )
