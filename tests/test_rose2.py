"""ROSE² as a segmenter (issue 28), exercised with a stand-in package of ROSE2's module layout
(tests/fixtures/rose2_standin; CI has no ROSE2 checkout): the driver's success, a failure and a
timeout each give the right row, the sweep always completes, no checkout is one line and exit 2;
the map drawn for ROSE² and its rooms carried back are checked by hand."""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import tempfile
import time
import uuid
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from benchmark.segmenters.rose2 import ROSE2_RESOLUTION, Rose2, rooms_to_instances, rose2_image
from envs.maps.gridmap import GridMap
from tests.procs import NEEDS_PROC

ROOT = Path(__file__).resolve().parents[1]
STANDIN = ROOT / "tests" / "fixtures" / "rose2_standin"


def _bench(tmp_path: Path, *args: str, mode: str = "ok", rose2: str | None = None):
    env = {**os.environ, "PYTHONPATH": str(ROOT), "ROSE2_STANDIN": mode}
    env.pop("ROOMSEG_ROSE2", None)
    if rose2 is not None:
        env["ROOMSEG_ROSE2"] = rose2
    return subprocess.run([sys.executable, "-m", "benchmark.commands.bench", "env=synthetic", "env.resolution=0.1",
                           "run.limit=2", "segmenter=rose2", f"segmenter.python={sys.executable}",
                           f"run.results_dir={tmp_path / 'R'}", "run.progress=false", *args],
                          cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)


def _rows(tmp_path: Path) -> pd.DataFrame:
    return pd.read_csv(tmp_path / "R" / "runs" / "default" / "metrics.csv")


@pytest.mark.slow
def test_no_checkout_is_one_line_and_exit_2(tmp_path):
    r = _bench(tmp_path)
    assert r.returncode == 2
    line = r.stderr.strip()
    assert "\n" not in line and "segmenter=rose2 needs a ROSE2 checkout" in line and "ROOMSEG_ROSE2" in line
    r = _bench(tmp_path, f"segmenter.checkout={tmp_path}")
    assert r.returncode == 2 and "not a ROSE2 checkout" in r.stderr


@pytest.mark.slow
def test_rooms_from_the_standin_are_scored_and_timed(tmp_path):
    r = _bench(tmp_path, rose2=str(STANDIN))
    assert r.returncode == 0, r.stderr[-2000:]
    df = _rows(tmp_path)
    assert (df["status"] == "ok").all() and (df["segmenter"] == "rose2").all()
    assert (df["n_pred_segments"] == 2).all()  # the stand-in's two halves
    timings = tmp_path / "R" / "runs" / "default" / "timings.csv"
    t = pd.read_csv(timings) if timings.exists() else df
    assert (t["t_rose2"] > 0).all()


@pytest.mark.slow
@pytest.mark.parametrize("mode,why", [("directions", "ROSE2: not enough directions (2 main directions"),
                                      ("crash", "ROSE2: ZeroDivisionError: division by zero in the stand-in at "
                                                "minibatch.py:")])
def test_a_map_rose2_fails_on_is_a_failed_row_and_the_run_completes(tmp_path, mode, why):
    r = _bench(tmp_path, f"segmenter.checkout={STANDIN}", mode=mode)
    assert r.returncode == 1, r.stderr[-2000:]  # houses failed; every row written
    df = _rows(tmp_path)
    assert len(df) == 2 and (df["status"] == "failed").all()
    assert all(why in e for e in df["error"]), df["error"].tolist()


@pytest.mark.slow
def test_a_map_that_takes_too_long_fails_alone_after_the_timeout(tmp_path):
    r = _bench(tmp_path, f"segmenter.checkout={STANDIN}", "segmenter.timeout=3", mode="sleep")
    assert r.returncode == 1
    df = _rows(tmp_path)
    assert (df["status"] == "failed").all() and all("timed out after 3 s" in e for e in df["error"])


