"""Processes of a test's subprocess tree, read from ``/proc`` (Linux): who is alive in a
process group, who are a process's children. Zombies (dead, not yet reaped) count as dead."""

from __future__ import annotations

import signal
import sys
import time
from pathlib import Path

import pytest

NEEDS_PROC = pytest.mark.skipif(not sys.platform.startswith("linux") or not Path("/proc/self/stat").exists(),
                                reason="reads processes from /proc (Linux only)")


def _stats() -> list[tuple[int, str, int, int]]:
    """(pid, state, ppid, pgrp) of every process."""
    out = []
    for d in Path("/proc").iterdir():
        if not d.name.isdigit():
            continue
        try:
            text = (d / "stat").read_text()
        except OSError:
            continue
        fields = text.rsplit(")", 1)[1].split()
        out.append((int(d.name), fields[0], int(fields[1]), int(fields[2])))
    return out


def alive_in_group(pgid: int) -> list[int]:
    """Pids of the living (not zombie) processes of process group ``pgid``."""
    return sorted(pid for pid, state, _, grp in _stats() if grp == pgid and state not in "ZXx")


def children(pid: int) -> list[int]:
    """Pids of the living children of ``pid``."""
    return sorted(c for c, state, ppid, _ in _stats() if ppid == pid and state not in "ZXx")


def wait_for(predicate, timeout: float, step: float = 0.02):
    """Poll ``predicate()`` until it returns something truthy (returned) or ``timeout`` s pass (None)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        got = predicate()
        if got:
            return got
        time.sleep(step)
    return None


def gone_within(pgid: int, seconds: float) -> list[int]:
    """The processes of group ``pgid`` still alive after ``seconds`` (polled; [] as soon as none is)."""
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        if not alive_in_group(pgid):
            return []
        time.sleep(0.05)
    return alive_in_group(pgid)


def default_sigint() -> None:
    """A ``preexec_fn`` for a process a test will Ctrl-C (SIGINT): SIGINT's default action in
    it, whatever this process inherited. ``make test`` run as a background job of a
    non-interactive shell starts with SIGINT ignored, a setting every child inherits (Python
    then installs no KeyboardInterrupt handler), so the child would never see the Ctrl-C."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def ignores_sigint(pid: int) -> bool:
    """Whether process ``pid`` ignores SIGINT (its ``SigIgn`` mask in ``/proc/<pid>/status``)."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("SigIgn:"):
            return bool(int(line.split()[1], 16) >> (signal.SIGINT - 1) & 1)
    return False
