"""A full disk (issue 24 item 8), on a real small tmpfs: a sweep whose second job cannot write
its results names the file in one line and exits 3 (some jobs finished, their results complete),
one with nothing written exits 2, and ``report`` says one line, exit 2. Skips where a tmpfs
cannot be mounted (not root)."""

from __future__ import annotations

import errno
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
ENV = {**os.environ, "PYTHONPATH": str(ROOT)}


@pytest.fixture
def small_disk(tmp_path):
    mnt = tmp_path / "mnt"
    mnt.mkdir()
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=4m", "tmpfs", str(mnt)], capture_output=True, text=True)
    if r.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here ({r.stderr.strip() or 'not root'})")
    try:
        yield mnt
    finally:
        subprocess.run(["umount", "-l", str(mnt)], capture_output=True)


def _fill(mnt: Path) -> None:
    """Write until the file system is full."""
    with open(mnt / "filler", "wb") as f:
        try:
            while True:
                f.write(b"\0" * 65536)
                f.flush()
        except OSError as e:
            assert e.errno == errno.ENOSPC


def _bench(mnt: Path, tmp_path: Path, *args: str) -> subprocess.Popen:
    flags = [a for a in args if a == "-m"]
    args = tuple(a for a in args if a != "-m")
    return subprocess.Popen([sys.executable, "-m", "benchmark.commands.bench", *flags, "env=synthetic",
                             "env.resolution=0.1",
                             "classifier=oracle", "viewpoints.spacing=1.0", f"run.results_dir={mnt / 'R'}",
                             f"run.cache_dir={tmp_path / 'cache'}", "run.progress=false", *args],
                            cwd=ROOT, env=ENV, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


@pytest.mark.slow
def test_a_sweep_into_a_disk_that_fills_up_names_the_file_and_exits_3(small_disk, tmp_path):
    p = _bench(small_disk, tmp_path, "-m", "aggregator=graph_knn,vision_cone", "run.limit=4", "run.workers=1",
               "hydra.launcher.n_jobs=1")

    def fill_after_first_job() -> None:
        while p.poll() is None:
            if list((small_disk / "R" / "runs").rglob("summary.json")):
                _fill(small_disk)
                return
            time.sleep(0.005)

    t = threading.Thread(target=fill_after_first_job)
    t.start()
    _, err = p.communicate(timeout=600)
    t.join()
    assert p.returncode == 3, err[-2000:]
    lines = [ln for ln in err.splitlines() if ln.startswith("roomseg-bench")]
    assert any("cannot write " + str(small_disk) in ln and "(No space left on device)" in ln for ln in lines), lines
    assert lines[-1].startswith("roomseg-bench: 1 of 2 job(s) finished and their results are complete"), lines
    done = list((small_disk / "R" / "runs").rglob("metrics.csv"))
    assert len(done) == 1  # the finished job's results are whole; the other left no metrics.csv
    # report on the finished run into the full disk: one line naming the file, exit 2
    r = subprocess.run([sys.executable, "-m", "benchmark.commands.report", str(done[0].parent), "--out",
                        str(small_disk / "report.html")], cwd=ROOT, env=ENV, capture_output=True, text=True)
    assert r.returncode == 2 and r.stderr.strip().count("\n") == 0, r.stderr
    assert "cannot write" in r.stderr and "No space left on device" in r.stderr


@pytest.mark.slow
def test_a_run_into_a_full_disk_writes_nothing_and_exits_2(small_disk, tmp_path):
    _fill(small_disk)
    p = _bench(small_disk, tmp_path, "run.limit=1")
    _, err = p.communicate(timeout=600)
    assert p.returncode == 2, err[-2000:]
    # one line: Hydra's own "Error executing job with overrides: [...]" no longer before it (issue 38 item 7)
    assert len(err.strip().splitlines()) == 1, err[-2000:]
    line = err.strip()
    assert line.startswith("roomseg-bench: error: ") and str(small_disk) in line and "No space left on device" in line
    # and no file half-written: Hydra's .hydra/*.yaml are written whole or not at all (was a 0-byte config.yaml)
    empty = [p for p in (small_disk / "R").rglob("*") if p.is_file() and p.stat().st_size == 0]
    assert empty == []
