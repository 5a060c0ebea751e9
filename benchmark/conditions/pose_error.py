"""View poses as SLAM gives them: noise, drift with distance travelled, loop-closure jumps.

The method receives perturbed poses; the camera still looked from the true ones (the
observations are not re-rendered). For view ``i`` at ``travelled[i]`` metres along the robot's
route (:func:`envs.maps.trajectory.view_distances` over the true poses):

* **Gaussian noise**: x and z each get an independent N(0, ``sigma_xy``) metres, the yaw
  N(0, ``sigma_yaw``) degrees, drawn per view.
* **Drift**: grows linearly with the distance travelled since the last loop closure,
  ``d = travelled - k * loop_closure`` (``k`` = closures passed; ``d = travelled`` without loop
  closures): the position is off by ``drift_xy * d`` metres along a direction drawn uniformly
  per segment between closures, the yaw by ``drift_yaw * d`` degrees with a sign drawn per
  segment.
* **Loop closure**: every ``loop_closure`` metres of travel the drift returns to zero, so the
  error jumps back (SLAM's correction at a recognised place).

All settings zero -> the poses come back unchanged, bit for bit. Perturbed poses are not
snapped to the map: a view that lands off the walkable cells is dropped by the aggregators
(which log how many), and the stats report the share.

What it leaves out: the coupling of heading error into position (a real odometry's
position drift grows faster than linearly once the heading is off), correlated noise between
consecutive views, the loop closure's own residual error, and re-localisation failures.
"""

from __future__ import annotations

import math
from typing import Annotated

import numpy as np

from benchmark.classifiers.noise import text_key
from envs.maps.gridmap import GridMap
from envs.maps.trajectory import view_distances
from envs.ranges import NonNegative, Positive


def _check(key: str, value, *, allow_none: bool = False) -> None:
    if allow_none and value is None:
        return
    ok = isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
    ok = ok and (value > 0 if allow_none else value >= 0)
    if not ok:
        want = "metres > 0, or null (no loop closures)" if allow_none else "a number >= 0"
        raise ValueError(f"pose_error.{key} = {value!r}: expected {want}")


def _all_zero(sigma_xy, sigma_yaw, drift_xy, drift_yaw) -> bool:
    return sigma_xy == 0 and sigma_yaw == 0 and drift_xy == 0 and drift_yaw == 0


def perturb_poses(poses: np.ndarray, travelled: np.ndarray, sigma_xy: float = 0.0, sigma_yaw: float = 0.0,
                  drift_xy: float = 0.0, drift_yaw: float = 0.0, loop_closure: float | None = None,
                  rng: np.random.Generator | None = None) -> np.ndarray:
    """Poses as SLAM would report them (module docstring).

    Args:
        poses: (N, 3) true x, z (metres), yaw (degrees).
        travelled: (N,) metres travelled up to each view (non-decreasing).
        sigma_xy: Gaussian sigma of x and of z, metres.
        sigma_yaw: Gaussian sigma of the yaw, degrees.
        drift_xy: position drift, metres per metre travelled.
        drift_yaw: heading drift, degrees per metre travelled.
        loop_closure: metres of travel between loop closures, or None.
        rng: the random generator (required unless every setting is zero).

    Returns:
        (N, 3) perturbed poses; yaw in [0, 360) when the yaw is perturbed, else the input's.
    """
    for key, v in (("sigma_xy", sigma_xy), ("sigma_yaw", sigma_yaw), ("drift_xy", drift_xy),
                   ("drift_yaw", drift_yaw)):
        _check(key, v)
    _check("loop_closure", loop_closure, allow_none=True)
    poses = np.asarray(poses, np.float64)
    if poses.ndim != 2 or poses.shape[1] != 3:
        raise ValueError(f"poses must be (N, 3) x, z, yaw; got shape {poses.shape}")
    travelled = np.asarray(travelled, np.float64)
    if travelled.shape != (len(poses),):
        raise ValueError(f"travelled must be ({len(poses)},) metres, got shape {travelled.shape}")
    if _all_zero(sigma_xy, sigma_yaw, drift_xy, drift_yaw) or len(poses) == 0:
        return poses.copy()
    if rng is None:
        raise ValueError("perturb_poses needs an rng when any error setting is non-zero")
    segment = (np.floor(travelled / loop_closure).astype(np.int64) if loop_closure is not None
               else np.zeros(len(poses), np.int64))
    since = travelled - segment * (loop_closure if loop_closure is not None else 0.0)
    n_seg = int(segment.max()) + 1
    # every draw is made whatever the settings, so severities share their random numbers
    angle = rng.uniform(0.0, 2.0 * np.pi, n_seg)
    sign = np.where(rng.random(n_seg) < 0.5, -1.0, 1.0)
    noise = rng.standard_normal((len(poses), 3))
    out = poses.copy()
    out[:, 0] += sigma_xy * noise[:, 0] + drift_xy * since * np.sin(angle[segment])
    out[:, 1] += sigma_xy * noise[:, 1] + drift_xy * since * np.cos(angle[segment])
    if sigma_yaw != 0 or drift_yaw != 0:
        out[:, 2] = np.mod(out[:, 2] + sigma_yaw * noise[:, 2] + drift_yaw * since * sign[segment], 360.0)
    return out


