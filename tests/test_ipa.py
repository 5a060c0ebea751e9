"""ipa_room_segmentation's five algorithms as segmenters (issue 60).

With the build (``make ipa-env``; skipped with the reason where it is absent): the driver on a
hand-made two-room map with a known answer for each algorithm, a bad map failing with the
driver's one line, a timeout killing the driver. Always (a stand-in driver written by the test
into a build folder of its own): the subprocess contract (a failed map fails alone with the
driver's message, a timeout, kill -9 of the run leaves no driver and no folder), the map drawn
for the driver and its labels carried back, checked by hand, and settings checked when built."""

from __future__ import annotations

import contextlib
import json
import os
import stat
import subprocess
import sys
import tempfile
import time
import uuid
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from benchmark.segmenters.ipa import (
    ALGORITHMS,
    IPA_RESOLUTION,
    PAD_PX,
    IpaSegmenter,
    clean_ipa_tmp,
    ipa_build,
    ipa_image,
    labels_to_instances,
)
from envs.maps.gridmap import GridMap
from tests.procs import NEEDS_PROC

ROOT = Path(__file__).resolve().parents[1]


def _build_or_none():
    try:
        return ipa_build()
    except FileNotFoundError as e:
        return str(e)


BUILD = _build_or_none()
NEEDS_BUILD = pytest.mark.skipif(isinstance(BUILD, str), reason=f"no ipa_room_segmentation build: {BUILD}")


def _two_rooms() -> tuple[np.ndarray, tuple[slice, slice], tuple[slice, slice]]:
    """A hand-made map at 0.05 m/px: two 6 x 5.5 m rooms side by side, a 0.3 m wall between
    them with a 0.7 m door in its middle, 0.25 m of obstacle around; the rooms' rectangles."""
    walk = np.zeros((130, 240), bool)
    a, b = (slice(5, 125), slice(5, 115)), (slice(5, 125), slice(121, 231))
    walk[a] = True
    walk[b] = True
    walk[58:72, 115:121] = True  # the door
    return walk, a, b


# ---------------------------------------------------------------- with the build
@NEEDS_BUILD
@pytest.mark.parametrize("algorithm", list(ALGORITHMS))
def test_each_algorithm_finds_the_two_rooms_of_a_hand_made_map(algorithm):
    if algorithm == "vrf" and not BUILD["vrf"]:
        pytest.skip("the build has no VRF (built without OpenGM)")
    walk, a, b = _two_rooms()
    seg = IpaSegmenter(algorithm)
    inst = seg(GridMap(walk, IPA_RESOLUTION, (0.0, 0.0)))
    assert inst.shape == walk.shape and (inst[~walk] == -1).all()
    rooms = []
    for rect in (a, b):
        ids, counts = np.unique(inst[rect], return_counts=True)
        rooms.append(ids[counts.argmax()])
        # each room is one segment: the semantic algorithm keeps the door's strip as a segment of
        # its own (a hallway), a little over 1 % of each room; the other four take every cell
        assert counts.max() / inst[rect].size > (0.97 if algorithm == "semantic" else 0.999), (algorithm, ids, counts)
    assert rooms[0] != rooms[1] and min(rooms) >= 0
    assert seg.last_info["t_ipa"] > 0


@NEEDS_BUILD
def test_the_same_map_at_another_resolution_gives_the_same_rooms():
    # 0.1 m/px: resampled to the authors' 0.05 m/px and back
    walk, a, b = _two_rooms()
    coarse = walk[::2, ::2]
    inst = IpaSegmenter("distance")(GridMap(coarse, 0.1, (0.0, 0.0)))
    left = inst[3:62, 3:57]
    right = inst[3:62, 61:115]
    assert len(np.unique(left)) == 1 and len(np.unique(right)) == 1 and left[0, 0] != right[0, 0] >= 0


@NEEDS_BUILD
def test_a_bad_map_fails_with_the_drivers_one_line():
    seg = IpaSegmenter("morphological")
    with pytest.raises(RuntimeError, match=r"the ipa driver failed on morphological \(exit 2\): ipa_segment: --map "
                                           r".*map\.png: no free \(255\) pixel"):
        seg.run_driver(np.zeros((20, 20), np.uint8))
    r = subprocess.run([str(BUILD["driver"]), "--map", "/nonexistent.png", "--resolution", "0.05", "--algorithm",
                        "voronoi", "--models", "m", "--work", "w", "--out", "o.png"], capture_output=True, text=True)
    assert r.returncode == 2 and r.stderr == "ipa_segment: --map /nonexistent.png: not a readable image\n"
    r = subprocess.run([str(BUILD["driver"]), "--map", "/nonexistent.png", "--resolution", "0.05", "--algorithm",
                        "voronoi", "--models", "m", "--work", "w", "--out", "o.png", "--param", "max_iteration=3"],
                       capture_output=True, text=True)
    assert r.returncode == 2 and r.stderr.startswith("ipa_segment: --param max_iteration: not a parameter of voronoi")


