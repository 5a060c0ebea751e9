"""Robot conditions through the harness (issue 25): level 0 of every condition gives the clean
run's rows byte for byte; cache keys follow every new setting and a change recomputes only
what depends on it; bad settings are one line, exit 2, nothing cached; methods and segmenters
see only the robot's map while the score stays on the ground truth's walkable area."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from benchmark.config import compose_job
from benchmark.harness.cache import load_npz
from benchmark.harness.runner import build_pipeline, run

ROOT = Path(__file__).resolve().parents[1]
FAST = ["env=synthetic", "env.resolution=0.1", "env.n_houses=2", "viewpoints.spacing=1.5", "classifier=oracle",
        "aggregator=vision_cone", "run.progress=false"]


def _run(tmp_path: Path, name: str, *overrides: str, results: str = "R") -> pd.DataFrame:
    cfg, ch = compose_job([*FAST, f"run.results_dir={tmp_path / results}", *overrides])
    return run(cfg, tmp_path / results / "jobs" / name, ch)


def _metrics_bytes(df: pd.DataFrame) -> bytes:
    """The job's metrics.csv, byte for byte except the timing columns (``t_*``: seconds measured)."""
    lines = (Path(df.attrs["job_dir"]) / "metrics.csv").read_text().splitlines()
    head = lines[0].split(",")
    keep = [i for i, c in enumerate(head) if not c.startswith("t_")]
    import csv

    rows = list(csv.reader(lines))
    return "\n".join(",".join(r[i] for i in keep) for r in rows).encode()


def _files(root: Path, stage: str) -> dict[str, int]:
    return {str(p.relative_to(root)): p.stat().st_mtime_ns for p in (root / stage).rglob("*")
            if p.is_file() and not p.name.endswith(".lock")}


@pytest.mark.slow
def test_level_zero_of_every_condition_is_the_clean_run_byte_for_byte(tmp_path):
    clean = _run(tmp_path, "clean", results="a")
    assert (clean["status"] == "ok").all() and set(clean["corruption"]) == {"clean"}
    assert (clean["pose_error_mean_m"] == 0).all() and (clean["map_free_iou"] == 1).all()
    assert clean["coverage_area"].between(0.9, 1.0).all()
    want = _metrics_bytes(clean)
    for i, extra in enumerate([["corruption=clean"], ["pose_error=slam"], ["label_noise=noisy"],
                               ["pose_error=slam", "pose_error.loop_closure=5.0", "label_noise=noisy"]]):
        got = _run(tmp_path, f"zero{i}", *extra, results=f"b{i}")  # fresh caches: computed, not served
        assert _metrics_bytes(got) == want, extra


def test_each_setting_recomputes_only_what_depends_on_it(tmp_path):
    cache = tmp_path / "R" / "cache"
    first = _run(tmp_path, "s1", "corruption=scan_1")
    assert (first["status"] == "ok").all() and (first["map_free_iou"] < 1).all()
    render, classify, maps = _files(cache, "render"), _files(cache, "classify"), _files(cache, "robot_maps")
    assert len(maps) == 2
    # another scanner: a new robot map and aggregation, the same render and classification
    second = _run(tmp_path, "s2", "corruption=scan_1", "mapping.dropout=0.3")
    assert _files(cache, "render") == render and _files(cache, "classify") == classify
    assert len(_files(cache, "robot_maps")) == 4 and not (second["iou"].to_numpy() == first["iou"].to_numpy()).all()
    # a pose error on top: the robot map is reused (it depends on the true poses only)
    maps = _files(cache, "robot_maps")
    third = _run(tmp_path, "s3", "corruption=scan_1", "mapping.dropout=0.3", "pose_error=slam",
                 "pose_error.sigma_xy=0.3")
    assert _files(cache, "robot_maps") == maps and _files(cache, "classify") == classify
    assert (third["pose_error_mean_m"] > 0.1).all()
    # and the same command again is served whole from the cache
    aggregate = _files(cache, "aggregate")
    again = _run(tmp_path, "s3", "corruption=scan_1", "mapping.dropout=0.3", "pose_error=slam",
                 "pose_error.sigma_xy=0.3")
    assert _files(cache, "aggregate") == aggregate
    cols = ["house_id", "iou", "pose_error_mean_m", "map_free_iou"]
    pd.testing.assert_frame_equal(again[cols], third[cols])