def pose_error_stats(true: np.ndarray, noisy: np.ndarray, grid: GridMap | None = None) -> dict:
    """Position error (metres, mean and max), absolute yaw error (degrees, mean, wrapped to
    [0, 180]) and, given a grid, the share of noisy poses off its walkable cells."""
    true, noisy = np.asarray(true, np.float64), np.asarray(noisy, np.float64)
    if len(true) == 0:
        stats = {"pose_error_mean_m": 0.0, "pose_error_max_m": 0.0, "yaw_error_mean_deg": 0.0}
    else:
        d = np.hypot(noisy[:, 0] - true[:, 0], noisy[:, 1] - true[:, 1])
        dyaw = np.abs(np.mod(noisy[:, 2] - true[:, 2] + 180.0, 360.0) - 180.0)
        stats = {"pose_error_mean_m": float(d.mean()), "pose_error_max_m": float(d.max()),
                 "yaw_error_mean_deg": float(dyaw.mean())}
    if grid is not None:
        r, c = grid.world_to_cell(noisy[:, 0], noisy[:, 1]) if len(noisy) else (np.zeros(0, int), np.zeros(0, int))
        stats["pose_off_walkable"] = float((~grid.is_walkable(r, c)).mean()) if len(noisy) else 0.0
    return stats


class PoseError:
    """The pose-error stage: perturbs the poses the method receives (module docstring).

    Args:
        sigma_xy: Gaussian sigma of x and z, metres.
        sigma_yaw: Gaussian sigma of the yaw, degrees.
        drift_xy: position drift, metres per metre travelled.
        drift_yaw: heading drift, degrees per metre travelled.
        loop_closure: metres of travel between loop closures, or None (never).
        seed: with the house id, seeds the draws.
    """

    def __init__(self, sigma_xy: Annotated[float, NonNegative()] = 0.0,
                 sigma_yaw: Annotated[float, NonNegative()] = 0.0,
                 drift_xy: Annotated[float, NonNegative()] = 0.0,
                 drift_yaw: Annotated[float, NonNegative()] = 0.0,
                 loop_closure: Annotated[float | None, Positive()] = None, seed: int = 0):
        for key, v in (("sigma_xy", sigma_xy), ("sigma_yaw", sigma_yaw), ("drift_xy", drift_xy),
                       ("drift_yaw", drift_yaw)):
            _check(key, v)
        _check("loop_closure", loop_closure, allow_none=True)
        if isinstance(seed, bool) or not isinstance(seed, int):
            raise ValueError(f"pose_error.seed = {seed!r}: expected an integer")
        self.sigma_xy, self.sigma_yaw, self.drift_xy, self.drift_yaw = sigma_xy, sigma_yaw, drift_xy, drift_yaw
        self.loop_closure, self.seed = loop_closure, seed

    @property
    def is_clean(self) -> bool:
        """True when every setting is zero (the poses pass through unchanged)."""
        return _all_zero(self.sigma_xy, self.sigma_yaw, self.drift_xy, self.drift_yaw)

    def __call__(self, poses: np.ndarray, grid: GridMap, house_id: str,
                 travelled: np.ndarray | None = None) -> tuple[np.ndarray, dict]:
        """(noisy (N, 3) poses, stats) for one house's views.

        Args:
            poses: (N, 3) true poses in capture order.
            grid: the house's map (the route is planned on its walkable cells).
            house_id: seeds the draws with ``seed``.
            travelled: (N,) metres travelled up to each view when the caller knows it (an
                exploration's odometer); default :func:`view_distances` over the true poses.
        """
        poses = np.asarray(poses, np.float64).reshape(-1, 3)
        if self.is_clean:
            noisy = poses.copy()
        else:
            if travelled is None:
                travelled = view_distances(grid.walkable, grid, poses)
            rng = np.random.default_rng([self.seed, text_key("pose_error", house_id)])
            noisy = perturb_poses(poses, travelled, self.sigma_xy, self.sigma_yaw, self.drift_xy, self.drift_yaw,
                                  self.loop_closure, rng)
        return noisy, pose_error_stats(poses, noisy, grid)


__all__ = ["PoseError", "perturb_poses", "pose_error_stats"]