@NEEDS_BUILD
@NEEDS_PROC
def test_a_timeout_stops_the_real_driver_and_removes_its_folder(tmp_path, monkeypatch):
    # VRF loads its classifiers and computes features for seconds even on the small map
    if not BUILD["vrf"]:
        pytest.skip("the build has no VRF (built without OpenGM)")
    mark = uuid.uuid4().hex
    monkeypatch.setenv("IPA_MARK", mark)
    monkeypatch.setenv("TMPDIR", str(tmp_path))
    monkeypatch.setattr(tempfile, "tempdir", None)
    walk, _, _ = _two_rooms()
    seg = IpaSegmenter("vrf", timeout=0.2)
    with pytest.raises(RuntimeError, match=r"ipa vrf timed out after 0.2 s \(segmenter.timeout\)"):
        seg(GridMap(walk, IPA_RESOLUTION, (0.0, 0.0)))
    assert _gone(mark, 5) == []
    assert list(tmp_path.glob("roomseg-ipa-*")) == []


# ---------------------------------------------------------------- a stand-in driver (no build needed)
STANDIN = r'''#!{python}
"""A stand-in for ipa_segment: IPA_STANDIN=ok (left and right halves of the free space),
fail (the driver's one line, exit 2), sleep / child (never finishes; child: with a child)."""
import os, subprocess, sys, time
import cv2, numpy as np
a = dict(zip(sys.argv[1::2], sys.argv[2::2]))
mode = os.environ.get("IPA_STANDIN", "ok")
if mode == "fail":
    sys.exit(print("ipa_segment: --map " + a["--map"] + ": no free (255) pixel", file=sys.stderr) or 2)
if mode in ("sleep", "child"):
    if mode == "child":
        subprocess.Popen([sys.executable, "-c", "import time; time.sleep(3600)"])
    time.sleep(3600)
m = cv2.imread(a["--map"], cv2.IMREAD_UNCHANGED)
out = np.zeros(m.shape, np.uint16)
out[:, : m.shape[1] // 2][m[:, : m.shape[1] // 2] == 255] = 1
out[:, m.shape[1] // 2 :][m[:, m.shape[1] // 2 :] == 255] = 2
cv2.imwrite(a["--out"], out)
print("rooms 2")
'''


def standin_build(tmp_path: Path, script: str, **build) -> Path:
    """A build folder under ``tmp_path`` whose ipa_segment runs ``script`` (Python, ``{python}``
    its interpreter), and whose build.json holds ``build`` (``vrf``, ``vrf_fix``) beside a source
    and a commit."""
    env = tmp_path / "ipa-env"
    (env / "bin").mkdir(parents=True)
    driver = env / "bin" / "ipa_segment"
    driver.write_text(script.replace("{python}", sys.executable))
    driver.chmod(driver.stat().st_mode | stat.S_IXUSR)
    (env / "build.json").write_text(json.dumps({"ipa_src": str(tmp_path / "src"), "ipa_commit": "f" * 40,
                                                **build}))
    return env


@pytest.fixture
def standin(tmp_path: Path) -> Path:
    """A build folder whose ipa_segment is the stand-in."""
    return standin_build(tmp_path, STANDIN, vrf=False)


def _bench(tmp_path: Path, env_dir: Path | None, *args: str, mode: str = "ok", extra_env: dict | None = None,
           popen: bool = False):
    env = {**os.environ, "PYTHONPATH": str(ROOT), "IPA_STANDIN": mode, **(extra_env or {})}
    env.pop("ROOMSEG_IPA_ENV", None)
    cmd = [sys.executable, "-m", "benchmark.commands.bench", "env=synthetic", "env.resolution=0.1", "run.limit=2",
           "segmenter=ipa_distance", f"run.results_dir={tmp_path / 'R'}", "run.progress=false", *args]
    if env_dir is not None:
        cmd.append(f"segmenter.env_dir={env_dir}")
    if popen:
        return subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)


def _rows(tmp_path: Path) -> pd.DataFrame:
    return pd.read_csv(tmp_path / "R" / "runs" / "default" / "metrics.csv")


