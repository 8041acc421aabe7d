"""The engine of ``mocapbench compare``: codecs on a user's clips at one L∞ bound, ranked, resumable, told as it goes.

For each codec, each clip is coded at the bound by the rate search (:mod:`mocapbench.ratesearch`: exact for the
codecs with a guarantee, a search over the main knob for the others), with a model obtained as
:mod:`mocapbench.experiments.held_out` says (held out by default, in-sample only when asked, and then paid for in
the ratio). A codec ranks by its pooled ratio (total float32 position bytes over total stream bytes, plus the
model bytes when the models were fit in-sample); a codec that cannot reach the bound on some clip, cannot run
here, or fails gets a row with the one-line reason.

Nothing finished is lost: each clip's row is appended to ``<store>/<codec>/results.jsonl`` as soon as it is
measured, under a key of everything it depends on (codec, clip content, bound, how its model was obtained and on
which clips); a second run with the same inputs reuses the rows whose key matches and measures only the rest.
Ctrl-C stops the run with :class:`CompareInterrupted`, which holds the outcomes finished so far.

The default codec set (:func:`default_codecs`) leaves out the codecs whose rate search trains a network per try
(the neural Fourier codecs): they run when named, after an estimate of their cost (:func:`estimate_cpu_s`).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import time
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from mocapbench.experiments.held_out import DEFAULT_FOLDS, FoldModels, describe_models, models_bytes, plan_folds

if TYPE_CHECKING:
    from mocapbench.motion import Motion

__all__ = ["CodecOutcome", "CompareInterrupted", "RowStore", "ON_REQUEST", "default_codecs", "estimate_cpu_s",
           "compare", "rank", "format_table", "format_codec_times", "model_note", "setting_text"]

#: Codecs left out of the default set: their rate search trains a network per try and clip (minutes per clip).
ON_REQUEST = ("fourier-mlp-int", "fourier-mlp-dct")
# Tries a rate search runs, for the estimate: one for a codec with a guarantee, a bisection otherwise.
_EXACT_TRIES, _SEARCH_TRIES = 1, 12
_ROW_VERSION = 1  # bump when a row's meaning changes: older rows are then measured again


class CompareInterrupted(Exception):
    """Ctrl-C during :func:`compare`: ``outcomes`` holds the codecs that finished, ``current`` the one cut short."""

    def __init__(self, outcomes: list[CodecOutcome], current: str | None) -> None:
        super().__init__(f"interrupted during {current}")
        self.outcomes = outcomes
        self.current = current


@dataclasses.dataclass
class CodecOutcome:
    """One codec's result over the clips: rows of the chosen settings, or the reason it has none."""

    codec: str
    rows: list[dict[str, Any]]
    reason: str = ""
    rotations: bool = False
    latency_frames: int = -1
    settings: list[dict[str, Any]] = dataclasses.field(default_factory=list)
    seconds: float = 0.0  # wall time of this codec's run, s
    cpu_seconds: float = 0.0  # CPU time of the process during this codec's run, s
    resumed: int = 0  # rows taken from an earlier run

    @property
    def raw_bytes(self) -> int:
        return sum(int(row["raw_bytes"]) for row in self.rows)

    @property
    def stream_bytes(self) -> int:
        return sum(int(row["bitstream_bytes"]) for row in self.rows)

    @property
    def model_bytes(self) -> int:
        """Bytes of the models the rows used (:func:`mocapbench.experiments.held_out.models_bytes`)."""
        return models_bytes(self.rows)

    @property
    def in_sample(self) -> bool:
        return any(row.get("model_source") == "in-sample" for row in self.rows)

    @property
    def stream_ratio(self) -> float:
        """Raw bytes over stream bytes (models not counted)."""
        return self.raw_bytes / self.stream_bytes if self.stream_bytes else 0.0

    @property
    def ratio_with_models(self) -> float:
        """Raw bytes over stream bytes plus the bytes of every model used."""
        total = self.stream_bytes + self.model_bytes
        return self.raw_bytes / total if total else 0.0

    @property
    def ratio(self) -> float:
        """The ranked ratio: with the model bytes when the models were fit in-sample, else the streams'."""
        return self.ratio_with_models if self.in_sample else self.stream_ratio


