"""Houses in parallel within a run (``run.workers``): rows byte-identical to one worker, one
pool per sweep, and worker processes that never outlive their parent (kill -9), stop at
once on Ctrl-C, and end the run with one line when one of them is killed."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest
from procs import NEEDS_PROC, alive_in_group, children, gone_within, wait_for

ROOT = Path(__file__).resolve().parents[1]
ENV = {**os.environ, "PYTHONPATH": str(ROOT)}
#: a run long enough to be caught with its workers busy: generated houses, one configuration
SLOW_RUN = ["env=synthetic", "env.n_houses=60", "classifier=oracle", "aggregator=vision_cone", "postprocess=default",
            "run.progress=false"]


def _bench(tmp_path: Path, *args: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "benchmark.commands.bench", *args,
                             f"run.results_dir={tmp_path / 'results'}"], cwd=ROOT, env=ENV,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, start_new_session=True)


def _kill_parent_when_busy(p: subprocess.Popen, n_children: int) -> None:
    """Wait until ``p`` has its worker processes (and they have scored a house), then kill -9 it."""
    got = wait_for(lambda: len(children(p.pid)) >= n_children, timeout=120)
    if not got:
        p.kill()
        _, err = p.communicate(timeout=30)
        pytest.fail(f"the workers never appeared (exit {p.returncode}): {err[-1500:]}")
    os.kill(p.pid, signal.SIGKILL)
    p.wait(timeout=30)


@NEEDS_PROC
@pytest.mark.slow
@pytest.mark.parametrize("mode", ["run", "multirun"])
def test_kill9_of_the_parent_leaves_no_worker(tmp_path, mode):
    """kill -9 of a run (or a multirun: its shared pool) with 2 house workers: no process of
    it is alive 5 s later (the workers die with their parent; issue #24)."""
    args = ["-m", "aggregator=vision_cone,graph_knn"] if mode == "multirun" else []
    p = _bench(tmp_path, *args, *SLOW_RUN, "run.workers=2")
    _kill_parent_when_busy(p, 2)
    assert gone_within(p.pid, 5.0) == []


@NEEDS_PROC
@pytest.mark.slow
def test_kill9_of_figures_leaves_no_drawing_process(tmp_path):
    """The drawing processes of ``figures from-run`` (its pool, busy with long tasks) die with it."""
    code = ("import functools, time\nfrom benchmark.reports.figures import _draw\n"
            "_draw([functools.partial(time.sleep, 60)] * 4, 2)\n")
    p = subprocess.Popen([sys.executable, "-c", code], cwd=ROOT, env=ENV, stdout=subprocess.DEVNULL,
                         stderr=subprocess.PIPE, text=True, start_new_session=True)
    _kill_parent_when_busy(p, 2)
    assert gone_within(p.pid, 5.0) == []
