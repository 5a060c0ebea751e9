"""The cache's inter-process lock (issue 39, item 8): mutual exclusion holds across processes,
and no empty ``.lock`` file is left behind once every holder is done (a cache had 5,738 of
them, and ``*.claim.lock`` files piled up in ``results/runs``)."""

from __future__ import annotations

import multiprocessing as mp
import os
import signal
from pathlib import Path

import pytest

from benchmark.harness.cache import locked


def _add(path: str, n: int) -> None:
    p = Path(path)
    for _ in range(n):
        with locked(p):
            v = int(p.read_text()) if p.exists() else 0
            tmp = p.with_suffix(".tmp" + str(os.getpid()))
            tmp.write_text(str(v + 1))  # read, then write: a lost update shows without the lock
            os.replace(tmp, p)


def test_processes_take_turns_and_leave_no_lock_file(tmp_path):
    counter = tmp_path / "sub" / "counter.txt"
    ctx = mp.get_context("fork")
    procs = [ctx.Process(target=_add, args=(str(counter), 150)) for _ in range(4)]
    for p in procs:
        p.start()
    for p in procs:
        p.join(60)
    assert [p.exitcode for p in procs] == [0] * 4
    assert int(counter.read_text()) == 600
    assert sorted(f.name for f in counter.parent.iterdir()) == ["counter.txt"]


def _hold(path: str, ready) -> None:
    with locked(Path(path)):
        ready.set()
        signal.pause()


def test_a_killed_holder_releases_and_a_timeout_is_one_line(tmp_path):
    entry = tmp_path / "entry.json"
    ctx = mp.get_context("fork")
    ready = ctx.Event()
    p = ctx.Process(target=_hold, args=(str(entry), ready))
    p.start()
    assert ready.wait(30)
    with pytest.raises(TimeoutError, match="entry.json.lock: held by another process"):
        with locked(entry, timeout=0.2):
            pass
    p.kill()
    p.join(30)
    assert (tmp_path / "entry.json.lock").exists()  # a killed holder leaves its file
    with locked(entry, timeout=5):  # taken over
        pass
    assert not (tmp_path / "entry.json.lock").exists()  # and removed by the next holder