def test_the_scan_map_is_what_methods_and_segmenters_see_and_the_score_stays_on_the_ground_truth(tmp_path):
    df = _run(tmp_path, "m", "corruption=scan_5")
    seg = _run(tmp_path, "g", "corruption=scan_5", "segmenter=distance")
    cfg, ch = compose_job([*FAST, f"run.results_dir={tmp_path / 'R'}", "corruption=scan_5"])
    pipe = build_pipeline(cfg, ch)
    for hid, row in zip(df["house_id"], df.itertuples()):
        scene = pipe.scene(hid)
        m = load_npz(Path(pipe.entry("maps", hid)))
        free = m["free"]
        assert free.shape == scene.grid.shape and not free.all()
        assert (m["post"][~free] == -1).all()  # nothing labelled where the robot's map is not free
        missed = scene.grid.walkable & ~free
        assert row.map_missed_share == pytest.approx(missed.sum() / scene.grid.walkable.sum())
        # the walkable cells the map misses count as unlabelled: accuracy cannot exceed the rest
        assert row.accuracy <= 1 - row.map_missed_share + 1e-9
    cfg, ch = compose_job([*FAST, f"run.results_dir={tmp_path / 'R'}", "corruption=scan_5", "segmenter=distance"])
    spipe = build_pipeline(cfg, ch)
    for hid in seg["house_id"]:
        m = load_npz(spipe.entry("maps", hid))
        assert (m["instances"][~m["free"]] == -1).all() and (m["instances"][m["free"]] >= 0).mean() > 0.5
    assert (seg["map_free_iou"] < 1).all() and set(seg["viewpoints"]) == {"autotrace"}


