"""Progress of a running sweep (one line per finished job, with an ETA) and its end-of-sweep summary.

The launcher (joblib, submitit) runs jobs in other processes and returns only when a whole batch is done, so the
sweeper watches the job folders instead: every job writes ``job.json`` (``status``: ``done`` or ``failed``) when it
ends (:mod:`mocapbench.experiments.run`). :class:`JobMonitor` polls the folders of the jobs it was given and prints
``[k/N] codec/overrides done in 12 s; elapsed 3 min, ETA 9 min`` as each one appears; :func:`summarize` reads them
all at the end and :func:`format_summary` prints jobs done, failed (grouped by the first line of their errors) and
time. Works with any launcher whose jobs write to the sweep folder.
"""

from __future__ import annotations

import json
import threading
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Mapping, Sequence

__all__ = ["JobMonitor", "SweepSummary", "summarize", "format_summary", "format_duration"]

JOB_FILE = "job.json"
ERRORS_FILE = "errors.jsonl"


def format_duration(seconds: float) -> str:
    """``42 s``, ``3.5 min``, ``1.2 h``."""
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 5400:
        return f"{seconds / 60:.1f} min"
    return f"{seconds / 3600:.1f} h"


def _job_record(folder: Path) -> dict | None:
    try:
        record = json.loads((folder / JOB_FILE).read_text())
    except (OSError, ValueError):
        return None
    return record if isinstance(record, dict) and record.get("status") else None


def _first_errors(folder: Path) -> list[str]:
    """First line of every error recorded in the job's ``errors.jsonl``."""
    out = []
    try:
        lines = (folder / ERRORS_FILE).read_text().splitlines()
    except OSError:
        return out
    for line in lines:
        try:
            record = json.loads(line)
        except ValueError:
            continue
        out.append(str(record.get("error", "unknown error")).split("\n")[0][:200])
    return out


class JobMonitor:
    """Prints a line when each job of ``folders`` (relative to ``root``) finishes; a background thread.

    Parameters
    ----------
    root : Path
        The sweep folder.
    folders : list of str
        Job folders to watch (those launched now).
    emit : callable
        Where lines go (default: ``print`` with flush).
    interval_s : float
        Polling period.
    estimates : mapping of str to float, optional
        Each job's estimated CPU s (:func:`mocapbench.experiments.cost.job_costs`). With them the ETA is the
        longest-first schedule of the pending jobs' estimates on ``workers``, scaled by how the finished jobs'
        wall times compared with their estimates; without them, the mean time per finished job.
    workers : int
        Jobs that run at once.
    """

    def __init__(self, root: Path, folders: Sequence[str], emit: Callable[[str], None] | None = None,
                 interval_s: float = 2.0, estimates: Mapping[str, float] | None = None, workers: int = 1) -> None:
        self.estimates = dict(estimates or {})
        self.workers = max(1, int(workers))
        self._actual_s = 0.0
        self._estimated_s = 0.0
        self.root = Path(root)
        self.pending = list(folders)
        self.total = len(self.pending)
        self.finished: list[str] = []
        self.emit = emit or (lambda line: print(line, flush=True))
        self.interval_s = interval_s
        self.start = time.perf_counter()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="sweep-progress", daemon=True)

    def __enter__(self) -> "JobMonitor":
        self.start = time.perf_counter()
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        self._thread.join()
        self.poll()  # the jobs that ended after the last poll

    def _run(self) -> None:
        while not self._stop.wait(self.interval_s):
            self.poll()

    def poll(self) -> None:
        """Report every job of the watch list that has finished since the last call."""
        for folder in list(self.pending):
            record = _job_record(self.root / folder)
            if record is None:
                continue
            self.pending.remove(folder)
            self.finished.append(folder)
            elapsed = time.perf_counter() - self.start
            done = len(self.finished)
            status = record.get("status")
            took = record.get("seconds")
            took_text = f" in {format_duration(float(took))}" if isinstance(took, (int, float)) else ""
            estimated = self.estimates.get(folder)
            if estimated and isinstance(took, (int, float)):
                took_text += f" (estimated {format_duration(estimated)})"
                self._actual_s += float(took)
                self._estimated_s += estimated
            eta = self.eta(elapsed, done)
            errors = f", {record.get('errors')} error(s)" if record.get("errors") else ""
            self.emit(f"[{done}/{self.total}] {folder} {status}{took_text}{errors}; elapsed "
                      f"{format_duration(elapsed)}, ETA {format_duration(eta) if done < self.total else 'done'}")


    def eta(self, elapsed: float, done: int) -> float:
        """Seconds until the last pending job ends (see the ``estimates`` parameter)."""
        from mocapbench.experiments.cost import makespan

        pending = [self.estimates.get(folder) for folder in self.pending]
        if self._estimated_s > 0 and pending and all(p is not None for p in pending):
            return makespan(pending, self.workers) * self._actual_s / self._estimated_s
        return elapsed / max(1, done) * (self.total - done)


@dataclass
class SweepSummary:
    """Outcome of a sweep: finished, failed (with their grouped reasons), skipped, missing; wall time."""

    done: list[str] = field(default_factory=list)
    failed: list[str] = field(default_factory=list)
    missing: list[str] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)
    reasons: Counter = field(default_factory=Counter)
    seconds: float = 0.0

    @property
    def ok(self) -> bool:
        return not self.failed and not self.missing


def summarize(root: Path, launched: Sequence[str], skipped: Sequence[str] = (), seconds: float = 0.0) -> SweepSummary:
    """Read the ``job.json`` and ``errors.jsonl`` of every launched job folder below ``root``."""
    summary = SweepSummary(skipped=list(skipped), seconds=seconds)
    for folder in launched:
        record = _job_record(Path(root) / folder)
        if record is None:
            summary.missing.append(folder)
            summary.reasons["no job.json: the job crashed or was killed before it ended"] += 1
        elif record.get("status") == "done":
            summary.done.append(folder)
        else:
            summary.failed.append(folder)
            errors = _first_errors(Path(root) / folder) or ["failed without an error record"]
            for reason in sorted(set(errors)):
                summary.reasons[reason] += 1
    return summary


def format_summary(summary: SweepSummary, allow_failures: bool = False, limit: int = 10) -> str:
    """The end-of-sweep lines: counts, grouped failure reasons (most frequent first), time, exit consequence."""
    bad = len(summary.failed) + len(summary.missing)
    total = len(summary.done) + bad
    lines = [f"sweep finished in {format_duration(summary.seconds)}: {len(summary.done)}/{total} jobs done, "
             f"{len(summary.failed)} failed, {len(summary.missing)} without a result"
             + (f", {len(summary.skipped)} skipped (already done)" if summary.skipped else "")]
    if bad:
        lines.append("failures by reason (jobs):")
        for reason, count in summary.reasons.most_common(limit):
            lines.append(f"  {count:>4}  {reason}")
        if len(summary.reasons) > limit:
            others = len(summary.reasons) - limit
            lines.append(f"  ... and {others} other reason(s); see errors.jsonl in the job folders")
        examples = (summary.failed + summary.missing)[:3]
        lines.append("  e.g. " + ", ".join(examples))
        lines.append("exit status 0 (--allow-failures)" if allow_failures
                     else "exit status 1: a job failed (pass --allow-failures, or hydra.sweeper.allow_failures=true, "
                          "to accept it)")
    return "\n".join(lines)
