"""Jobs side by side start on different houses (benchmark.harness.processes.staggered), and a
job's rows keep the order of its houses whatever order it ran them in."""

from __future__ import annotations

import pytest

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

    def __init__(self) -> None:
        self.ran: list[str] = []

    def entry(self, stage, hid):
        raise FileNotFoundError(hid)  # no entry yet: nothing served from the cache

    def run_house(self, hid):
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
