"""A lidar SLAM robot's front end: laser odometry fused with wheel odometry, and loop closures
proposed from the robot's own estimate and accepted on the scan match.

The robot has a 2D scan at every pose-graph node (:func:`envs.maps.scan.scan_ranges`: measured at
the node's *true* pose with the front end's scanner, its range noise, dropout and max range; the
robot knows only the ranges and its beams' angles, so the points are in its own frame). Matching is
:mod:`benchmark.conditions.scan_matching` (correlative, Olson 2009).

1. **Laser odometry on keyframes.** A node becomes a *keyframe* (its likelihood grid is built)
   when the robot has moved ``keyframe_xy`` metres (0.5, slam_toolbox's minimum travel) or turned
   ``keyframe_yaw`` degrees (180 by default: the scan is 360 degrees, so a turn in place at a
   viewpoint sees the same room; a narrow field of view would want 10-30) from the last keyframe
   by its chain, or when its scan no longer matched it; node 0 is one (0 and 0: every node, as the
   first pass). Each move between consecutive nodes: scan ``j`` is matched on the last keyframe's
   grid around the chain's pose of ``j - 1`` composed with the wheels' reported move (the prior);
   the window is 3 sigma of the wheels' covariance (at least
   ``min_window_xy`` metres and ``min_window_yaw`` degrees, at most ``closure_window_xy`` and
   ``closure_window_yaw``). The matched pose less the chain's pose of ``j - 1`` is the laser's
   move (its covariance turned into ``j - 1``'s frame); a match whose score (mean likelihood of its points, 0..1) reaches
   ``odometry_min_score`` gives the matched relative pose (the score surface's weighted mean) with
   its covariance (floored at ``sigma_xy`` metres, ``sigma_yaw`` degrees), fused with the wheel
   move (the product of the two Gaussians: the sum of their information). A poorer match leaves
   the wheel move alone. So the heading comes from the scans, as in real lidar SLAM; a carried
   (kidnapped) robot's wheels report no move with a standing robot's confidence, which the fusion
   keeps. The whole chain (matches, fusions, keyframe grids) is one compiled call, :func:`_chain`.
2. **The robot's estimate**: the fused moves chained from the start (its dead reckoning), with
   each node's covariance propagated along the chain.
3. **Loop-closure candidates** from that estimate, between keyframes only: keyframe ``j`` (at least ``closure_every`` metres of
   route after the last node that looked) and each earlier node ``i`` at least
   ``closure_min_travel`` metres of route before it whose estimated displacement ``d = t_j - t_i``
   passes the Mahalanobis gate ``d^T (Q_ij + r^2 I)^-1 d <= closure_gate`` (``Q_ij`` the chain's
   covariance of j relative to i in the world frame, ``r`` = ``closure_radius``: "within r metres of
   where I was, given how unsure I am"). The ``closure_candidates`` best (smallest gate value) are
   matched, each in a window of 3 sigma of ``Q_ij`` (at most ``closure_window_xy`` metres,
   ``closure_window_yaw`` degrees) around the estimated relative pose.
4. **Acceptance**: the first candidate whose score reaches ``closure_min_score`` becomes a loop
   closure (its matched pose and covariance, floored as above). Nothing checks the truth: two
   identical rooms, or a long corridor, can match well at the wrong place. An accepted closure whose
   matched relative pose is farther than :data:`WRONG_XY` metres or :data:`WRONG_YAW` degrees from
   the true one is counted wrong (``wrong_closures``).
5. **Place recognition** (``place_recognition``, off by default): a keyframe that looks and closes
   nothing from its estimate compares its ring descriptor (:func:`descriptor`: the mean range in
   each of 60 sectors of 6 degrees) with every earlier keyframe's, at least ``closure_min_travel``
   metres of route before it, wherever the estimate puts them: the three nearest by the sorted
   sector ranges (turn-free), then the best whole-sector turn of those (:func:`ring_distance`). If
   its mean difference is at most ``place_max_distance`` metres, the matcher verifies it in a wide
   window (``place_window_xy`` metres around the same place, ``place_window_yaw`` degrees around the
   descriptor's turn) and accepts it at ``place_min_score``: a closure like the others (robust
   kernel, counted wrong the same way). Its cost: one descriptor per keyframe (tens of
   microseconds), a few sector comparisons and at most one match per keyframe that looks.
6. **Tracking loss and relocalisation** (a kidnapped robot). ``lost_after`` consecutive moves whose
   scan no longer matched the keyframe near the predicted pose (score below ``odometry_min_score``)
   mean tracking is lost: the run's first move becomes a weak odometry edge (``lost_sigma_xy`` metres,
   ``lost_sigma_yaw`` degrees: a prior that ties the rest to where the chain lost track and keeps the
   graph solvable; one weak edge a loss, as weaker or more of them leave GTSAM's incremental solve
   too poorly conditioned) and the node after it starts a new chain segment, its covariance counted
   from its own start (the carried nodes of the run belong to it). A segment is off the map until it relocalises: each of its keyframes runs place recognition
   (the descriptor and the wide verifying match of 5, on whether or not ``place_recognition`` is)
   against the keyframes on the map before the segment began; a match reaching ``place_min_score`` is
   kept, and when two of the segment's keyframes' matches agree on where the segment is (within
   ``relocalise_xy`` metres and ``relocalise_yaw`` degrees) both become closures, the segment's chain is
   moved onto the map (every later node with it) and its covariance made the map's. A segment never
   relocalised floats on its weak edges and takes no closure from its estimate. Counted:
   ``tracking_lost`` (runs detected) and ``relocalised`` (segments put back). A route without such a
   run (every level but the kidnappings on the shared houses) is unchanged, bit for bit.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from dataclasses import dataclass
from typing import Annotated

import numpy as np

from benchmark.conditions.odometry import wrap
from benchmark.conditions.pose_graph import relative
from benchmark.conditions.scan_matching import (
    EPS,
    SMALL,
    LikelihoodGrid,
    _likelihood_grid,
    _match,
    _padded,
    _pool,
    match,
    pad_for,
)
from envs.kernel_cache import njit
from envs.maps.gridmap import GridMap
from envs.maps.scan import ScanSettings, scan_ranges
from envs.ranges import Angle, Between, Metres, NonNegative, Positive, Share

#: an accepted closure is wrong when its matched relative pose is this far (metres) from the true one ...
WRONG_XY = 0.3
#: ... or its heading this far (degrees)
WRONG_YAW = 3.0
#: reference grids the loop-closure search keeps (the keyframes last matched against)
KEPT_GRIDS = 8


@dataclass(frozen=True)
class FrontEndSettings:
    """The front end's settings (module docstring; units in each name's description).

    Attributes:
        max_range: metres, the scanner's range.
        angular_step: degrees between the beams matched.
        range_noise: metres, Gaussian sigma of a range reading.
        dropout: share of beams returning nothing, in [0, 1).
        resolution: metres, the matcher's grid cell and translation step.
        sigma: metres, the smoothing of a reference point (with range noise: ``hypot(sigma, sqrt(2) range_noise)``,
            the spread of the difference of two noisy readings of one surface).
        step_yaw: degrees between the headings searched.
        min_window_xy: metres searched either side of the wheel move, at least.
        min_window_yaw: degrees searched either side of the wheel move's heading, at least.
        odometry_min_score: mean likelihood (0..1) a consecutive match needs to be used.
        sigma_xy: metres, the least sigma per axis of a matched edge.
        sigma_yaw: degrees, the least heading sigma of a matched edge.
        scan_matching: False: wheel odometry only (the matcher still tests loop closures).
        closure_radius: metres, the place radius of the closure gate (0: no loop closures).
        closure_min_travel: metres of route between two nodes before they may close a loop.
        closure_gate: the Mahalanobis gate (chi-square, 2 degrees of freedom; 9.21: 99 %).
        closure_candidates: candidates matched per node that looks, at most.
        closure_every: metres of route between nodes that look for a closure.
        closure_window_xy: metres, a search's half-width per axis, at most (closures and odometry).
        closure_window_yaw: degrees, a search's heading half-width, at most (closures and odometry).
        closure_min_score: mean likelihood (0..1) a closure match needs to be accepted.
        keyframe_xy: metres the robot moves from the last keyframe before a node becomes one (0 with
            ``keyframe_yaw`` 0: every node is a keyframe).
        keyframe_yaw: degrees it turns from the last keyframe before a node becomes one.
        place_recognition: a keyframe that looks and closes no loop from the estimate compares its
            scan descriptor with every earlier keyframe's (module docstring, 5).
        place_max_distance: metres, the largest mean sector-range difference of a descriptor match.
        place_window_xy: metres, the verifying match's half-width per axis around the same place.
        place_window_yaw: degrees, its heading half-width around the descriptor's turn.
        place_min_score: mean likelihood (0..1) the verifying match needs (stricter than a closure's).
        lost_after: consecutive failed laser-odometry matches after which tracking counts as lost
            (module docstring, 6; 0: never).
        lost_sigma_xy: metres, the sigma per axis of the odometry edge across a tracking loss (a weak prior).
        lost_sigma_yaw: degrees, its heading sigma.
        relocalise_xy: metres two place matches of a lost segment may disagree on where it is and still
            relocalise it.
        relocalise_yaw: degrees they may disagree on its heading.
    """

    max_range: Annotated[float, Metres()] = 10.0
    angular_step: Annotated[float, Angle()] = 2.0
    range_noise: Annotated[float, NonNegative()] = 0.0
    dropout: Annotated[float, Between(0, 1, high_open=True)] = 0.0
    resolution: Annotated[float, Positive()] = 0.05
    sigma: Annotated[float, Positive()] = 0.05
    step_yaw: float = 0.25
    min_window_xy: Annotated[float, NonNegative()] = 0.1
    min_window_yaw: float = 2.0
    odometry_min_score: Annotated[float, Share()] = 0.5
    sigma_xy: Annotated[float, Positive()] = 0.02
    sigma_yaw: Annotated[float, Positive()] = 0.25
    scan_matching: bool = True
    closure_radius: Annotated[float, NonNegative()] = 1.0
    closure_min_travel: Annotated[float, NonNegative()] = 5.0
    closure_gate: Annotated[float, Positive()] = 9.21
    closure_candidates: int = 2
    closure_every: Annotated[float, NonNegative()] = 2.0
    closure_window_xy: Annotated[float, Positive()] = 1.0
    closure_window_yaw: float = 15.0
    closure_min_score: Annotated[float, Share()] = 0.5
    keyframe_xy: Annotated[float, NonNegative()] = 0.5
    keyframe_yaw: float = 180.0
    place_recognition: bool = False
    place_max_distance: Annotated[float, NonNegative()] = 0.5
    place_window_xy: Annotated[float, Positive()] = 1.0
    place_window_yaw: float = 10.0
    place_min_score: Annotated[float, Share()] = 0.7
    lost_after: Annotated[int, NonNegative()] = 3
    lost_sigma_xy: Annotated[float, Positive()] = 1.0
    lost_sigma_yaw: Annotated[float, Positive()] = 20.0
    relocalise_xy: Annotated[float, Positive()] = 0.5
    relocalise_yaw: Annotated[float, Positive()] = 5.0

    def check(self) -> FrontEndSettings:
        """Raise a one-line ``ValueError`` naming the first out-of-range setting
        (``pose_error.<key> = value: expected ...``); return self."""
        def number(v) -> bool:
            return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)

        rules = {
            "max_range": (lambda v: number(v) and v > 0, "metres > 0"),
            "angular_step": (lambda v: number(v) and 0 < v <= 360, "degrees, 0 < angular_step <= 360"),
            "range_noise": (lambda v: number(v) and v >= 0, "metres >= 0"),
            "dropout": (lambda v: number(v) and 0 <= v < 1, "a share in [0, 1)"),
            "resolution": (lambda v: number(v) and v > 0, "metres > 0"),
            "sigma": (lambda v: number(v) and v > 0, "metres > 0"),
            "step_yaw": (lambda v: number(v) and 0 < v <= 10, "degrees, 0 < step_yaw <= 10"),
            "min_window_xy": (lambda v: number(v) and v >= 0, "metres >= 0"),
            "min_window_yaw": (lambda v: number(v) and 0 <= v <= 180, "degrees in [0, 180]"),
            "odometry_min_score": (lambda v: number(v) and 0 <= v <= 1, "a mean likelihood in [0, 1]"),
            "sigma_xy": (lambda v: number(v) and v > 0, "metres > 0"),
            "sigma_yaw": (lambda v: number(v) and v > 0, "degrees > 0"),
            "scan_matching": (lambda v: isinstance(v, bool), "true or false"),
            "closure_radius": (lambda v: number(v) and v >= 0, "metres >= 0"),
            "closure_min_travel": (lambda v: number(v) and v >= 0, "metres >= 0"),
            "closure_gate": (lambda v: number(v) and v > 0, "a chi-square value > 0"),
            "closure_candidates": (lambda v: number(v) and float(v).is_integer() and v >= 1, "an integer >= 1"),
            "closure_every": (lambda v: number(v) and v >= 0, "metres >= 0"),
            "closure_window_xy": (lambda v: number(v) and v > 0, "metres > 0"),
            "closure_window_yaw": (lambda v: number(v) and 0 < v <= 180, "degrees in (0, 180]"),
            "closure_min_score": (lambda v: number(v) and 0 <= v <= 1, "a mean likelihood in [0, 1]"),
            "keyframe_xy": (lambda v: number(v) and v >= 0, "metres >= 0"),
            "keyframe_yaw": (lambda v: number(v) and 0 <= v <= 180, "degrees in [0, 180]"),
            "place_recognition": (lambda v: isinstance(v, bool), "true or false"),
            "place_max_distance": (lambda v: number(v) and v >= 0, "metres >= 0"),
            "place_window_xy": (lambda v: number(v) and v > 0, "metres > 0"),
            "place_window_yaw": (lambda v: number(v) and 0 < v <= 180, "degrees in (0, 180]"),
            "place_min_score": (lambda v: number(v) and 0 <= v <= 1, "a mean likelihood in [0, 1]"),
            "lost_after": (lambda v: number(v) and float(v).is_integer() and v >= 0, "an integer >= 0"),
            "lost_sigma_xy": (lambda v: number(v) and v > 0, "metres > 0"),
            "lost_sigma_yaw": (lambda v: number(v) and v > 0, "degrees > 0"),
            "relocalise_xy": (lambda v: number(v) and v > 0, "metres > 0"),
            "relocalise_yaw": (lambda v: number(v) and 0 < v <= 180, "degrees in (0, 180]"),
        }
        for key, (ok, want) in rules.items():
            v = getattr(self, key)
            if not ok(v):
                raise ValueError(f"pose_error.{key} = {v!r}: expected {want}")
        return self


@dataclass
class FrontEndResult:
    """What the front end hands the back end.

    Attributes:
        z: (M-1, 3) the odometry edges' relative poses (dx, dz metres, dphi radians).
        sqrt_info: (M-1, 3, 3) their square-root information.
        laser: (M-1,) bool, the moves the scan match measured (fused with the wheels).
        dead: (M, 3) SE(2) the fused moves chained from the start.
        closures: (C, 2) accepted closure node pairs (i, j), wrong ones included.
        closure_z: (C, 3) their matched relative poses; closure_sqrt_info (C, 3, 3).
        wrong: (C,) bool, the wrong ones (module docstring).
        candidates: closure candidates matched.
        keyframes: (M,) bool, the keyframes (module docstring, 1).
        place: (C,) bool, the closures place recognition found (module docstring, 5).
        place_tried: descriptor matches verified by the matcher.
        broken: (M-1,) bool, the odometry edges across a tracking loss (weak; module docstring, 6).
        tracking_lost: tracking losses detected.
        relocalised: lost segments relocalised on the earlier map.
        relocalising: (C,) bool, the closures that put a lost segment back on the map (module docstring,
            6): the online solve takes them without the robust kernel (:func:`benchmark.conditions.pose_graph.online`);
            None: none.
        known_at: (C,) int, the node at which the robot knows each closure: its later node, but for a
            relocalising closure the node whose place match confirmed the relocalisation (the later of
            its two closures' nodes; the online solve adds it there); None: every closure's later node.
    """

    z: np.ndarray
    sqrt_info: np.ndarray
    laser: np.ndarray
    dead: np.ndarray
    closures: np.ndarray
    closure_z: np.ndarray
    closure_sqrt_info: np.ndarray
    wrong: np.ndarray
    candidates: int
    keyframes: np.ndarray
    place: np.ndarray
    place_tried: int
    broken: np.ndarray
    tracking_lost: int = 0
    relocalised: int = 0
    relocalising: np.ndarray | None = None
    known_at: np.ndarray | None = None

    def relocalising_mask(self) -> np.ndarray:
        """(C,) bool, :attr:`relocalising` or all False."""
        if self.relocalising is None:
            return np.zeros(len(self.closures), bool)
        return np.asarray(self.relocalising, bool).reshape(len(self.closures))

    def closures_known_at(self) -> np.ndarray:
        """(C,) int, :attr:`known_at` or each closure's later node."""
        if self.known_at is None:
            return np.asarray(self.closures, np.int64).reshape(-1, 2).max(axis=1, initial=0)
        return np.asarray(self.known_at, np.int64).reshape(len(self.closures))


def robot_points(obstacles: np.ndarray, grid: GridMap, true_states: np.ndarray, scanner: ScanSettings) -> list[np.ndarray]:
    """Each node's scan as (K, 2) points in the robot's own frame (x along its heading, z to its left).

    Args:
        obstacles: (H, W) bool what the scan plane hits.
        grid: the map's geometry.
        true_states: (M, 3) SE(2) true node states (x, z metres, phi radians).
        scanner: the scanner.
    """
    s = np.asarray(true_states, np.float64)
    yaw_deg = np.rad2deg(np.pi / 2 - s[:, 2])
    ranges, headings, origins = scan_ranges(obstacles, grid, np.column_stack([s[:, :2], yaw_deg]), scanner)
    ranges = np.asarray(ranges, np.float64).reshape(len(s), -1)
    ok = np.isfinite(ranges)
    ranges = np.where(ok, ranges, 0.0)  # no beam: no point (and no inf * 0)
    wx = origins[:, 0, None] + ranges * np.sin(headings)[None, :] - s[:, 0, None]
    wz = origins[:, 1, None] + ranges * np.cos(headings)[None, :] - s[:, 1, None]
    c = np.array([math.cos(v) for v in s[:, 2]])[:, None]
    sn = np.array([math.sin(v) for v in s[:, 2]])[:, None]
    # every node's points in one array, node by node; each node's scan a view of it
    flat = np.column_stack([(c * wx + sn * wz)[ok], (-sn * wx + c * wz)[ok]])
    return np.split(flat, np.cumsum(ok.sum(axis=1))[:-1]) if len(s) else []


def _floored(cov: np.ndarray, st: FrontEndSettings) -> np.ndarray:
    return cov + np.diag([st.sigma_xy ** 2, st.sigma_xy ** 2, math.radians(st.sigma_yaw) ** 2])


def _upper(info: np.ndarray) -> np.ndarray:
    """Upper factor U of an information matrix (U^T U = info)."""
    return np.linalg.cholesky(info).T


def compose(state: np.ndarray, z: np.ndarray) -> np.ndarray:
    """SE(2) state moved by relative pose ``z`` (in the state's frame)."""
    c, s = math.cos(state[2]), math.sin(state[2])
    return np.array([state[0] + c * z[0] - s * z[1], state[1] + s * z[0] + c * z[1], float(wrap(state[2] + z[2]))])


def run_front_end(obstacles: np.ndarray, grid: GridMap, true_states: np.ndarray, wheel_z: np.ndarray,
                  wheel_sqrt_info: np.ndarray, travelled: np.ndarray, st: FrontEndSettings,
                  scan_seed: int = 0) -> FrontEndResult:
    """The front end along one route (module docstring).

    Args:
        obstacles: (H, W) bool what the scan plane hits.
        grid: the map's geometry.
        true_states: (M, 3) SE(2) true node states (the scans are measured there).
        wheel_z, wheel_sqrt_info: (M-1, 3), (M-1, 3, 3) the wheels' reported moves as edges
            (:func:`benchmark.conditions.pose_graph.move_edge`).
        travelled: (M,) metres of route up to each node.
        st: the settings.
        scan_seed: seeds the scanner's draws.
    """
    true_states = np.asarray(true_states, np.float64)
    n = len(true_states)
    scanner = ScanSettings(max_range=st.max_range, angular_step=st.angular_step, range_noise=st.range_noise,
                           dropout=st.dropout, seed=int(scan_seed))
    points = robot_points(obstacles, grid, true_states, scanner)
    grids: OrderedDict[int, LikelihoodGrid] = OrderedDict()
    # a point's spread: the matcher's own smoothing and the range noise of both scans it compares
    smoothing = math.hypot(st.sigma, math.sqrt(2.0) * st.range_noise)

    def ref(k: int) -> LikelihoodGrid:
        # the last KEPT_GRIDS keyframes matched against are kept (a grid made again is the same grid):
        # memory let go and written again costs less than fresh memory for every keyframe's grid
        if k in grids:
            grids.move_to_end(k)
        else:
            grids[k] = LikelihoodGrid(points[k], st.resolution, smoothing)
            while len(grids) > KEPT_GRIDS:
                grids.popitem(last=False)
        return grids[k]

    step = math.radians(st.step_yaw)
    z = np.array(wheel_z, np.float64, copy=True).reshape(-1, 3)
    sqrt_info = np.array(wheel_sqrt_info, np.float64, copy=True).reshape(-1, 3, 3)
    counts = np.array([len(p) for p in points], np.int64)
    start = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    flat = np.ascontiguousarray(np.concatenate(points) if n else np.zeros((0, 2)), np.float64).reshape(-1, 2)
    floor = np.array([st.sigma_xy ** 2, st.sigma_xy ** 2, math.radians(st.sigma_yaw) ** 2])
    weak = np.diag([1.0 / st.lost_sigma_xy, 1.0 / st.lost_sigma_xy, 1.0 / math.radians(st.lost_sigma_yaw)])
    laser, dead, cov, key, broken, lost = _chain(flat, start, true_states, z, sqrt_info, bool(st.scan_matching),
                                                 float(st.resolution), smoothing, step, float(st.min_window_xy),
                                                 math.radians(st.min_window_yaw), float(st.closure_window_xy),
                                                 math.radians(st.closure_window_yaw), float(st.odometry_min_score),
                                                 floor, float(st.keyframe_xy), math.radians(st.keyframe_yaw),
                                                 math.log(EPS), EPS, int(st.lost_after), weak)
    pairs, zc, infos, wrong, tried, place, place_tried, relocalised, n_reloc, known = _closures(
        points, ref, dead, cov, true_states, travelled, key, st, step, broken)
    return FrontEndResult(z, sqrt_info, laser, dead, pairs, zc, infos, wrong, tried, key, place, place_tried,
                          broken, int(lost), relocalised, np.arange(len(pairs)) < n_reloc, known)


@njit(cache=True, nogil=True)
def _wrap(a):
    return np.mod(a + np.pi, 2.0 * np.pi) - np.pi


@njit(cache=True, nogil=True)
def _compose(state, z):
    c, s = math.cos(state[2]), math.sin(state[2])
    return np.array([state[0] + c * z[0] - s * z[1], state[1] + s * z[0] + c * z[1], _wrap(state[2] + z[2])])


@njit(cache=True, nogil=True)
def _chain(flat, start, true_states, z, sqrt_info, scan_matching, res, smoothing, step, min_wxy, min_wt, max_wxy,
           max_wt, min_score, floor, keyframe_xy, turn, low, eps, lost_after, weak):
    """Laser odometry on keyframes and the robot's estimate along the route (module docstring, 1-2, 6),
    compiled: node ``m``'s scan is ``flat[start[m]:start[m + 1]]``. Fuses into ``z``, ``sqrt_info`` in
    place (a move across a tracking loss gets ``weak``); returns (laser (M-1,), dead (M, 3), each node's
    covariance (M, 3, 3) since its segment began, keyframes (M,), the moves across a loss (M-1,), losses)."""
    n = true_states.shape[0]
    laser = np.zeros(max(n - 1, 0), np.bool_)
    broken = np.zeros(max(n - 1, 0), np.bool_)
    dead = np.empty((n, 3))
    cov = np.zeros((n, 3, 3))  # each node's covariance along the chain (node 0 exact)
    key = np.zeros(n, np.bool_)
    losses = 0
    fails = 0  # consecutive failed matches
    if n == 0:
        return laser, dead, cov, key, broken, losses
    dead[0] = true_states[0]
    key[0] = True
    kf = 0
    at = np.zeros(3)  # the last node's pose in the last keyframe's frame (the chain's)
    built = -1  # the keyframe whose grid (and block maxima, when pooled) is at hand
    pooled = False
    grid = np.zeros((1, 1))
    p4 = grid
    p16 = grid
    # the keyframe's grid and block maxima padded for the search (kept while the pads are wide enough)
    g1 = g4 = g16 = grid
    pad1 = pad4 = pad16 = -1
    x0 = y0 = 0.0
    for k in range(n - 1):
        u = sqrt_info[k].copy()
        info_w = u.T.copy() @ u
        matched = False
        a_n = start[kf + 1] - start[kf]
        b = flat[start[k + 1]:start[k + 2]]
        if scan_matching and a_n and b.shape[0]:
            cov_w = np.linalg.inv(info_w)
            wxy = min(max(3.0 * math.sqrt(max(cov_w[0, 0], cov_w[1, 1])), min_wxy), max_wxy)
            wt = min(max(3.0 * math.sqrt(cov_w[2, 2]), min_wt), max_wt)
            if built != kf:
                grid, x0, y0 = _likelihood_grid(flat[start[kf]:start[kf + 1]], res, smoothing, eps)
                built, pooled = kf, False
                pad1 = pad4 = pad16 = -1
            kx = int(math.ceil(wxy / res - 1e-9))
            bounded = 2 * kx + 1 > SMALL
            if bounded and not pooled:
                p4 = _pool(grid, 3, 1, low)
                p16 = _pool(p4, 12, 4, low)
                pooled = True
            need1, need4, need16 = pad_for(kx)
            if pad1 < need1:
                g1, pad1 = _padded(grid, need1, low), need1
            if bounded and pad4 < need4:
                g4, pad4 = _padded(p4, need4, low), need4
            if bounded and pad16 < need16:
                g16, pad16 = _padded(p16, need16, low), need16
            # scan k + 1 on the keyframe's grid, around the chain's pose of k composed with the wheel move
            c = _compose(at, z[k])
            _, _, score, mean, mcov = _match(grid, g1, pad1, g4 if bounded else g1, pad4 if bounded else pad1,
                                             g16 if bounded else g1, pad16 if bounded else pad1, x0, y0, res, b,
                                             c[0], c[1], c[2], wxy, wt, step, low, eps)
            if score >= min_score:
                matched = True
                # the laser's move k -> k + 1 (in k's frame) and its covariance turned into that frame
                ca, sa = math.cos(at[2]), math.sin(at[2])
                dx, dz = mean[0] - at[0], mean[1] - at[1]
                zl = np.array([ca * dx + sa * dz, -sa * dx + ca * dz, _wrap(mean[2] - at[2])])
                rot = np.array([[ca, sa, 0.0], [-sa, ca, 0.0], [0.0, 0.0, 1.0]])
                fl = mcov.copy()
                for d in range(3):
                    fl[d, d] += floor[d]
                info = np.linalg.inv(rot @ fl @ rot.T.copy()) + info_w
                diff = z[k] - zl
                diff[2] = _wrap(diff[2])
                fused = zl + np.linalg.solve(info, info_w @ diff)
                fused[2] = _wrap(fused[2])
                z[k] = fused
                sqrt_info[k] = np.linalg.cholesky(info).T
                laser[k] = True
                info_w = info
            # tracking lost: lost_after failed matches in a row; the run's first move becomes a weak
            # edge and the node after it starts a new segment (its covariance from there)
            fails = 0 if matched else fails + 1
            if lost_after > 0 and fails == lost_after:
                losses += 1
                m0 = k - lost_after + 1
                broken[m0] = True
                sqrt_info[m0] = weak
                cov[m0 + 1] = 0.0
                for m in range(m0 + 1, k):
                    u_m = sqrt_info[m].copy()
                    cov[m + 1] = _carry(cov[m], dead[m], dead[m + 1], np.linalg.inv(u_m.T.copy() @ u_m))
        at = _compose(at, z[k])
        # a new keyframe: moved or turned enough since the last one, or the scans no longer matched
        if not matched or math.hypot(at[0], at[1]) >= keyframe_xy or abs(at[2]) >= turn:
            kf = k + 1
            at = np.zeros(3)
            key[k + 1] = True
        c_k = np.linalg.inv(info_w)
        dead[k + 1] = _compose(dead[k], z[k])
        cov[k + 1] = _carry(cov[k], dead[k], dead[k + 1], c_k)
    return laser, dead, cov, key, broken, losses


@njit(cache=True, nogil=True)
def _carry(p, a, b, c_k):
    """The covariance at ``b``: ``p`` at ``a`` carried along the move a -> b and the move's own
    ``c_k`` (in ``a``'s frame) turned into the world."""
    c, s = math.cos(a[2]), math.sin(a[2])
    f = np.array([[1.0, 0.0, -(b[1] - a[1])], [0.0, 1.0, b[0] - a[0]], [0.0, 0.0, 1.0]])
    g = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return f @ p.copy() @ f.T.copy() + g @ c_k @ g.T.copy()


#: sectors of a scan descriptor (6 degrees each)
SECTORS = 60


def descriptor(points: np.ndarray, max_range: float) -> np.ndarray:
    """(SECTORS,) a scan's ring descriptor: the mean range of its points in each 6-degree sector
    around the robot (``max_range`` where a sector holds none), sector 0 along the heading."""
    pts = np.asarray(points, np.float64).reshape(-1, 2)
    r = np.hypot(pts[:, 0], pts[:, 1])
    sector = np.floor(np.mod(np.arctan2(pts[:, 1], pts[:, 0]), 2 * np.pi) / (2 * np.pi / SECTORS)).astype(np.int64)
    sector = np.minimum(sector, SECTORS - 1)
    total = np.bincount(sector, r, SECTORS)
    count = np.bincount(sector, None, SECTORS)
    return np.where(count > 0, total / np.maximum(count, 1), max_range)


def ring_distance(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    """(metres, radians): the least mean absolute difference of descriptor ``a`` and ``b`` turned by
    whole sectors, and the turn of ``b``'s robot relative to ``a``'s that gives it."""
    shifts = np.arange(SECTORS)
    d = np.abs(a[(np.arange(SECTORS)[None, :] + shifts[:, None]) % SECTORS] - b[None, :]).mean(axis=1)
    k = int(np.argmin(d))
    return float(d[k]), float(wrap(k * 2 * np.pi / SECTORS))


def _between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """SE(2) pose ``b`` in the frame of ``a`` (both in one frame): ``compose(a, _between(a, b)) = b``."""
    c, s = math.cos(a[2]), math.sin(a[2])
    dx, dz = b[0] - a[0], b[1] - a[1]
    return np.array([c * dx + s * dz, -s * dx + c * dz, float(wrap(b[2] - a[2]))])


def _closures(points, ref, dead, cov, true_states, travelled, key, st: FrontEndSettings, step: float,
              broken: np.ndarray | None = None):
    """Loop closures between keyframes, proposed from the estimate and accepted on the match (module
    docstring, 3-4), and the relocalisation of the segments after a tracking loss (6: ``dead`` and
    ``cov`` of a relocalised segment moved onto the map in place). Returns (pairs, their relative
    poses, square-root informations, wrong, candidates matched, place, place matches verified,
    segments relocalised, relocalisation closures: the first ones of the pairs, the node at which the
    robot knows each pair: the keyframe whose match made it, for a relocalisation's two the one whose
    match confirmed it)."""
    pairs, zs, infos, place, desc, known = [], [], [], [], {}, []
    tried = p_tried = relocalised = 0
    n = len(dead)
    last = -np.inf
    # segments: a new one after each move across a tracking loss; segment 0 is on the map
    seg = np.concatenate([[0], np.cumsum(broken)]) if broken is not None and n else np.zeros(n, np.int64)
    on_map = seg == 0
    pending: dict[int, list] = {}
    if n > 1 and seg[-1] > 0:
        for j in range(n):
            if on_map[j] or not key[j] or not len(points[j]):
                continue
            p_tried += _relocalise(j, seg, on_map, points, ref, dead, cov, key, st, step, desc, pending,
                                   pairs, zs, infos, place, known)
            relocalised += int(on_map[j])
    n_reloc = len(pairs)
    # the node pairs joined so far: a pair the relocalisation joined is not entered again when the
    # closure search (or place recognition) proposes it (its information would count twice)
    joined = {(int(a), int(b)) for a, b in pairs}
    if (st.closure_radius > 0 or st.place_recognition) and n > 1:
        r2 = st.closure_radius ** 2
        for j in range(n):
            if (not key[j] or travelled[j] < st.closure_min_travel or travelled[j] - last < st.closure_every
                    or not len(points[j]) or not on_map[j]):
                continue
            cand = np.flatnonzero(key & on_map & (travelled <= travelled[j] - st.closure_min_travel))
            if len(cand) == 0:
                continue
            last = travelled[j]
            d = dead[j, :2] - dead[cand, :2]
            # j's covariance relative to i, world frame: P_j - F P_i F^T (F carries i's error to j)
            f = np.broadcast_to(np.eye(3), (len(cand), 3, 3)).copy()
            f[:, 0, 2], f[:, 1, 2] = -d[:, 1], d[:, 0]
            q_full = cov[j] - np.einsum("nab,nbc,ndc->nad", f, cov[cand], f)
            q = q_full[:, :2, :2] + r2 * np.eye(2)
            gate = np.einsum("na,nab,nb->n", d, np.linalg.inv(q), d)
            ok = np.flatnonzero(gate <= st.closure_gate) if st.closure_radius > 0 else np.zeros(0, np.int64)
            for t in ok[np.argsort(gate[ok], kind="stable")][: st.closure_candidates]:
                i = int(cand[t])
                if not len(points[i]) or (i, j) in joined:
                    continue
                tried += 1
                centre = relative(dead, np.array([i]), np.array([j]))[0]
                # the relative pose's uncertainty in i's frame: 3 sigma of the larger position axis
                sd_xy = math.sqrt(max(np.linalg.eigvalsh(q_full[t, :2, :2]).max(), 0.0))
                sd_t = math.sqrt(max(q_full[t, 2, 2], 0.0))
                wxy = min(max(3.0 * sd_xy, st.min_window_xy), st.closure_window_xy)
                wt = min(max(3.0 * sd_t, math.radians(st.min_window_yaw)), math.radians(st.closure_window_yaw))
                m, _ = match(ref(i), points[j], centre, wxy, wt, step, surface=False)
                if m.score >= st.closure_min_score:
                    pairs.append((i, j))
                    zs.append(m.best)
                    infos.append(_upper(np.linalg.inv(_floored(m.cov, st))))
                    known.append(j)
                    break
            else:
                if st.place_recognition:
                    p_tried += _recognise(j, points, ref, key, travelled, st, step, desc, pairs, zs, infos, place,
                                          known, joined)
                continue
            place.append(False)
    pairs = np.array(pairs, np.int64).reshape(-1, 2)
    zs = np.array(zs, np.float64).reshape(-1, 3)
    infos = np.array(infos, np.float64).reshape(-1, 3, 3)
    if len(pairs):
        truth = relative(true_states, pairs[:, 0], pairs[:, 1])
        err_xy = np.hypot(*(truth[:, :2] - zs[:, :2]).T)
        err_t = np.abs(wrap(truth[:, 2] - zs[:, 2]))
        wrong = (err_xy > WRONG_XY) | (err_t > math.radians(WRONG_YAW))
    else:
        wrong = np.zeros(0, bool)
    return (pairs, zs, infos, wrong, tried, np.array(place, bool).reshape(-1), p_tried, relocalised, n_reloc,
            np.array(known, np.int64).reshape(-1))


def _recognise(j, points, ref, key, travelled, st: FrontEndSettings, step, desc, pairs, zs, infos, place, known,
               joined=frozenset()) -> int:
    """Place recognition at keyframe ``j`` (module docstring, 5): the earlier keyframe whose descriptor
    is nearest, verified by the matcher; appends an accepted closure (known at ``j``) unless that pair is
    among ``joined`` (node pairs already in the graph). Returns the matches verified (0, 1)."""
    cand = np.flatnonzero(key & (travelled <= travelled[j] - st.closure_min_travel))
    i, m, verified = _place(j, cand, points, ref, st, step, desc)
    if m is not None and m.score >= st.place_min_score and (int(i), int(j)) not in joined:
        pairs.append((i, j))
        zs.append(m.best)
        infos.append(_upper(np.linalg.inv(_floored(m.cov, st))))
        place.append(True)
        known.append(j)
    return verified


def _onto(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(3,) the SE(2) transform ``t`` with ``compose(t, b) = a`` (both poses in their own frames)."""
    th = float(wrap(a[2] - b[2]))
    c, s = math.cos(th), math.sin(th)
    return np.array([a[0] - (c * b[0] - s * b[1]), a[1] - (s * b[0] + c * b[1]), th])


def _lever(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(3, 3) the Jacobian carrying a pose error at ``a`` to ``b`` (world frame)."""
    return np.array([[1.0, 0.0, -(b[1] - a[1])], [0.0, 1.0, b[0] - a[0]], [0.0, 0.0, 1.0]])


def _turn3(th: float) -> np.ndarray:
    c, s = math.cos(th), math.sin(th)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _relocalise(j, seg, on_map, points, ref, dead, cov, key, st: FrontEndSettings, step, desc, pending,
                pairs, zs, infos, place, known) -> int:
    """Relocalisation at keyframe ``j`` of a segment not yet on the map (module docstring, 6): place
    recognition against the keyframes on the map before the segment began; a verified match is kept
    and the segment is relocalised when two of its keyframes' matches agree on where it is (within
    ``relocalise_xy`` metres and ``relocalise_yaw`` degrees): both become closures, known at ``j`` (the
    robot knows neither before the second match confirms the first), the segment's ``dead`` is moved
    onto the map and its ``cov`` made the map's. Returns the matches verified (0, 1)."""
    s = int(seg[j])
    first = int(np.flatnonzero(seg == s)[0])
    cand = np.flatnonzero(key & on_map & (np.arange(len(seg)) < first))
    i, m, verified = _place(j, cand, points, ref, st, step, desc, tries=3)
    if m is None or m.score < st.place_min_score:
        return verified
    here = compose(dead[i], m.best)  # j on the map, by this match
    t = _onto(here, dead[j])
    info = _upper(np.linalg.inv(_floored(m.cov, st)))
    for earlier in pending.get(s, []):
        other = compose(earlier[3], dead[j])  # j on the map, by the earlier match
        if (math.hypot(*(other[:2] - here[:2])) <= st.relocalise_xy
                and abs(float(wrap(other[2] - here[2]))) <= math.radians(st.relocalise_yaw)):
            break
    else:
        pending.setdefault(s, []).append(((i, j), m.best, info, t))
        return verified
    for pair, zz, ii in (earlier[:3], ((i, j), m.best, info)):
        pairs.append(pair)
        zs.append(zz)
        infos.append(ii)
        place.append(True)
        known.append(j)
    members = np.flatnonzero(seg == s)
    later = np.arange(first, len(seg))
    c, sn = math.cos(t[2]), math.sin(t[2])
    x, z = dead[later, 0].copy(), dead[later, 1].copy()
    dead[later, 0] = t[0] + c * x - sn * z
    dead[later, 1] = t[1] + sn * x + c * z
    dead[later, 2] = wrap(dead[later, 2] + t[2])
    # the segment's covariance on the map: i's, the match's (turned into the world) carried to j, then
    # to each member, and each member's own since the segment began (turned with it)
    g = _turn3(float(dead[i, 2]))
    p_j = _lever(dead[i], dead[j]) @ cov[i] @ _lever(dead[i], dead[j]).T + g @ _floored(m.cov, st) @ g.T
    r = _turn3(float(t[2]))
    for k in members:
        f = _lever(dead[j], dead[k])
        cov[k] = f @ p_j @ f.T + r @ cov[k] @ r.T
    on_map[members] = True
    return verified


def _place(j, cand, points, ref, st: FrontEndSettings, step, desc, tries: int = 1):
    """(i, the verifying match or None, matches verified): of keyframes ``cand``, the one whose
    descriptor is nearest ``j``'s, matched in the wide window when within ``place_max_distance``
    (``tries`` > 1: the nearest ``tries`` in turn until one reaches ``place_min_score``)."""
    cand = np.asarray(cand, np.int64)
    cand = cand[[len(points[i]) > 0 for i in cand]]
    if len(cand) == 0:
        return -1, None, 0
    for k in (j, *cand):
        if k not in desc:
            desc[k] = descriptor(points[k], st.max_range)
    # the turn-free prefilter: the sorted sector ranges; then the best turn of the three nearest
    keys = np.sort(np.array([desc[i] for i in cand]), axis=1)
    near = cand[np.argsort(np.abs(keys - np.sort(desc[j])).mean(axis=1), kind="stable")[:3]]
    ranked = sorted((ring_distance(desc[i], desc[j]) + (int(i),) for i in near), key=lambda t: (t[0], t[2]))
    i, m, verified = ranked[0][2], None, 0
    for dist, turn, i in ranked[:tries]:
        if dist > st.place_max_distance:
            break
        m, _ = match(ref(i), points[j], np.array([0.0, 0.0, turn]), st.place_window_xy,
                     math.radians(st.place_window_yaw), step, surface=False)
        verified += 1
        if m.score >= st.place_min_score:
            break
    return i, m, verified


__all__ = ["FrontEndResult", "FrontEndSettings", "WRONG_XY", "WRONG_YAW", "compose", "descriptor", "ring_distance",
           "robot_points", "run_front_end"]
