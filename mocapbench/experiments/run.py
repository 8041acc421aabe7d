"""Hydra entry point: one job = one shard (a codec config over a list of clips), rows appended to ``results.jsonl``.

Usage::

    python -m mocapbench.experiments.run                                    # default codec on synthetic clips
    python -m mocapbench.experiments.run -m sweep=rd_quant-delta-zstd       # one codec's RD curve
    python -m mocapbench.experiments.run -m sweep=all dataset=cmu_test      # every codec's curve on CMU
    python -m mocapbench.experiments.run -m sweep=all hydra.sweep.dir=multirun/mine   # re-run resumes

A job measures shard ``shard.index`` of ``shard.count`` of its dataset (:mod:`mocapbench.experiments.shards`; the
sweeper sizes shards to a CPU budget): it names the shard's clips from the dataset's catalogue, gives the codec its
learned state (:mod:`mocapbench.experiments.fitted`: nothing, the shipped model, or the state fit once for the
whole sweep), then reads, encodes and decodes one clip at a time with
:func:`mocapbench.experiments.evaluate.evaluate`, appending each clip's row to ``results.jsonl``
(:mod:`mocapbench.experiments.results`: one ``O_APPEND`` write per row, earlier rows never rewritten). A killed job
loses at most the clip in progress; a re-run skips the clips already in the file (a line that does not parse is
moved aside with the file and its clip runs again), and a finished job leaves ``job.json`` with
``"status": "done"`` so the sweeper does not launch it again. A clip that fails is logged (clip, codec, config,
error) to the log and ``errors.jsonl``; the job goes on with the next clip and the sweep with the next job.
"""

from __future__ import annotations

import json
import logging
import math
import os
import sys
import time
import traceback
from pathlib import Path
from typing import Any

import hydra
import numpy as np
from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig

from mocapbench.experiments.results import (
    ERRORS_FILE,
    RESULTS_FILE,
    CorruptResultsError,
    append_row,
    read_rows,
    repair,
    write_rows_atomic,
)

__all__ = [
    "main",
    "run_job",
    "read_rows",
    "write_rows_atomic",
    "CorruptResultsError",
    "RESULTS_FILE",
    "ERRORS_FILE",
    "EXAMPLE_FILE",
]

log = logging.getLogger(__name__)

EXAMPLE_FILE = "example.npz"


def _set_threads(threads: int | None) -> None:
    """Keep each job to ``threads`` BLAS/torch threads so that parallel jobs do not oversubscribe the cores."""
    if not threads:
        return
    from threadpoolctl import threadpool_limits

    if "torch" in sys.modules:
        sys.modules["torch"].set_num_threads(int(threads))
    threadpool_limits(int(threads))


def _shard_settings(cfg: Any) -> tuple[int, int, str]:
    """``(index, count, packing)`` of the job's shard; a config without ``shard`` is the one shard of its job."""
    from omegaconf import OmegaConf

    shard = OmegaConf.to_container(cfg.shard, resolve=True) if cfg.get("shard") is not None else {}
    return int(shard.get("index", 0)), int(shard.get("count", 1)), str(shard.get("packing", "balanced"))


def _evaluate_clip(codec: Any, motion: Any, encoded: Any, timing: Any, output_dir: Path, example_clip: str | None,
                   worst: float | None) -> tuple[dict[str, Any], tuple | None]:
    """One clip's result row, and the clip as the job's new worst clip or None.

    ``encoded`` is the clip's stream when the codec encodes clips in batches (an exception if that failed), else
    None. The clip named ``example_clip`` is saved as the job's example; a clip whose largest error exceeds
    ``worst`` (``worst`` None: no worst clip is kept) comes back as ``(motion, reference, decoded positions,
    row)``, which the job writes once at its end (:func:`_save_worst`): a compressed write at every new worst
    clip was a large share of a cheap job's CPU (README, "Timings").
    """
    from mocapbench.experiments.evaluate import evaluate_with_decoded

    if isinstance(encoded, Exception):
        raise encoded
    reference = motion.positions()
    row, decoded = evaluate_with_decoded(codec, motion, reference_positions=reference, timing=timing, encoded=encoded)
    if motion.name == example_clip:
        _save_example(output_dir, motion, reference, decoded.positions)
    if worst is not None and row["max_err_cm"] > worst:
        return row, (motion, reference, decoded.positions, row)
    return row, None