@pytest.mark.slow
def test_no_build_is_one_line_and_exit_2(tmp_path):
    r = _bench(tmp_path, tmp_path / "nothing")
    assert r.returncode == 2
    line = r.stderr.strip()
    assert "\n" not in line and "segmenter=ipa_distance: no ipa_room_segmentation build in" in line
    assert "make ipa-env" in line


@pytest.mark.slow
def test_rooms_from_the_standin_are_scored_and_timed(tmp_path, standin):
    r = _bench(tmp_path, standin)
    assert r.returncode == 0, r.stderr[-2000:]
    df = _rows(tmp_path)
    assert (df["status"] == "ok").all() and (df["segmenter"] == "ipa_distance").all()
    assert (df["n_pred_segments"] >= 2).all()
    timings = tmp_path / "R" / "runs" / "default" / "timings.csv"
    t = pd.read_csv(timings) if timings.exists() else df
    assert (t["t_ipa"] > 0).all()


@pytest.mark.slow
def test_a_map_the_driver_fails_on_is_a_failed_row_with_its_message(tmp_path, standin):
    r = _bench(tmp_path, standin, mode="fail")
    assert r.returncode == 1, r.stderr[-2000:]  # houses failed; every row written
    df = _rows(tmp_path)
    assert len(df) == 2 and (df["status"] == "failed").all()
    assert all("the ipa driver failed on distance (exit 2): ipa_segment: --map " in e and "no free (255) pixel" in e
               for e in df["error"]), df["error"].tolist()


@pytest.mark.slow
def test_a_map_that_takes_too_long_fails_alone_after_the_timeout(tmp_path, standin):
    r = _bench(tmp_path, standin, "segmenter.timeout=3", mode="sleep")
    assert r.returncode == 1
    df = _rows(tmp_path)
    assert (df["status"] == "failed").all() and all("ipa distance timed out after 3 s" in e for e in df["error"])


def _marked(mark: str) -> list[int]:
    """Pids of the living processes whose environment holds ``IPA_MARK=<mark>``."""
    out = []
    for d in Path("/proc").iterdir():
        if not d.name.isdigit():
            continue
        try:
            if f"IPA_MARK={mark}".encode() not in (d / "environ").read_bytes().split(b"\0"):
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
def test_a_timeout_kills_the_drivers_whole_group_and_its_folder(tmp_path, monkeypatch, standin):
    mark = uuid.uuid4().hex
    monkeypatch.setenv("IPA_STANDIN", "child")
    monkeypatch.setenv("IPA_MARK", mark)
    monkeypatch.setenv("TMPDIR", str(tmp_path))
    monkeypatch.setattr(tempfile, "tempdir", None)
    seg = IpaSegmenter("voronoi", env_dir=str(standin), timeout=2)
    try:
        with pytest.raises(RuntimeError, match="ipa voronoi timed out after 2 s"):
            seg.run_driver(np.full((20, 20), 255, np.uint8))
        assert _gone(mark, 3) == []
    finally:
        for pid in _marked(mark):
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, 9)
    assert list(tmp_path.glob("roomseg-ipa-*")) == []


@NEEDS_PROC
@pytest.mark.slow
def test_kill_9_of_the_run_leaves_no_driver_and_no_folder(tmp_path, standin):
    # roomseg-bench with two workers, each inside a driver that started a child; kill -9 of the run
    mark = uuid.uuid4().hex
    (tmp_path / "tmp").mkdir()
    p = _bench(tmp_path, standin, "run.workers=2", mode="child", popen=True,
               extra_env={"IPA_MARK": mark, "TMPDIR": str(tmp_path / "tmp")})
    try:
        def up():  # both stand-ins' own children are running
            kids = [q for q in _marked(mark) if b"time.sleep(3600)" in _cmdline(q)]
            return len(kids) == 2 and len(list((tmp_path / "tmp").glob("roomseg-ipa-*"))) == 2
        deadline = time.monotonic() + 240
        while not up():
            assert p.poll() is None and time.monotonic() < deadline, "the drivers never started"
            time.sleep(0.2)
        time.sleep(0.5)
        p.kill()
        p.wait()
        assert _gone(mark, 5) == []
        assert list((tmp_path / "tmp").glob("roomseg-ipa-*")) == []
    finally:
        p.kill()
        for pid in _marked(mark):
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, 9)