def default_codecs() -> list[str]:
    """Every registered codec but :data:`ON_REQUEST`, then the unavailable ones (they keep a row with the reason)."""
    from mocapbench.codecs import CODECS, UNAVAILABLE

    return [n for n in sorted(CODECS) if n not in ON_REQUEST] + sorted(set(UNAVAILABLE) - set(CODECS))


def estimate_cpu_s(name: str, motions: Sequence[Motion]) -> float:
    """CPU seconds ``compare`` will spend on codec ``name`` over ``motions`` (an estimate, from the costs file).

    The measured CPU seconds per frame of one encode and decode (:func:`mocapbench.experiments.cost.cpu_cost`,
    the codec's most expensive config) times the frames, times the rate search's tries (1 for a codec with a
    guarantee, about 12 for a bisection), plus one more decode per clip (the row's, of the chosen stream: it is
    not encoded again). For a codec whose searches run in lockstep (``encode_many``: the neural codecs train the
    clips of a try side by side) this is an upper bound: the cost file measures one clip at a time.
    """
    from mocapbench.experiments.cost import cpu_cost, load_costs
    from mocapbench.ratesearch import KNOBS

    per_frame, per_clip = cpu_cost(load_costs(), f"{name}/")
    knob = KNOBS.get(name)
    tries = _EXACT_TRIES if knob is None or knob.exact is not None else _SEARCH_TRIES
    frames = sum(motion.num_frames for motion in motions)
    return (tries + 1) * (per_frame * frames + per_clip * len(motions))  # the decode counted as an encode: a bound


def _fingerprint(motion: Motion) -> str:
    """A hash of what a codec sees of a clip: skeleton, frame rate, unit, axis and every channel."""
    import numpy as np

    digest = hashlib.sha1()
    skeleton = motion.skeleton
    digest.update("|".join(skeleton.names).encode())
    for array in (skeleton.parents, skeleton.offsets, motion.root_positions, motion.rotations,
                  getattr(motion, "translations", None), getattr(motion, "scales", None)):
        if array is not None:
            digest.update(np.ascontiguousarray(array).tobytes())
    digest.update(f"{motion.fps!r}|{motion.source_unit_cm!r}|{motion.up_axis}".encode())
    return digest.hexdigest()


class RowStore:
    """Rows of finished clips, appended as they finish, found again by key (the resume of ``compare``).

    Layout: ``<folder>/<codec>/results.jsonl`` (one row per clip, the layout the report reads) and
    ``<folder>/<codec>/failed.jsonl`` (a codec's one-line reason, under the key of the whole run of that codec).
    """

    def __init__(self, folder: str | Path) -> None:
        self.folder = Path(folder)

    def _rows(self, codec: str, file: str) -> list[dict[str, Any]]:
        from mocapbench.experiments.results import scan_rows

        rows, _ = scan_rows(self.folder / codec / file)  # a torn last line (killed mid-write) is measured again
        return rows

    def find(self, codec: str, key: str) -> dict[str, Any] | None:
        """The latest row of ``codec`` stored under ``key`` (None if none)."""
        found = [row for row in self._rows(codec, "results.jsonl") if row.get("compare_key") == key]
        return found[-1] if found else None

    def find_failure(self, codec: str, key: str) -> str | None:
        found = [row for row in self._rows(codec, "failed.jsonl") if row.get("compare_key") == key]
        return found[-1]["reason"] if found else None

    def add(self, codec: str, row: dict[str, Any]) -> None:
        from mocapbench.experiments.results import append_row

        append_row(self.folder / codec / "results.jsonl", row)

    def add_failure(self, codec: str, key: str, reason: str) -> None:
        from mocapbench.experiments.results import append_row

        append_row(self.folder / codec / "failed.jsonl", {"codec": codec, "compare_key": key, "reason": reason})


class _NoStore(RowStore):
    def __init__(self) -> None:
        super().__init__(".")

    def find(self, codec, key):
        return None

    def find_failure(self, codec, key):
        return None

    def add(self, codec, row):
        pass

    def add_failure(self, codec, key, reason):
        pass


def _one_line(error: BaseException) -> str:
    text = error.args[0] if isinstance(error, KeyError) and error.args else str(error)
    return f"{type(error).__name__}: {' '.join(str(text).split())}"