def test_the_map_drawn_for_rose2_and_its_rooms_carried_back_by_hand():
    # a 2 x 1 m free rectangle at 0.025 m/px (80 x 40 px) inside a 3 x 2 m map
    res = 0.025
    walk = np.zeros((80, 120), bool)
    walk[20:60, 20:100] = True
    img, height, pad = rose2_image(walk, res, wall_m=0.1, margin_m=0.5)
    assert (height, pad) == (40, 10) and img.shape == (60, 80)  # 0.05 m/px + 10 px margin each side
    assert img.dtype == np.uint8 and set(np.unique(img)) == {0, 200, 255}
    free = img[::-1] == 255  # row 0 of the image is the map's bottom
    assert free.sum() == 40 * 20 and free[20:40, 20:60].all()
    wall = img[::-1] == 0
    # occupied: every non-free cell within 2 px (0.1 m) of a free cell, counted cell by cell
    fr, fc = np.nonzero(free)
    want = sum(1 for r in range(img.shape[0]) for c in range(img.shape[1])
               if not free[r, c] and np.min((fr - r) ** 2 + (fc - c) ** 2) <= 4)
    assert wall.sum() == want and wall[18:42, 18:62].sum() == want
    # rooms back: the left and the right halves of the free rectangle, in image pixels (x right,
    # y up from the image's bottom row, pixel centres at integers)
    left = {"exterior": [[19.5, 19.5], [39.5, 19.5], [39.5, 29.5], [19.5, 29.5]]}
    right = {"exterior": [[39.5, 19.5], [59.5, 19.5], [59.5, 29.5], [39.5, 29.5]]}
    inst = rooms_to_instances([left, right], GridMap(walk, res, (0.0, 0.0)), height, pad)
    assert (inst[~walk] == -1).all()
    # image rows 19.5..29.5 from the bottom = the lower half of the free rectangle on the grid
    assert (inst[40:60, 20:60] == 0).all() and (inst[40:60, 60:100] == 1).all() and (inst[20:40] == -1).all()
    assert ROSE2_RESOLUTION == 0.05


def test_settings_are_checked_when_built(tmp_path):
    with pytest.raises(ValueError, match="segmenter.timeout=0"):
        Rose2(checkout=str(STANDIN), python=sys.executable, timeout=0)
    with pytest.raises(ValueError, match="make rose2-env"):
        Rose2(checkout=str(STANDIN), python=str(tmp_path / "nope"))


# ---------------------------------------------------------------- the driver's processes (issue 38, item 2)
def _marked(mark: str) -> list[int]:
    """Pids of the living processes whose environment holds ``ROSE2_MARK=<mark>``."""
    out = []
    for d in Path("/proc").iterdir():
        if not d.name.isdigit():
            continue
        try:
            if f"ROSE2_MARK={mark}".encode() not in (d / "environ").read_bytes().split(b"\0"):
                continue
            state = (d / "stat").read_text().rsplit(")", 1)[1].split()[0]
        except OSError:
            continue
        if state not in "ZXx":
            out.append(int(d.name))
    return out


def _cmdline(pid: int) -> bytes:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes()
    except OSError:
        return b""


def _gone(mark: str, seconds: float) -> list[int]:
    end = time.monotonic() + seconds
    while time.monotonic() < end and _marked(mark):
        time.sleep(0.1)
    return _marked(mark)


@NEEDS_PROC
@pytest.mark.slow
def test_a_timeout_kills_the_drivers_whole_group_and_its_folder(tmp_path, monkeypatch):
    # the stand-in starts a child of its own and never finishes: before, only the driver was
    # killed on the timeout and its child lived on
    mark = uuid.uuid4().hex
    monkeypatch.setenv("ROSE2_STANDIN", "child")
    monkeypatch.setenv("ROSE2_MARK", mark)
    monkeypatch.setenv("TMPDIR", str(tmp_path))
    monkeypatch.setattr(tempfile, "tempdir", None)
    seg = Rose2(checkout=str(STANDIN), python=sys.executable, timeout=2)
    try:
        with pytest.raises(RuntimeError, match="ROSE2 timed out after 2 s"):
            seg.run_driver(np.full((20, 20), 255, np.uint8))
        assert _gone(mark, 3) == []
    finally:
        for pid in _marked(mark):
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, 9)
    assert list(tmp_path.glob("roomseg-rose2-*")) == []


