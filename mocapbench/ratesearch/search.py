"""Rate search: the smallest stream of a codec whose worst joint error stays within a bound (``--max-error-cm``).

Every codec has one main knob (:data:`KNOBS`): the bound itself for the codecs that guarantee it (``mcb-linf``,
``mcb-rot``: exact, one encode), a quantization step with a known worst case for ``quant-delta-zstd`` (exact, one
encode; ``fourier-mlp-dct``: its own stopping threshold, one encode), otherwise a step, a bit depth, a rank or a frequency count searched by bisection: each try encodes,
decodes and measures the L-inf error in cm; the smallest stream that meets the bound wins. A codec with no knob
(``raw-zstd``, lossless) is coded once. If no setting in the knob's range meets the bound, the result says so
(``met`` is False) and holds the setting with the smallest error.

:func:`search_many` runs the searches of several clips in lockstep, so that the clips trying the same setting are
encoded together (``encode_many``: the neural Fourier codecs train their networks side by side).
"""

from __future__ import annotations

import copy
import dataclasses
import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Callable

from mocapbench import metrics
from mocapbench.codecs.base import Codec
from mocapbench.codecs.registry import create
from mocapbench.motion import Motion
from mocapbench.ratesearch.source import known_kinematics

__all__ = ["KNOBS", "Knob", "SearchResult", "ratio", "search", "search_many", "with_config"]


@dataclass(frozen=True)
class Knob:
    """The main rate-distortion knob of a codec.

    Attributes
    ----------
    field : str
        Config field searched.
    low, high : float, or a callable of the motion for ``high``
        Range searched (inclusive).
    error_grows : bool
        True when a larger value gives a larger error (a step); False for a bit depth, a rank, a count.
    integer : bool
        The field is an int.
    exact : callable or None
        ``bound_cm -> value`` for codecs with a guarantee: one encode, no search.
    fixed : mapping
        Other fields set with the knob (e.g. ``threshold_unit="cm"``); values may be callables of the bound.
    grow : bool
        For an integer knob whose error shrinks as it grows and whose tries cost more as it grows (a frequency
        count: a network per try, its size growing with K): start from the cheap end and double (0, 1, 2, 4, ...)
        until a try meets the bound, then bisect between the last miss and that try, as Algorithm 1 of the neural
        Fourier paper grows its frequencies from none. No try is ever above twice the answer, where starting from
        the safe end first trains the largest network of the range. With a monotone error both orders end on the
        same smallest setting that meets the bound.
    """

    field: str
    low: float
    high: float | Callable[[Motion], float]
    error_grows: bool = True
    integer: bool = False
    exact: Callable[[float], float] | None = None
    fixed: Mapping[str, Any] = field(default_factory=dict)
    grow: bool = False


_STEP = dict(low=1e-3, high=50.0)
# Margin under the bound for the exact knobs: the worst case is met with float rounding to spare.
_EXACT_MARGIN = 1.0 - 1e-9

KNOBS: dict[str, Knob | None] = {
    "raw-zstd": None,
    "mcb-linf": Knob("eps_cm", 1e-3, 100.0, exact=lambda bound: bound),
    "mcb-rot": Knob("eps_cm", 1e-3, 100.0, exact=lambda bound: bound),
    # per coordinate <= step / 2, so per joint <= step sqrt(3) / 2
    "quant-delta-zstd": Knob("step_cm", 1e-4, 100.0, exact=lambda bound: 2.0 * bound / math.sqrt(3.0) * _EXACT_MARGIN),
    "quant-pred-zstd": Knob("step_cm", 1e-4, 100.0, exact=lambda bound: 2.0 * bound / math.sqrt(3.0) * _EXACT_MARGIN),
    "quant-rot-zstd": Knob("rotation_bits", 2, 24, error_grows=False, integer=True,
                           fixed={"translation_step_cm": lambda bound: min(100.0, bound / 4.0)}),
    "acl": Knob("precision_cm", 1e-5, 100.0),  # ACL's shell-error target; the joint error is measured
    "lsdt-frame": Knob("step_cm", **_STEP),
    "lsdt-clip": Knob("step_cm", **_STEP),
    "dct-spatial-frame": Knob("step_cm", **_STEP),
    "dct-spatial-clip": Knob("step_cm", **_STEP),
    "dwt-spatial-frame": Knob("step_cm", **_STEP),
    "dwt-spatial-clip": Knob("step_cm", **_STEP),
    # ranks above min(F, 3 J) and geodesics above 3 J change nothing: the search range stops there
    "svd": Knob("rank", 1, lambda motion: min(4096, motion.num_frames, 3 * motion.num_joints), error_grows=False,
                integer=True),
    "pga-ik": Knob("num_geodesics", 1, lambda motion: min(300, 3 * motion.num_joints), error_grows=False,
                   integer=True, fixed={"root_levels_dropped": 0, "end_levels_dropped": 0}),
    # its own stopping rule is the L-inf error in cm: one encode (the measured error still decides `met`)
    "fourier-mlp-dct": Knob("threshold", 1e-3, 100.0, exact=lambda bound: bound, fixed={"threshold_unit": "cm"}),
    "fourier-mlp-int": Knob("K", 0, 64, error_grows=False, integer=True, grow=True),
}


