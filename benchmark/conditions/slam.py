"""One robot, one pose estimate: odometry along the driven path, loop closures, a pose-graph solve.

``pose_error=odometry`` (:class:`OdometrySlam`). The robot drives its route through the views
(:func:`envs.maps.trajectory.trajectory_with_views`: a node every ``spacing`` metres of path and
one at every view). Its estimate of where it was at each node is what a graph-SLAM system gives:

1. **Odometry** (:mod:`benchmark.conditions.odometry`): the moves between consecutive nodes reported with
   the coupled rot1 / trans / rot2 noise of Probabilistic Robotics (``alpha1..alpha4``), so a
   heading error bends every later move.
2. **The front end** (:mod:`benchmark.conditions.front_end`, on the correlative scan matcher of
   :mod:`benchmark.conditions.scan_matching`): a scan at every node, measured at its true pose on the
   scan plane's obstacles (the mapping stage's walls, furniture legs and closed doors, which the
   harness hands over; the route grid's non-walkable cells without them); laser odometry (each scan matched to the previous one around the
   wheel move, fused with it) makes the odometry edges, so the heading comes from the scans; loop
   closures are proposed from the robot's own estimate (a Mahalanobis gate on the chained relative
   pose, ``closure_radius`` metres) and accepted when the match scores ``closure_min_score``.
3. **Wrong loop closures** come from places that look alike (two identical rooms, a corridor):
   accepted matches whose matched relative pose is off the true one
   (:data:`benchmark.conditions.front_end.WRONG_XY` m, ``WRONG_YAW`` deg) are counted
   (``wrong_closures``). The lost robot (``lost_k``) is a front end that accepts more loosely and
   searches wider. A **kidnapping** (``kidnap_m``): for ``kidnap_m`` metres of route from a point drawn after
   ``closure_min_travel`` metres the robot is carried: odometry reports no move and no turn
   (with the confidence of a robot standing still). The front end detects the loss of tracking
   (scans that no longer match, several moves in a row), cuts the chain there (weak odometry edges)
   and relocalises the segment after it by verified place matches on the earlier map
   (:mod:`benchmark.conditions.front_end`, 6; ``slam_tracking_lost``, ``slam_relocalised``).
4. **Pose-graph solve** (:mod:`benchmark.conditions.pose_graph`, on GTSAM): odometry edges (information
   from the motion model's covariance of the *reported* moves, Gaussian) and closure edges under a
   robust kernel (``robust_kernel``, default ``cauchy``: a closure whose error is many sigmas off
   weighs little), Levenberg-Marquardt from the dead-reckoning chain run to convergence (at most
   ``max_iterations``; a solve cut off there is recorded, ``slam_converged`` 0), node 0 fixed at the
   true start (the map's frame is the robot's start pose). Noisy edges leave a residual.

The corrected node poses (the final optimum) are the robot's map estimate: the scan map is built by
inserting each scan (ranges measured from the true pose) at the estimated node pose
(:func:`envs.maps.slam_map.scan_map_at_estimate`, through ``mapping=scan``). The views take
``views_at``: ``online``, the estimate the robot had when it took the view (iSAM2 updated node by
node, :func:`benchmark.conditions.pose_graph.online`), or ``final``, the same final optimum as the
map. Every alpha 0, no wrong closures and no kidnapping: the true poses unchanged, bit for bit.

Leaves out: wheel slip events and bumps (heavy-tailed odometry), a scan matcher's own failure
modes other than the wrong closures (degenerate corridors), closures found by appearance
beyond ``closure_radius``, and a map rebuilt online (the map is built at the final optimum).
"""

from __future__ import annotations

import math
import zlib
from collections import OrderedDict
from dataclasses import dataclass, replace

import numpy as np

from benchmark.classifiers.noise import text_key
from benchmark.conditions.alignment import ate_rmse
from benchmark.conditions.front_end import FrontEndSettings, run_front_end
from benchmark.conditions.odometry import (
    from_se2,
    increments,
    move_sigmas,
    noisy_moves,
    to_se2,
)
from benchmark.conditions.pose_error import pose_error_stats
from benchmark.conditions.pose_graph import (
    PoseGraph,
    check_kernel,
    gtsam_reason,
    move_edge,
    online,
    solve,
)
from envs.maps.gridmap import GridMap
from envs.maps.trajectory import trajectory_with_views

#: sigma floor (metres, radians) for an edge measured exactly, so its information is finite
SIGMA_FLOOR = 1e-3