def _save_worst(output_dir: Path, candidate: tuple | None) -> None:
    """Write the job's worst clip (:func:`_evaluate_clip`'s candidate), if any."""
    if candidate is not None:
        from mocapbench.experiments.worst_clip import save_worst

        save_worst(output_dir, *candidate)


def run_job(cfg: Any, output_dir: Path, fitted_dir: Path | None = None) -> dict[str, Any]:
    """Run one benchmark job (a shard); every failure is caught, logged and recorded.

    Parameters
    ----------
    cfg : DictConfig
        The composed ``benchmark`` config (``codec``, ``dataset``, ``shard``, ``threads_per_job``,
        ``save_example``, ``save_worst``).
    output_dir : Path
        The job's folder: ``results.jsonl``, ``errors.jsonl``, ``example.npz``, ``worst.npz``
        (:mod:`mocapbench.experiments.worst_clip`) and ``job.json`` go there.
    fitted_dir : Path, optional
        Where the sweep keeps learned state shared by its jobs (``<sweep dir>/fitted``); default
        ``<output_dir>/fitted``.

    Returns
    -------
    dict
        The ``job.json`` record: ``status`` (``done`` or ``failed``), ``rows``, ``errors``, ``seconds`` (wall),
        ``cpu_s`` (CPU time of the job's process), ``clips`` (of the shard), ``shard`` (``index``, ``count``),
        ``pid`` and ``process_cpu_s`` (the worker process and its CPU time so far at the job's end: the
        difference between two jobs of one worker is the whole cost of the second, the launcher's share included,
        which :func:`mocapbench.experiments.cost.calibrate_from` reads).
    """
    from hydra.utils import instantiate
    from omegaconf import OmegaConf
    from tqdm import tqdm

    from mocapbench.experiments import datasets, fitted, shards
    from mocapbench.experiments.worst_clip import worst_error
    from mocapbench.experiments.sweeper import JOB_FILE

    start, start_cpu = time.perf_counter(), time.process_time()
    output_dir = Path(output_dir)
    output_dir.mkdir(parents=True, exist_ok=True)
    _set_threads(cfg.get("threads_per_job"))
    results_path = output_dir / RESULTS_FILE
    job_path = output_dir / JOB_FILE
    if job_path.exists():
        job_path.unlink()  # re-running: the job is unfinished until it says otherwise
    rows = repair(results_path)
    done = {row.get("clip") for row in rows}
    count = len(rows)
    codec_cfg = OmegaConf.to_container(cfg.codec, resolve=True)
    dataset_cfg = OmegaConf.to_container(cfg.dataset, resolve=True)
    index, total, packing = _shard_settings(cfg)
    context = {"codec": codec_cfg.get("name"), "config": {k: v for k, v in codec_cfg.items() if not k.startswith("_")}}
    errors = 0

    def fail(stage: str, error: BaseException, clip: str | None = None) -> None:
        nonlocal errors
        errors += 1
        record = {**context, "clip": clip, "stage": stage, "error": f"{type(error).__name__}: {error}",
                  "traceback": traceback.format_exc(limit=8)}
        log.error("job failed at %s: codec=%s clip=%s config=%s error=%s", stage, context["codec"], clip,
                  context["config"], record["error"])
        append_row(output_dir / ERRORS_FILE, record)

    def refuse(error: BaseException, clip: str) -> None:
        """A codec's refusal of a game rig's track (:class:`~mocapbench.codecs.base.TrackRefusal`): recorded beside
        the failures as its one-line reason, without failing the job."""
        record = {**context, "clip": clip, "stage": "refused", "error": f"{type(error).__name__}: {error}"}
        log.info("refused: codec=%s clip=%s: %s", context["codec"], clip, error)
        append_row(output_dir / ERRORS_FILE, record)

    from mocapbench.codecs.base import TrackRefusal
    from mocapbench.experiments.evaluate import TimingSettings

    timing = TimingSettings(**OmegaConf.to_container(cfg.timing, resolve=True)) if cfg.get("timing") else None
    status, clips = "failed", []
    try:
        clips = [ref.name for ref in shards.shard_clips(datasets.catalogue(dataset_cfg), index, total, packing)]
        todo = [name for name in clips if name not in done]
        if todo:
            codec = instantiate(cfg.codec)
            fit = fitted.prepare(codec, dataset_cfg, fitted_dir or output_dir / fitted.FITTED_DIR)
            extra = {
                "dataset": dataset_cfg.get("name"),
                "dataset_desc": datasets.describe_dataset(dataset_cfg),
                "train_set": datasets.describe_training(dataset_cfg),
                "cmu_data": datasets.cmu_used(dataset_cfg),
                "bandai_data": datasets.bandai_used(dataset_cfg),
                **fit,
                "job_dir": str(output_dir),
                "shard_index": index,
                "shard_count": total,
            }
            example = cfg.get("save_example", True) and index == 0 and not (output_dir / EXAMPLE_FILE).exists()
            keep_worst = cfg.get("save_worst", True)
            worst = worst_error(output_dir)
            candidate = None
            motions = datasets.iter_clips(dataset_cfg, todo)
            if not codec.encodes_many:
                motions = _warm_up(codec, motions)
            batches = _encode_batches(codec, motions, timing) if codec.encodes_many else None
            try:
                for motion in tqdm(batches or motions, total=len(todo), desc=f"{codec.name} clips", unit="clip",
                                   leave=False, disable=None):
                    encoded = None
                    if batches is not None:
                        motion, encoded = motion
                    try:
                        row, new_worst = _evaluate_clip(codec, motion, encoded, timing, output_dir,
                                                        clips[0] if example else None,
                                                        worst if keep_worst else None)
                    except TrackRefusal as error:  # the codec cannot carry this rig's tracks: its reason, not a failure
                        refuse(error, motion.name)
                        continue
                    except Exception as error:  # noqa: BLE001 - every failure is recorded and the job goes on
                        fail("evaluate", error, motion.name)
                        continue
                    row.update(extra)
                    row["row_index"] = count
                    append_row(results_path, row)
                    count += 1
                    if new_worst is not None:
                        candidate, worst = new_worst, row["max_err_cm"]
            finally:  # the worst clip of the clips measured, even when a later step failed
                _save_worst(output_dir, candidate)
        status = "done" if errors == 0 else "failed"
    except Exception as error:  # noqa: BLE001
        fail("setup", error)
    end_cpu = time.process_time()
    record = {"status": status, "rows": count, "errors": errors, "seconds": time.perf_counter() - start,
              "cpu_s": end_cpu - start_cpu, "clips": len(clips), "shard": {"index": index, "count": total},
              "pid": os.getpid(), "process_cpu_s": end_cpu}
    tmp = job_path.with_name(f".{JOB_FILE}.tmp-{os.getpid()}")
    tmp.write_text(json.dumps(record))
    os.replace(tmp, job_path)
    return record