@dataclass(frozen=True, eq=False)
class SearchResult:
    """The outcome of :func:`search`.

    Attributes
    ----------
    codec : Codec
        The codec (config at the chosen setting) that wrote ``data``.
    data : bytes
        The chosen stream.
    settings : dict
        The config fields the search set.
    max_error_cm, mean_error_cm : float
        Of the decoded stream against the motion.
    met : bool
        ``max_error_cm <= bound``.
    exact : bool
        The setting came from the codec's guarantee (no search).
    tries : int
        Encodes run.
    encode_stats : dict
        The codec's ``last_encode_stats`` right after it wrote ``data``.
    encode_wall_s, encode_cpu_s : float, s
        Wall time and CPU time of the process of the encode that wrote ``data`` (one call, as it ran).
    """

    codec: Codec
    data: bytes
    settings: dict[str, Any]
    max_error_cm: float
    mean_error_cm: float
    met: bool
    exact: bool
    tries: int
    encode_stats: dict[str, Any] = field(default_factory=dict)
    encode_wall_s: float = 0.0
    encode_cpu_s: float = 0.0


def with_config(fitted: Codec, codec: Codec) -> Codec:
    """A copy of ``fitted`` (its learned state shared, read-only) with ``codec``'s config: a ``prepare`` for
    :func:`search` when the knob is not a field the fit depends on (a step, a bound), so one fit serves every try."""
    clone = copy.copy(fitted)
    clone.config = codec.config
    clone.last_encode_stats = {}
    return clone


def _codec(name: str, base: Mapping[str, Any], knob_settings: dict[str, Any], prepare) -> Codec:
    codec = create(name, **{**base, **knob_settings})
    return prepare(codec) if prepare is not None else codec


def _measured(codec: Codec, data: bytes, stats: dict[str, Any], reference, knob_settings: dict[str, Any],
              met_at: float, exact: bool, wall: float, cpu: float) -> SearchResult:
    """Decode ``data`` and measure it against ``reference`` (F, J, 3) cm; ``tries`` is left 0."""
    decoded = codec.decode(data).positions
    worst = metrics.max_joint_error(reference, decoded)
    return SearchResult(codec, data, knob_settings, worst, metrics.mean_joint_error(reference, decoded),
                        worst <= met_at, exact, 0, stats, wall, cpu)


def _try(name: str, base: Mapping[str, Any], knob_settings: dict[str, Any], motion: Motion, prepare, reference,
         met_at: float, exact: bool) -> SearchResult:
    """One encode and decode at ``knob_settings``, measured against ``reference``; ``tries`` is left 0."""
    codec = _codec(name, base, knob_settings, prepare)
    wall, cpu = time.perf_counter(), time.process_time()
    data = codec.encode(motion)
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    return _measured(codec, data, dict(codec.last_encode_stats), reference, knob_settings, met_at, exact, wall, cpu)


