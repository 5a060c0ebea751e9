"""The scan matcher's branch and bound (its block sums taken side by side) against a plain exhaustive
search in NumPy that shares no code with it: every pose of the window scored by the definition, the
grid rasterised by the definition. The same best pose and score on hand-made scans and on a shared
house; every pose the bound scores, scored as the reference does; the mean and covariance of the
scored poses (taken over the blocks the bound visited, each weight once) as the weighted moments of
the reference's scores of those poses; the same answer without the surface (scratch buffers reused
from call to call) and from grids padded wider than a window needs (the compiled chain keeps a
keyframe's padded grid for the windows after it)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from benchmark.conditions.scan_matching import (
    EPS,
    SMALL,
    LikelihoodGrid,
    _match,
    _padded,
    _pool,
    match,
    pad_for,
)


def _grid_by_definition(points: np.ndarray, res: float, sigma: float):
    """(grid (H, W), x0, y0): points plus 3 sigma + res a side; a cell holds
    log(eps + (1 - eps) exp(-d^2 / 2 sigma^2)) of its centre's nearest point within 3 sigma, else log(eps)."""
    margin = 3.0 * sigma + res
    x0, y0 = points[:, 0].min() - margin, points[:, 1].min() - margin
    w = max(int(math.ceil((points[:, 0].max() + margin - x0) / res)), 1)
    h = max(int(math.ceil((points[:, 1].max() + margin - y0) / res)), 1)
    cx = x0 + (np.arange(w) + 0.5) * res
    cy = y0 + (np.arange(h) + 0.5) * res
    d2 = np.full((h, w), np.inf)
    for px, py in points:
        d2 = np.minimum(d2, (cy[:, None] - py) ** 2 + (cx[None, :] - px) ** 2)
    g = np.where(d2 <= 9.0 * sigma * sigma, np.exp(-d2 / (2.0 * sigma * sigma)), 0.0)
    return np.log(EPS + (1.0 - EPS) * g), x0, y0


def _exhaustive(grid, x0, y0, res, points, centre, kx, kt, step):
    """(2 kt + 1, 2 kx + 1, 2 kx + 1) score of every pose (axis 1: dx in cells, axis 2: dz): each point's
    cell at the heading and the window's centre (floor), shifted; off the grid log(eps). Points are
    added one after another, as a sum over the points is defined."""
    h, w = grid.shape
    n = 2 * kx + 1
    shifts = np.arange(-kx, kx + 1)
    out = np.empty((2 * kt + 1, n, n))
    for k in range(2 * kt + 1):
        th = centre[2] + (k - kt) * step
        c, s = math.cos(th), math.sin(th)
        total = np.zeros((n, n))  # [j (rows: dz), i (columns: dx)]
        for px, py in points:
            r = math.floor((s * px + c * py + centre[1] - y0) / res) + shifts
            q = math.floor((c * px - s * py + centre[0] - x0) / res) + shifts
            vals = np.full((n, n), math.log(EPS))
            rv, qv = (r >= 0) & (r < h), (q >= 0) & (q < w)
            vals[np.ix_(rv, qv)] = grid[np.ix_(r[rv], q[qv])]
            total += vals
        out[k] = total.T
    return out


def _moments_by_definition(scores, centre, kx, kt, res, step):
    """(mean (3,), cov (3, 3)) of the poses with a finite score, each weighted exp(score - best)."""
    k, i, j = np.nonzero(np.isfinite(scores))
    poses = np.column_stack([centre[0] + (i - kx) * res, centre[1] + (j - kx) * res, centre[2] + (k - kt) * step])
    w = np.exp(scores[k, i, j] - scores[k, i, j].max())
    w /= w.sum()
    mean = w @ poses
    d = poses - mean
    return mean, (w[:, None] * d).T @ d