@dataclasses.dataclass(frozen=True)
class _Plan:
    """What every clip of one comparison depends on, besides the codec (shared by the codecs)."""

    bound_cm: float
    policy: str
    folds: int
    dataset: str
    fingerprints: tuple[str, ...]

    def key(self, codec: str, clip: int, train: Sequence[int]) -> str:
        text = json.dumps([_ROW_VERSION, codec, self.fingerprints[clip], self.bound_cm, self.policy,
                           sorted(self.fingerprints[i] for i in train)])
        return hashlib.sha1(text.encode()).hexdigest()


def _compare_codec(name: str, motions: Sequence[Motion], plan: _Plan, store: RowStore, progress) -> CodecOutcome:
    from mocapbench.codecs import CODECS
    from mocapbench.experiments.evaluate import TimingSettings, evaluate
    from mocapbench.metrics.timing import single_thread
    from mocapbench.ratesearch import known_kinematics, search, with_config

    start, start_cpu = time.perf_counter(), time.process_time()
    outcome = CodecOutcome(name, [], rotations=bool(CODECS[name].codes_rotations))
    folds = plan_folds(motions, plan.policy, plan.folds)
    train_of = {clip: fold.train for fold in folds for clip in fold.test}
    keys = [plan.key(name, clip, train_of[clip]) for clip in range(len(motions))]
    run_key = hashlib.sha1("".join(keys).encode()).hexdigest()
    known = store.find_failure(name, run_key)
    if known is not None:
        outcome.reason = known
        progress.skip(name, len(motions))
        return outcome
    models = FoldModels(name, motions, folds)
    clip = None
    try:
        searched = _searched_together(name, motions, plan, models, [store.find(name, key) is None for key in keys],
                                      progress)
        for clip, motion in enumerate(motions):
            stored = store.find(name, keys[clip])
            if stored is not None:
                outcome.rows.append(stored)
                outcome.settings.append(stored.get("rate_search_settings", {}))
                outcome.latency_frames = int(stored.get("latency_frames", -1))
                outcome.resumed += 1
                progress.clip_done(name, motion.name, resumed=True)
                continue
            source = known_kinematics(motion)  # forward kinematics once for every try and the evaluation
            if clip in searched:
                result, source = searched[clip]
                if clip != min(searched):  # the first clip's time holds the searches run together
                    progress.clip_start(name, motion.name)
            else:
                progress.clip_start(name, motion.name)
                fitted = models.fitted(clip)

                def prepare(codec, fitted=fitted):
                    progress.try_started(name)
                    return with_config(fitted, codec) if fitted is not None else codec

                with single_thread(1):  # one core, as evaluate times: the tries' streams are the evaluated ones
                    result = search(name, source, plan.bound_cm, prepare=prepare)
            if not result.met:
                chosen = setting_text([result.settings])
                outcome.reason = (f"cannot reach L-inf <= {plan.bound_cm:g} cm on {motion.name}: the closest "
                                  f"setting ({chosen}) gives {result.max_error_cm:.3g} cm")
                break
            row = evaluate(result.codec, source, reference_positions=source.positions(),
                           timing=TimingSettings(repeats=1, warmup=0), encoded=_chosen_stream(result))
            row.update(models.source(clip, result.codec).row_fields())
            row.update({"dataset": plan.dataset, "rate_search_tries": result.tries, "max_error_bound_cm": plan.bound_cm,
                        "rate_search_settings": result.settings, "compare_key": keys[clip]})
            store.add(name, row)
            outcome.rows.append(row)
            outcome.settings.append(result.settings)
            outcome.latency_frames = int(result.codec.latency_frames)
            progress.clip_done(name, motion.name)
    except Exception as error:  # noqa: BLE001 - a codec that fails gets its row and reason; the others go on
        outcome.reason = _one_line(error) + _unfit_note(models, folds, clip)
    if outcome.reason:
        outcome.rows = []
        store.add_failure(name, run_key, outcome.reason)
        progress.skip(name, len(motions) - progress.done_in(name))
    outcome.seconds = time.perf_counter() - start
    outcome.cpu_seconds = time.process_time() - start_cpu
    return outcome