#: Frames of the job's warm-up call (:func:`_warm_up`).
WARMUP_FRAMES = 64


def _warm_up(codec: Any, motions: Any):
    """``motions`` unchanged, after one untimed encode and decode of the first ``WARMUP_FRAMES`` frames of the first.

    The first call of a codec in a process pays for lazy imports and compiled kernels loaded from their cache;
    this call pays it once per job, so that the timing of every clip can skip its own warm-up call
    (``timing.warmup: 0``) without the job's first clip carrying it. A failure here is ignored: the clip itself
    reports it.
    """
    import itertools

    from mocapbench.metrics.timing import single_thread

    motions = iter(motions)
    first = next(motions, None)
    if first is None:
        return iter(())
    try:
        with single_thread(1):
            codec.decode(codec.encode(first.slice(0, min(first.num_frames, WARMUP_FRAMES))))
    except Exception:  # noqa: BLE001 - the clip's own encode says what is wrong
        pass
    return itertools.chain([first], motions)


#: Most frames a job encodes in one :meth:`~mocapbench.codecs.base.Codec.encode_many` call (the clips are held
#: together, and a killed job loses the batch in progress).
BATCH_FRAMES = 20_000


def _encode_batches(codec: Any, motions: Any, timing: Any):
    """Yield ``(motion, (stream, stats, Timing) or Exception)`` for ``motions``, encoded in batches of clips.

    For a codec whose :meth:`encode_many` shares work between clips: up to :data:`BATCH_FRAMES` frames are encoded
    in one call, timed once (CPU time of the process and wall time), and each clip's row gets the batch's time in
    proportion to its frames (``encode_repeats`` 1, no warm-up: like a call too slow to repeat).
    """
    from mocapbench.metrics.timing import Timing, load_average, single_thread

    threads = timing.threads if timing is not None else 1
    batch: list[Any] = []

    def flush():
        load_before = load_average()
        cpu, wall = time.process_time(), time.perf_counter()
        with single_thread(threads):
            results = codec.encode_many(batch)
        cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
        load_after = load_average()
        total = sum(m.num_frames for m in batch)
        for motion, (data, stats) in zip(batch, results):
            if isinstance(data, Exception):
                yield motion, data
                continue
            share = motion.num_frames / total
            clip_timing = Timing(wall_s=wall * share, cpu_s=cpu * share, wall_spread_s=0.0, repeats=1, warmup=0,
                                 threads=threads, load_before=load_before, load_after=load_after)
            yield motion, (data, {**stats, "encode_batch_clips": len(batch), "encode_batch_cpu_s": cpu}, clip_timing)

    frames = 0
    for motion in motions:
        if batch and frames + motion.num_frames > BATCH_FRAMES:
            yield from flush()
            batch, frames = [], 0
        batch.append(motion)
        frames += motion.num_frames
    if batch:
        yield from flush()


