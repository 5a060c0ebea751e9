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
3. **Branch and bound** (Olson's multi-resolution search, exact): a window wider than :data:`SMALL`
   translations a side is cut into blocks of 16 x 16 translations, each cut into blocks of 4 x 4;
   a block's bound reads a grid whose cell holds the maximum over the block's cells (never below
   any pose's score in the block). Blocks are visited from the highest bound down, level by level,
   until no bound beats the best score found: the best pose is the exhaustive search's
   (``exhaustive=True`` visits every block, for the tests). A small window is scored pose by pose.
   Sums are taken several at a time (a 4 x 4 block's poses, a 16-block's sixteen bounds, a heading's
   16-block bounds: one pass over the points), each in the points' order: the same sums, bit for
   bit, as one at a time. The bound is Olson's block maxima, kept loose on purpose: the mean and
   covariance (step 4) are over the poses it evaluates, so a tighter bound would change them.
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
import threading
from dataclasses import dataclass

import numpy as np

from envs.kernel_cache import njit

#: outlier share of a point's likelihood: a point landing nowhere costs log(EPS), not -inf
EPS = 0.05
#: translations per side of a window searched pose by pose (no bound): small windows
SMALL = 8


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
    """(h, w) log-likelihood grid of ``points`` (module docstring, step 1): each cell's squared
    distance to its nearest point within ``3 sigma`` first, then one likelihood per cell reached
    (the likelihood falls with the distance); every other cell is ``log(eps)``."""
    cut = 9.0 * sigma * sigma
    d2min = np.full((h, w), np.inf)
    rad = int(np.ceil(3.0 * sigma / res))
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
                if d2 < d2min[r, c]:
                    d2min[r, c] = d2
    grid = np.empty((h, w), np.float64)
    low = np.log(eps)
    for r in range(h):
        for c in range(w):
            d2 = d2min[r, c]
            if d2 <= cut:
                grid[r, c] = np.log(eps + (1.0 - eps) * np.exp(-d2 / (2.0 * sigma * sigma)))
            else:
                grid[r, c] = low
    return grid


@njit(cache=True, nogil=True)
def _pool(src, pad, stride, low):
    """Block maxima: ``out[R, C]`` is the maximum of ``src[R - a, C - b]`` over ``a, b`` in
    ``0, stride, 2 stride, 3 stride`` (entries off ``src`` count as ``low``); ``out`` is ``src``'s shape
    plus ``pad`` = 3 ``stride`` rows and columns. From the grid with stride 1: the maximum over the
    4 x 4 cells ending at (R, C); from that with stride 4: over the 16 x 16 cells ending there."""
    h, w = src.shape
    rows = np.full((h + pad, w), low)
    for r in range(h + pad):
        for c in range(w):
            m = low
            for a in range(4):
                rr = r - a * stride
                if 0 <= rr < h and src[rr, c] > m:
                    m = src[rr, c]
            rows[r, c] = m
    out = np.full((h + pad, w + pad), low)
    for r in range(h + pad):
        for c in range(w + pad):
            m = low
            for b in range(4):
                cc = c - b * stride
                if 0 <= cc < w and rows[r, cc] > m:
                    m = rows[r, cc]
            out[r, c] = m
    return out


@njit(cache=True, nogil=True)
def _moments(out, seen, bounded, evaluated, best, cx, cy, ct, kx, kt, res, step):
    """Weighted mean (3,) and covariance (3, 3) of the evaluated poses (weights exp(L - best)), taken
    in (k, i, j) order. ``bounded``: only the 4 x 4 blocks ``seen[k, i // 4, j // 4]`` were evaluated
    (every pose of such a block; ``out`` holds nothing elsewhere); else every pose was. Each pose's
    weight is computed once and kept for the covariance's pass: the same sums, bit for bit, as reading
    every pose of ``out`` (the unevaluated at -inf) twice."""
    nx = out.shape[1]
    n4 = seen.shape[1]
    wts = np.empty(evaluated)
    sw = 0.0
    m = np.zeros(3)
    e = 0
    for k in range(out.shape[0]):
        for i in range(nx):
            for bj in range(n4 if bounded else 1):
                if bounded and not seen[k, i // 4, bj]:
                    continue
                for j in range(bj * 4 if bounded else 0, min(bj * 4 + 4, nx) if bounded else nx):
                    wt = np.exp(out[k, i, j] - best)
                    wts[e] = wt
                    e += 1
                    sw += wt
                    m[0] += wt * (cx + (i - kx) * res)
                    m[1] += wt * (cy + (j - kx) * res)
                    m[2] += wt * (ct + (k - kt) * step)
    m /= sw
    cov = np.zeros((3, 3))
    d = np.zeros(3)
    e = 0
    for k in range(out.shape[0]):
        for i in range(nx):
            for bj in range(n4 if bounded else 1):
                if bounded and not seen[k, i // 4, bj]:
                    continue
                for j in range(bj * 4 if bounded else 0, min(bj * 4 + 4, nx) if bounded else nx):
                    wt = wts[e] / sw
                    e += 1
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
def _padded(src, pad, low):
    """(H + 2 ``pad``, W + 2 ``pad``) ``src`` padded with ``low`` by ``pad`` cells a side: read at shifts
    ``lo..hi`` (rows and columns) from cells clamped by :func:`_bases` when ``pad >= hi - lo + 1``
    (:func:`pad_for`; a wider pad reads the same cells and pad cells)."""
    h, w = src.shape
    return _padded_into(np.empty((h + 2 * pad) * (w + 2 * pad)), src, pad, low)


@njit(cache=True, nogil=True)
def _padded_into(buf, src, pad, low):
    """:func:`_padded` written into the start of the flat ``buf`` (every cell of it: pad and ``src``),
    returned as a (H + 2 ``pad``, W + 2 ``pad``) view of it."""
    h, w = src.shape
    wp = w + 2 * pad
    out = buf[:(h + 2 * pad) * wp].reshape((h + 2 * pad, wp))
    for r in range(h + 2 * pad):
        if r < pad or r >= pad + h:
            out[r, :] = low
        else:
            out[r, :pad] = low
            out[r, pad:pad + w] = src[r - pad]
            out[r, pad + w:] = low
    return out


@njit(cache=True, nogil=True)
def pad_for(kx):
    """(pad of the grid, of the 4 x 4 block maxima, of the 16 x 16 ones) a search of ``kx`` translations a
    side reads (:func:`_search`: shifts ``-kx..kx``, and each block level's first cells)."""
    n16 = (2 * kx + 1 + 15) // 16
    n4 = (2 * kx + 1 + 3) // 4
    return 2 * kx + 1, (n4 - 1) * 4 + 1, (n16 - 1) * 16 + 1


@njit(cache=True, nogil=True, inline="always")
def _bases(rows, cols, lo, hi, h, w, pad, wp, base):
    """Each point's flat index in a :func:`_padded` grid, its cell clamped to one cell past where a
    shift in ``lo..hi`` could bring it onto the grid: every shifted read of a point off the grid is
    ``low`` (a pad cell), as the search takes it, with no test per point and shift."""
    for p in range(rows.shape[0]):
        base[p] = (min(max(rows[p], -hi - 1), h - lo) + pad) * wp + min(max(cols[p], -hi - 1), w - lo) + pad


@njit(cache=True, nogil=True)
def _sums(flat, base, offs, m, acc):
    """``acc[q]`` = the sum over the points of ``flat`` at each point's index shifted by ``offs[q]``, for
    ``q < m``: every shift's sum taken in the points' order (the same sum, bit for bit, as one shift at
    a time), the ``m`` sums side by side so that no addition waits on the one before it."""
    for q in range(m):
        acc[q] = 0.0
    for p in range(base.shape[0]):
        b = base[p]
        for q in range(m):
            acc[q] += flat[b + offs[q]]


@njit(cache=True, nogil=True)
def _sums4(flat, base, off, wp, stride, acc):
    """:func:`_sums` over a whole block of 4 x 4 shifts: ``acc[4 jj + ii]`` = the sum over the points of
    ``flat`` at each point's index shifted by ``off + jj wp + ii stride`` (4 rows of 4 cells ``stride``
    apart: with ``stride`` 1, each row read as one run), each sum in the points' order."""
    a0 = np.zeros(4)
    a1 = np.zeros(4)
    a2 = np.zeros(4)
    a3 = np.zeros(4)
    for p in range(base.shape[0]):
        b = base[p] + off
        for ii in range(4):
            a0[ii] += flat[b + ii * stride]
        b += wp
        for ii in range(4):
            a1[ii] += flat[b + ii * stride]
        b += wp
        for ii in range(4):
            a2[ii] += flat[b + ii * stride]
        b += wp
        for ii in range(4):
            a3[ii] += flat[b + ii * stride]
    for ii in range(4):
        acc[ii] = a0[ii]
        acc[4 + ii] = a1[ii]
        acc[8 + ii] = a2[ii]
        acc[12 + ii] = a3[ii]


@njit(cache=True, nogil=True)
def _search(g1, pad, g4, pad4, g16, pad16, x0, y0, res, points, cx, cy, ctheta, kx, kt, step, bounded, exhaustive,
            low, out, seen):
    """The search (module docstring, steps 2-3). ``out`` (n_theta, 2 kx + 1, 2 kx + 1) receives the
    score of every evaluated pose (others are left as they are). ``bounded``: branch and bound over blocks of
    16 x 16 translations (bounds from the 16 x 16 block maxima), then 4 x 4 (the 4 x 4 ones), then poses, each level visited from
    the highest bound down while a bound can beat the best (``exhaustive``: every block), ``seen``
    (n_theta, n4, n4) marking the 4 x 4 blocks evaluated; else every pose in turn. Each grid is read
    padded (``g1``, ``g4``, ``g16``: the grid and the block maxima padded by ``pad``, ``pad4``, ``pad16``
    cells a side, :func:`_padded`, at least :func:`pad_for`'s): a point's sum at a shift is the same, bit
    for bit, as with a test whether each shifted cell is on the grid. Returns (best k, i, j, L,
    evaluated) as indices into ``out``; ties go to the lowest (k, i, j)."""
    n = points.shape[0]
    nt = 2 * kt + 1
    nx = 2 * kx + 1
    rows = np.empty(n, np.int64)
    cols = np.empty(n, np.int64)
    base = np.empty(n, np.int64)
    best = -np.inf
    bk = 0
    bi_ = 0
    bj_ = 0
    evaluated = 0
    h, w = g1.shape[0] - 2 * pad, g1.shape[1] - 2 * pad
    flat, wp = g1.ravel(), g1.shape[1]
    if not bounded:
        offs = np.empty(nx * nx, np.int64)
        acc = np.empty(nx * nx, np.float64)
        for i in range(nx):
            for j in range(nx):
                offs[i * nx + j] = (j - kx) * wp + i - kx
        for k in range(nt):
            th = ctheta + (k - kt) * step
            _cells(points, np.cos(th), np.sin(th), cx, cy, x0, y0, res, rows, cols)
            _bases(rows, cols, -kx, kx, h, w, pad, wp, base)
            _sums(flat, base, offs, nx * nx, acc)
            for i in range(nx):
                for j in range(nx):
                    s = acc[i * nx + j]
                    out[k, i, j] = s
                    evaluated += 1
                    if s > best:
                        best = s
                        bk = k
                        bi_ = i
                        bj_ = j
        return bk, bi_, bj_, best, evaluated
    n16 = (nx + 15) // 16  # 16-blocks per side
    n4 = (nx + 3) // 4  # 4-blocks per side
    # the shifts each level reads: 16-blocks b * 16 - kx + 15, 4-blocks b * 4 - kx + 3 (p16's and p4's
    # index of a block's first cell)
    lo16, hi16 = 15 - kx, (n16 - 1) * 16 - kx + 15
    lo4, hi4 = 3 - kx, (n4 - 1) * 4 - kx + 3
    f16, wp16 = g16.ravel(), g16.shape[1]
    f4, wp4 = g4.ravel(), g4.shape[1]
    h16, w16 = g16.shape[0] - 2 * pad16, wp16 - 2 * pad16
    h4, w4 = g4.shape[0] - 2 * pad4, wp4 - 2 * pad4
    top = np.empty(nt * n16 * n16, np.float64)
    offs = np.empty(max(n16 * n16, 16), np.int64)
    acc = np.empty(max(n16 * n16, 16), np.float64)
    for a in range(n16):
        for b in range(n16):
            # (j: rows, i: columns)
            offs[a * n16 + b] = (b * 16 - kx + 15) * wp16 + a * 16 - kx + 15
    # each heading's cells, kept: the blocks below are visited by bound, from heading to heading, and
    # each heading's flat indices in the 4-block bounds and the grid are made once, when first visited
    all_rows = np.empty((nt, n), np.int64)
    all_cols = np.empty((nt, n), np.int64)
    all_b4 = np.empty((nt, n), np.int64)
    all_b = np.empty((nt, n), np.int64)
    made = np.zeros(nt, np.bool_)
    for k in range(nt):
        th = ctheta + (k - kt) * step
        _cells(points, np.cos(th), np.sin(th), cx, cy, x0, y0, res, all_rows[k], all_cols[k])
        _bases(all_rows[k], all_cols[k], lo16, hi16, h16, w16, pad16, wp16, base)
        _sums(f16, base, offs, n16 * n16, acc)
        top[k * n16 * n16:(k + 1) * n16 * n16] = acc[:n16 * n16]
    order = np.argsort(-top, kind="mergesort")
    mid = np.empty(16, np.float64)
    mid_i = np.empty(16, np.int64)
    mid_j = np.empty(16, np.int64)
    poffs = np.empty(16, np.int64)
    pacc = np.empty(16, np.float64)
    for o in range(order.shape[0]):
        q = order[o]
        if not exhaustive and top[q] < best:
            break
        k = q // (n16 * n16)
        a = (q // n16) % n16
        b = q % n16
        if not made[k]:
            _bases(all_rows[k], all_cols[k], lo4, hi4, h4, w4, pad4, wp4, all_b4[k])
            _bases(all_rows[k], all_cols[k], -kx, kx, h, w, pad, wp, all_b[k])
            made[k] = True
        base4 = all_b4[k]
        kbase = all_b[k]
        m = 0
        for bi in range(a * 4, min(a * 4 + 4, n4)):
            for bj in range(b * 4, min(b * 4 + 4, n4)):
                offs[m] = (bj * 4 - kx + 3) * wp4 + bi * 4 - kx + 3
                mid_i[m] = bi
                mid_j[m] = bj
                m += 1
        if m == 16:  # a whole 16-block: its 4 x 4 bounds as 4 rows of 4 cells 4 apart (pacc[4 bj' + bi'])
            _sums4(f4, base4, offs[0], 4 * wp4, 4, pacc)
            for t in range(16):
                mid[t] = pacc[4 * (t % 4) + t // 4]
        else:
            _sums(f4, base4, offs, m, mid)
        sub = np.argsort(-mid[:m], kind="mergesort")
        for t in range(m):
            u = sub[t]
            if not exhaustive and mid[u] < best:
                break
            # the block's poses, summed side by side (pacc[4 (j - j0) + i - i0]), then taken in (i, j) order
            # the block's poses summed side by side, then taken in (i, j) order: a whole block as 4 runs
            # of 4 cells (pacc[4 (j - j0) + i - i0]); a block cut by the window's edge pose by pose
            i0 = mid_i[u] * 4
            j0 = mid_j[u] * 4
            seen[k, mid_i[u], mid_j[u]] = True
            whole = i0 + 4 <= nx and j0 + 4 <= nx
            if whole:
                _sums4(flat, kbase, (j0 - kx) * wp + i0 - kx, wp, 1, pacc)
            else:
                e = 0
                for i in range(i0, min(i0 + 4, nx)):
                    for j in range(j0, min(j0 + 4, nx)):
                        poffs[e] = (j - kx) * wp + i - kx
                        e += 1
                _sums(flat, kbase, poffs, e, pacc)
            e = 0
            for i in range(i0, min(i0 + 4, nx)):
                for j in range(j0, min(j0 + 4, nx)):
                    s = pacc[4 * (j - j0) + i - i0] if whole else pacc[e]
                    e += 1
                    out[k, i, j] = s
                    evaluated += 1
                    if s > best or (s == best and (k, i, j) < (bk, bi_, bj_)):
                        best = s
                        bk = k
                        bi_ = i
                        bj_ = j
    return bk, bi_, bj_, best, evaluated


@njit(cache=True, nogil=True)
def _likelihood_grid(pts, res, sigma, eps):
    """(grid, x0, y0) of :class:`LikelihoodGrid`: ``pts`` plus ``3 sigma + res`` a side (a grid of
    one cell at the origin when there are none)."""
    margin = 3.0 * sigma + res
    if pts.shape[0]:
        lo_x = pts[:, 0].min() - margin
        lo_y = pts[:, 1].min() - margin
        hi_x = pts[:, 0].max() + margin
        hi_y = pts[:, 1].max() + margin
    else:
        lo_x, lo_y, hi_x, hi_y = 0.0, 0.0, 1.0, 1.0
    w = int(math.ceil((hi_x - lo_x) / res))
    h = int(math.ceil((hi_y - lo_y) / res))
    return _rasterise(pts, lo_x, lo_y, res, sigma, max(h, 1), max(w, 1), eps), lo_x, lo_y


@njit(cache=True, nogil=True)
def _match(grid, g1, pad, g4, pad4, g16, pad16, x0, y0, res, points, cx, cy, ct, window_xy, window_theta, step, low,
           eps):
    """:func:`match` compiled, for a caller's compiled loop: ``grid`` and, padded (:func:`_search`), ``g1``
    and the block maxima ``g4``, ``g16`` (read only when the window is wider than :data:`SMALL`), each pad
    at least :func:`pad_for`'s for the window. Returns (best (3,), loglik, score, mean (3,), cov (3, 3))."""
    kx = int(math.ceil(window_xy / res - 1e-9))
    kt = int(math.ceil(window_theta / step - 1e-9))
    out = np.empty((2 * kt + 1, 2 * kx + 1, 2 * kx + 1))
    bounded = 2 * kx + 1 > SMALL
    seen = np.zeros((2 * kt + 1, (2 * kx + 4) // 4, (2 * kx + 4) // 4), np.bool_)
    k, i, j, best, n = _search(g1, pad, g4, pad4, g16, pad16, x0, y0, res, points, cx, cy, ct, kx, kt, step, bounded,
                               False, low, out, seen)
    mean, cov = _moments(out, seen, bounded, n, best, cx, cy, ct, kx, kt, res, step)
    bp = np.array([cx + (i - kx) * res, cy + (j - kx) * res, ct + (k - kt) * step])
    score = _mean_g(grid, x0, y0, res, points, bp[0], bp[1], bp[2], eps)
    return bp, best, score, mean, cov


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
        self.grid, self.x0, self.y0 = _likelihood_grid(pts, self.resolution, self.sigma, EPS)
        self._pools: tuple[np.ndarray, np.ndarray] | None = None

    def pools(self) -> tuple[np.ndarray, np.ndarray]:
        """The block maxima over 4 x 4 and 16 x 16 cells the branch and bound reads (made on first use)."""
        if self._pools is None:
            low = math.log(EPS)
            p4 = _pool(self.grid, 3, 1, low)
            self._pools = (p4, _pool(p4, 12, 4, low))
        return self._pools

    def padded(self, kx: int, bounded: bool) -> tuple:
        """(grid, pad, 4 x 4 block maxima, pad, 16 x 16 block maxima, pad) padded for a search of ``kx``
        translations a side (:func:`_search`; the block maxima only when ``bounded``, else the grid in
        their place), in this thread's scratch buffers (:func:`_scratch`): valid until its next call.
        Padded anew each call: a grid is matched a few times, and memory written again is cheaper than
        fresh memory kept per grid."""
        low = math.log(EPS)
        need = pad_for(kx)
        srcs = (self.grid, *self.pools()) if bounded else (self.grid,)
        out = []
        for level, src in enumerate(srcs):
            size = (src.shape[0] + 2 * need[level]) * (src.shape[1] + 2 * need[level])
            out += [_padded_into(_scratch(f"pad{level}", size), src, need[level], low), need[level]]
        while len(out) < 6:
            out += out[:2]
        return tuple(out)


_SCRATCH = threading.local()


def _scratch(name: str, size: int) -> np.ndarray:
    """This thread's flat float64 buffer ``name`` of at least ``size`` cells (kept, grown when needed):
    :func:`match`'s padded grids and window scores, written again each call."""
    kept = getattr(_SCRATCH, name, None)
    if kept is None or kept.size < size:
        kept = np.empty(max(size, 1 if kept is None else 2 * kept.size))
        setattr(_SCRATCH, name, kept)
    return kept


def match(ref: LikelihoodGrid, points: np.ndarray, centre, window_xy: float, window_theta: float, step: float,
          exhaustive: bool = False, surface: bool = True) -> tuple[Match, np.ndarray | None]:
    """Match ``points`` (K, 2) of scan ``b`` (its own frame) against ``ref`` around ``centre``.

    Args:
        ref: the reference scan's :class:`LikelihoodGrid`.
        points: (K, 2) metres.
        centre: (3,) the search centre: b's pose in a's frame (dx, dz metres, dphi radians).
        window_xy: metres searched either side of the centre per axis.
        window_theta: radians searched either side of the centre's heading.
        step: radians between headings.
        exhaustive: score every pose (no bound): the same best pose, for the tests.
        surface: False: the scores of the evaluated poses are not returned (None; the window's
            array is not filled with -inf first), as a caller that wants the match alone.

    Returns:
        (the :class:`Match`, (n_theta, n_xy, n_xy) scores of the evaluated poses, -inf elsewhere;
        axis 1 steps dx, axis 2 dz; None when not ``surface``).
    """
    pts = np.ascontiguousarray(points, np.float64).reshape(-1, 2)
    res = ref.resolution
    kx = int(math.ceil(window_xy / res - 1e-9))
    kt = int(math.ceil(window_theta / step - 1e-9))
    cx, cy, ct = (float(v) for v in centre)
    shape = (2 * kt + 1, 2 * kx + 1, 2 * kx + 1)
    out = np.full(shape, -np.inf) if surface else _scratch("out", math.prod(shape))[:math.prod(shape)].reshape(shape)
    low = math.log(EPS)
    bounded = 2 * kx + 1 > SMALL
    seen = np.zeros((2 * kt + 1, (2 * kx + 4) // 4, (2 * kx + 4) // 4), np.bool_)
    k, i, j, best, n = _search(*ref.padded(kx, bounded), ref.x0, ref.y0, res, pts, cx, cy, ct, kx, kt, float(step),
                               bounded, bool(exhaustive), low, out, seen)
    mean, cov = _moments(out, seen, bounded, n, best, cx, cy, ct, kx, kt, res, float(step))
    bp = np.array([cx + (i - kx) * res, cy + (j - kx) * res, ct + (k - kt) * step])
    score = mean_likelihood(ref, pts, bp)
    return Match(bp, float(best), score, mean, cov, int(n)), (out if surface else None)


def mean_likelihood(ref: LikelihoodGrid, points: np.ndarray, pose) -> float:
    """Mean ``g`` (0..1) of ``points`` placed at ``pose`` on ``ref`` (each point's cell by ``floor``, as
    the search takes it; a point off the grid counts 0)."""
    pts = np.ascontiguousarray(points, np.float64).reshape(-1, 2)
    return float(_mean_g(ref.grid, ref.x0, ref.y0, ref.resolution, pts, float(pose[0]), float(pose[1]),
                         float(pose[2]), EPS))


__all__ = ["EPS", "SMALL", "LikelihoodGrid", "Match", "match", "mean_likelihood"]
