"""The order a job runs its houses in: jobs side by side start on different houses
(benchmark.harness.processes.staggered), a house whose entry another process is computing is
put off (benchmark.harness.cache.EntryBusy), and the rows keep the order of the houses
whatever order they ran in."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

import benchmark.harness.cache as cache
from benchmark.harness.cache import EntryBusy, defer_when_busy, locked
from benchmark.harness.executor import SerialExecutor
from benchmark.harness.processes import JOB_SLOT_ENV, job_slot, staggered


@pytest.mark.parametrize("value, want", [("1/2", (1, 2)), ("0/3", (0, 3)), ("", (0, 1)), ("2/2", (0, 1)),
                                         ("-1/2", (0, 1)), ("x/2", (0, 1)), ("1/2/3", (0, 1))])
def test_job_slot_reads_the_variable(monkeypatch, value, want):
    monkeypatch.setenv(JOB_SLOT_ENV, value)
    assert job_slot() == want


def test_staggered_starts_at_the_workers_share(monkeypatch):
    monkeypatch.delenv(JOB_SLOT_ENV, raising=False)
    assert staggered(5) == [0, 1, 2, 3, 4] and staggered(0) == []
    monkeypatch.setenv(JOB_SLOT_ENV, "1/2")
    assert staggered(5) == [2, 3, 4, 0, 1]
    monkeypatch.setenv(JOB_SLOT_ENV, "2/3")
    assert staggered(30)[:2] == [20, 21] and sorted(staggered(30)) == list(range(30))
    assert staggered(1) == [0]


class _Pipe:
    """What run_house asks of a pipeline; records the order houses were run in."""

    force: set = set()
    cache_failures = False

    def __init__(self, busy: set[str] | None = None) -> None:
        self.ran: list[str] = []
        self.busy = set(busy or ())
        self.deferring: list[bool] = []

    def entry(self, stage, hid):
        raise FileNotFoundError(hid)  # no entry yet: nothing served from the cache

    def run_house(self, hid):
        self.deferring.append(cache._DEFER_WHEN_BUSY.get())
        if hid in self.busy and cache._DEFER_WHEN_BUSY.get():
            self.busy.discard(hid)
            raise EntryBusy(f"{hid}.lock")
        self.ran.append(hid)
        return {"house_id": hid, "status": "ok"}

    def contents(self, hid):
        return {"score": f"c-{hid}"}

    def built(self):
        return []


def test_serial_executor_runs_staggered_and_returns_in_order(monkeypatch):
    ids = [f"h{i}" for i in range(7)]
    monkeypatch.setenv(JOB_SLOT_ENV, "1/2")
    pipe = _Pipe()
    out = SerialExecutor(pipe).map(None, ids)
    assert pipe.ran == ["h3", "h4", "h5", "h6", "h0", "h1", "h2"]
    assert [r.row["house_id"] for r in out] == ids and [r.content for r in out] == [f"c-{h}" for h in ids]
    monkeypatch.delenv(JOB_SLOT_ENV)
    pipe = _Pipe()
    assert [r.row["house_id"] for r in SerialExecutor(pipe).map(None, ids)] == ids and pipe.ran == ids


def test_a_busy_lock_raises_only_when_asked(tmp_path):
    """Another holder of the lock (here a second open file of this process: flock locks are per
    open file) makes locked() raise EntryBusy inside defer_when_busy, and wait otherwise."""
    p = tmp_path / "entry.npz"
    with locked(p):
        with defer_when_busy(), pytest.raises(EntryBusy):
            with locked(p):
                pass
        with defer_when_busy(False), pytest.raises(TimeoutError):
            with locked(p, timeout=0.2):
                pass
        with pytest.raises(TimeoutError):
            with locked(p, timeout=0.2):
                pass
    with defer_when_busy(), locked(p):  # free: taken at once
        pass
    assert not (tmp_path / "entry.npz.lock").exists()


def test_a_busy_house_runs_after_the_others_and_waits_then(monkeypatch):
    monkeypatch.delenv(JOB_SLOT_ENV, raising=False)
    ids = [f"h{i}" for i in range(5)]
    pipe = _Pipe(busy={"h1", "h4"})
    out = SerialExecutor(pipe).map(None, ids)
    # h1 put off; h4, the last, is not (nothing else to run meanwhile): it waits
    assert pipe.ran == ["h0", "h2", "h3", "h4", "h1"]
    assert pipe.deferring == [True, True, True, True, False, False]
    assert [r.row["house_id"] for r in out] == ids
    seen = []
    out = SerialExecutor(_Pipe(busy={"h0"})).map(None, ids, progress=lambda it, total: (seen.append(total), it)[1])
    assert seen == [5] and [r.row["house_id"] for r in out] == ids


def test_two_runs_on_one_cache_at_once_give_the_rows_of_one_run(tmp_path):
    """Two processes computing the same houses into one cache (two runs, one cache folder): each
    puts off the houses the other is computing, and both write the rows a run alone writes."""
    root = Path(__file__).resolve().parents[1]
    args = ["env=synthetic", "env.n_houses=8", "classifier=oracle", "aggregator=vision_cone", "run.progress=false",
            f"run.cache_dir={tmp_path / 'cache'}"]
    env = {**os.environ, "PYTHONPATH": str(root)}
    procs = [subprocess.Popen([sys.executable, "-m", "benchmark.commands.bench", *args, f"run.results_dir={tmp_path / n}",
                               "run.name=r"], cwd=root, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
             for n in ("a", "b")]
    for p in procs:
        assert p.wait(timeout=600) == 0, p.stderr.read()[-2000:]
    alone = subprocess.run([sys.executable, "-m", "benchmark.commands.bench", *args[:-1],
                            f"run.cache_dir={tmp_path / 'cache2'}", f"run.results_dir={tmp_path / 'c'}", "run.name=r"],
                           cwd=root, env=env, capture_output=True, text=True, timeout=600)
    assert alone.returncode == 0, alone.stderr[-2000:]
    import pandas as pd

    drop = ["seconds", "cached", "worker"]
    rows = [pd.read_csv(tmp_path / n / "runs" / "r" / "metrics.csv") for n in ("a", "b", "c")]
    rows = [r.drop(columns=[c for c in r.columns if c in drop or c.startswith("t_")]) for r in rows]
    assert len(rows[0]) == 8
    pd.testing.assert_frame_equal(rows[0], rows[2])
    pd.testing.assert_frame_equal(rows[1], rows[2])