def _save_example(folder: Path, motion: Any, reference: np.ndarray, decoded: np.ndarray) -> None:
    """Original and decoded positions (float32) of the job's first clip, for the report's pictures."""
    tmp = folder / f".{EXAMPLE_FILE}.tmp-{os.getpid()}.npz"
    np.savez_compressed(
        tmp,
        original=reference.astype(np.float32),
        decoded=decoded.astype(np.float32),
        parents=np.asarray(motion.skeleton.parents),
        names=np.asarray(motion.skeleton.names),
        clip=np.asarray(motion.name),
        fps=np.asarray(motion.fps),
    )
    os.replace(tmp, folder / EXAMPLE_FILE)


def _ensure_sweeper_plugin() -> None:
    """Make the benchmark sweeper importable as ``hydra_plugins.mocapbench_sweeper`` (Hydra's plugin check).

    It is packaged with mocapbench; in a source checkout where the installed package does not carry it, the
    checkout's own ``hydra_plugins/`` folder is used.
    """
    # Only look for it: importing it before Hydra's plugin scan would leave a stale class behind.
    import importlib.util

    try:
        found = importlib.util.find_spec("hydra_plugins.mocapbench_sweeper") is not None
    except ImportError:
        found = False
    if not found:
        sys.path.append(str(Path(__file__).resolve().parents[2]))


@hydra.main(version_base="1.3", config_path="pkg://mocapbench.configs", config_name="benchmark")
def main(cfg: DictConfig) -> float:
    """The Hydra task: one job in ``HydraConfig.get().runtime.output_dir``; returns its rows (NaN if it failed).

    Learned state is shared through ``<sweep dir>/fitted`` in a multirun, ``<job dir>/fitted`` in a single run.
    """
    from hydra.types import RunMode

    from mocapbench.experiments.fitted import FITTED_DIR

    hydra_cfg = HydraConfig.get()
    output_dir = Path(hydra_cfg.runtime.output_dir)
    shared = Path(hydra_cfg.sweep.dir) if hydra_cfg.mode == RunMode.MULTIRUN else output_dir
    record = run_job(cfg, output_dir, shared / FITTED_DIR)
    return math.nan if record["status"] != "done" else float(record["rows"])


if __name__ == "__main__":
    _ensure_sweeper_plugin()
    main()
