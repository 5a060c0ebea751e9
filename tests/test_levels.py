"""The robustness levels (issue 58 items 1 and 5): the `realistic` levels run on the one pose
estimate (odometry SLAM on the scan map, with every scan-level setting), the scan and realistic
levels use closed doors, people, grazing and surface dropout at rising severities, the views-only
`pose` family is an ablation in neither mCE nor the mean drop, and surface dropout (glass, dark
walls) is in the compiled scan kernels as in the slow reference, and changes nothing at 0."""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hydra import compose, initialize_config_dir
from hydra.core.global_hydra import GlobalHydra

from benchmark.paths import CONF_DIR
from benchmark.reports import robustness as rb
from envs.datasets.synthetic import generate_house
from envs.maps.scan import (
    DARK_SHARE,
    GLASS_SHARE,
    ScanSettings,
    scan_map,
    scan_map_reference,
    scan_obstacles,
    scan_ranges,
    surface_shares,
)
from envs.maps.scene import rasterise_house
from envs.maps.slam_map import scan_map_at_estimate
from envs.world.house import House

SEVERITIES = range(1, 6)


def _level(name: str):
    GlobalHydra.instance().clear()
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base=None):
        return compose("config", [f"corruption={name}"])


# ---------------------------------------------------------------- the levels


@pytest.mark.parametrize("k", SEVERITIES)
def test_every_realistic_level_is_odometry_slam_on_the_scan_map_with_the_matching_levels(k):
    real, scan, slam, explore, clf = (_level(f"{f}_{k}") for f in ("realistic", "scan", "slam", "explore", "classifier"))
    # one pose estimate: odometry SLAM that places the scans, never views-only noise on a perfect map
    assert real.pose_error._target_ == "benchmark.conditions.slam.OdometrySlam"
    assert real.mapping._target_ == "envs.maps.mapping.ScanMapping" and real.mapping.route == "views"
    assert real.viewpoints._target_.endswith("Frontier") and real.label_noise is not None
    for a in ("alpha1", "alpha2", "alpha3", "alpha4"):
        assert real.pose_error[a] == slam.pose_error[a] > 0
    # the scanner, and what the house does to it, at the scan level's severity
    for key in ("max_range", "range_noise", "dropout", "door_closed", "people", "person_radius", "grazing_dropout",
                "surface_dropout"):
        assert real.mapping[key] == scan.mapping[key], key
    assert real.mapping.legs == slam.mapping.legs is True
    # the SLAM front end matches the scans of the same scanner; so does the slam level's
    for lvl in (real, slam):
        for key in ("max_range", "range_noise", "dropout"):
            assert lvl.pose_error[key] == scan.mapping[key] == lvl.mapping[key], key
    assert real.viewpoints.budget == explore.viewpoints.budget
    assert real.label_noise.share == clf.label_noise.share
    assert real.robot.corruption == "realistic" and real.robot.severity == k


def test_scan_and_realistic_levels_rise_in_doors_people_grazing_and_surface_dropout():
    for family in ("scan", "realistic"):
        levels = [_level(f"{family}_{k}").mapping for k in SEVERITIES]
        for key in ("door_closed", "people", "grazing_dropout", "surface_dropout", "range_noise", "dropout"):
            values = [m[key] for m in levels]
            assert all(a < b for a, b in zip(values[1:], values[2:])) and values == sorted(values), (family, key)
            assert values[-1] > 0, (family, key)
        assert [m.max_range for m in levels] == sorted((m.max_range for m in levels), reverse=True)
    # clean (severity 0 of every family but explore) builds no scan map and keeps the poses exact
    clean = _level("clean")
    assert clean.get("mapping") is None and clean.get("pose_error") is None


def test_the_pose_family_is_labelled_views_only_on_a_perfect_map():
    for k in SEVERITIES:
        lvl = _level(f"pose_{k}")
        assert lvl.pose_error._target_.endswith("pose_error.PoseError") and lvl.get("mapping") is None
        text = (Path(CONF_DIR) / "corruption" / f"pose_{k}.yaml").read_text()
        assert "views-only pose noise, perfect map" in text and "Ablation" in text
    assert "views-only pose noise, perfect map" in rb.FAMILY_WORDS["pose"]