@pytest.mark.parametrize("override,line", [
    ("pose_error.sigma_xy=-0.1", "pose_error.sigma_xy=-0.1: expected a number >= 0"),
    ("mapping.height=3.0", "mapping.height=3.0: expected metres, 0 < height < 2.6 (below the walls)"),
    ("mapping.max_range=0", "mapping.max_range=0: expected metres > 0 (.inf: unlimited)"),
    ("viewpoints.budget=0", "viewpoints.budget=0: expected metres > 0 (.inf: unlimited)"),
])
def test_bad_settings_are_one_line_exit_2_and_cache_nothing(tmp_path, override, line):
    group = override.split(".")[0]
    base = {"pose_error": "pose_error=slam", "mapping": "mapping=scan", "viewpoints": "viewpoints=frontier"}[group]
    r = subprocess.run([sys.executable, "-m", "benchmark.commands.bench", *FAST, base, override,
                        f"run.results_dir={tmp_path / 'R'}"], cwd=ROOT, env={**os.environ, "PYTHONPATH": str(ROOT)},
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 2 and r.stderr.strip() == f"roomseg-bench: error: {line}"
    assert not (tmp_path / "R" / "cache").exists()


def test_exploration_and_pose_error_rows_record_what_the_robot_had(tmp_path):
    df = _run(tmp_path, "e", "corruption=explore_5")
    assert (df["status"] == "ok").all() and (df["viewpoints"] == "frontier").all()
    assert (df["coverage_area"] < 0.95).any() and df["coverage_rooms"].between(0, 1).all()
    pose = _run(tmp_path, "p", "corruption=pose_5")
    assert (pose["pose_error_max_m"] >= pose["pose_error_mean_m"]).all() and (pose["pose_error_mean_m"] > 0.5).all()
    noisy = _run(tmp_path, "n", "corruption=classifier_5")
    assert noisy["label_noise_share"].between(0.3, 0.7).all()
    assert np.all(noisy["view_accuracy_seen"] < 0.8)


@pytest.mark.slow
def test_one_slam_estimate_per_house_is_shared_by_every_method_of_a_condition(tmp_path):
    """A SLAM robot's estimate is solved once per house and condition, cached beside its map;
    a second method loads it (no ``t_slam``) and scores what a run with an empty cache scores."""
    cache = tmp_path / "R" / "cache"
    first = _run(tmp_path, "knn", "corruption=slam_3", "aggregator=graph_knn")
    assert (first["status"] == "ok").all() and (first["ate_rmse_m"] > 0).all()
    timings = pd.read_csv(Path(first.attrs["job_dir"]) / "timings.csv")
    assert (timings["t_slam"] > 0).all()
    slam = _files(cache, "slam")
    assert len(slam) == 2
    shared = _run(tmp_path, "cone", "corruption=slam_3")
    assert _files(cache, "slam") == slam
    assert "t_slam" not in pd.read_csv(Path(shared.attrs["job_dir"]) / "timings.csv")
    alone = _run(tmp_path, "cone", "corruption=slam_3", results="fresh")
    assert _metrics_bytes(shared) == _metrics_bytes(alone)
    assert (shared["ate_rmse_m"] == first["ate_rmse_m"]).all()
    # a damaged entry is one warning and solved again, to the same rows
    victim = cache / next(iter(slam))
    victim.write_bytes(b"not an npz")
    again = _run(tmp_path, "cone2", "corruption=slam_3", "run.force=[score]")
    assert _metrics_bytes(again) == _metrics_bytes(alone)
    assert set(load_npz(victim)) >= {"true", "estimate", "view_index"}


def test_scenes_are_kept_per_process_up_to_a_memory_bound(monkeypatch):
    """A worker keeps scenes up to ``ROOMSEG_SCENE_CACHE_MB``, least recently used dropped
    first; each kept scene is the one the environment builds (compared array by array); a bad
    bound is one line before any work."""
    from benchmark.harness import pipeline as pl
    from benchmark.harness.checks import ConfigError

    cfg, ch = compose_job([*FAST, "env.n_houses=4"])
    pipe = build_pipeline(cfg, ch)
    ids = pipe.env.house_ids()
    one = pl.scene_bytes(pipe.env.scene(ids[0]))
    assert one > pipe.env.scene(ids[0]).instances.nbytes
    monkeypatch.setattr(pl, "_SCENES", pl.ByteLRU())
    monkeypatch.setenv("ROOMSEG_SCENE_CACHE_MB", str(2.5 * one / 2**20))  # room for two such scenes
    first = [pipe.scene(h) for h in ids]
    assert [k[1] for k in pl._SCENES] == ids[-2:]
    assert pipe.scene(ids[-1]) is first[-1] and pipe.scene(ids[0]) is not first[0]
    fresh = pipe.env.scene(ids[0])
    assert (pipe.scene(ids[0]).instances == fresh.instances).all()
    assert (pipe.scene(ids[0]).grid.walkable == fresh.grid.walkable).all()
    monkeypatch.setenv("ROOMSEG_SCENE_CACHE_MB", "0")
    pipe.scene(ids[1])
    assert not pl._SCENES
    monkeypatch.delenv("ROOMSEG_SCENE_CACHE_MB")
    from benchmark.harness.sweep import SWEEP_ENV

    monkeypatch.delenv(SWEEP_ENV, raising=False)
    assert pl.scene_cache_limit() == 64 * 2**20  # a single run reads each house once
    monkeypatch.setenv(SWEEP_ENV, "a-sweep")
    assert pl.scene_cache_limit() == 512 * 2**20  # a sweep's jobs read the same houses again
    monkeypatch.setenv("ROOMSEG_SCENE_CACHE_MB", "lots")
    with pytest.raises(ConfigError, match=r"^ROOMSEG_SCENE_CACHE_MB='lots': expected a number of MiB >= 0$"):
        run(cfg, Path("/nonexistent/never"), ch)


def test_a_slam_entry_is_checked_when_read():
    """The slam cache entry round-trips a hand-made estimate; a missing array, a view count
    other than the views', an index past the trajectory or a float index is a BadEntry."""
    from benchmark.conditions.slam import SlamEstimate
    from benchmark.harness.entries import BadEntry, check_slam_entry, slam_arrays

    true = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 90.0]])
    est = SlamEstimate(true, true + 0.1, true + 0.2, np.array([0, 2]), np.array([0.0, 1.0, 2.0]),
                       np.array([[0, 2]]), np.zeros((0, 2), np.int64), 1.5, 3, 0.0)
    back = check_slam_entry(slam_arrays(est), 2)
    assert (back.views == true[[0, 2]] + 0.1).all() and back.chi2 == 1.5 and back.dof == 3
    assert back.closures.tolist() == [[0, 2]] and back.wrong.shape == (0, 2)
    z = slam_arrays(est)
    for bad, match in (({k: v for k, v in z.items() if k != "wrong"}, r"^no wrong$"),
                       (z, r"one node per each of 3 views"),
                       ({**z, "view_index": np.array([0, 3])}, r"one node per each of 2 views"),
                       ({**z, "view_index": np.array([0.0, 2.0])}, r"^view_index hold float64, expected integer")):
        with pytest.raises(BadEntry, match=match):
            check_slam_entry(bad, 3 if bad is z else 2)


