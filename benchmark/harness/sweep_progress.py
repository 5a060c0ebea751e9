"""A sweep's one progress line (jobs done of N, houses per second, time left). Standard library
only: the sweep plugin (``hydra_plugins``) imports it whenever any app starts."""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from typing import IO


def duration_words(seconds: float) -> str:
    """``seconds`` in words a reader takes in at a glance: ``45 s``, ``3 min 20 s``, ``1 h 05 min``."""
    s = max(int(round(seconds)), 0)
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60:02d} s"
    return f"{s // 3600} h {s % 3600 // 60:02d} min"


class SweepProgress:
    """One line for a sweep of ``total`` jobs: ``sweep: 12 of 30 jobs done (1 failed), 41.3
    houses/s, about 1 min 05 s left``.

    The time left is the mean time per finished job so far times the jobs left (jobs of one
    sweep are of a similar size; cached jobs make it pessimistic early on). On a terminal the
    line is redrawn in place; elsewhere (a log, CI) it is written when the jobs done pass each
    tenth of the total, so a 624-job sweep writes at most 10 lines.

    Args:
        total: jobs in the sweep.
        stream: where the line goes (stderr).
        clock: seconds, monotonic (tests pass their own).
    """

    def __init__(self, total: int, stream: IO[str] | None = None, clock: Callable[[], float] = time.monotonic,
                 label: str = "sweep") -> None:
        self.total, self.label = int(total), label
        self.stream = sys.stderr if stream is None else stream
        self.clock = clock
        self.t0 = clock()
        self.done = self.failed = self.houses = 0
        isatty = getattr(self.stream, "isatty", None)
        self.tty = bool(callable(isatty) and isatty())
        self._tenth = 0
        self._width = 0

    def line(self) -> str:
        """The progress line as it stands."""
        dt = self.clock() - self.t0
        rate = f"{self.houses / dt:.1f} houses/s" if dt > 0 and self.houses else "– houses/s"
        failed = f" ({self.failed} failed)" if self.failed else ""
        if self.done >= self.total:
            left = f"took {duration_words(dt)}"
        elif self.done:
            left = f"about {duration_words(dt / self.done * (self.total - self.done))} left"
        else:
            left = "time left: after the first job"
        return f"{self.label}: {self.done} of {self.total} jobs done{failed}, {rate}, {left}"

    def update(self, houses: int = 0, failed: bool = False) -> None:
        """One more job finished (``houses`` of them scored; ``failed``: it failed)."""
        self.done += 1
        self.houses += int(houses)
        self.failed += bool(failed)
        if self.tty:
            text = self.line()
            self.stream.write("\r" + text + " " * max(self._width - len(text), 0))
            self._width = len(text)
            self.stream.flush()
            return
        tenth = self.done * 10 // max(self.total, 1)
        if tenth > self._tenth or self.done == self.total:
            self._tenth = tenth
            self.stream.write(self.line() + "\n")
            self.stream.flush()

    def close(self) -> None:
        """End the line (a terminal's redrawn line gets its newline)."""
        if self.tty and self._width:
            self.stream.write("\n")
            self.stream.flush()
            self._width = 0