@pytest.mark.slow
def test_a_realistic_row_carries_the_trajectory_error(tmp_path):
    from benchmark.config import compose_job
    from benchmark.harness.runner import run

    cfg, ch = compose_job(["env=synthetic", "env.resolution=0.1", "env.n_houses=1", "classifier=oracle",
                           "aggregator=vision_cone", "run.progress=false", f"run.results_dir={tmp_path / 'R'}",
                           "corruption=realistic_2"])
    df = run(cfg, tmp_path / "R" / "jobs" / "r", ch)
    assert (df["status"] == "ok").all() and set(df["corruption"]) == {"realistic"}
    assert "ate_rmse_m" in df and np.isfinite(df["ate_rmse_m"].astype(float)).all()
    assert (df["ate_rmse_m"].astype(float) > 0).all() and (df["map_free_iou"] < 1).all()


# ---------------------------------------------------------------- the ablation in the report


def _rows() -> pd.DataFrame:
    """Two methods, three houses: clean, scan and slam degrade both (A more); the views-only
    ablation `pose` hurts B a lot and A not at all, so that it would move mCE and the mean drop,
    and rule A out as the reference, if it counted."""
    rows = []
    for h in range(3):
        for m, base in (("A", 0.8), ("B", 0.7)):
            rows.append(dict(method=m, corruption="clean", severity=0, house_id=f"h{h}", iou=base + 0.01 * h))
            for s in SEVERITIES:
                rows.append(dict(method=m, corruption="scan", severity=s, house_id=f"h{h}",
                                 iou=base - 0.02 * s + 0.01 * h))
                rows.append(dict(method=m, corruption="slam", severity=s, house_id=f"h{h}",
                                 iou=base - (0.03 if m == "A" else 0.01) * s + 0.01 * h))
                rows.append(dict(method=m, corruption="pose", severity=s, house_id=f"h{h}",
                                 iou=base - (0.1 * s if m == "B" else 0.0) + 0.01 * h))
    return pd.DataFrame(rows).assign(status="ok")


def test_the_views_only_ablation_is_in_neither_mce_nor_the_mean_drop():
    assert "pose" in rb.ABLATION and "pose" in rb.APART
    cells = rb.cell_means(_rows(), "iou")
    t = rb.summary_table(cells, "A")
    for m in ("A", "B"):
        assert t.loc[m, "mCE"] == pytest.approx((t.loc[m, "CE scan"] + t.loc[m, "CE slam"]) / 2)
        assert t.loc[m, "rel mCE"] == pytest.approx((t.loc[m, "rel CE scan"] + t.loc[m, "rel CE slam"]) / 2)
        assert t.loc[m, "mean drop"] == pytest.approx((t.loc[m, "drop scan"] + t.loc[m, "drop slam"]) / 2)
    # it is still shown, apart (after the mean drop), with its drop
    cols = list(t.columns)
    assert cols.index("pose") > cols.index("mean drop") and t.loc["B", "drop pose"] == pytest.approx(30.0)
    assert any("views-only pose noise, perfect map (ablation)" in n and "neither mCE nor the mean drop" in n
               for n in t.attrs["notes"])
    # the reference pick ignores it: `pose` leaves A untouched, every family that counts degrades it
    auto = rb.summary_table(cells, None, values=rb.house_values(_rows(), "iou"), n_boot=200)
    assert auto.attrs["reference"] == "A"
    assert not any(n.startswith("No CE for scan") or n.startswith("No CE for SLAM") for n in auto.attrs["notes"])


# ---------------------------------------------------------------- surface dropout


@pytest.fixture(scope="module")
def glass_house():
    """A generated house whose first window reaches down to 0.1 m (glass at the 0.25 m scan plane)
    and one other wall of that room of a dark material; 12 scan poses in that room."""
    h = generate_house(3)
    data = copy.deepcopy(h.data)
    window = data["windows"][0]
    window["holePolygon"][0]["y"] = 0.1
    dark = next(w for w in data["walls"] if w["roomId"] == window["room0"] and w["id"] != window["wall0"])
    dark["material"] = {"name": "DarkGranite"}
    scene = rasterise_house(House(h.id, data), resolution=0.1)
    room = [r["id"] for r in data["rooms"]].index(window["room0"])
    cells = np.argwhere(scene.instances == room)
    pick = cells[np.random.default_rng(0).choice(len(cells), 12, replace=False)]
    poses = np.array([[*scene.grid.pixel_to_world(r, c), 30.0 * i] for i, (r, c) in enumerate(pick)], float)
    return h, scene, poses