@pytest.mark.slow
def test_a_process_reads_each_robot_map_once_and_a_rewritten_map_again(tmp_path, monkeypatch):
    """The jobs of a sweep share a condition's maps and SLAM estimates: a process keeps each as
    read (read-only), so a second segmenter neither reads them nor makes the views again, and
    scores what a run from empty caches scores; a map entry written anew is read anew."""
    from benchmark.harness import robot_stages as rs
    from benchmark.harness.cache import atomic_save_npz

    monkeypatch.setattr(rs, "_ROBOT_MEMO", rs.ByteLRU())
    one = ["corruption=slam_3", "run.workers=1"]
    first = _run(tmp_path, "dist", *one, "segmenter=distance")
    assert (first["status"] == "ok").all()
    assert sorted(k[0] for k in rs._ROBOT_MEMO) == ["grid", "grid", "slam", "slam"]
    free, info, frames = next(v for k, v in zip(rs._ROBOT_MEMO, rs._ROBOT_MEMO.values()) if k[0] == "grid")
    assert not free.flags.writeable and not any(a.flags.writeable for a in frames)
    second = _run(tmp_path, "morph", *one, "segmenter=morphological")
    assert "t_viewpoints" not in pd.read_csv(Path(second.attrs["job_dir"]) / "timings.csv")
    # each job gets its own map to work on (the voronoi segmenter's skeleton needs a writable one)
    vor = _run(tmp_path, "vor", *one, "segmenter=voronoi")
    assert (vor["status"] == "ok").all()
    # a map written anew (another file) is not served from what the process kept
    cfg, ch = compose_job([*FAST, f"run.results_dir={tmp_path / 'R'}", *one, "segmenter=morphological"])
    hid = str(second["house_id"].iloc[0])
    path = build_pipeline(cfg, ch).entry("robot_map", hid)
    free = load_npz(path)["free"]
    atomic_save_npz(path, free=np.ones_like(free))
    third = _run(tmp_path, "morph3", *one, "segmenter=morphological", "run.force=[score]")
    row = third.set_index("house_id").loc[hid]
    assert row["map_free_iou"] < second.set_index("house_id").loc[hid, "map_free_iou"]
    assert row["map_missed_share"] == 0.0
    # the rows read through what the process kept are those of a run from empty caches
    monkeypatch.setattr(rs, "_ROBOT_MEMO", rs.ByteLRU())
    alone = _run(tmp_path, "morph", *one, "segmenter=morphological", results="fresh")
    assert _metrics_bytes(second) == _metrics_bytes(alone)


@pytest.mark.slow
def test_a_process_reads_each_renders_poses_once_and_a_rewritten_render_again(tmp_path, monkeypatch):
    """Every method on the same views checks its classification against the render's poses: a
    process keeps each render's table as read (read-only), so a second method reads none, with
    the rows of a run from empty caches; a poses file written anew is read anew."""
    from benchmark.harness import robot_stages as rs
    from envs.atomic import atomic_write_bytes
    from envs.render import cache as render_cache

    monkeypatch.setattr(rs, "_POSES_MEMO", rs.ByteLRU())
    reads = []
    real = render_cache.read_poses
    monkeypatch.setattr(render_cache, "read_poses", lambda folder: reads.append(folder) or real(folder))
    one = ["run.workers=1", "corruption=pose_2"]  # the views' poses move: the classification is checked against them
    _run(tmp_path, "cone", *one)
    reads.clear()
    knn = _run(tmp_path, "knn", *one, "aggregator=graph_knn")
    assert (knn["status"] == "ok").all() and reads == []
    assert all(not a.flags.writeable for table in rs._POSES_MEMO.values() for a in table)
    # the render rewritten (another file, the same bytes): read again, once per house
    cfg, ch = compose_job([*FAST, f"run.results_dir={tmp_path / 'R'}", *one, "aggregator=graph_knn"])
    pipe = build_pipeline(cfg, ch)
    for hid in knn["house_id"].astype(str):
        path = pipe.entry("render", hid) / render_cache.POSES_FILE
        atomic_write_bytes(path, path.read_bytes())
    again = _run(tmp_path, "knn2", *one, "aggregator=graph_knn", "run.force=[score]")
    assert sorted(map(str, reads)) == sorted(str(pipe.entry("render", h)) for h in knn["house_id"].astype(str))
    # the rows read through what the process kept are those of a run from empty caches
    monkeypatch.setattr(rs, "_POSES_MEMO", rs.ByteLRU())
    alone = _run(tmp_path, "knn", *one, "aggregator=graph_knn", results="fresh")
    assert _metrics_bytes(knn) == _metrics_bytes(alone) == _metrics_bytes(again)