def _searched_together(name: str, motions: Sequence[Motion], plan: _Plan, models: FoldModels, pending: list[bool],
                       progress) -> dict[int, Any]:
    """The rate searches of the pending clips run in lockstep (:func:`mocapbench.ratesearch.search_many`), for a
    codec whose ``encode_many`` shares work between clips and that fits no model; else nothing ({}).

    The neural Fourier codecs train one network per try: in lockstep, the clips trying the same setting train side
    by side. Their rows are then written when every search has finished (an interrupt in between keeps none of
    them). Returns ``{clip index: (SearchResult, the clip as searched, its kinematics known)}``.
    """
    from mocapbench.codecs import CODECS
    from mocapbench.metrics.timing import single_thread
    from mocapbench.ratesearch import known_kinematics, search_many

    clips = [clip for clip, waiting in enumerate(pending) if waiting]
    if not clips or not CODECS[name].encodes_many or models.learns:
        return {}
    progress.clip_start(name, f"{len(clips)} clip(s) searched side by side")

    def prepare(codec):
        progress.try_started(name)
        return codec

    sources = [known_kinematics(motions[clip]) for clip in clips]
    with single_thread(1):
        results = search_many(name, sources, plan.bound_cm, prepare=prepare)
    return {clip: pair for clip, pair in zip(clips, zip(results, sources))}


def _chosen_stream(result):
    """The stream the rate search chose, with its encode stats and the timing of that one encode: ``evaluate``
    decodes and measures it without encoding the clip again (``encoded``). Compare ranks by rate, not speed: one
    timed call is enough, and the encode that wrote the stream is that call."""
    from mocapbench.metrics.timing import Timing, load_average

    load = load_average()
    timing = Timing(wall_s=result.encode_wall_s, cpu_s=result.encode_cpu_s, wall_spread_s=0.0, repeats=1, warmup=0,
                    threads=1, load_before=load, load_after=load)
    return result.data, dict(result.encode_stats), timing


def _unfit_note(models: FoldModels, folds, clip: int | None) -> str:
    """Why a learned codec had no model of its own for ``clip``: the only clip of its skeleton (else "")."""
    if clip is None or not models.learns:
        return ""
    fold = next(f for f in folds if clip in f.test)
    if fold.scheme != "no fit":
        return ""
    motion = models.motions[clip]
    return (f" ({motion.name} is the only clip of its {motion.num_joints}-joint skeleton: no other clip to fit a "
            f"model on out of sample; --in-sample fits one on it and counts its bytes)")


class _Quiet:
    """Progress that says nothing (the default of :func:`compare`)."""

    def clip_start(self, codec, clip):
        pass

    def try_started(self, codec=None):
        pass

    def clip_done(self, codec, clip, resumed=False):
        pass

    def skip(self, codec, clips):
        pass

    def done_in(self, codec):
        return 0


