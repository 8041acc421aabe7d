"""Hydra entry point: one job = one codec config over one dataset, rows to ``results.jsonl`` in the job's folder.

Usage::

    python -m mocapbench.experiments.run                                    # default codec on synthetic clips
    python -m mocapbench.experiments.run -m sweep=rd_quant-delta-zstd       # one codec's RD curve
    python -m mocapbench.experiments.run -m sweep=all dataset=cmu_test      # every codec's curve on CMU
    python -m mocapbench.experiments.run -m sweep=all hydra.sweep.dir=multirun/mine   # re-run resumes

A job fits the codec on the dataset's training set (``fit``), then encodes and decodes every clip with
:func:`mocapbench.experiments.evaluate.evaluate`. After each clip it rewrites ``results.jsonl`` atomically
(temporary file + ``os.replace``), so a killed job loses at most the clip in progress; a re-run skips clips
already in the file, and a finished job leaves ``job.json`` with ``"status": "done"`` so the sweeper does not
launch it again. A clip that fails is logged (clip, codec, config, error) to the log and ``errors.jsonl``; the job
goes on with the next clip and the sweep with the next job.
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

__all__ = ["main", "run_job", "read_rows", "write_rows_atomic", "RESULTS_FILE", "ERRORS_FILE", "EXAMPLE_FILE"]

log = logging.getLogger(__name__)

RESULTS_FILE = "results.jsonl"
ERRORS_FILE = "errors.jsonl"
EXAMPLE_FILE = "example.npz"


def _builtin(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    return str(value)


def read_rows(path: Path) -> list[dict[str, Any]]:
    """Rows of a ``results.jsonl`` (empty list if absent). A torn last line (impossible with atomic writes,
    possible in a file edited by hand) is reported and dropped."""
    if not path.exists():
        return []
    rows = []
    for number, line in enumerate(path.read_text().splitlines(), 1):
        if not line.strip():
            continue
        try:
            rows.append(json.loads(line))
        except json.JSONDecodeError as error:
            log.error("%s:%d: unreadable results line dropped (%s)", path, number, error)
    return rows


def write_rows_atomic(path: Path, rows: list[dict[str, Any]]) -> None:
    """Write ``rows`` as JSON lines to ``path`` through a temporary file and ``os.replace`` (atomic on POSIX)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    with open(tmp, "w") as handle:
        for row in rows:
            handle.write(json.dumps(row, default=_builtin) + "\n")
        handle.flush()
        os.fsync(handle.fileno())
    os.replace(tmp, path)


def _append_error(folder: Path, record: dict[str, Any]) -> None:
    errors = read_rows(folder / ERRORS_FILE)
    errors.append(record)
    write_rows_atomic(folder / ERRORS_FILE, errors)


def _set_threads(threads: int | None) -> None:
    """Keep each job to ``threads`` BLAS/torch threads so that parallel jobs do not oversubscribe the cores."""
    if not threads:
        return
    from threadpoolctl import threadpool_limits

    if "torch" in sys.modules:
        sys.modules["torch"].set_num_threads(int(threads))
    threadpool_limits(int(threads))


def run_job(cfg: Any, output_dir: Path) -> dict[str, Any]:
    """Run one benchmark job; every failure is caught, logged and recorded.

    Parameters
    ----------
    cfg : DictConfig
        The composed ``benchmark`` config (``codec``, ``dataset``, ``threads_per_job``, ``save_example``).
    output_dir : Path
        The job's folder: ``results.jsonl``, ``errors.jsonl``, ``example.npz`` and ``job.json`` go there.

    Returns
    -------
    dict
        The ``job.json`` record: ``status`` (``done`` or ``failed``), ``rows``, ``errors``, ``seconds``.
    """
    from hydra.utils import instantiate
    from omegaconf import OmegaConf
    from tqdm import tqdm

    from mocapbench.experiments import datasets
    from mocapbench.experiments.evaluate import evaluate
    from mocapbench.experiments.sweeper import JOB_FILE

    start = time.perf_counter()
    output_dir = Path(output_dir)
    output_dir.mkdir(parents=True, exist_ok=True)
    _set_threads(cfg.get("threads_per_job"))
    results_path = output_dir / RESULTS_FILE
    rows = read_rows(results_path)
    done = {row.get("clip") for row in rows}
    codec_cfg = OmegaConf.to_container(cfg.codec, resolve=True)
    dataset_cfg = OmegaConf.to_container(cfg.dataset, resolve=True)
    context = {"codec": codec_cfg.get("name"), "config": {k: v for k, v in codec_cfg.items() if not k.startswith("_")}}
    errors = 0

    def fail(stage: str, error: BaseException, clip: str | None = None) -> None:
        nonlocal errors
        errors += 1
        record = {**context, "clip": clip, "stage": stage, "error": f"{type(error).__name__}: {error}",
                  "traceback": traceback.format_exc(limit=8)}
        log.error("job failed at %s: codec=%s clip=%s config=%s error=%s", stage, context["codec"], clip,
                  context["config"], record["error"])
        _append_error(output_dir, record)

    status = "failed"
    try:
        motions = datasets.load_clips(dataset_cfg)
        todo = [motion for motion in motions if motion.name not in done]
        if todo:
            codec = instantiate(cfg.codec)
            fit_start = time.perf_counter()
            codec.fit(datasets.load_training(dataset_cfg))
            fit_s = time.perf_counter() - fit_start
            extra = {
                "dataset": dataset_cfg.get("name"),
                "dataset_desc": datasets.describe_dataset(dataset_cfg),
                "train_set": datasets.describe_training(dataset_cfg),
                "cmu_data": datasets.cmu_used(dataset_cfg),
                "fit_s": fit_s,
                "job_dir": str(output_dir),
            }
            example = cfg.get("save_example", True) and not (output_dir / EXAMPLE_FILE).exists()
            for motion in tqdm(todo, desc=f"{codec.name} clips", unit="clip", leave=False, disable=None):
                try:
                    reference = motion.positions()
                    row = evaluate(codec, motion, reference_positions=reference)
                    if example and motion is motions[0]:
                        _save_example(output_dir, codec, motion, reference)
                except Exception as error:  # noqa: BLE001 - every failure is recorded and the job goes on
                    fail("evaluate", error, motion.name)
                    continue
                row.update(extra)
                row["row_index"] = len(rows)
                rows.append(row)
                write_rows_atomic(results_path, rows)
        status = "done" if errors == 0 else "failed"
    except Exception as error:  # noqa: BLE001
        fail("setup", error)
    record = {"status": status, "rows": len(rows), "errors": errors, "seconds": time.perf_counter() - start}
    (output_dir / JOB_FILE).write_text(json.dumps(record))
    return record


def _save_example(folder: Path, codec: Any, motion: Any, reference: np.ndarray) -> None:
    """Original and decoded positions of the job's first clip (float32), for the report's pictures."""
    decoded = codec.decode(codec.encode(motion)).positions
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
    """The Hydra task: one job in ``HydraConfig.get().runtime.output_dir``; returns its rows (NaN if it failed)."""
    record = run_job(cfg, Path(HydraConfig.get().runtime.output_dir))
    return math.nan if record["status"] != "done" else float(record["rows"])


if __name__ == "__main__":
    _ensure_sweeper_plugin()
    main()