def _check(pts_a, pts_b, centre, window_xy, window_theta, step, res=0.05, sigma=0.05):
    """The compiled search (bounded and exhaustive) against :func:`_exhaustive`; returns the bounded match."""
    kx = int(math.ceil(window_xy / res - 1e-9))
    kt = int(math.ceil(window_theta / step - 1e-9))
    grid_ref, x0, y0 = _grid_by_definition(pts_a, res, sigma)
    ref = LikelihoodGrid(pts_a, res, sigma)
    np.testing.assert_allclose(ref.grid, grid_ref, rtol=0, atol=1e-12)
    assert (ref.x0, ref.y0) == pytest.approx((x0, y0), abs=1e-12)
    want = _exhaustive(grid_ref, x0, y0, res, pts_b, centre, kx, kt, step)
    k, i, j = np.unravel_index(int(np.argmax(want)), want.shape)  # the first (lowest k, i, j) of the best
    best = np.array([centre[0] + (i - kx) * res, centre[1] + (j - kx) * res, centre[2] + (k - kt) * step])
    bound, partial = match(ref, pts_b, centre, window_xy, window_theta, step)
    full, surface = match(ref, pts_b, centre, window_xy, window_theta, step, exhaustive=True)
    np.testing.assert_allclose(surface, want, rtol=1e-12, atol=1e-9)
    for m in (bound, full):
        np.testing.assert_allclose(m.best, best, rtol=0, atol=1e-12)  # the same best pose
        assert m.loglik == pytest.approx(want[k, i, j], rel=1e-12)  # and score
    # the mean likelihood there, by the definition: (exp(cell) - eps) / (1 - eps), 0 off the grid
    c, s = math.cos(best[2]), math.sin(best[2])
    r = np.floor((s * pts_b[:, 0] + c * pts_b[:, 1] + best[1] - y0) / res).astype(int)
    q = np.floor((c * pts_b[:, 0] - s * pts_b[:, 1] + best[0] - x0) / res).astype(int)
    on = (r >= 0) & (r < grid_ref.shape[0]) & (q >= 0) & (q < grid_ref.shape[1])
    g = np.zeros(len(pts_b))
    g[on] = (np.exp(grid_ref[r[on], q[on]]) - EPS) / (1.0 - EPS)
    assert bound.score == pytest.approx(g.mean(), abs=1e-12)
    # the bound scored fewer poses, each as the reference does (whole 4 x 4 blocks and blocks cut
    # by the window's edge alike); a small window: every pose
    seen = np.isfinite(partial)
    assert bound.evaluated == seen.sum()
    assert seen.sum() < surface.size if 2 * kx + 1 > SMALL else seen.all()
    np.testing.assert_allclose(partial[seen], want[seen], rtol=1e-12, atol=1e-9)
    # the moments: over the poses each search scored, weighted by the reference's scores of them
    for m, scored in ((bound, np.where(seen, want, -np.inf)), (full, want)):
        mean, cov = _moments_by_definition(scored, centre, kx, kt, res, step)
        np.testing.assert_allclose(m.mean, mean, rtol=0, atol=1e-12)
        np.testing.assert_allclose(m.cov, cov, rtol=1e-9, atol=1e-15)
    # without the surface: the same match, bit for bit
    bare, none = match(ref, pts_b, centre, window_xy, window_theta, step, surface=False)
    assert none is None
    for name in ("best", "loglik", "score", "mean", "cov", "evaluated"):
        np.testing.assert_array_equal(getattr(bare, name), getattr(bound, name))
    return bound


def _in_frame(world: np.ndarray, pose) -> np.ndarray:
    c, s = math.cos(pose[2]), math.sin(pose[2])
    d = world - np.asarray(pose[:2])
    return np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]])


def test_branch_and_bound_matches_a_plain_exhaustive_search_on_hand_made_scans():
    # a T-shaped room with a pillar, b's points other samples of the same walls, a wide window (41 x 41
    # translations: two whole 16-blocks and one cut a side, 4-blocks cut at the window's edge)
    corners = [(0, 0), (6, 0), (6, 1.5), (4, 1.5), (4, 4), (2, 4), (2, 1.5), (0, 1.5), (0, 0)]
    walls = []
    for (xa, ya), (xb, yb) in zip(corners[:-1], corners[1:]):
        t = np.arange(int(math.hypot(xb - xa, yb - ya) / 0.04)) / int(math.hypot(xb - xa, yb - ya) / 0.04)
        walls.append(np.column_stack([xa + t * (xb - xa), ya + t * (yb - ya)]))
    a = np.linspace(0, 2 * np.pi, 30, endpoint=False)
    walls.append(np.column_stack([3.0 + 0.15 * np.cos(a), 3.0 + 0.15 * np.sin(a)]))
    world = np.vstack(walls)
    rng = np.random.default_rng(11)
    pose_a, pose_b = np.array([3.0, 0.8, 0.1]), np.array([3.3, 1.0, 0.2])
    pts_a = _in_frame(world[::2], pose_a) + rng.normal(0, 0.01, (len(world[::2]), 2))
    pts_b = _in_frame(world[1::2][rng.permutation(len(world[1::2]))[:90]], pose_b)
    truth = np.array([math.cos(0.1) * 0.3 + math.sin(0.1) * 0.2, -math.sin(0.1) * 0.3 + math.cos(0.1) * 0.2, 0.1])
    m = _check(pts_a, pts_b, truth + np.array([0.35, -0.4, 0.05]), 1.0, math.radians(6.0), math.radians(0.5))
    assert np.hypot(*(m.best[:2] - truth[:2])) <= 0.08 and abs(m.best[2] - truth[2]) <= math.radians(0.5) + 1e-12


