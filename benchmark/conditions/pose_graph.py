"""A 2D pose graph and its robust solve on GTSAM (graph SLAM's back end).

Nodes are SE(2) states (x, z metres, phi radians counter-clockwise from +x; see
:mod:`benchmark.conditions.odometry`). An edge ``(i, j, z, sqrt_info)`` says "node j seen from node
i is at ``z``" (dx, dz in i's frame, metres; dphi, radians), with ``sqrt_info`` (3, 3) the upper
Cholesky factor of its information matrix (inverse covariance). Each edge is a GTSAM
``BetweenFactorPose2``: its whitened residual is

    r_ij = sqrt_info @ Log(Z^-1 (X_i^-1 X_j))

(``Log`` SE(2)'s logarithm, ``Z`` the measured relative pose), unit covariance when the edge is
right. Edges flagged ``robust`` (the loop closures) carry a robust kernel (:data:`KERNELS`);
odometry edges stay Gaussian (a robot's wheels do not report a move 3 m long that never happened;
a scan matcher does match two places that only look alike).

:func:`solve` is the final (offline) estimate: GTSAM's Levenberg-Marquardt run to convergence
(relative decrease of the cost below :data:`RELATIVE_TOLERANCE`), ``max_iterations`` at most, a
solve cut off there reported as not converged. With ``kernel="gnc"`` (graduated non-convexity,
Yang et al. 2020, truncated least squares) GTSAM's ``GncLMOptimizer`` starts from the plain
least-squares solution and turns the closures' cost non-convex step by step, ending with every
closure an inlier (weight 1) or an outlier (weight 0); the estimate is then the Levenberg-
Marquardt solve over the odometry and the inlier closures. :func:`online` is the estimate the
robot had at each moment: iSAM2 updated node by node in travel order, each node's pose read
right after its own update.

Node 0 is the map's frame (the robot's start, ``initial[0]``): a prior there fixes the gauge for
the linear algebra, and the answer is moved rigidly to put node 0 at ``initial[0]`` exactly (every
between factor is unchanged by a rigid move of the whole graph). With noisy constraints a
residual stays: the corrected poses are not the true ones.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np

from benchmark.conditions.odometry import wrap

#: the robust kernels a closure edge may carry ("none": Gaussian, plain least squares)
KERNELS = ("none", "huber", "cauchy", "dcs", "gnc")

#: Levenberg-Marquardt stops when one iteration lowers the cost by less than this share of it
RELATIVE_TOLERANCE = 1e-6
#: ... or by less than this (absolute, in units of the cost: half the sum of squared whitened residuals)
ABSOLUTE_TOLERANCE = 1e-12

#: iSAM2 (:func:`online`): a variable is relinearised when its update exceeds this (m and rad),
#: checked every :data:`RELINEARIZE_SKIP` updates: GTSAM's defaults, as a robot runs it. (0.01 and
#: every update moved the views' online poses by 6 cm at most on a 1,000-node house graph and took
#: three times as long: most of the online estimate's time.)
RELINEARIZE_THRESHOLD = 0.1
RELINEARIZE_SKIP = 10


@dataclass
class PoseGraph:
    """Edges of a pose graph over ``n`` nodes.

    Attributes:
        n: number of nodes.
        i, j: (E,) int node indices of each edge (from i to j).
        z: (E, 3) measured relative poses (dx, dz metres in i's frame; dphi radians).
        sqrt_info: (E, 3, 3) square roots of the edges' information matrices.
        robust: (E,) bool, the edges that carry the robust kernel (loop closures); None: none.
    """

    n: int
    i: np.ndarray
    j: np.ndarray
    z: np.ndarray
    sqrt_info: np.ndarray
    robust: np.ndarray | None = None

    def robust_mask(self) -> np.ndarray:
        """(E,) bool, :attr:`robust` or all False."""
        if self.robust is None:
            return np.zeros(len(self.i), bool)
        return np.asarray(self.robust, bool).reshape(len(self.i))


def graph_of_file(g) -> PoseGraph:
    """A pose graph read from a file (:class:`envs.logs.g2o.PoseGraphFile`) as a :class:`PoseGraph`:
    nodes 0..N-1 in the order of its ids, square-root information the upper Cholesky factor of
    each edge's information, no robust edges."""
    lower = np.linalg.cholesky(g.information)
    return PoseGraph(n=g.n, i=g.i.copy(), j=g.j.copy(), z=g.z.copy(),
                     sqrt_info=np.ascontiguousarray(np.transpose(lower, (0, 2, 1))))


def relative(states: np.ndarray, i: np.ndarray, j: np.ndarray) -> np.ndarray:
    """(E, 3) pose of node j in node i's frame (dx, dz metres, dphi radians wrapped)."""
    s = np.asarray(states, np.float64)
    d = s[j, :2] - s[i, :2]
    c, sn = np.cos(s[i, 2]), np.sin(s[i, 2])
    return np.column_stack([c * d[:, 0] + sn * d[:, 1], -sn * d[:, 0] + c * d[:, 1], wrap(s[j, 2] - s[i, 2])])


def check_kernel(kernel: str, width: float) -> None:
    """One line for a kernel not in :data:`KERNELS` or a width that is not a number > 0."""
    if kernel not in KERNELS:
        raise ValueError(f"pose_error.robust_kernel = {kernel!r}: expected one of {', '.join(KERNELS)}")
    ok = isinstance(width, int | float) and not isinstance(width, bool) and math.isfinite(width) and width > 0
    if not ok:
        raise ValueError(f"pose_error.kernel_width = {width!r}: expected a number > 0 (sigmas of a closure's "
                         f"whitened error)")


def _gtsam():
    try:
        import gtsam
    except ImportError as e:  # a core dependency; a broken install says so in one line
        raise ImportError(f"the pose-graph solve needs GTSAM ({e}); pip install 'gtsam==4.3.0' "
                          f"(a core dependency of roomseg-bench)") from None
    return gtsam


def _noise(gtsam, sqrt_info: np.ndarray, kernel: str, width: float):
    """The GTSAM noise model of one edge: Gaussian from its square-root information, under
    ``kernel`` (``width`` sigmas: Huber's k, Cauchy's c, DCS's sqrt(phi)) unless "none" / "gnc"."""
    base = gtsam.noiseModel.Gaussian.SqrtInformation(np.ascontiguousarray(sqrt_info, np.float64))
    m = gtsam.noiseModel.mEstimator
    if kernel == "huber":
        return gtsam.noiseModel.Robust.Create(m.Huber(width), base)
    if kernel == "cauchy":
        return gtsam.noiseModel.Robust.Create(m.Cauchy(width), base)
    if kernel == "dcs":
        return gtsam.noiseModel.Robust.Create(m.DCS(width * width), base)
    return base


def _factors(gtsam, graph: PoseGraph, kernel: str, width: float, keep: np.ndarray | None = None):
    """(the factor graph of ``graph``'s edges, the index in it of each robust edge's factor)."""
    fg = gtsam.NonlinearFactorGraph()
    robust = graph.robust_mask()
    at = []
    for e in range(len(graph.i)):
        if keep is not None and not keep[e]:
            continue
        k = kernel if robust[e] else "none"
        if robust[e]:
            at.append(fg.size())
        z = graph.z[e]
        fg.add(gtsam.BetweenFactorPose2(int(graph.i[e]), int(graph.j[e]), gtsam.Pose2(float(z[0]), float(z[1]),
                                                                                      float(z[2])),
                                        _noise(gtsam, graph.sqrt_info[e], k, width)))
    return fg, np.array(at, np.int64)


def _values(gtsam, states: np.ndarray):
    v = gtsam.Values()
    for k, (x, y, t) in enumerate(np.asarray(states, np.float64).tolist()):
        v.insert(k, gtsam.Pose2(x, y, t))
    return v


def _states(values, n: int) -> np.ndarray:
    return np.array([[p.x(), p.y(), p.theta()] for p in (values.atPose2(k) for k in range(n))], np.float64)


def _anchor(states: np.ndarray, start: np.ndarray) -> np.ndarray:
    """``states`` moved rigidly so that the first sits at ``start`` exactly."""
    s = np.asarray(states, np.float64)
    dphi = float(start[2] - s[0, 2])
    c, sn = math.cos(dphi), math.sin(dphi)
    d = s[:, :2] - s[0, :2]
    out = np.empty_like(s)
    out[:, 0] = start[0] + c * d[:, 0] - sn * d[:, 1]
    out[:, 1] = start[1] + sn * d[:, 0] + c * d[:, 1]
    out[:, 2] = wrap(s[:, 2] + dphi)
    out[0] = start
    return out


def _prior(gtsam, start: np.ndarray):
    """Node 0 held at ``start`` (a hard constraint: the gauge of the map's frame)."""
    return gtsam.PriorFactorPose2(0, gtsam.Pose2(*map(float, start)), gtsam.noiseModel.Constrained.All(3))


def _lm_params(gtsam, max_iterations: int):
    params = gtsam.LevenbergMarquardtParams()
    params.setMaxIterations(max_iterations)
    params.setRelativeErrorTol(RELATIVE_TOLERANCE)
    params.setAbsoluteErrorTol(ABSOLUTE_TOLERANCE)
    return params


def _stationary(gtsam, fg, values, cost: float, rounding: float) -> bool:
    """True when the Gauss-Newton model of ``fg`` at ``values`` promises to lower ``cost`` by no more
    than the tolerances or ``rounding`` (the cost's own rounding error: a minimum to rounding);
    False when it promises more, or has no solution."""
    lin = fg.linearize(values)
    try:
        step = lin.optimize()
    except RuntimeError:  # indeterminant system: no model step at all
        return False
    gain = lin.error(gtsam.VectorValues.Zero(step)) - lin.error(step)
    return bool(np.isfinite(gain) and gain <= max(RELATIVE_TOLERANCE * cost, ABSOLUTE_TOLERANCE, rounding))


def _levenberg_marquardt(gtsam, fg, values, max_iterations: int, rounding: float = 0.0):
    """(values, iterations, converged): GTSAM's LM on ``fg`` from ``values``, iteration by
    iteration until the cost falls by less than the tolerances, or no damping finds a step that
    lowers it, or ``max_iterations`` are done (not converged). A stop for want of a step is
    converged only at a stationary point (:func:`_stationary`): ill-conditioned information can
    leave LM with no step far from any minimum, after 0 iterations or more."""
    opt = gtsam.LevenbergMarquardtOptimizer(fg, values, _lm_params(gtsam, max_iterations))
    prev = opt.error()
    if prev <= ABSOLUTE_TOLERANCE:
        return opt.values(), 0, True
    while opt.iterations() < max_iterations:
        before = opt.iterations()
        opt.iterate()
        cur = opt.error()
        if opt.iterations() == before:  # no damping lowered the cost
            return opt.values(), int(opt.iterations()), _stationary(gtsam, fg, opt.values(), cur, rounding)
        if gtsam.checkConvergence(RELATIVE_TOLERANCE, ABSOLUTE_TOLERANCE, 0.0, prev, cur):
            return opt.values(), int(opt.iterations()), True
        prev = cur
    return opt.values(), int(opt.iterations()), False


def solve(graph: PoseGraph, initial: np.ndarray, kernel: str = "cauchy", width: float = 3.37,
          max_iterations: int = 1000) -> tuple[np.ndarray, dict]:
    """The final estimate: node states minimising the (robust) cost, node 0 held at ``initial[0]``.

    Args:
        graph: the edges (``graph.robust``: those under the kernel).
        initial: (n, 3) starting states (the dead-reckoning chain).
        kernel: one of :data:`KERNELS` on the robust edges (module docstring).
        width: the kernel's constant in sigmas of a closure's whitened error (GNC: a closure
            whose whitened error is within ``width`` is an inlier; 3.37 = sqrt of the 99 %
            quantile of chi-square with 3 degrees of freedom).
        max_iterations: Levenberg-Marquardt iterations allowed (GNC: per inner solve).

    Returns:
        ((n, 3) states, info): ``chi2`` the final sum of squared whitened residuals over the edges
        kept (Gaussian: every edge; robust kernels: every edge, unweighted; GNC: the odometry and
        the inlier closures), ``dof`` (3 x edges kept - 3 (n - 1)), ``iterations`` (the final
        Levenberg-Marquardt solve's), ``converged`` (False when that solve was cut off at
        ``max_iterations``, or GNC's weights did not settle at 0 / 1), ``outliers`` (robust edges
        down-weighted: GNC weight 0, or whitened error beyond ``width`` at the answer).
    """
    check_kernel(kernel, width)
    x0 = np.asarray(initial, np.float64).reshape(-1, 3)
    if graph.n != len(x0):
        raise ValueError(f"pose graph has {graph.n} nodes, initial states {len(x0)}")
    robust = graph.robust_mask()
    if graph.n < 2 or len(graph.i) == 0:
        return x0.copy(), {"chi2": 0.0, "dof": 0, "iterations": 0, "converged": True, "outliers": 0}
    gtsam = _gtsam()
    values = _values(gtsam, x0)
    keep = np.ones(len(graph.i), bool)
    converged = True
    if kernel == "gnc" and robust.any():
        fg, at = _factors(gtsam, graph, "none", width)
        fg.add(_prior(gtsam, x0[0]))
        params = gtsam.GncLMParams(_lm_params(gtsam, max_iterations))
        params.setLossType(gtsam.GncLossType.TLS)
        inliers = np.setdiff1d(np.arange(fg.size()), at)
        params.setKnownInliers([int(k) for k in inliers])
        gnc = gtsam.GncLMOptimizer(fg, values, params)
        gnc.setInlierCostThresholds(0.5 * width * width)  # GTSAM's factor cost is half the squared error
        values = gnc.optimize()
        w = np.asarray(gnc.getWeights(), np.float64)[at]
        converged = bool(np.all((w < 1e-4) | (w > 1 - 1e-4)))
        keep[np.flatnonzero(robust)[w < 0.5]] = False
        kernel = "none"
    fg, at = _factors(gtsam, graph, kernel, width, keep)
    fg.add(_prior(gtsam, x0[0]))
    # the cost's rounding error: a state's last bit (eps times its size) through each edge's largest weight
    scale = np.finfo(np.float64).eps * (1.0 + np.abs(x0[:, :2]).max())
    rounding = float(np.sum((scale * np.abs(graph.sqrt_info).max(axis=(1, 2))) ** 2))
    values, iterations, lm_ok = _levenberg_marquardt(gtsam, fg, values, max_iterations, rounding)
    plain, _ = _factors(gtsam, graph, "none", width, keep)
    chi2 = 2.0 * plain.error(values)
    if kernel in ("huber", "cauchy", "dcs"):
        per = np.array([2.0 * plain.at(int(k)).error(values) for k in at])
        outliers = int((per > width * width).sum())
    else:
        outliers = int((~keep).sum())
    states = _anchor(_states(values, graph.n), x0[0])
    return states, {"chi2": float(chi2), "dof": int(3 * keep.sum() - 3 * (graph.n - 1)), "iterations": iterations,
                    "converged": bool(converged and lm_ok), "outliers": outliers}


def online(graph: PoseGraph, initial: np.ndarray, nodes: np.ndarray, kernel: str = "cauchy",
           width: float = 3.37, plain: np.ndarray | None = None, known_at: np.ndarray | None = None) -> np.ndarray:
    """The estimate the robot had of each of ``nodes`` when it reached it: iSAM2 updated in travel
    order (node k joins with every edge whose later node is k, or that ``known_at`` makes known
    at k), each node's pose read right after it joined.

    A node whose only new edge is the odometry edge from node k - 1 changes no earlier estimate:
    its pose is its predecessor's current estimate composed with that edge's measurement (what
    iSAM2 would give it), and it enters iSAM2 with the next node that brings a loop closure (or
    more than one edge); iSAM2 is updated only there. ``kernel`` as :func:`solve`'s on the robust
    edges; GNC is a batch method (it needs every closure at once), so online a closure under
    ``"gnc"`` carries its end point, the truncated quadratic (GTSAM's ``TruncatedLeastSquares``,
    inlier bound ``width`` sigmas): a robot that rejects a closure inconsistent with its estimate
    at that moment.

    ``plain`` robust edges join without the kernel: the closures that put a lost segment back on
    the map (:mod:`benchmark.conditions.front_end`, 6). iSAM2 linearises such a closure where it
    had the segment, still floating on the weak edge across the loss (metres off after a
    kidnapping: a whitened residual of a hundred sigmas), not where the front end relocalised it
    (:func:`solve` starts there, where the kernel judges it at a residual of centimetres); a
    redescending kernel (Cauchy, DCS, truncated) weighs it ~0 there, so the segment, and every one
    after it, hangs on weak edges alone beside odometry a million times stronger, and GTSAM's Bayes
    tree can find an update indeterminate (shared house 00101 at ``kidnap_1``: three losses, two
    segments relocalised, one never). Online, the front end's verification of such a closure (two
    agreeing place matches) is its outlier test.

    Args:
        graph: the edges; every edge joins two nodes, the later one determines when it is added.
        initial: (n, 3) dead reckoning: node 0's pose (held there), and a node that joins with
            a loop closure starts at its predecessor's estimate composed with the dead-reckoning move.
        nodes: (V,) node indices wanted (the views' nodes).
        plain: (E,) bool, robust edges taken without the kernel here; None: none.
        known_at: (E,) int, the node at which the robot learns each edge (at least its later node:
            a relocalising closure is known only when a second place match confirms it); None:
            every edge at its later node.

    Returns:
        (V, 3) states.

    Raises:
        RuntimeError: GTSAM could not solve an update (one line: the node, GTSAM's reason).
    """
    check_kernel(kernel, width)
    x0 = np.asarray(initial, np.float64).reshape(-1, 3)
    nodes = np.asarray(nodes, np.int64).reshape(-1)
    if len(nodes) == 0:
        return np.zeros((0, 3))
    gtsam = _gtsam()
    n = graph.n
    later = np.maximum(graph.i, graph.j)
    if known_at is not None:
        known_at = np.asarray(known_at, np.int64).reshape(len(graph.i))
        if (known_at < later).any() or (known_at >= n).any():
            raise ValueError(f"online: known_at must be at least each edge's later node and below {n}")
        later = known_at
    order = np.argsort(later, kind="stable")
    bounds = np.searchsorted(later[order], np.arange(n + 1))
    robust = graph.robust_mask()
    if plain is not None:
        robust = robust & ~np.asarray(plain, bool).reshape(len(graph.i))
    if kernel == "gnc":
        m = gtsam.noiseModel.mEstimator.TruncatedLeastSquares(width)
    params = gtsam.ISAM2Params()
    params.setRelinearizeThreshold(RELINEARIZE_THRESHOLD)
    params.relinearizeSkip = RELINEARIZE_SKIP
    isam = gtsam.ISAM2(params)
    out = np.zeros((n, 3))
    fg, v = gtsam.NonlinearFactorGraph(), gtsam.Values()
    fg.add(_prior(gtsam, x0[0]))
    prev = gtsam.Pose2(*map(float, x0[0]))
    v.insert(0, prev)
    out[0] = x0[0]
    for k in range(1, n):
        edges = order[bounds[k]:bounds[k + 1]]
        for e in edges:
            z = graph.z[e]
            if robust[e] and kernel == "gnc":
                base = gtsam.noiseModel.Gaussian.SqrtInformation(np.ascontiguousarray(graph.sqrt_info[e]))
                noise = gtsam.noiseModel.Robust.Create(m, base)
            else:
                noise = _noise(gtsam, graph.sqrt_info[e], kernel if robust[e] else "none", width)
            fg.add(gtsam.BetweenFactorPose2(int(graph.i[e]), int(graph.j[e]),
                                            gtsam.Pose2(float(z[0]), float(z[1]), float(z[2])), noise))
        if len(edges) == 1 and graph.i[edges[0]] == k - 1 and graph.j[edges[0]] == k:
            prev = prev.compose(gtsam.Pose2(*map(float, graph.z[edges[0]])))  # odometry alone
            v.insert(k, prev)
        else:
            a, b = gtsam.Pose2(*map(float, x0[k - 1])), gtsam.Pose2(*map(float, x0[k]))
            v.insert(k, prev.compose(a.between(b)))
            try:
                isam.update(fg, v)
            except RuntimeError as e:
                raise RuntimeError(f"online pose-graph solve (iSAM2), update at node {k}: {gtsam_reason(e)}") from None
            fg, v = gtsam.NonlinearFactorGraph(), gtsam.Values()
            prev = isam.calculateEstimatePose2(k)
        out[k] = prev.x(), prev.y(), prev.theta()
    return out[nodes]


def gtsam_reason(e: BaseException) -> str:
    """One line for a GTSAM error (its message runs over several lines with a guide's address)."""
    text = " ".join(str(e).split())
    found = re.search(r"Indeterminate linear system detected while working near variable (\d+)", text)
    if found:
        return (f"GTSAM found the linear system indeterminate near node {found.group(1)} (a part of the graph no edge "
                f"constrains in some direction, or one too poorly conditioned to solve)")
    return text if len(text) <= 300 else text.split(". ")[0]


def move_edge(moves: np.ndarray, sigmas: np.ndarray, floor: float = 1e-4) -> tuple[np.ndarray, np.ndarray]:
    """Odometry edges from (K, 3) reported moves (rot1, trans, rot2) and their (K, 3) sigmas.

    The relative pose is (trans cos rot1, trans sin rot1, rot1 + rot2); its covariance is the
    moves' diagonal covariance through that map's Jacobian, plus ``floor`` squared (metres and
    radians) on the diagonal so that an exact move still has finite information.

    Returns:
        ((K, 3) z, (K, 3, 3) sqrt_info).
    """
    m = np.asarray(moves, np.float64).reshape(-1, 3)
    r1, t = m[:, 0], m[:, 1]
    z = np.column_stack([t * np.cos(r1), t * np.sin(r1), wrap(r1 + m[:, 2])])
    jac = np.zeros((len(m), 3, 3))
    jac[:, 0, 0], jac[:, 0, 1] = -t * np.sin(r1), np.cos(r1)
    jac[:, 1, 0], jac[:, 1, 1] = t * np.cos(r1), np.sin(r1)
    jac[:, 2, 0], jac[:, 2, 2] = 1.0, 1.0
    cov = np.einsum("eab,eb,ecb->eac", jac, np.asarray(sigmas, np.float64) ** 2, jac) + floor ** 2 * np.eye(3)
    return z, sqrt_information(cov)


def sqrt_information(cov: np.ndarray) -> np.ndarray:
    """(E, 3, 3) covariances -> (E, 3, 3) upper factors U with U^T U = inverse covariance."""
    info = np.linalg.inv(np.asarray(cov, np.float64))
    low = np.linalg.cholesky(info)  # info = L L^T -> U = L^T
    return np.transpose(low, (0, 2, 1))


__all__ = ["KERNELS", "PoseGraph", "relative", "check_kernel", "solve", "online", "move_edge", "sqrt_information",
           "gtsam_reason"]