def search(
    name: str,
    motion: Motion,
    bound_cm: float,
    settings: Mapping[str, Any] | None = None,
    *,
    prepare: Callable[[Codec], Codec] | None = None,
    max_tries: int = 12,
    knob: Knob | None = None,
) -> SearchResult:
    """The smallest stream of codec ``name`` on ``motion`` with L-inf error <= ``bound_cm``.

    Parameters
    ----------
    name : str
        Registry name.
    motion : Motion
    bound_cm : float, cm, > 0
    settings : mapping, optional
        Other config fields (``--set``); the knob's field, if given here, is overridden by the search.
    prepare : callable, optional
        Applied to every codec built (e.g. load a model, fit), before it encodes.
    max_tries : int, keyword-only
        Encodes a bisection may run (after the two ends of the range).
    knob : Knob, optional, keyword-only
        Search this knob instead of the codec's entry in :data:`KNOBS` (e.g. a narrower range).

    Raises
    ------
    ValueError
        A bound that is not a positive finite number.
    """
    knob = _checked_knob(name, bound_cm, knob)
    motion = known_kinematics(motion)  # every try reads the same source positions: forward kinematics once
    reference = motion.positions()
    base = dict(settings or {})
    steps = _steps(knob, motion, bound_cm, max_tries)
    request = next(steps)
    while True:
        chosen, exact = request
        try:
            request = steps.send(_try(name, base, chosen, motion, prepare, reference, bound_cm, exact))
        except StopIteration as done:
            return done.value


def search_many(
    name: str,
    motions: Sequence[Motion],
    bound_cm: float,
    settings: Mapping[str, Any] | None = None,
    *,
    prepare: Callable[[Codec], Codec] | None = None,
    max_tries: int = 12,
    knob: Knob | None = None,
) -> list[SearchResult]:
    """:func:`search` on every motion, the searches in lockstep: the clips that try the same setting in a round are
    encoded by one :meth:`~mocapbench.codecs.base.Codec.encode_many` call.

    For a codec whose ``encode_many`` shares work between clips (the neural Fourier codecs train their networks
    side by side) this is the same search for a fraction of the cost; each clip takes the steps :func:`search`
    takes, and its streams are the ones ``encode_many`` writes (for those codecs: the streams of ``encode``, up to
    the order of floating-point sums). Parameters as :func:`search`; ``prepare`` is applied to each codec built
    for a round's group of clips (the same for every motion). Each result's encode time is its share, by frames, of
    its group's ``encode_many`` call.

    Returns
    -------
    list of SearchResult
        One per motion, in order.

    Raises
    ------
    ValueError
        A bad bound; or the first error a clip's encode raised (as :func:`search` would on that clip).
    """
    knob = _checked_knob(name, bound_cm, knob)
    sources = [known_kinematics(motion) for motion in motions]
    references = [source.positions() for source in sources]
    base = dict(settings or {})
    steps = [_steps(knob, source, bound_cm, max_tries) for source in sources]
    requests = {clip: next(step) for clip, step in enumerate(steps)}
    results: list[SearchResult | None] = [None] * len(sources)
    while requests:
        groups: dict[str, tuple[dict[str, Any], bool, list[int]]] = {}
        for clip, (chosen, exact) in requests.items():
            groups.setdefault(repr(sorted(chosen.items())), (chosen, exact, []))[2].append(clip)
        requests = {}
        for chosen, exact, clips in groups.values():
            tried = _try_many(name, base, chosen, [sources[c] for c in clips], prepare, [references[c] for c in clips],
                              bound_cm, exact)
            for clip, result in zip(clips, tried):
                try:
                    requests[clip] = steps[clip].send(result)
                except StopIteration as done:
                    results[clip] = done.value
    return results  # type: ignore[return-value]


def _checked_knob(name: str, bound_cm: float, knob: Knob | None) -> Knob | None:
    if not (isinstance(bound_cm, (int, float)) and math.isfinite(bound_cm) and bound_cm > 0):
        raise ValueError(f"--max-error-cm must be a positive number of cm, got {bound_cm!r}.")
    knob = KNOBS.get(name, "unknown") if knob is None else knob
    if knob == "unknown":
        raise ValueError(f"codec {name!r} has no rate knob known to the rate search; set its config with --set.")
    return knob


