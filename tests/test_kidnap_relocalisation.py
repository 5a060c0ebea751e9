"""The kidnapped robot relocalises (issue 58): the front end detects the loss of tracking (failed scan
matches in a row), starts a new segment behind a weak odometry edge and puts it back on the map by
two agreeing place matches (benchmark/conditions/front_end.py, module docstring 6)."""

from __future__ import annotations

import numpy as np
import pytest

from benchmark.classifiers.noise import text_key
from benchmark.conditions.slam import OdometrySlam

#: kidnap_1's odometry (conf/corruption/kidnap_1.yaml), views at the final optimum
KIDNAP = dict(alpha1=4e-05, alpha2=2e-05, alpha3=4e-05, alpha4=1e-05, views_at="final")


@pytest.fixture(scope="module")
def house(procthor_file):
    from benchmark.viewpoints import Autotrace
    from envs.datasets.house_files import load_houses
    from envs.maps.scene import rasterise_house

    # the third shared house: a kidnapping of 3 m from a point drawn on its 103 m route
    scene = rasterise_house(list(load_houses(procthor_file, 0, 3))[2])
    return scene, Autotrace().generate(scene)


def test_a_kidnapped_robot_detects_the_loss_and_relocalises_near_the_unkidnapped_estimate(house):
    scene, poses = house
    free = OdometrySlam(**KIDNAP).estimate(scene.grid, poses, "2", 0.5)
    carried = OdometrySlam(**KIDNAP, kidnap_m=3.0).estimate(scene.grid, poses, "2", 0.5)
    before = OdometrySlam(**KIDNAP, kidnap_m=3.0, lost_after=0).estimate(scene.grid, poses, "2", 0.5)
    assert carried.kidnapped_m >= 3.0
    # no loss on the route driven: no segment, nothing relocalised
    assert free.tracking_lost == 0 and free.relocalised == 0
    # the carry is detected and the segment after it put back on the map
    assert carried.tracking_lost >= 1 and carried.relocalised >= 1
    ate = {k: e.stats()["ate_rmse_m"] for k, e in (("free", free), ("carried", carried), ("before", before))}
    # without relocalisation (loss detection off: the chain as it was) the rest of the route is offset
    assert before.tracking_lost == 0 and ate["before"] > 1.0
    # relocalised: back near the un-kidnapped estimate; what is left is the carried stretch's own
    # nodes (no scan placed them: they ride with the segment after the carry, up to 3 m off)
    assert ate["carried"] < 0.1 * ate["before"] and ate["carried"] < ate["free"] + 0.4, ate
    carry = OdometrySlam(kidnap_m=3.0)._kidnap(carried.travelled, np.random.default_rng([0, text_key("slam", "2"), 4]))
    after = np.arange(np.flatnonzero(carry)[-1] + 2, len(carried.true))
    assert len(after) > 50
    off = np.hypot(*(carried.estimate[after, :2] - carried.true[after, :2]).T)
    free_off = np.hypot(*(free.estimate[after, :2] - free.true[after, :2]).T)
    # the route driven after the carry: within a few centimetres of where the un-kidnapped robot put it
    assert np.median(off) < np.median(free_off) + 0.1, (np.median(off), np.median(free_off))


def test_no_loss_is_detected_along_a_route_without_a_kidnapping_and_off_changes_nothing(house):
    scene, poses = house
    on = OdometrySlam(**KIDNAP).estimate(scene.grid, poses, "2", 0.5)
    off = OdometrySlam(**KIDNAP, lost_after=0).estimate(scene.grid, poses, "2", 0.5)
    assert on.tracking_lost == 0 and on.relocalised == 0
    np.testing.assert_array_equal(on.estimate, off.estimate)
    np.testing.assert_array_equal(on.odometry, off.odometry)


def test_the_loss_and_relocalisation_counts_reach_the_row_and_the_cache_entry(house):
    from benchmark.harness.entries import check_slam_entry, slam_arrays
    from benchmark.method import PoseErrorTransform

    scene, poses = house
    slam = OdometrySlam(**KIDNAP, kidnap_m=3.0)
    _, stats = slam(poses, scene.grid, "2", spacing=0.5)
    est = slam.estimate(scene.grid, poses, "2", 0.5)
    assert stats["slam_tracking_lost"] == est.tracking_lost >= 1
    assert stats["slam_relocalised"] == est.relocalised >= 1
    assert {"slam_tracking_lost", "slam_relocalised"} <= set(PoseErrorTransform.KEEP)
    back = check_slam_entry(slam_arrays(est), len(poses))
    assert (back.tracking_lost, back.relocalised) == (est.tracking_lost, est.relocalised)
    assert back.stats()["slam_tracking_lost"] == stats["slam_tracking_lost"]


def test_bad_loss_settings_are_one_line():
    with pytest.raises(ValueError, match=r"pose_error.lost_after = 1.5: expected an integer >= 0"):
        OdometrySlam(lost_after=1.5)
    with pytest.raises(ValueError, match=r"pose_error.lost_sigma_xy = 0: expected metres > 0"):
        OdometrySlam(lost_sigma_xy=0)
    with pytest.raises(ValueError, match=r"pose_error.relocalise_yaw = 200: expected degrees in \(0, 180\]"):
        OdometrySlam(relocalise_yaw=200)
