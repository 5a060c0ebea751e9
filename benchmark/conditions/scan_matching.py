"""Correlative scan matching (Olson 2009, "Real-time correlative scan matching"), compiled.

Why correlative and not ICP: the front end must give every match a *covariance* (the odometry
edge's information, and the loop-closure gate) and must search a window set by the robot's own
uncertainty, where ICP converges to the nearest local minimum from its start and gives no
covariance of its own. A correlative matcher scores every pose of the window on a lattice, so it
finds the best pose anywhere in the window (it is fooled only by places that really look alike),
its score is a stated acceptance test, and the score surface gives the covariance.

The matcher, for a reference scan ``a`` and a scan ``b`` (points in each robot's own frame,
metres: x forward along the heading, z to its left, as :mod:`benchmark.conditions.odometry`'s SE(2)):

1. **Likelihood grid** (:class:`LikelihoodGrid`): ``a``'s points rasterised on a grid of ``resolution``
   metres covering them plus ``3 sigma``; a cell holds ``log(eps + (1 - eps) g)`` with
   ``g = exp(-d^2 / (2 sigma^2))``, ``d`` the distance from the cell centre to the nearest point
   of ``a`` within ``3 sigma`` (``g = 0`` beyond; ``eps`` :data:`EPS` keeps a point that lands
   nowhere from vetoing a pose). Cells off the grid hold ``log(eps)``.
2. **Search window**: relative poses ``z = centre + (i * resolution, j * resolution, k * step)``,
   ``|i|, |j| <= ceil(window_xy / resolution)``, ``|k| <= ceil(window_theta / step)``: translations in
   whole grid cells from the centre. The score of a pose is
   ``L = sum over b's points of grid[cell of (R(z_theta) p + z_xy)]``, a point's cell taken once per
   heading at the window centre (``floor``) and shifted by ``(i, j)`` cells.
3. **Branch and bound** (Olson's multi-resolution search, exact): the window is cut into blocks
   of :data:`BLOCK` x :data:`BLOCK` translations; a block's bound uses a grid whose cell holds the
   maximum over the block's cells (never below any pose's score in the block). Blocks are
   evaluated pose by pose from the highest bound down until no bound beats the best score found:
   the best pose is the exhaustive search's (``exhaustive=True`` evaluates every pose, for the
   tests).
4. **Answer** (:class:`Match`): the best pose and its score ``L``; ``score`` the mean ``g`` of ``b``'s
   points there (0..1, what acceptance thresholds are stated on); the mean and covariance of the
   poses evaluated, each weighted ``exp(L - L_best)`` (Olson's eq. 15; poses left unevaluated by the
   bound weigh less than ``exp(0)``, and the far tail is negligible). The covariance treats the
   points as independent and is overconfident, as Olson notes: callers floor it.

:func:`match` is the entry point; ``tests/test_front_end.py`` holds a slow plain-Python reference
of the same search that shares no code with it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from envs.kernel_cache import njit

#: outlier share of a point's likelihood: a point landing nowhere costs log(EPS), not -inf
EPS = 0.05
#: translations per block side in the branch-and-bound search
BLOCK = 4


@dataclass(frozen=True)
class Match:
    """One match of a scan ``b`` against a reference ``a``.

    Attributes:
        best: (3,) the best relative pose of ``b`` in ``a``'s frame (dx, dz metres, dphi radians).
        loglik: its score ``L`` (sum of the points' log-likelihoods).
        score: mean ``g`` of ``b``'s points at ``best`` (0..1; 1: every point on a point of ``a``).
        mean: (3,) the weighted mean pose over the evaluated poses (module docstring).
        cov: (3, 3) their weighted covariance (metres, radians).
        evaluated: poses scored (the window's size when exhaustive).
    """

    best: np.ndarray
    loglik: float
    score: float
    mean: np.ndarray
    cov: np.ndarray
    evaluated: int


@njit(cache=True, nogil=True)
def _rasterise(points, x0, y0, res, sigma, h, w, eps):
    """(h, w) log-likelihood grid of ``points`` (module docstring, step 1) and its block-max grid:
    ``pooled[r + BLOCK - 1, c + BLOCK - 1]`` is the maximum of ``grid`` over rows ``r .. r + BLOCK - 1``
    and columns ``c .. c + BLOCK - 1`` (cells off the grid count as ``log(eps)``). Only the cells
    within ``3 sigma`` of a point are computed; every other cell is ``log(eps)``."""
    low = np.log(eps)
    grid = np.full((h, w), low)
    pooled = np.full((h + 3, w + 3), low)  # BLOCK = 4
    rad = int(np.ceil(3.0 * sigma / res))
    cut = 9.0 * sigma * sigma
    for p in range(points.shape[0]):
        px = points[p, 0]
        py = points[p, 1]
        cr = int(np.floor((py - y0) / res))
        cc = int(np.floor((px - x0) / res))
        for r in range(max(cr - rad, 0), min(cr + rad + 1, h)):
            dy = y0 + (r + 0.5) * res - py
            for c in range(max(cc - rad, 0), min(cc + rad + 1, w)):
                dx = x0 + (c + 0.5) * res - px
                d2 = dx * dx + dy * dy
                if d2 <= cut:
                    v = np.log(eps + (1.0 - eps) * np.exp(-d2 / (2.0 * sigma * sigma)))
                    if v > grid[r, c]:
                        grid[r, c] = v
                        # the blocks whose first cell is within 3 cells before (r, c) hold it
                        for a in range(4):
                            for b in range(4):
                                if v > pooled[r + a, c + b]:
                                    pooled[r + a, c + b] = v
    return grid, pooled


@njit(cache=True, nogil=True)
def _moments(out, best, cx, cy, ct, kx, kt, res, step):
    """Weighted mean (3,) and covariance (3, 3) of the evaluated poses (weights exp(L - best))."""
    sw = 0.0
    m = np.zeros(3)
    for k in range(out.shape[0]):
        for i in range(out.shape[1]):
            for j in range(out.shape[2]):
                if out[k, i, j] > -np.inf:
                    wt = np.exp(out[k, i, j] - best)
                    sw += wt
                    m[0] += wt * (cx + (i - kx) * res)
                    m[1] += wt * (cy + (j - kx) * res)
                    m[2] += wt * (ct + (k - kt) * step)
    m /= sw
    cov = np.zeros((3, 3))
    d = np.zeros(3)
    for k in range(out.shape[0]):
        for i in range(out.shape[1]):
            for j in range(out.shape[2]):
                if out[k, i, j] > -np.inf:
                    wt = np.exp(out[k, i, j] - best) / sw
                    d[0] = cx + (i - kx) * res - m[0]
                    d[1] = cy + (j - kx) * res - m[1]
                    d[2] = ct + (k - kt) * step - m[2]
                    for a in range(3):
                        for b in range(3):
                            cov[a, b] += wt * d[a] * d[b]
    return m, cov


@njit(cache=True, nogil=True)
def _mean_g(grid, x0, y0, res, points, px, py, pt, eps):
    """Mean ``g`` of ``points`` at pose (px, py, pt), each point's cell by ``floor``."""
    h, w = grid.shape
    c = np.cos(pt)
    s = np.sin(pt)
    tot = 0.0
    for p in range(points.shape[0]):
        x = c * points[p, 0] - s * points[p, 1] + px
        y = s * points[p, 0] + c * points[p, 1] + py
        r = int(np.floor((y - y0) / res))
        cc = int(np.floor((x - x0) / res))
        if 0 <= r < h and 0 <= cc < w:
            tot += (np.exp(grid[r, cc]) - eps) / (1.0 - eps)
    return tot / max(points.shape[0], 1)


@njit(cache=True, nogil=True, inline="always")
def _cells(points, ct, st, cx, cy, x0, y0, res, rows, cols):
    """Each point's cell at heading (cos ``ct``, sin ``st``) and the window centre translation."""
    for p in range(points.shape[0]):
        x = ct * points[p, 0] - st * points[p, 1] + cx
        y = st * points[p, 0] + ct * points[p, 1] + cy
        rows[p] = int(np.floor((y - y0) / res))
        cols[p] = int(np.floor((x - x0) / res))


@njit(cache=True, nogil=True)
def _search(grid, pooled, x0, y0, res, points, cx, cy, ctheta, kx, kt, step, exhaustive, low, out):
    """The branch-and-bound search (module docstring, steps 2-3). ``out`` (n_theta, 2 kx + 1, 2 kx + 1)
    receives the score of every evaluated pose (others stay -inf). Returns (best k, i, j, L, evaluated)
    as indices into ``out``."""
    h, w = grid.shape
    n = points.shape[0]
    nt = 2 * kt + 1
    nx = 2 * kx + 1
    nb = (nx + 3) // 4  # blocks per side (BLOCK = 4)
    rows = np.empty(n, np.int64)
    cols = np.empty(n, np.int64)
    bounds = np.empty(nt * nb * nb, np.float64)
    for k in range(nt):
        th = ctheta + (k - kt) * step
        _cells(points, np.cos(th), np.sin(th), cx, cy, x0, y0, res, rows, cols)
        for bi in range(nb):
            for bj in range(nb):
                s = 0.0
                for p in range(n):
                    r = rows[p] + bj * 4 - kx + 3  # pooled's index of the block's first cell (j: rows)
                    c = cols[p] + bi * 4 - kx + 3  # (i: columns)
                    if 0 <= r < h + 3 and 0 <= c < w + 3:
                        s += pooled[r, c]
                    else:
                        s += low
                bounds[(k * nb + bi) * nb + bj] = s
    order = np.argsort(-bounds, kind="mergesort")
    best = -np.inf
    bk = 0
    bi_ = 0
    bj_ = 0
    evaluated = 0
    last_k = -1
    for o in range(order.shape[0]):
        q = order[o]
        if not exhaustive and bounds[q] < best:
            break
        k = q // (nb * nb)
        bi = (q // nb) % nb
        bj = q % nb
        if k != last_k:
            th = ctheta + (k - kt) * step
            _cells(points, np.cos(th), np.sin(th), cx, cy, x0, y0, res, rows, cols)
            last_k = k
        for i in range(bi * 4, min(bi * 4 + 4, nx)):
            for j in range(bj * 4, min(bj * 4 + 4, nx)):
                s = 0.0
                for p in range(n):
                    r = rows[p] + j - kx
                    c = cols[p] + i - kx
                    if 0 <= r < h and 0 <= c < w:
                        s += grid[r, c]
                    else:
                        s += low
                out[k, i, j] = s
                evaluated += 1
                # ties: the lowest (k, i, j), whatever the order blocks are visited in
                if s > best or (s == best and (k, i, j) < (bk, bi_, bj_)):
                    best = s
                    bk = k
                    bi_ = i
                    bj_ = j
    return bk, bi_, bj_, best, evaluated


class LikelihoodGrid:
    """A reference scan rasterised for matching (module docstring, step 1).

    Args:
        points: (K, 2) the reference's points in its frame, metres.
        resolution: metres per cell (the search's translation step).
        sigma: metres, the smoothing of a point (the scanner's range error and the cells' size).
    """

    def __init__(self, points: np.ndarray, resolution: float, sigma: float):
        pts = np.ascontiguousarray(points, np.float64).reshape(-1, 2)
        self.resolution, self.sigma = float(resolution), float(sigma)
        margin = 3.0 * self.sigma + self.resolution
        lo = pts.min(axis=0) - margin if len(pts) else np.zeros(2)
        hi = pts.max(axis=0) + margin if len(pts) else np.ones(2)
        self.x0, self.y0 = float(lo[0]), float(lo[1])
        w, h = (int(math.ceil(v)) for v in (hi - lo) / self.resolution)
        self.grid, self.pooled = _rasterise(pts, self.x0, self.y0, self.resolution, self.sigma, max(h, 1), max(w, 1),
                                            EPS)


def match(ref: LikelihoodGrid, points: np.ndarray, centre, window_xy: float, window_theta: float, step: float,
          exhaustive: bool = False) -> tuple[Match, np.ndarray]:
    """Match ``points`` (K, 2) of scan ``b`` (its own frame) against ``ref`` around ``centre``.

    Args:
        ref: the reference scan's :class:`LikelihoodGrid`.
        points: (K, 2) metres.
        centre: (3,) the search centre: b's pose in a's frame (dx, dz metres, dphi radians).
        window_xy: metres searched either side of the centre per axis.
        window_theta: radians searched either side of the centre's heading.
        step: radians between headings.
        exhaustive: score every pose (no bound): the same best pose, for the tests.

    Returns:
        (the :class:`Match`, (n_theta, n_xy, n_xy) scores of the evaluated poses, -inf elsewhere;
        axis 1 steps dx, axis 2 dz).
    """
    pts = np.ascontiguousarray(points, np.float64).reshape(-1, 2)
    res = ref.resolution
    kx = int(math.ceil(window_xy / res - 1e-9))
    kt = int(math.ceil(window_theta / step - 1e-9))
    cx, cy, ct = (float(v) for v in centre)
    out = np.full((2 * kt + 1, 2 * kx + 1, 2 * kx + 1), -np.inf)
    low = math.log(EPS)
    k, i, j, best, n = _search(ref.grid, ref.pooled, ref.x0, ref.y0, res, pts, cx, cy, ct, kx, kt, float(step),
                               bool(exhaustive), low, out)
    mean, cov = _moments(out, best, cx, cy, ct, kx, kt, res, float(step))
    bp = np.array([cx + (i - kx) * res, cy + (j - kx) * res, ct + (k - kt) * step])
    score = mean_likelihood(ref, pts, bp)
    return Match(bp, float(best), score, mean, cov, int(n)), out


def mean_likelihood(ref: LikelihoodGrid, points: np.ndarray, pose) -> float:
    """Mean ``g`` (0..1) of ``points`` placed at ``pose`` on ``ref`` (each point's cell by ``floor``, as
    the search takes it; a point off the grid counts 0)."""
    pts = np.ascontiguousarray(points, np.float64).reshape(-1, 2)
    return float(_mean_g(ref.grid, ref.x0, ref.y0, ref.resolution, pts, float(pose[0]), float(pose[1]),
                         float(pose[2]), EPS))


__all__ = ["BLOCK", "EPS", "LikelihoodGrid", "Match", "match", "mean_likelihood"]
