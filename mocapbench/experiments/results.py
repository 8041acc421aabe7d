"""``results.jsonl`` and ``errors.jsonl``: one JSON object per line, appended, never rewritten; corrupt lines found.

A job (a shard: one codec config over a list of clips) appends one row per finished clip with a single
``write`` on a file opened with ``O_APPEND``: earlier rows are never rewritten, so the cost per row is constant
(the file is not copied and fsynced after every clip). A killed job leaves at most one torn last line.

A line that does not parse is never dropped silently:

- :func:`read_rows` (what aggregation and the report use) raises :class:`CorruptResultsError` naming the file
  and the line;
- :func:`scan_rows` returns the good rows and the numbers of the bad lines; :func:`repair` (what a resumed job
  runs) moves the damaged file aside to ``results.jsonl.corrupt-<n>`` and writes its good rows back, so the job
  re-runs exactly the clips whose rows are missing;
- :func:`is_intact` tells the sweeper that a job whose ``job.json`` says done is unfinished after all.
"""

from __future__ import annotations

import json
import logging
import os
from pathlib import Path
from typing import Any

import numpy as np

__all__ = [
    "RESULTS_FILE",
    "ERRORS_FILE",
    "CorruptResultsError",
    "append_row",
    "read_rows",
    "scan_rows",
    "is_intact",
    "repair",
    "write_rows_atomic",
]

log = logging.getLogger(__name__)

RESULTS_FILE = "results.jsonl"
ERRORS_FILE = "errors.jsonl"


class CorruptResultsError(ValueError):
    """A line of a results file does not parse; the message names the file and the line."""

    def __init__(self, path: Path, line: int, reason: str) -> None:
        super().__init__(
            f"{path}:{line}: results line does not parse ({reason}); re-run the sweep with the same "
            f"hydra.sweep.dir to redo that job's missing clips"
        )
        self.path = path
        self.line = line


def _builtin(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    return str(value)


def _encode(row: dict[str, Any]) -> bytes:
    text = json.dumps(row, default=_builtin)
    return (text + "\n").encode()


def append_row(path: Path, row: dict[str, Any]) -> None:
    """Append ``row`` as one JSON line to ``path`` (created if absent) with one ``write`` on an ``O_APPEND`` file.

    The line is flushed to the kernel before returning, so a killed process keeps it; a machine crash may lose
    or tear the last line, which :func:`scan_rows` then reports.
    """
    path.parent.mkdir(parents=True, exist_ok=True)
    data = _encode(row)
    fd = os.open(path, os.O_RDWR | os.O_APPEND | os.O_CREAT, 0o644)
    try:
        # A file whose last line is torn (no newline) would glue the new row onto it: start a new line instead.
        size = os.fstat(fd).st_size
        if size and os.pread(fd, 1, size - 1) != b"\n":
            data = b"\n" + data
        written = 0
        while written < len(data):
            written += os.write(fd, data[written:])
    finally:
        os.close(fd)


def scan_rows(path: Path) -> tuple[list[dict[str, Any]], list[tuple[int, str]]]:
    """``(rows, bad)``: the rows that parse and ``(line number, reason)`` of every line that does not.

    A missing file is ``([], [])``; blank lines are ignored. A line that parses to something other than a JSON
    object counts as bad.
    """
    if not path.exists():
        return [], []
    rows: list[dict[str, Any]] = []
    bad: list[tuple[int, str]] = []
    with open(path, "rb") as handle:
        for number, raw in enumerate(handle, 1):
            if not raw.strip():
                continue
            try:
                row = json.loads(raw)
            except (json.JSONDecodeError, UnicodeDecodeError) as error:
                bad.append((number, str(error)))
                continue
            if not isinstance(row, dict):
                bad.append((number, f"expected a JSON object, got {type(row).__name__}"))
                continue
            rows.append(row)
    return rows, bad


def read_rows(path: Path) -> list[dict[str, Any]]:
    """Every row of a results file (empty list if absent).

    Raises
    ------
    CorruptResultsError
        At the first line that does not parse (file and line in the message).
    """
    path = Path(path)
    rows, bad = scan_rows(path)
    if bad:
        raise CorruptResultsError(path, *bad[0])
    return rows


def is_intact(path: Path) -> bool:
    """Whether every line of ``path`` parses (a missing file is intact)."""
    return not scan_rows(Path(path))[1]


def repair(path: Path) -> list[dict[str, Any]]:
    """The good rows of ``path``; if some line is bad, move the file aside and write the good rows back.

    The damaged file is kept as ``<name>.corrupt-<n>`` (evidence), and the error names every bad line.
    """
    path = Path(path)
    rows, bad = scan_rows(path)
    if bad:
        number = 1
        while path.with_name(f"{path.name}.corrupt-{number}").exists():
            number += 1
        aside = path.with_name(f"{path.name}.corrupt-{number}")
        os.replace(path, aside)
        write_rows_atomic(path, rows)
        lines = ", ".join(f"{line} ({reason})" for line, reason in bad)
        log.warning("%s: lines that do not parse: %s; kept as %s, %d good rows written back, the missing "
                    "clips run again", path, lines, aside.name, len(rows))
    return rows


def write_rows_atomic(path: Path, rows: list[dict[str, Any]]) -> None:
    """Write ``rows`` as JSON lines to ``path`` through a temporary file and ``os.replace`` (atomic on POSIX)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    with open(tmp, "wb") as handle:
        for row in rows:
            handle.write(_encode(row))
        handle.flush()
        os.fsync(handle.fileno())
    os.replace(tmp, path)
