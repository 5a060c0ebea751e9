"""Pose error (benchmark/conditions/pose_error.py): known answers on a straight trajectory."""

import numpy as np
import pytest

from benchmark.conditions.pose_error import PoseError, perturb_poses, pose_error_stats
from envs.maps.gridmap import GridMap


def _line(n=11, step=1.0):
    """Views every ``step`` metres along +x, yaw 90 (facing +x); travelled = their x."""
    x = np.arange(n) * step + 0.5
    poses = np.column_stack([x, np.full(n, 1.0), np.full(n, 90.0)])
    return poses, x - x[0]


def test_zero_settings_change_nothing_bit_for_bit():
    poses = np.array([[1.0, -0.0, 370.0], [0.1 + 0.2, 3.0, -45.0]])
    out = perturb_poses(poses, np.array([0.0, 1.0]), rng=np.random.default_rng(0))
    assert out.tobytes() == poses.tobytes() and out is not poses
    grid = GridMap(np.ones((10, 10), bool), 0.5, (0.0, 5.0))
    noisy, stats = PoseError()(poses, grid, "h")
    assert noisy.tobytes() == poses.tobytes()
    assert stats["pose_error_mean_m"] == 0 and stats["pose_error_max_m"] == 0 and stats["yaw_error_mean_deg"] == 0


def test_drift_grows_with_distance():
    poses, travelled = _line()
    out = perturb_poses(poses, travelled, drift_xy=0.1, drift_yaw=2.0, rng=np.random.default_rng(1))
    err = out[:, :2] - poses[:, :2]
    np.testing.assert_allclose(np.hypot(*err.T), 0.1 * travelled, atol=1e-12)
    # one direction for the whole run (no loop closure)
    unit = err[1:] / np.hypot(*err[1:].T)[:, None]
    np.testing.assert_allclose(unit, np.tile(unit[0], (len(unit), 1)), atol=1e-12)
    dyaw = np.mod(out[:, 2] - poses[:, 2] + 180, 360) - 180
    np.testing.assert_allclose(np.abs(dyaw), 2.0 * travelled, atol=1e-9)
    assert len(np.unique(np.sign(dyaw[1:]))) == 1


def test_loop_closures_reset_the_drift():
    poses, travelled = _line(n=13)  # travelled 0, 1, ..., 12
    out = perturb_poses(poses, travelled, drift_xy=0.1, loop_closure=4.0, rng=np.random.default_rng(2))
    err = np.hypot(*(out[:, :2] - poses[:, :2]).T)
    np.testing.assert_allclose(err, 0.1 * np.mod(travelled, 4.0), atol=1e-12)
    assert err[4] == 0 and err[8] == 0 and err[12] == 0  # the jump back at each closure
    d = out[:, :2] - poses[:, :2]
    directions = [d[k] / np.hypot(*d[k]) for k in (1, 5, 9)]
    for seg, k in ((0, 1), (1, 5), (2, 9)):
        for j in range(k, k + 3):
            np.testing.assert_allclose(d[j] / np.hypot(*d[j]), directions[seg], atol=1e-12)
    assert not np.allclose(directions[0], directions[1])  # a new direction after a closure


def test_gaussian_sigmas():
    n = 20000
    poses = np.column_stack([np.zeros(n), np.zeros(n), np.full(n, 180.0)])
    out = perturb_poses(poses, np.zeros(n), sigma_xy=0.2, sigma_yaw=5.0, rng=np.random.default_rng(3))
    assert np.std(out[:, 0]) == pytest.approx(0.2, rel=0.05)
    assert np.std(out[:, 1]) == pytest.approx(0.2, rel=0.05)
    assert abs(np.mean(out[:, 0])) < 0.01
    assert np.std(out[:, 2]) == pytest.approx(5.0, rel=0.05)
    assert abs(np.mean(out[:, 2]) - 180.0) < 0.2
    assert np.corrcoef(out[:, 0], out[:, 1])[0, 1] == pytest.approx(0.0, abs=0.03)
    stats = pose_error_stats(poses, out)
    # mean of a Rayleigh distance: sigma * sqrt(pi / 2)
    assert stats["pose_error_mean_m"] == pytest.approx(0.2 * np.sqrt(np.pi / 2), rel=0.05)


def test_stage_uses_the_route_and_the_house():
    walk = np.zeros((20, 240), bool)
    walk[2:18, 2:238] = True
    grid = GridMap(walk, 0.05, (0.0, 1.0))
    poses, travelled = _line(n=11)  # 10 m along the corridor, 1 m apart
    poses[:, 1] = 0.5
    stage = PoseError(drift_xy=0.05, seed=4)
    noisy, stats = stage(poses, grid, "house-a")
    np.testing.assert_allclose(np.hypot(*(noisy[:, :2] - poses[:, :2]).T), 0.05 * travelled, atol=1e-9)
    assert stats["pose_error_max_m"] == pytest.approx(0.5)
    assert stats["pose_error_mean_m"] == pytest.approx(0.05 * travelled.mean())
    again, _ = stage(poses, grid, "house-a")
    np.testing.assert_array_equal(noisy, again)
    other, _ = stage(poses, grid, "house-b")
    assert not np.array_equal(noisy, other)
    assert 0 <= stats["pose_off_walkable"] <= 1
    # the caller's own odometer when given
    given, _ = stage(poses, grid, "house-a", travelled=2 * travelled)
    np.testing.assert_allclose(np.hypot(*(given[:, :2] - poses[:, :2]).T), 0.1 * travelled, atol=1e-9)


@pytest.mark.parametrize("kw, key", [
    (dict(sigma_xy=-0.1), "sigma_xy"),
    (dict(sigma_yaw=-1), "sigma_yaw"),
    (dict(drift_xy=float("nan")), "drift_xy"),
    (dict(drift_yaw=-0.5), "drift_yaw"),
    (dict(loop_closure=0), "loop_closure"),
    (dict(loop_closure=-5.0), "loop_closure"),
])
def test_bad_settings_one_line(kw, key):
    with pytest.raises(ValueError) as e:
        PoseError(**kw)
    msg = str(e.value)
    assert "\n" not in msg and key in msg and "expected" in msg
