"""What ``mocapbench compare`` tells while it runs: each clip of each codec, each rate-search try, the time left.

On a terminal, one tqdm bar over every (codec, clip) pair, its text naming the codec, the clip and the try of
the rate search under way, with tqdm's estimate of the time left. Elsewhere (a log, a pipe), one line per finished
clip with the same facts. The time left is the average time of the clips measured so far in this run (a resumed
clip costs nothing and does not count) times the clips left, over the codecs run at once; it is an estimate: codecs
differ in cost. Codecs run side by side (``compare --workers``) each keep their own clip's start and tries.
"""

from __future__ import annotations

import sys
import time
from typing import TextIO

__all__ = ["Progress", "duration_text"]


def duration_text(seconds: float) -> str:
    """``"45 s"``, ``"3 min 5 s"``, ``"1 h 02 min"``."""
    seconds = max(0.0, float(seconds))
    if seconds < 60:
        return f"{seconds:.0f} s"
    if seconds < 3600:
        return f"{int(seconds // 60)} min {int(seconds % 60)} s"
    return f"{int(seconds // 3600)} h {int(seconds % 3600 // 60):02d} min"


class Progress:
    """Progress of a comparison of ``codecs`` codecs on ``clips`` clips (the ``progress`` of ``compare``).

    Parameters
    ----------
    total : int
        (codec, clip) pairs to go through.
    stream : file, optional
        Default stderr.
    bar : bool, optional
        A tqdm bar (default: when ``stream`` is a terminal), else one line per clip.
    workers : int, optional
        Codecs measured at once (the time left is divided among them); default 1.
    """

    def __init__(self, total: int, stream: TextIO | None = None, bar: bool | None = None, workers: int = 1) -> None:
        self.stream = stream or sys.stderr
        self.total = int(total)
        self.workers = max(1, int(workers))
        self.finished = 0
        self.measured = 0
        self.measured_s = 0.0
        self._done: dict[str, int] = {}
        self._tries: dict[str, int] = {}
        self._clip_start: dict[str, float] = {}
        self._last = ""
        self._what = ""
        use_bar = bar if bar is not None else bool(getattr(self.stream, "isatty", lambda: False)())
        self._bar = None
        if use_bar:
            from tqdm import tqdm

            self._bar = tqdm(total=self.total, file=self.stream, unit="clip", dynamic_ncols=True, leave=False)

    def done_in(self, codec: str) -> int:
        """Clips of ``codec`` finished (measured, resumed or skipped) so far."""
        return self._done.get(codec, 0)

    def left_s(self) -> float | None:
        """Seconds left: the mean time of a measured clip times the clips left (None before the first)."""
        if not self.measured:
            return None
        return self.measured_s / self.measured * (self.total - self.finished) / self.workers

    def clip_start(self, codec: str, clip: str) -> None:
        self._tries[codec] = 0
        self._clip_start[codec] = time.perf_counter()
        self._last = codec
        self._what = f"{codec} on {clip}"
        if self._bar is not None:
            self._bar.set_description_str(self._what)

    def try_started(self, codec: str | None = None) -> None:
        """A rate-search try of ``codec`` (default: the codec last started) begins: an encode and decode of one
        setting."""
        codec = codec or self._last
        self._tries[codec] = self._tries.get(codec, 0) + 1
        if self._bar is not None:
            self._bar.set_postfix_str(f"{codec} try {self._tries[codec]}")

    def _advance(self, codec: str, clips: int) -> None:
        self._done[codec] = self._done.get(codec, 0) + clips
        self.finished += clips
        if self._bar is not None:
            self._bar.update(clips)

    def clip_done(self, codec: str, clip: str, resumed: bool = False) -> None:
        """A clip is measured (or taken from an earlier run: ``resumed``)."""
        seconds = 0.0
        if not resumed:
            seconds = time.perf_counter() - self._clip_start.get(codec, time.perf_counter())
            self.measured += 1
            self.measured_s += seconds
        self._advance(codec, 1)
        if self._bar is None:
            left = self.left_s()
            tries = self._tries.get(codec, 0)
            what = "kept from the last run" if resumed else f"{tries} tries, {duration_text(seconds)}"
            tail = f"; about {duration_text(left)} left" if left is not None and self.finished < self.total else ""
            print(f"[{self.finished}/{self.total}] {codec} on {clip}: {what}{tail}", file=self.stream, flush=True)

    def skip(self, codec: str, clips: int) -> None:
        """``clips`` clips of ``codec`` will not be measured (the codec failed or its failure is known)."""
        if clips > 0:
            self._advance(codec, clips)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
