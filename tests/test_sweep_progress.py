"""One progress line for a sweep (issue 39, item 6): jobs done of the total, houses per second
and the time left, redrawn on a terminal and written at each tenth of the jobs elsewhere; the
jobs' own lines go to their log files, not the console."""

from __future__ import annotations

import io
import subprocess
import sys
from pathlib import Path

import pytest

from benchmark.harness.sweep_progress import SweepProgress, duration_words

ROOT = Path(__file__).resolve().parents[1]


class Clock:
    def __init__(self):
        self.t = 100.0

    def __call__(self):
        return self.t


class Tty(io.StringIO):
    def isatty(self):
        return True


def test_duration_words():
    assert [duration_words(s) for s in (0.4, 45, 200, 3725)] == ["0 s", "45 s", "3 min 20 s", "1 h 02 min"]


def test_a_long_sweep_writes_ten_lines_with_known_rates_and_time_left():
    out, clock = io.StringIO(), Clock()
    p = SweepProgress(624, stream=out, clock=clock)
    for k in range(624):
        clock.t += 0.5  # every job: 0.5 s and 20 houses
        p.update(houses=20, failed=(k == 3))
    p.close()
    lines = out.getvalue().splitlines()
    assert len(lines) == 10
    assert lines[0] == "sweep: 63 of 624 jobs done (1 failed), 40.0 houses/s, about 4 min 40 s left"  # 561 x 0.5 s
    assert lines[-1] == "sweep: 624 of 624 jobs done (1 failed), 40.0 houses/s, took 5 min 12 s"


def test_on_a_terminal_the_line_is_redrawn_in_place():
    out, clock = Tty(), Clock()
    p = SweepProgress(3, stream=out, clock=clock)
    for _ in range(3):
        clock.t += 2.0
        p.update(houses=4)
    p.close()
    text = out.getvalue()
    assert text.count("\r") == 3 and text.endswith("\n") and text.rstrip(" \n").endswith("took 6 s")
    assert text.count("\n") == 1
    assert "\rsweep: 1 of 3 jobs done, 2.0 houses/s, about 4 s left" in text


@pytest.mark.slow
def test_a_sweep_prints_its_progress_and_keeps_job_lines_in_their_logs(tmp_path):
    r = subprocess.run([sys.executable, "-m", "benchmark.commands.bench", "-m", "env=synthetic", "env.resolution=0.1",
                        "classifier=oracle", "aggregator=graph_knn,vision_cone", "run.limit=2", "run.name=p",
                        f"run.results_dir={tmp_path}", "run.workers=1"], cwd=ROOT, capture_output=True, text=True,
                       timeout=600)
    assert r.returncode == 0, r.stderr
    console = r.stdout + r.stderr
    assert "sweep: 2 of 2 jobs done" in r.stderr and "houses/s, took " in r.stderr
    assert "#0 : " not in console and "[INFO]" not in console and "mean IoU" not in console
    run = tmp_path / "runs" / "p"
    assert "#1 : " in (run / "sweep.log").read_text()
    logs = sorted(run.glob("*/bench.log"))
    assert len(logs) == 2 and all("2 houses, 2 ok, 0 failed; mean IoU" in f.read_text() for f in logs)


@pytest.mark.slow
def test_a_warning_repeated_by_every_job_shows_once_and_stays_whole_in_the_logs(tmp_path):
    """A pose error pushes views off the map in every house of every job: the console shows that
    warning once per worker process; each job's bench.log keeps every one of its own."""
    r = subprocess.run([sys.executable, "-m", "benchmark.commands.bench", "-m", "env=synthetic", "env.resolution=0.1",
                        "classifier=oracle", "aggregator=graph_knn,vision_cone", "corruption=pose_5", "run.limit=3",
                        "run.name=w", f"run.results_dir={tmp_path}", "run.workers=1"], cwd=ROOT, capture_output=True,
                       text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    console = r.stdout + r.stderr
    message = "viewpoints are off the walkable map and were dropped"
    logs = sorted((tmp_path / "runs" / "w").glob("*/bench.log"))
    in_logs = [sum(message in line for line in f.read_text().splitlines()) for f in logs]
    assert len(logs) == 2 and sum(in_logs) >= 3, in_logs  # the condition does drop views (known: pose_5 at 0.1 m/px)
    assert console.count(message) == 1, console
    assert "shows here once per worker" in console