def compare(
    motions: Sequence[Motion],
    bound_cm: float,
    codecs: Sequence[str] | None = None,
    *,
    dataset: str = "your clips",
    policy: str = "out-of-sample",
    folds: int = DEFAULT_FOLDS,
    store: RowStore | None = None,
    progress=None,
    workers: int = 1,
) -> list[CodecOutcome]:
    """Every codec of ``codecs`` (default :func:`default_codecs`) on ``motions``, ranked.

    Parameters
    ----------
    motions : sequence of Motion
    bound_cm : float
        The L∞ bound every clip must meet, cm.
    codecs : sequence of str, optional
    dataset : str, keyword-only
        The ``dataset`` column of the rows.
    policy, folds : keyword-only
        How learned models are obtained (:mod:`mocapbench.experiments.held_out`).
    store : RowStore, optional, keyword-only
        Where rows are appended as they finish and found again (default: nowhere).
    progress : optional, keyword-only
        An object with ``clip_start(codec, clip)``, ``try_started(codec)``, ``clip_done(codec, clip, resumed)``,
        ``skip(codec, clips)``, ``done_in(codec)`` (:class:`mocapbench.experiments.compare_progress.Progress`).
    workers : int, keyword-only
        Codecs run at once, each in a worker process of its own (:func:`_compare_in_pool`); 1: one after another
        in this process. The rows are the same either way.

    Returns
    -------
    list of CodecOutcome
        Codecs with rows by decreasing :attr:`CodecOutcome.ratio`, then the others by name.

    Raises
    ------
    CompareInterrupted
        Ctrl-C: the outcomes finished so far are in the exception; every finished clip's row is in ``store``.
    """
    from mocapbench.codecs import CODECS, UNAVAILABLE

    # A codec named twice runs once (two workers would append to its one results file at once).
    names = list(dict.fromkeys(codecs)) if codecs else default_codecs()
    plan = _Plan(float(bound_cm), policy, int(folds), dataset, tuple(_fingerprint(m) for m in motions))
    plan_folds(motions, policy, folds)  # a bad policy or fold count fails before any codec runs
    store = store or _NoStore()
    progress = progress or _Quiet()
    if workers < 1:
        raise ValueError(f"compare: workers must be >= 1, got {workers}")
    outcomes: list[CodecOutcome] = []
    runnable = []
    for name in names:
        if name in UNAVAILABLE and name not in CODECS:
            outcomes.append(CodecOutcome(name, [], reason=f"unavailable here: {UNAVAILABLE[name]}"))
            progress.skip(name, len(motions))
        elif name not in CODECS:
            outcomes.append(CodecOutcome(name, [], reason="unknown codec; `mocapbench codecs` lists them"))
            progress.skip(name, len(motions))
        else:
            runnable.append(name)
    if workers > 1 and len(runnable) > 1:
        return rank(outcomes + _compare_in_pool(runnable, motions, plan, store, progress, workers))
    current = None
    try:
        for name in runnable:
            current = name
            outcomes.append(_compare_codec(name, motions, plan, store, progress))
            current = None
    except KeyboardInterrupt:
        raise CompareInterrupted(rank(outcomes), current) from None
    return rank(outcomes)


class _Relay:
    """A worker's progress: each call is sent down the worker's pipe for the parent's progress.

    A worker runs one codec, so it counts that codec's finished clips itself (``done_in``).
    """

    def __init__(self, connection, codec: str) -> None:
        self.connection = connection
        self.codec = codec
        self.done = 0

    def clip_start(self, codec, clip):
        self.connection.send(("clip_start", (codec, clip)))

    def try_started(self, codec=None):
        self.connection.send(("try_started", (codec or self.codec,)))

    def clip_done(self, codec, clip, resumed=False):
        self.done += 1
        self.connection.send(("clip_done", (codec, clip, resumed)))

    def skip(self, codec, clips):
        self.done += clips
        self.connection.send(("skip", (codec, clips)))

    def done_in(self, codec):
        return self.done


def _worker(connection, name: str, motions: Sequence[Motion], plan: _Plan, store: RowStore) -> None:
    """A compare worker process: :func:`_compare_codec` of one codec; its progress calls, then its outcome (or the
    error that stopped it, as the parent would have met it) go down ``connection``."""
    import pickle
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to handle: it stops the workers
    try:
        message = ("outcome", _compare_codec(name, motions, plan, store, _Relay(connection, name)))
    except Exception as error:  # noqa: BLE001 - handed to the parent, which raises it
        try:
            pickle.dumps(error)
        except Exception:  # noqa: BLE001 - an exception that cannot travel: its line does
            error = RuntimeError(f"{name}: {_one_line(error)}")
        message = ("error", error)
    connection.send(message)
    connection.close()


def _start_worker(process) -> bool:
    """Start ``process``; True when a Ctrl-C came meanwhile: the caller raises it once the worker is one it stops.

    The parent used to ignore SIGINT while a worker started (so that the spawned child, which keeps an ignored
    signal, ignored it from its first instruction), and a Ctrl-C that landed then was lost: the run went on to its
    end. It is now noted instead. The child then starts with SIGINT at its default, until :func:`_worker` ignores
    it: a Ctrl-C in the second of its imports ends it with a traceback of its own, beside the parent's interrupt.
    """
    import signal
    import threading

    before = signal.getsignal(signal.SIGINT)
    # Only the main thread sets handlers; a handler not set from Python (None) could not be put back.
    if threading.current_thread() is not threading.main_thread() or before is None:
        process.start()
        return False
    noted: list[int] = []
    signal.signal(signal.SIGINT, lambda signum, frame: noted.append(signum))
    try:
        process.start()
    finally:
        signal.signal(signal.SIGINT, before)  # (a signal caught but not yet handled goes to the note first)
    return bool(noted) and before is not signal.SIG_IGN


