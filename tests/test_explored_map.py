"""Exploration leaves every method the map the robot built (mapping=explored, the explore
family): hand-made rooms with known answers, the harness's rows and maps, and the family's own
severity 0 (the frontier robot run until no reachable frontier is left)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from benchmark.conditions.exploration import Frontier, RandomWalk
from benchmark.conditions.explored_map import ExploredMapping
from benchmark.config import compose_job
from benchmark.harness.cache import load_npz
from benchmark.harness.checks import ConfigError
from benchmark.harness.robot_stages import rooms_mapped
from benchmark.harness.runner import build_pipeline
from benchmark.harness.typed import RobotLabel
from benchmark.metrics import score_instances
from envs.maps.reachable import reachable_mask
from tests.test_exploration import two_room_scene
from tests.test_robot_conditions import FAST, _run


def test_the_explored_map_is_the_explorers_own_and_reaches_every_room_unlimited():
    scene = two_room_scene()
    e = Frontier(budget=math.inf).explore(scene)
    assert e.stop == "explored"
    free = ExploredMapping()(scene, e.poses, exploration=e)
    # the explorer's free cells, less pockets no view reaches (here: none but the walls' edges)
    assert np.array_equal(free, reachable_mask(e.scan_map.free, free))
    assert (free <= e.scan_map.free).all() and free[scene.grid.walkable].mean() > 0.99
    assert rooms_mapped(scene.instances, free) == {"rooms_mapped": 2, "rooms_total": 2}


def test_a_short_sighted_robot_on_a_budget_maps_one_room_and_misses_the_other():
    """A 2 m laser and 2 m of driving from x = 0.5 m: the room beyond the wall at x = 3 m is never
    seen; the map holds none of it, so it counts as a missed room."""
    scene = two_room_scene()
    e = Frontier(budget=2.0, sensor_range=2.0).explore(scene)
    free = ExploredMapping()(scene, e.poses, exploration=e)
    assert not free[scene.instances == 1].any() and free[scene.instances == 0].mean() > 0.5
    assert rooms_mapped(scene.instances, free) == {"rooms_mapped": 1, "rooms_total": 2}
    # a perfect segmentation of what was mapped: room 0 matched exactly, room 1 missed
    pred = np.where(free, 0, -1)
    s = score_instances(pred, scene.instances, resolution=scene.grid.resolution)
    inter = (free & (scene.instances == 0)).sum()
    iou0 = inter / ((scene.instances == 0) | free).sum()
    assert s["matched_iou"] == pytest.approx(iou0 / 2)  # one match over n + m - matches = 1 + 2 - 1
    assert s["n_gt_segments"] == 2 and s["matched_recall"] <= 0.5


def test_explored_mapping_needs_an_exploration_and_no_slam_estimate():
    scene = two_room_scene()
    poses = np.array([[0.5, 1.5, 0.0]])
    with pytest.raises(ValueError, match=r"^mapping=explored: the viewpoints stage made no map of its own; expected"):
        ExploredMapping()(scene, poses)
    e = Frontier(budget=1.0).explore(scene)
    with pytest.raises(ValueError, match=r"^mapping=explored: a SLAM pose error"):
        ExploredMapping()(scene, e.poses, estimate=(e.poses, e.poses, np.arange(len(e.poses))), exploration=e)


def test_only_the_frontier_explores_without_a_budget():
    assert Frontier(budget=math.inf).budget == math.inf
    with pytest.raises(ValueError, match=r"^viewpoints.budget = inf: expected metres > 0$"):
        RandomWalk(budget=math.inf)
    with pytest.raises(ValueError, match=r"^viewpoints.budget = nan: expected metres > 0 \(.inf: until no"):
        Frontier(budget=float("nan"))


def test_the_explore_family_has_its_own_severity_zero():
    assert RobotLabel.check({"corruption": "explore", "severity": 0}) == RobotLabel("explore", 0)
    assert "explore" in RobotLabel.own_severity_zero() and "scan" not in RobotLabel.own_severity_zero()
    with pytest.raises(ConfigError, match=r"^robot.severity=0 with robot.corruption='scan': expected severity 0"):
        RobotLabel.check({"corruption": "scan", "severity": 0})


@pytest.mark.slow
def test_every_method_and_segmenter_gets_the_explored_map(tmp_path):
    """explore_0 (no budget) and explore_5 (15 m): the segmenters and the methods score on the
    same explored map (equal map columns), unseen floor is unlabelled, and the short budget maps
    fewer rooms in some house while the unlimited robot maps them all."""
    full = _run(tmp_path, "s0", "corruption=explore_0", "segmenter=distance", "run.save_maps=true")
    short = _run(tmp_path, "s5", "corruption=explore_5", "segmenter=distance", "run.save_maps=true")
    method = _run(tmp_path, "m5", "corruption=explore_5")
    for df in (full, short, method):
        assert (df["status"] == "ok").all() and (df["viewpoints"] == "frontier").all()
        assert (df["rooms_mapped"] <= df["rooms_total"]).all() and (df["map_free_iou"] < 1).all()
    assert (full["rooms_mapped"] == full["rooms_total"]).all() and (full["map_missed_share"] < 0.1).all()
    assert (short["rooms_mapped"] < short["rooms_total"]).any() and (short["map_missed_share"] > 0.1).any()
    for col in ("map_free_iou", "rooms_mapped", "rooms_total"):  # one map for the segmenter and the method
        assert list(short[col]) == list(method[col])
    cfg, ch = compose_job([*FAST, f"run.results_dir={tmp_path / 'R'}", "corruption=explore_5", "segmenter=distance",
                           "run.save_maps=true"])
    pipe = build_pipeline(cfg, ch)
    for hid in short["house_id"]:
        m = load_npz(pipe.entry("maps", hid))
        assert (m["instances"][~m["free"]] == -1).all()
        e = pipe.stage("viewpoints").explore(pipe.scene(hid))
        assert (m["free"] <= e.scan_map.free).all()  # nothing beyond what the explorer's laser saw free


@pytest.mark.slow
def test_a_scan_map_along_the_mapping_run_is_the_mapper_on_that_route(tmp_path):
    """mapping.route=explore (the scan family): the harness's robot map is the scan mapper run on
    the frontier mapping route (called directly here); it is not the map along the views; an
    unknown route is refused in one line."""
    from benchmark.conditions.exploration import exploration_route
    from envs.maps.mapping import ScanMapping

    over = ["corruption=scan_3", "segmenter=distance", "run.save_maps=true"]
    df = _run(tmp_path, "scan3", *over)
    assert (df["status"] == "ok").all()
    cfg, ch = compose_job([*FAST, f"run.results_dir={tmp_path / 'R'}", *over])
    pipe = build_pipeline(cfg, ch)
    mapping = ScanMapping(**{k: v for k, v in cfg.mapping.items() if k != "_target_"})
    assert mapping.route == "explore"
    for hid in df["house_id"]:
        scene, house = pipe.scene(hid), pipe.env.house(hid)
        saved = load_npz(pipe.entry("maps", hid))["free"]
        # the route explored here (not the process's kept one): the frontier run of exploration_route
        drive = Frontier(budget=math.inf, spacing=1.0, n_headings=1, heading_spread=0.0).explore(scene).poses
        assert np.array_equal(drive, exploration_route(scene))
        assert np.array_equal(saved, mapping(scene, drive, house=house))
        views = pipe.stage("viewpoints").generate(scene)
        assert not np.array_equal(saved, mapping(scene, views, house=house))
    with pytest.raises(ValueError, match=r"^mapping.route='bogus': expected one of views, explore$"):
        ScanMapping(route="bogus")
    bad = _run(tmp_path, "slam", "corruption=slam_1", "mapping.route=explore", "segmenter=distance")
    assert (bad["status"] == "failed").all()
    assert bad["error"].str.contains("mapping.route=explore with a SLAM pose error that places the scans").all()



def test_the_mapping_route_is_explored_once_per_house_and_process(monkeypatch):
    """Every scan-map severity drives the same frontier route through a house: a process keeps it
    (read-only) by what the explorer reads, so a second call explores nothing, and a house whose
    walls differ, or another house id (its scan noise seed), is explored anew."""
    from benchmark.conditions import exploration as ex
    from envs.memo import ByteLRU

    monkeypatch.setattr(ex, "_ROUTES", ByteLRU())
    scene = two_room_scene()
    want = Frontier(budget=math.inf, spacing=1.0, n_headings=1, heading_spread=0.0).explore(scene).poses
    runs = []
    real = ex.Frontier._explore
    monkeypatch.setattr(ex.Frontier, "_explore",
                        lambda self, scene, obstacles: runs.append(scene.house_id) or real(self, scene, obstacles))
    first = ex.exploration_route(scene)
    assert np.array_equal(first, want) and not first.flags.writeable and len(runs) == 1
    assert np.array_equal(ex.exploration_route(scene), want) and len(runs) == 1
    other = two_room_scene()
    other.house_id = "another"
    ex.exploration_route(other)
    assert len(runs) == 2
    walled = two_room_scene()
    walled.grid.walkable[:, walled.grid.shape[1] // 2 + 3] = False  # a wall across the second room
    assert not np.array_equal(ex.exploration_route(walled), want) and len(runs) == 3