@NEEDS_PROC
@pytest.mark.slow
def test_the_drivers_output_is_bounded(tmp_path):
    # 300 MB on the driver's stderr: before, captured whole in the worker (peak > 600 MB)
    code = ("import sys, numpy as np; from benchmark.segmenters.rose2 import Rose2; "
            f"seg = Rose2(checkout={str(STANDIN)!r}, python=sys.executable); "
            "img = np.full((40, 40), 200, np.uint8); img[10:30, 10:30] = 255; img[9, 9:31] = 0; "
            "out = seg.run_driver(img); assert out['status'] == 'ok', out; "
            # VmHWM: this program's own peak (ru_maxrss would carry the forking test process's over exec)
            "print(next(int(x.split()[1]) for x in open('/proc/self/status') if x.startswith('VmHWM')) // 1024)")
    env = {**os.environ, "PYTHONPATH": str(ROOT), "ROSE2_STANDIN": "spam", "ROSE2_STANDIN_MB": "300"}
    r = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    peak_mb = int(r.stdout.split()[-1])
    assert peak_mb < 250, peak_mb


@NEEDS_PROC
@pytest.mark.slow
def test_kill_9_of_the_run_leaves_no_driver_and_no_folder(tmp_path):
    # roomseg-bench with two workers, each inside a driver whose ROSE2 started a child; kill -9
    # of roomseg-bench: before, drivers and children lived on (parent pid 1) with their folders
    mark = uuid.uuid4().hex
    (tmp_path / "tmp").mkdir()
    env = {**os.environ, "PYTHONPATH": str(ROOT), "ROSE2_STANDIN": "child", "ROSE2_MARK": mark,
           "TMPDIR": str(tmp_path / "tmp")}
    p = subprocess.Popen([sys.executable, "-m", "benchmark.commands.bench", "env=synthetic", "env.resolution=0.1",
                          "run.limit=2", "run.workers=2", "segmenter=rose2", f"segmenter.python={sys.executable}",
                          f"segmenter.checkout={STANDIN}", f"run.results_dir={tmp_path / 'R'}",
                          "run.progress=false"], cwd=ROOT, env=env,
                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        def up():  # both stand-ins' own children are running
            kids = [q for q in _marked(mark) if b"time.sleep(3600)" in _cmdline(q)]
            return len(kids) == 2 and len(list((tmp_path / "tmp").glob("roomseg-rose2-*"))) == 2
        deadline = time.monotonic() + 240
        while not up():
            assert p.poll() is None and time.monotonic() < deadline, "the drivers never started"
            time.sleep(0.2)
        time.sleep(0.5)
        p.kill()
        p.wait()
        assert _gone(mark, 5) == []
        assert list((tmp_path / "tmp").glob("roomseg-rose2-*")) == []
    finally:
        p.kill()
        for pid in _marked(mark):
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, 9)


def test_folders_of_dead_drivers_are_removed_first(tmp_path, monkeypatch):
    from benchmark.segmenters.rose2 import clean_rose2_tmp

    monkeypatch.setenv("TMPDIR", str(tmp_path))
    monkeypatch.setattr(tempfile, "tempdir", None)
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    stale = tmp_path / f"roomseg-rose2-{int(dead.stdout)}-abc"
    live = tmp_path / f"roomseg-rose2-{os.getpid()}-abc"
    other = tmp_path / "roomseg-rose2-notapid"
    for d in (stale, live, other):
        (d / "x").mkdir(parents=True)
    assert clean_rose2_tmp() == [stale]
    assert not stale.exists() and live.exists() and other.exists()