def test_the_map_drawn_for_the_driver_and_its_labels_carried_back_by_hand():
    # a 2 x 1 m free rectangle at 0.1 m/px (20 x 10 cells) inside a 3 x 2 m map
    walk = np.zeros((20, 30), bool)
    walk[5:15, 5:25] = True
    img = ipa_image(walk, 0.1)
    assert img.shape == (40 + 2 * PAD_PX, 60 + 2 * PAD_PX) and img.dtype == np.uint8
    assert set(np.unique(img)) == {0, 255}
    free = img == 255
    assert free.sum() == 20 * 40 and free[PAD_PX + 10:PAD_PX + 30, PAD_PX + 10:PAD_PX + 50].all()
    # labels back: the driver's rooms 3 (left half) and 7 (right half), 0 elsewhere
    labels = np.zeros(img.shape, np.uint16)
    labels[PAD_PX + 10:PAD_PX + 30, PAD_PX + 10:PAD_PX + 30] = 3
    labels[PAD_PX + 10:PAD_PX + 30, PAD_PX + 30:PAD_PX + 50] = 7
    inst = labels_to_instances(labels, walk, 0.1)
    assert (inst[~walk] == -1).all()
    assert (inst[5:15, 5:15] == 0).all() and (inst[5:15, 15:25] == 1).all()  # ids 0..K-1 in the labels' order
    # a walkable cell no room took stays unlabelled
    labels[PAD_PX + 10:PAD_PX + 12, PAD_PX + 10:PAD_PX + 12] = 0
    assert labels_to_instances(labels, walk, 0.1)[5, 5] == -1


def test_settings_are_checked_when_built(tmp_path, standin):
    with pytest.raises(ValueError, match="segmenter.algorithm='watershed': expected one of morphological"):
        IpaSegmenter("watershed", env_dir=str(standin))
    with pytest.raises(ValueError, match=r"segmenter.params.max_iteration: not a parameter of ipa voronoi"):
        IpaSegmenter("voronoi", params={"max_iteration": 3}, env_dir=str(standin))
    with pytest.raises(ValueError, match=r"segmenter.params.max_area_for_merging=-1: expected a number >= 0"):
        IpaSegmenter("voronoi", params={"max_area_for_merging": -1}, env_dir=str(standin))
    with pytest.raises(ValueError, match="segmenter.timeout=0"):
        IpaSegmenter("distance", env_dir=str(standin), timeout=0)
    with pytest.raises(ValueError, match="segmenter=ipa_vrf: the build in .* has no VRF"):
        IpaSegmenter("vrf", env_dir=str(standin))
    with pytest.raises(ValueError, match="no ipa_room_segmentation build in .*make ipa-env"):
        IpaSegmenter("distance", env_dir=str(tmp_path / "nothing"))


def test_the_configs_hold_the_authors_defaults():
    # room_segmentation_action_server_params.yaml of ipa_room_segmentation at f8a1dae
    from omegaconf import OmegaConf

    want = {"morphological": {"room_area_factor_lower_limit": 0.8, "room_area_factor_upper_limit": 47.0},
            "distance": {"room_area_factor_lower_limit": 0.35, "room_area_factor_upper_limit": 163.0},
            "voronoi": {"room_area_factor_lower_limit": 0.1, "room_area_factor_upper_limit": 1000000.0,
                        "voronoi_neighborhood_index": 280, "max_iterations": 150,
                        "min_critical_point_distance_factor": 0.5, "max_area_for_merging": 12.5},
            "semantic": {"room_area_factor_lower_limit": 1.0, "room_area_factor_upper_limit": 1000000.0},
            "vrf": {"room_area_lower_limit": 1.53, "room_area_upper_limit": 1000000.0,
                    "voronoi_random_field_epsilon_for_neighborhood": 5, "max_iterations": 150,
                    "min_neighborhood_size": 4, "min_voronoi_random_field_node_distance": 7.0,
                    "max_voronoi_random_field_inference_iterations": 9000, "max_area_for_merging": 12.5}}
    for algorithm, params in want.items():
        conf = OmegaConf.load(ROOT / "conf" / "segmenter" / f"ipa_{algorithm}.yaml")
        assert conf.algorithm == algorithm and OmegaConf.to_container(conf.params) == params
        assert tuple(params) == ALGORITHMS[algorithm]


def test_folders_of_dead_drivers_are_removed_first(tmp_path, monkeypatch):
    monkeypatch.setenv("TMPDIR", str(tmp_path))
    monkeypatch.setattr(tempfile, "tempdir", None)
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    stale = tmp_path / f"roomseg-ipa-{int(dead.stdout)}-abc"
    live = tmp_path / f"roomseg-ipa-{os.getpid()}-abc"
    for d in (stale, live):
        (d / "x").mkdir(parents=True)
    assert clean_ipa_tmp() == [stale]
    assert not stale.exists() and live.exists()