def test_branch_and_bound_matches_a_plain_exhaustive_search_on_a_shared_house(procthor_file):
    from benchmark.conditions.front_end import robot_points
    from benchmark.viewpoints import Autotrace
    from envs.datasets.house_files import load_houses
    from envs.maps.scan import ScanSettings
    from envs.maps.scene import rasterise_house

    scene = rasterise_house(next(iter(load_houses(procthor_file, 0, 1))))
    poses = Autotrace().generate(scene)
    # two views' positions in one room, the robot's heading (x, z, phi = pi/2 - yaw)
    states = np.array([[p[0], p[1], math.pi / 2 - math.radians(p[2])] for p in poses[[0, 1]]])
    states[1, 2] += 0.3
    pts = robot_points(~scene.grid.walkable, scene.grid, states, ScanSettings(max_range=10.0, angular_step=2.0))
    c, s = math.cos(states[0, 2]), math.sin(states[0, 2])
    d = states[1, :2] - states[0, :2]
    truth = np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1], states[1, 2] - states[0, 2]])
    m = _check(pts[0], pts[1], truth + np.array([0.3, 0.25, math.radians(2.0)]), 0.8, math.radians(4.0),
               math.radians(0.5))
    assert m.score > 0.8


def test_windows_of_every_size_in_turn_and_grids_padded_wider_than_needed_give_the_reference_answer():
    # one thread's scratch buffers through small, wide and small windows on two grids in turn, and the
    # compiled match (the chain's) on grids padded wider than each window needs
    rng = np.random.default_rng(5)
    a = np.linspace(0, 2 * np.pi, 120, endpoint=False)
    room = np.column_stack([2.5 * np.cos(a), 1.5 * np.sin(a)])
    room = np.vstack([room, [[0.8, 0.3], [0.85, 0.3], [-1.0, -0.6]]])
    other = np.column_stack([np.cos(a) * 1.2, np.sin(a) * 2.0]) + [0.3, 0.0]
    step = math.radians(0.5)
    for pts_a, window in ((room, 0.1), (other, 0.9), (room, 0.6), (other, 0.15), (room, 1.0), (other, 0.1)):
        pts_b = pts_a[rng.permutation(len(pts_a))[:80]] + rng.normal(0, 0.01, (80, 2))
        _check(pts_a, pts_b, np.array([0.12, -0.07, 0.02]), window, math.radians(3.0), step)
        ref = LikelihoodGrid(pts_a, 0.05, 0.05)
        kx = int(math.ceil(window / 0.05 - 1e-9))
        low = math.log(EPS)
        p4 = _pool(ref.grid, 3, 1, low)
        p16 = _pool(p4, 12, 4, low)
        want, _ = match(ref, pts_b, (0.12, -0.07, 0.02), window, math.radians(3.0), step)
        for extra in (0, 1, 9):
            n1, n4, n16 = (n + extra for n in pad_for(kx))
            got = _match(ref.grid, _padded(ref.grid, n1, low), n1, _padded(p4, n4, low), n4, _padded(p16, n16, low),
                         n16, ref.x0, ref.y0, 0.05, np.ascontiguousarray(pts_b), 0.12, -0.07, 0.02, window,
                         math.radians(3.0), step, low, EPS)
            for g, w in zip(got, (want.best, want.loglik, want.score, want.mean, want.cov)):
                np.testing.assert_array_equal(g, w)