def test_surface_shares_mark_glass_at_the_scan_plane_and_dark_walls(glass_house):
    h, scene, _ = glass_house
    shares = surface_shares(scene, 0.25)
    glass, dark = shares == GLASS_SHARE, shares == DARK_SHARE
    assert glass.sum() >= 5 and dark.sum() >= 10 and set(np.unique(shares)) == {0.0, DARK_SHARE, GLASS_SHARE}
    assert scene.walls[glass].all() and scene.walls[dark].all()
    # a plane above the window's top sees wall; the house as generated (windows from 0.9 m) has no glass there
    assert not (surface_shares(scene, 2.0) == GLASS_SHARE).any()
    assert not surface_shares(rasterise_house(h, resolution=0.1), 0.25).any()


def test_a_glass_wall_gets_no_hits_at_surface_dropout_one(glass_house):
    _, scene, poses = glass_house
    shares = surface_shares(scene, 0.25)
    glass = shares == GLASS_SHARE
    obstacles = scan_obstacles(scene, 0.25)
    seen = scan_map(obstacles, scene.grid, poses, ScanSettings(angular_step=2.0), shares)
    assert (seen.log_odds[glass] > 0).sum() >= 3  # without surface dropout the laser sees the pane
    for mapped in (scan_map(obstacles, scene.grid, poses, ScanSettings(angular_step=2.0, surface_dropout=1.0), shares),
                   scan_map_at_estimate(obstacles, scene.grid, poses, poses,
                                        ScanSettings(angular_step=2.0, surface_dropout=1.0), shares)):
        assert not (mapped.log_odds[glass] > 0).any()
        assert (mapped.log_odds[shares == 0] > 0).sum() > 100  # the other walls still return
    ranges, _, _ = scan_ranges(obstacles, scene.grid, poses, ScanSettings(angular_step=2.0, surface_dropout=1.0),
                               shares)
    assert np.isnan(ranges).sum() > np.isnan(scan_ranges(obstacles, scene.grid, poses,
                                                         ScanSettings(angular_step=2.0), shares)[0]).sum()


@pytest.mark.parametrize("settings", [
    ScanSettings(angular_step=2.0, surface_dropout=1.0),
    ScanSettings(angular_step=2.0, surface_dropout=0.6, range_noise=0.03, dropout=0.1, seed=3),
    ScanSettings(angular_step=3.0, surface_dropout=0.8, grazing_dropout=0.5, max_range=4.0, seed=5),
    ScanSettings(angular_step=3.0, surface_dropout=0.4, grazing_dropout=0.3, people=3, range_noise=0.05, seed=7),
])
def test_the_compiled_kernel_equals_the_reference_with_surface_dropout(glass_house, settings):
    _, scene, poses = glass_house
    shares = surface_shares(scene, 0.25)
    obstacles = scan_obstacles(scene, 0.25)
    fast = scan_map(obstacles, scene.grid, poses, settings, shares)
    ref = scan_map_reference(obstacles, scene.grid, poses, settings, shares)
    assert fast.n_scans == ref.n_scans == len(poses)
    np.testing.assert_array_equal(fast.log_odds, ref.log_odds)
    np.testing.assert_array_equal(fast.occupancy, ref.occupancy)


@pytest.mark.parametrize("settings", [ScanSettings(angular_step=2.0, range_noise=0.03, dropout=0.1, seed=3),
                                      ScanSettings(angular_step=3.0, grazing_dropout=0.5, people=2, seed=5)])
def test_surface_dropout_zero_changes_nothing_bit_for_bit(glass_house, settings):
    """At surface_dropout 0 the shares are never read and no draw is added: the maps (and a SLAM
    map at the true poses) are those without shares, bit for bit, so severity 0 stays clean."""
    _, scene, poses = glass_house
    shares = surface_shares(scene, 0.25)
    obstacles = scan_obstacles(scene, 0.25)
    np.testing.assert_array_equal(scan_map(obstacles, scene.grid, poses, settings, shares).log_odds,
                                  scan_map(obstacles, scene.grid, poses, settings).log_odds)
    np.testing.assert_array_equal(scan_map_at_estimate(obstacles, scene.grid, poses, poses, settings, shares).log_odds,
                                  scan_map_at_estimate(obstacles, scene.grid, poses, poses, settings).log_odds)


def test_surface_dropout_is_checked_in_one_line():
    with pytest.raises(ValueError, match=r"surface_dropout = 1\.5: expected a share in \[0, 1\]"):
        ScanSettings(surface_dropout=1.5).check()
    with pytest.raises(ValueError, match=r"mapping\.surface_dropout = -0\.1"):
        ScanSettings(surface_dropout=-0.1).check({"surface_dropout": "mapping.surface_dropout"})