@dataclass
class SlamEstimate:
    """The robot's trajectory and its estimate.

    Attributes:
        true: (M, 3) true node poses (x, z metres, yaw degrees) in travel order.
        estimate: (M, 3) the corrected estimate (same units).
        odometry: (M, 3) dead reckoning (before the solve).
        view_index: (N,) node index of each view.
        travelled: (M,) metres driven up to each node.
        closures: (C, 2) node pairs (i, j) of the true loop closures.
        wrong: (W, 2) node pairs of the wrong ones.
        chi2: the solve's final sum of squared whitened residuals; dof its degrees of freedom.
        kidnapped_m: metres of route driven while carried (the whole moves overlapping the window).
        converged: False when the solve was cut off at its iteration cap (or GNC's weights did not settle).
        iterations: the final Levenberg-Marquardt solve's iterations.
        rejected: loop closures (true or wrong) the robust back end rejected or down-weighted.
        tracking_lost: tracking losses the front end detected (failed scan matches in a row).
        relocalised: segments after a loss the front end put back on the map (verified place matches).
        online: (N, 3) each view's pose as the robot estimated it when taking the view (made
            whatever ``views_at`` says, so that one estimate serves both), or None where no loop
            closure was found (then it is ``estimate``'s, dead reckoning at every moment).
        odometry_edges: (M-1, 3) the odometry edges the back end got (the front end's fused moves
            between consecutive nodes: dx, dz metres in the earlier node's frame, dphi radians), or
            None where there is no front end (a clean estimate) or it is not kept (a cached one).
    """

    true: np.ndarray
    estimate: np.ndarray
    odometry: np.ndarray
    view_index: np.ndarray
    travelled: np.ndarray
    closures: np.ndarray
    wrong: np.ndarray
    chi2: float = 0.0
    dof: int = 0
    kidnapped_m: float = 0.0
    converged: bool = True
    iterations: int = 0
    rejected: int = 0
    online: np.ndarray | None = None
    odometry_edges: np.ndarray | None = None
    tracking_lost: int = 0
    relocalised: int = 0
    views_at: str = "online"

    @property
    def views(self) -> np.ndarray:
        """(N, 3) the views' estimated poses, as :attr:`views_at` says: ``online`` (:attr:`online`
        where set) or ``final`` (the final estimate's)."""
        return self.view_poses(self.views_at)

    def view_poses(self, views_at: str) -> np.ndarray:
        """(N, 3) the views' estimated poses at capture time (``online``) or at the final optimum
        (``final``)."""
        if views_at not in ("online", "final"):
            raise ValueError(f"views_at = {views_at!r}: expected online or final")
        return self.estimate[self.view_index] if views_at == "final" or self.online is None else self.online

    def stats(self) -> dict[str, float]:
        """Row columns: ATE RMSE after rigid alignment of the whole trajectory (metres), the same
        for dead reckoning, route length, closures found and wrong, chi2 per degree of freedom.
        Computed once per estimate (an estimate is not changed once made)."""
        got = self.__dict__.get("_stats")
        if got is None:
            got = {"ate_rmse_m": ate_rmse(self.estimate[:, :2], self.true[:, :2]),
                   "odometry_ate_rmse_m": ate_rmse(self.odometry[:, :2], self.true[:, :2]),
                   "route_m": float(self.travelled[-1]) if len(self.travelled) else 0.0,
                   "loop_closures": int(len(self.closures)), "wrong_closures": int(len(self.wrong)),
                   "kidnapped_m": self.kidnapped_m,
                   "slam_chi2_dof": float(self.chi2 / self.dof) if self.dof > 0 else 0.0,
                   "slam_converged": float(bool(self.converged)), "slam_iterations": int(self.iterations),
                   "closures_rejected": int(self.rejected), "slam_tracking_lost": int(self.tracking_lost),
                   "slam_relocalised": int(self.relocalised)}
            self.__dict__["_stats"] = got
        return dict(got)


def _number(key: str, value, *, integer: bool = False, positive: bool = False) -> None:
    ok = isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
    ok = ok and (value > 0 if positive else value >= 0) and (not integer or float(value).is_integer())
    if not ok:
        want = ("an integer >= 0" if integer else "a number > 0" if positive else "a number >= 0")
        raise ValueError(f"pose_error.{key} = {value!r}: expected {want}")