def _ended_without_outcome(name: str, exitcode: int | None) -> CodecOutcome:
    """The outcome of a codec whose worker process ended without sending one (killed, or crashed)."""
    import signal

    if exitcode is not None and exitcode < 0:
        try:
            how = f"killed by {signal.Signals(-exitcode).name}"
        except ValueError:
            how = f"killed by signal {-exitcode}"
    else:
        how = f"exit code {exitcode}"
    return CodecOutcome(name, [], reason=f"its worker process ended without a result ({how})")


def _compare_in_pool(names: Sequence[str], motions: Sequence[Motion], plan: _Plan, store: RowStore, progress,
                     workers: int) -> list[CodecOutcome]:
    """:func:`_compare_codec` of every codec of ``names``, each in a process of its own, ``workers`` at once, longest
    first; the outcomes in the order of ``names`` (so that :func:`rank` breaks ties as one after another does).

    A codec is the unit of work: its clips share the models fit for their folds, and the neural codecs' clips
    train side by side, so a codec's rows are the ones it gives alone. The codecs are started by decreasing
    :func:`estimate_cpu_s` (the longest-processing-time-first schedule), so that the neural codecs, the longest,
    start first instead of running alone at the end. Workers are started fresh (``spawn``: no thread or library
    state of this process is copied into them). Each sends its progress calls and then its outcome down a pipe of
    its own; this thread replays the calls on ``progress`` as they come and sees a worker end (its pipe closes):
    a worker that ends without an outcome (killed: out of memory, a crash in native code) gives its codec a row
    with that reason and the others go on; an error that stopped a worker stops the others and is raised here.
    Ctrl-C stops every worker and raises :class:`CompareInterrupted` with the codecs that finished (the rows of
    every finished clip are in ``store`` already).
    """
    import multiprocessing
    from multiprocessing.connection import wait

    context = multiprocessing.get_context("spawn")
    waiting = sorted(names, key=lambda name: -estimate_cpu_s(name, motions))
    running: dict[Any, tuple[str, Any]] = {}  # a worker's pipe (read end) -> (codec, process)
    outcomes: list[CodecOutcome] = []

    def finished(reader, outcome: CodecOutcome | None) -> None:
        name, process = running.pop(reader)
        reader.close()
        process.join()
        outcomes.append(outcome if outcome is not None else _ended_without_outcome(name, process.exitcode))
        if outcome is None:
            progress.skip(name, len(motions) - progress.done_in(name))

    try:
        while waiting or running:
            while waiting and len(running) < workers:
                name = waiting.pop(0)
                reader, writer = context.Pipe(duplex=False)
                process = context.Process(target=_worker, args=(writer, name, list(motions), plan, store),
                                          name=f"compare {name}", daemon=True)
                interrupted = _start_worker(process)
                writer.close()  # the worker holds the write end: the pipe closes when it ends
                running[reader] = (name, process)
                if interrupted:
                    raise KeyboardInterrupt
            for reader in wait(list(running)):
                try:
                    method, arguments = reader.recv()
                except (EOFError, OSError):  # ended without its outcome (or in the middle of a message)
                    finished(reader, None)
                    continue
                if method == "outcome":
                    finished(reader, arguments)
                elif method == "error":
                    raise arguments
                else:
                    getattr(progress, method)(*arguments)
    except KeyboardInterrupt:
        cut = [name for name, _ in running.values()]
        _stop(running)
        raise CompareInterrupted(rank(outcomes), ", ".join(cut) or None) from None
    except BaseException:
        _stop(running)
        raise
    order = {name: index for index, name in enumerate(names)}
    return sorted(outcomes, key=lambda outcome: order[outcome.codec])


def _stop(running: dict) -> None:
    """Terminate the workers still running and wait for them (a row cut short is a torn last line: measured again)."""
    for _, process in running.values():
        process.terminate()
    for reader, (_, process) in list(running.items()):
        process.join()
        reader.close()
    running.clear()