def _try_many(name: str, base: Mapping[str, Any], knob_settings: dict[str, Any], motions: Sequence[Motion], prepare,
              references: Sequence, met_at: float, exact: bool) -> list[SearchResult]:
    """:func:`_try` on several motions with one codec and one ``encode_many`` call (time shared by frames)."""
    codec = _codec(name, base, knob_settings, prepare)
    wall, cpu = time.perf_counter(), time.process_time()
    encoded = codec.encode_many(motions)
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    total = sum(motion.num_frames for motion in motions)
    out = []
    for motion, reference, (data, stats) in zip(motions, references, encoded):
        if isinstance(data, Exception):
            raise data
        share = motion.num_frames / total
        out.append(_measured(codec, data, dict(stats), reference, knob_settings, met_at, exact, wall * share,
                             cpu * share))
    return out


def _steps(knob: Knob | None, motion: Motion, bound_cm: float, max_tries: int):
    """The search of one clip as a generator: yields ``(settings, exact)`` to try, is sent each try's
    :class:`SearchResult`, and returns the chosen one (with ``tries`` set).

    No knob: one try. An exact knob: one try at the guaranteed setting. Else :func:`_bisect`.
    """
    if knob is None:
        result = yield {}, True
        return dataclasses.replace(result, tries=1)
    fixed = {key: value(bound_cm) if callable(value) else value for key, value in knob.fixed.items()}
    if knob.exact is not None:
        result = yield {knob.field: knob.exact(bound_cm), **fixed}, True
        return dataclasses.replace(result, tries=1)
    if callable(knob.high):
        knob = dataclasses.replace(knob, high=max(knob.low, knob.high(motion)))
    return (yield from _bisect(knob, fixed, bound_cm, max_tries))


def _bisect(knob: Knob, fixed, bound_cm, max_tries):
    """Bisection over the knob (log scale for floats, whose error grows with the value: steps, thresholds), as a
    generator of tries (see :func:`_steps`).

    Returns the smallest stream among the tries within the bound, else the try with the smallest error.
    """
    tries = 0
    best = None  # (bytes, result) within the bound
    closest = None  # the try with the smallest error, if none meets the bound

    def attempt(value):
        nonlocal tries, best, closest
        value = int(round(value)) if knob.integer else float(value)
        result = yield {knob.field: value, **fixed}, False
        tries += 1
        if result.met and (best is None or len(result.data) < len(best.data)):
            best = result
        if closest is None or result.max_error_cm < closest.max_error_cm:
            closest = result
        return result.met

    # "safe" end: the smallest error; "coarse" end: the largest.
    safe, coarse = (knob.low, knob.high) if knob.error_grows else (knob.high, knob.low)
    if knob.integer and knob.grow and not knob.error_grows:
        lo, hi = int(knob.low), int(knob.high)
        value = lo
        met = yield from attempt(value)
        while not met and value < hi:  # double up to the first setting that meets the bound
            lo = value
            value = min(hi, max(value + 1, 2 * value))
            met = yield from attempt(value)
        if met:
            hi = value
            while hi - lo > 1 and tries < max_tries + 2:
                middle = (lo + hi) // 2
                if (yield from attempt(middle)):
                    hi = middle
                else:
                    lo = middle
    elif knob.integer:
        coarse_met = yield from attempt(coarse)
        if not coarse_met and safe != coarse and (yield from attempt(safe)):
            lo, hi = sorted((int(safe), int(coarse)))
            while hi - lo > 1 and tries < max_tries + 2:
                middle = (lo + hi) // 2
                meets = yield from attempt(middle)
                # keep the met end on the safe side
                if meets == knob.error_grows:
                    lo = middle
                else:
                    hi = middle
    else:
        # Start near the bound (a step about the bound is a good first guess), then bisect in log scale.
        guess = min(max(bound_cm, knob.low), knob.high)
        low_value, high_value = math.log(knob.low), math.log(knob.high)
        met = yield from attempt(guess)
        if met:
            low_value = math.log(guess)
        else:
            high_value = math.log(guess)
            met_low = yield from attempt(knob.low)
            if not met_low:
                high_value = low_value
        while high_value - low_value > math.log(1.05) and tries < max_tries + 2:
            middle = 0.5 * (low_value + high_value)
            if (yield from attempt(math.exp(middle))):
                low_value = middle
            else:
                high_value = middle
    return dataclasses.replace(best if best is not None else closest, tries=tries)


def ratio(motion: Motion, data: bytes) -> float:
    """Compression ratio of ``data`` against the motion's float32 positions."""
    return metrics.compression_ratio(metrics.raw_position_bytes(motion.num_joints, motion.num_frames), len(data))