class OdometrySlam:
    """``pose_error=odometry``: the graph-SLAM estimate of map and views (module docstring).

    Args:
        alpha1: rad^2 of turn noise per rad^2 turned.
        alpha2: rad^2 of turn noise per m^2 driven.
        alpha3: m^2 of translation noise per m^2 driven.
        alpha4: m^2 of translation noise per rad^2 turned.
        **front_end: the fields of :class:`benchmark.conditions.front_end.FrontEndSettings` (the
            scanner, the matcher, laser odometry, the closure gate and acceptance), each checked.
        kidnap_m: metres of route the robot is carried while odometry reports nothing (a kidnapping).
        spacing: metres of path between nodes when no ``mapping`` stage sets it (the scan spacing).
        robust_kernel: the loop closures' kernel in the solve, one of
            :data:`benchmark.conditions.pose_graph.KERNELS` (odometry edges stay Gaussian).
        kernel_width: sigmas of a closure's whitened error: the kernel's constant (GNC: the inlier bound).
        max_iterations: Levenberg-Marquardt iterations allowed before the solve counts as not converged.
        views_at: ``online`` (each view the estimate the robot had when taking it) or ``final``
            (the final optimum, as the map).
        seed: with the house id, seeds the draws.
    """

    AMOUNTS = ("alpha1", "alpha2", "alpha3", "alpha4", "kidnap_m")
    #: the dataclass ``**front_end`` goes to (the configuration check takes its fields)
    SETTINGS = FrontEndSettings

    def __init__(self, alpha1: float = 0.0, alpha2: float = 0.0, alpha3: float = 0.0, alpha4: float = 0.0,
                 kidnap_m: float = 0.0, spacing: float = 0.5, robust_kernel: str = "cauchy", kernel_width: float = 3.37,
                 max_iterations: int = 1000, views_at: str = "online", seed: int = 0, **front_end):
        for key, v in (("alpha1", alpha1), ("alpha2", alpha2), ("alpha3", alpha3), ("alpha4", alpha4),
                       ("kidnap_m", kidnap_m)):
            _number(key, v)
        unknown = sorted(set(front_end) - set(FrontEndSettings.__dataclass_fields__))
        if unknown:
            raise ValueError(f"pose_error: unknown setting(s) {unknown}; expected the odometry settings or "
                             f"{sorted(FrontEndSettings.__dataclass_fields__)}")
        self.front_end = FrontEndSettings(**front_end).check()
        _number("spacing", spacing, positive=True)
        if isinstance(seed, bool) or not isinstance(seed, int):
            raise ValueError(f"pose_error.seed = {seed!r}: expected an integer")
        check_kernel(robust_kernel, kernel_width)
        if isinstance(max_iterations, bool) or not isinstance(max_iterations, int) or max_iterations < 1:
            raise ValueError(f"pose_error.max_iterations = {max_iterations!r}: expected an integer >= 1")
        if views_at not in ("online", "final"):
            raise ValueError(f"pose_error.views_at = {views_at!r}: expected online or final")
        self.robust_kernel, self.kernel_width = str(robust_kernel), float(kernel_width)
        self.max_iterations, self.views_at = int(max_iterations), str(views_at)
        self.alphas = (float(alpha1), float(alpha2), float(alpha3), float(alpha4))
        self.kidnap_m = float(kidnap_m)
        self.spacing, self.seed = float(spacing), seed
        self._memo: OrderedDict = OrderedDict()

    @property
    def is_clean(self) -> bool:
        """True when the estimate is the truth (every alpha 0, no kidnapping): the front end is not run."""
        return all(a == 0 for a in self.alphas) and self.kidnap_m == 0

    # ------------------------------------------------------------------ the estimate
    def estimate(self, grid: GridMap, poses: np.ndarray, house_id: str, spacing: float | None = None,
                 obstacles: np.ndarray | None = None) -> SlamEstimate:
        """The estimate along the route through ``poses`` (memoised per house, views, spacing, obstacles).

        Args:
            grid: the house's map (the route runs on its walkable cells).
            poses: (N, 3) true view poses in capture order (every view, refused ones included).
            house_id: seeds the draws.
            spacing: metres between nodes (the scan map's spacing); default ``self.spacing``.
            obstacles: (H, W) bool what the scan plane hits, the scans the front end matches (the
                mapping stage's: walls, furniture legs, closed doors); None: ``grid``'s non-walkable cells.
        """
        key, poses, spacing = self._key(grid, poses, house_id, spacing, obstacles)
        if key not in self._memo:
            self.remember(grid, poses, house_id, spacing, self._estimate(grid, poses, house_id, spacing, obstacles),
                          obstacles)
        return self._memo[key]

    def known(self, grid: GridMap, poses: np.ndarray, house_id: str, spacing: float | None = None,
              obstacles: np.ndarray | None = None) -> SlamEstimate | None:
        """:meth:`estimate`'s answer for these arguments if it is at hand (made or remembered), else None."""
        return self._memo.get(self._key(grid, poses, house_id, spacing, obstacles)[0])

    def remember(self, grid: GridMap, poses: np.ndarray, house_id: str, spacing: float | None,
                 est: SlamEstimate, obstacles: np.ndarray | None = None) -> None:
        """Keep ``est`` as :meth:`estimate`'s answer for these arguments (the last four kept):
        a caller that stored an estimate made with these settings hands it back here."""
        key = self._key(grid, poses, house_id, spacing, obstacles)[0]
        if est.views_at != self.views_at:  # one estimate serves both: its views as this stage takes them
            est = replace(est, views_at=self.views_at)
        self._memo[key] = est
        while len(self._memo) > 4:
            self._memo.popitem(last=False)

    def _key(self, grid: GridMap, poses: np.ndarray, house_id: str, spacing: float | None,
             obstacles: np.ndarray | None = None) -> tuple:
        poses = np.ascontiguousarray(poses, np.float64).reshape(-1, 3)
        spacing = self.spacing if spacing is None else float(spacing)
        seen = None if obstacles is None else zlib.crc32(np.packbits(np.asarray(obstacles, bool)).tobytes())
        key = (house_id, poses.tobytes(), spacing, grid.shape, grid.resolution, tuple(grid.origin),
               zlib.crc32(np.packbits(grid.walkable).tobytes()), seen)
        return key, poses, spacing

    def _estimate(self, grid: GridMap, poses: np.ndarray, house_id: str, spacing: float,
                  obstacles: np.ndarray | None = None) -> SlamEstimate:
        true, view_index = trajectory_with_views(grid.walkable, grid, poses, spacing)
        steps = np.hypot(*np.diff(true[:, :2], axis=0).T) if len(true) > 1 else np.zeros(0)
        travelled = np.concatenate([[0.0], np.cumsum(steps)])
        none = np.zeros((0, 2), np.int64)
        if self.is_clean or len(true) < 2:
            return SlamEstimate(true, true.copy(), true.copy(), view_index, travelled, none, none)
        hk = text_key("slam", house_id)
        rng_moves, rng_scan = (np.random.default_rng([self.seed, hk, k]) for k in (1, 2))
        states = to_se2(true)
        moves = increments(states)
        reported = noisy_moves(moves, self.alphas, rng_moves.standard_normal(moves.shape))
        kidnapped = self._kidnap(travelled, np.random.default_rng([self.seed, hk, 4]))
        reported[kidnapped] = 0.0  # carried: the wheels report no move, no turn
        z, info = move_edge(reported, move_sigmas(reported, self.alphas), SIGMA_FLOOR)
        n = len(states)
        # the front end: laser odometry fused with the wheels, closures from the robot's own estimate
        if obstacles is None:
            obstacles = ~grid.walkable
        elif np.shape(obstacles) != grid.shape:
            raise ValueError(f"slam obstacles have shape {np.shape(obstacles)}: expected the grid's {grid.shape}")
        fe = run_front_end(np.asarray(obstacles, bool), grid, states, z, info, travelled, self.front_end,
                           int(rng_scan.integers(2 ** 31)))
        dead = fe.dead
        ei, ej, ez, einfo, robust = [np.arange(n - 1)], [np.arange(1, n)], [fe.z], [fe.sqrt_info], [np.zeros(n - 1, bool)]
        if len(fe.closures):
            ei.append(fe.closures[:, 0])
            ej.append(fe.closures[:, 1])
            ez.append(fe.closure_z)
            einfo.append(fe.closure_sqrt_info)
            robust.append(np.ones(len(fe.closures), bool))  # closures carry the robust kernel
        closures, wrong = fe.closures[~fe.wrong], fe.closures[fe.wrong]
        chi2, dof, est, solved, views = 0.0, 0, dead, {"converged": True, "iterations": 0, "outliers": 0}, None
        if len(ei) > 1:
            graph = PoseGraph(n, np.concatenate(ei), np.concatenate(ej), np.vstack(ez), np.concatenate(einfo),
                              np.concatenate(robust))
            try:
                est, solved = solve(graph, dead, self.robust_kernel, self.kernel_width, self.max_iterations)
            except RuntimeError as e:  # GTSAM's reason runs over lines: one line, the house named
                raise RuntimeError(f"house {house_id!r}: pose-graph solve: {gtsam_reason(e)}") from None
            chi2, dof = solved["chi2"], solved["dof"]
            # the online views whatever views_at says: one estimate (and one cache entry, one
            # map) for both settings, which only choose the views' poses from it.
            # Online, the closures that put a lost segment back on the map join without the kernel
            plain = np.concatenate([np.zeros(n - 1, bool), fe.relocalising_mask()])
            known = np.concatenate([np.arange(1, n), fe.closures_known_at()])  # when the robot learns each edge
            try:
                views = from_se2(online(graph, dead, view_index, self.robust_kernel, self.kernel_width, plain,
                                        known))
            except RuntimeError as e:
                raise RuntimeError(f"house {house_id!r}: {gtsam_reason(e)}") from None
        return SlamEstimate(true, from_se2(est), from_se2(dead), view_index, travelled, closures, wrong, chi2, dof,
                            float(np.hypot(*np.diff(true[:, :2], axis=0)[kidnapped].T).sum()),
                            bool(solved["converged"]), int(solved["iterations"]), int(solved["outliers"]),
                            online=views, odometry_edges=fe.z, tracking_lost=int(fe.tracking_lost), relocalised=int(fe.relocalised),
                            views_at=self.views_at)

    def _kidnap(self, travelled: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """(M-1,) bool moves made while carried: ``kidnap_m`` metres of route from a point drawn
        uniformly between ``closure_min_travel`` metres and the end (none when the route is shorter)."""
        out = np.zeros(len(travelled) - 1, bool)
        u = rng.random()  # drawn whatever the settings
        lead = self.front_end.closure_min_travel
        if self.kidnap_m <= 0 or travelled[-1] <= lead + self.kidnap_m:
            return out
        start = lead + u * (travelled[-1] - self.kidnap_m - lead)
        return (travelled[1:] > start) & (travelled[:-1] < start + self.kidnap_m)

    # ------------------------------------------------------------------ the stage
    def __call__(self, poses: np.ndarray, grid: GridMap, house_id: str, travelled: np.ndarray | None = None,
                 route_poses: np.ndarray | None = None, spacing: float | None = None,
                 obstacles: np.ndarray | None = None) -> tuple[np.ndarray, dict]:
        """(estimated (N, 3) poses of ``poses``, stats).

        Args:
            poses: (N, 3) the true poses of the views the method receives, in capture order.
            grid: the house's map.
            house_id: seeds the draws.
            travelled: unused (the route is measured here); accepted for the stage's signature.
            route_poses: (N', 3) every view the robot took in capture order, of which ``poses``
                is a subsequence (default ``poses``): the route the estimate is made along.
            spacing: metres between nodes (default ``self.spacing``).
            obstacles: (H, W) bool what the scan plane hits (:meth:`estimate`): the scans the front
                end matches; the map's estimate is made with them, and the views must take that one.
        """
        poses = np.asarray(poses, np.float64).reshape(-1, 3)
        route_poses = poses if route_poses is None else np.asarray(route_poses, np.float64).reshape(-1, 3)
        if self.is_clean:
            noisy = poses.copy()
            extra = {"ate_rmse_m": 0.0}
        else:
            est = self.estimate(grid, route_poses, house_id, spacing, obstacles)
            noisy = est.view_poses(self.views_at)[subsequence(route_poses, poses)]
            extra = est.stats()
        stats = pose_error_stats(poses, noisy, grid)
        stats.update(extra)
        return noisy, stats


def subsequence(route: np.ndarray, poses: np.ndarray) -> np.ndarray:
    """(N,) index into ``route`` of each of ``poses``, a subsequence of it (in order).

    Raises:
        ValueError: a pose is not in ``route`` after the previous one (one line).
    """
    out = np.empty(len(poses), np.int64)
    # rows as tuples of Python floats: equal exactly where NumPy's rows are (NaN equals nothing)
    steps, wanted = [tuple(r) for r in np.asarray(route).tolist()], [tuple(p) for p in np.asarray(poses).tolist()]
    k = 0
    for n, p in enumerate(wanted):
        while k < len(steps) and steps[k] != p:
            k += 1
        if k == len(steps):
            raise ValueError(f"view {n} at {list(p)} is not among the robot's route poses in order")
        out[n] = k
        k += 1
    return out


__all__ = ["OdometrySlam", "SlamEstimate", "subsequence"]