def rank(outcomes: Sequence[CodecOutcome]) -> list[CodecOutcome]:
    """Codecs with rows by decreasing ranked ratio, then the others by name."""
    ranked = sorted((o for o in outcomes if o.rows), key=lambda o: -o.ratio)
    return ranked + sorted((o for o in outcomes if not o.rows), key=lambda o: o.codec)


def _latency(frames: int) -> str:
    return "whole clip" if frames < 0 else ("0 (frame by frame)" if frames == 0 else f"{frames} frames")


def _rounded(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.3g}"
    return str(value)


def setting_text(settings: Sequence[dict[str, Any]]) -> str:
    """The knob values the rate search chose over the clips, rounded: one value, or the range."""
    settings = [s for s in settings if s]
    if not settings:
        return "-"
    parts = []
    for key in settings[0]:
        values = [s[key] for s in settings if key in s]
        numbers = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values)
        if numbers and len(set(values)) > 1:
            parts.append(f"{key}={_rounded(min(values))}..{_rounded(max(values))}")
        else:
            parts.append(f"{key}={_rounded(values[0])}")
    return ", ".join(parts)


def _ratio_text(value: float) -> str:
    return f"{value:,.1f}:1" if math.isfinite(value) and value > 0 else "-"


def format_table(outcomes: Sequence[CodecOutcome], bound_cm: float) -> str:
    """The ranked table as aligned text (what ``compare`` prints)."""
    header = ["rank", "codec", f"ratio at L-inf <= {bound_cm:g} cm", "with models", "L-inf cm", "mean cm",
              "rotations", "model", "latency", "setting"]
    lines = []
    rank_number = 0
    for outcome in outcomes:
        if not outcome.rows:
            lines.append(["-", outcome.codec, "-", "-", "-", "-", "yes" if outcome.rotations else "no", "-", "-",
                          outcome.reason])
            continue
        rank_number += 1
        rows = outcome.rows
        frames = sum(row["frames"] for row in rows)
        mean = sum(row["mean_err_cm"] * row["frames"] for row in rows) / frames
        learned = any(row.get("model_source", "none") != "none" for row in rows)
        ranked = _ratio_text(outcome.ratio) + (" (models in)" if outcome.in_sample else "")
        lines.append([
            str(rank_number), outcome.codec, ranked, _ratio_text(outcome.ratio_with_models) if learned else "-",
            f"{max(r['max_err_cm'] for r in rows):.3f}", f"{mean:.3f}", "yes" if outcome.rotations else "no",
            describe_models(rows), _latency(outcome.latency_frames), setting_text(outcome.settings),
        ])
    widths = [max(len(row[i]) for row in [header, *lines]) for i in range(len(header) - 1)]
    return "\n".join("  ".join(cell.ljust(width) for cell, width in zip(row[:-1], widths)) + "  " + row[-1]
                     for row in [header, *lines])


def format_codec_times(outcomes: Sequence[CodecOutcome]) -> str:
    """Where the time went: each codec's wall and CPU seconds, most CPU first (codecs that ran nothing left out).

    Returns
    -------
    str
        ``"time per codec (wall / CPU): svd 12.0 / 11.8 s, mcb-linf ..."``, or "" when no codec ran.
    """
    ran = sorted((o for o in outcomes if o.seconds > 0), key=lambda o: (-o.cpu_seconds, o.codec))
    if not ran:
        return ""
    return "time per codec (wall / CPU): " + ", ".join(f"{o.codec} {o.seconds:.1f} / {o.cpu_seconds:.1f} s"
                                                        for o in ran)


def model_note(outcomes: Sequence[CodecOutcome]) -> str | None:
    """The line under the table that says how the models were obtained (None when no codec learned anything)."""
    learned = [o for o in outcomes if o.rows and any(r.get("model_source", "none") != "none" for r in o.rows)]
    if not learned:
        return None
    if any(o.in_sample for o in learned):
        return ("Models fit in-sample (on the clips they code): the ranked ratio includes their bytes; "
                "'with models' is the same figure.")
    return ("Models held out: each clip coded with a model fit on other clips of its skeleton (leave-one-out or "
            "k-fold), or the codec's shipped model or untrained mode where its skeleton has one clip; the ranked "
            "ratio counts the streams, 'with models' adds one model per skeleton (and each shipped model).")