def test_doctor_reports_the_build(tmp_path, monkeypatch, standin):
    from benchmark.commands.doctor import checks

    def row():
        return next(r for r in checks(shared=str(tmp_path)) if r[0].startswith("ipa_room_segmentation"))

    monkeypatch.setenv("ROOMSEG_IPA_ENV", str(standin))
    status, how = row()[1:]
    assert status == "OK" and how == f"{standin}/bin/ipa_segment (ipa_coverage_planning ffffffff; no VRF (built without OpenGM))"
    monkeypatch.setenv("ROOMSEG_IPA_ENV", str(tmp_path / "nothing"))
    status, how = row()[1:]
    assert status == "optional" and how.startswith(f"no ipa_room_segmentation build in {tmp_path / 'nothing'}")
    assert "make ipa-env IPA_SRC=" in how


def test_table5_names_its_ipa_rows_build_and_command(monkeypatch, standin):
    import argparse

    from benchmark.commands.selros import ipa_line, published_command

    monkeypatch.setenv("ROOMSEG_IPA_ENV", str(standin))
    assert ipa_line() == "ipa rows: run here from ipa_coverage_planning at commit ffffffff (`make ipa-env`; no VRF)."
    a = argparse.Namespace(data=None, resolution=None, occupancy_dir=None, occupancy_pattern=None,
                           gt_pattern="{id}_ground_truth.png", ipa="vrf", method=[], method_pattern="{id}.png",
                           no_geometric=False, no_sanity=True, markdown=Path("t.md"))
    assert published_command(a, []) == "python -m benchmark.commands.selros --ipa vrf --no-sanity --markdown t.md"


def test_table5_with_ipa_but_no_build_is_one_line_and_exit_2(tmp_path, monkeypatch, capsys):
    # a SeLRoS-shaped folder with one map: the ipa rows cannot be built, nothing is scored
    import cv2

    from benchmark.commands.selros import main

    for sub, name in (("ground_truth", "01_ground_truth.png"), ("vrf", "01_segmented.png"),
                      ("selros", "01_segmented.png")):
        (tmp_path / "data" / sub).mkdir(parents=True)
        img = np.zeros((40, 40, 3), np.uint8)
        img[5:35, 5:35] = (0, 0, 255)
        cv2.imwrite(str(tmp_path / "data" / sub / name), img)
    monkeypatch.setenv("ROOMSEG_IPA_ENV", str(tmp_path / "nothing"))
    rc = main(["--data", str(tmp_path / "data"), "--ipa", "vrf", "--no-sanity"])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1
    assert err.startswith(f"error: segmenter=ipa_vrf: no ipa_room_segmentation build in {tmp_path / 'nothing'}")


def test_ports_against_originals_table_by_hand():
    from benchmark.commands.ipa_ports import table

    df = pd.DataFrame({"source": ["selros", "selros", "real"], "map": ["a", "b", "c"],
                       "algorithm": ["distance"] * 3, "rooms": [2.0, 2.0, float("nan")],
                       "agreement_matched_iou": [1.0, 0.5, 0.1], "port_segments": [2.0, 4.0, 9.0],
                       "original_segments": [2.0, 2.0, 1.0], "port_matched_iou": [0.8, 0.6, float("nan")],
                       "original_matched_iou": [0.7, 0.7, float("nan")], "port_pq": [0.5, 0.5, float("nan")],
                       "original_pq": [0.5, 0.5, float("nan")]})
    lines = table(df).splitlines()
    row = lines[2]
    # means 75 % agreement, 1.5 and 1.0 segments per room, differences +0.0 matched IoU and PQ; the
    # map without ground truth (rooms NaN) is not in this table
    assert row.startswith("| SeLRoS release | distance | 2 | 75.00 [50.00, 100.00] | 1.50 [1.00, 2.00] | "
                          "1.00 [1.00, 1.00] | ")
    assert not lines[3].startswith("|")
    assert "| 0.00 [-10.00, 10.00] | 0.00 [0.00, 0.00] |" in row


def test_ports_against_originals_without_a_build_is_one_line_and_exit_2(tmp_path, monkeypatch, capsys):
    import cv2

    from benchmark.commands.ipa_ports import main

    for sub, name in (("ground_truth", "01_ground_truth.png"), ("vrf", "01_segmented.png")):
        (tmp_path / "data" / sub).mkdir(parents=True)
        img = np.zeros((40, 40, 3), np.uint8)
        img[5:35, 5:35] = (0, 0, 255)
        cv2.imwrite(str(tmp_path / "data" / sub / name), img)
    monkeypatch.setenv("ROOMSEG_IPA_ENV", str(tmp_path / "nothing"))
    assert main(["--data", str(tmp_path / "data"), "--sources", "selros"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("error: segmenter=ipa_morphological: no ipa_room_segmentation build")
