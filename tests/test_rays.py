"""envs.maps.rays (the one ray walk: renderer, vision cone, scan maps, coverage) against a slow reference written from the definition of a digital line.

The reference does not share code or the error-term loop with the kernel: on every step
along the line's major axis it takes the cell nearest the exact line (exact rational
arithmetic), ties going to the cell nearer the start. A ray ends at the cell containing
the point ``max_range`` pixels from the camera cell's centre, and stops before the first
blocked cell or at the map edge.
"""

import math
from fractions import Fraction

import numpy as np
import pytest

from envs.maps.rays import cast_rays, cone_thetas, ray_end, trace_ray


def _nearest(exact: Fraction, step: int) -> int:
    """Integer nearest ``exact``; a tie goes toward the start of a line moving by ``step``."""
    low = math.floor(exact)
    frac = exact - low
    if frac != Fraction(1, 2):
        return low if frac < Fraction(1, 2) else low + 1
    return low if step > 0 else low + 1


def line_cells(r0: int, c0: int, r1: int, c1: int) -> list[tuple[int, int]]:
    """Cells of the digital line from (r0, c0) to (r1, c1), in order, one per major-axis step."""
    dr, dc = r1 - r0, c1 - c0
    n = max(abs(dr), abs(dc))
    if n == 0:
        return [(r0, c0)]
    cells = []
    for i in range(n + 1):
        if abs(dc) >= abs(dr):
            cells.append((_nearest(r0 + Fraction(dr * i, n), dr), c0 + i * (1 if dc > 0 else -1)))
        else:
            cells.append((r0 + i * (1 if dr > 0 else -1), _nearest(c0 + Fraction(dc * i, n), dc)))
    return cells


def reference_ray(blocked: np.ndarray, r0: int, c0: int, theta: float, max_range: float):
    """Free cells one ray visits (in order) and the blocked cell it hits, or None."""
    h, w = blocked.shape
    r1 = math.floor(r0 + 0.5 - math.cos(theta) * max_range)
    c1 = math.floor(c0 + 0.5 + math.sin(theta) * max_range)
    seen = []
    for r, c in line_cells(r0, c0, r1, c1):
        if not (0 <= r < h and 0 <= c < w):
            return seen, None
        if blocked[r, c]:
            return seen, (r, c)
        seen.append((r, c))
    return seen, None


def test_line_reference_is_a_line():
    # the reference's own sanity: endpoints, 8-connected unit steps, within half a cell of the line
    rng = np.random.default_rng(0)
    for _ in range(300):
        r0, c0, r1, c1 = (int(v) for v in rng.integers(-20, 20, 4))
        cells = line_cells(r0, c0, r1, c1)
        assert cells[0] == (r0, c0) and cells[-1] == (r1, c1)
        steps = np.abs(np.diff(np.array(cells), axis=0))
        assert (steps.max(axis=1) == 1).all()
        n = max(abs(r1 - r0), abs(c1 - c0))
        for i, (r, c) in enumerate(cells):
            if abs(c1 - c0) >= abs(r1 - r0):
                assert abs(r - (r0 + (r1 - r0) * i / max(n, 1))) <= 0.5
            else:
                assert abs(c - (c0 + (c1 - c0) * i / max(n, 1))) <= 0.5


@pytest.mark.parametrize("seed", range(8))
def test_cast_rays_equals_reference_on_random_maps(seed):
    rng = np.random.default_rng(seed)
    h, w = int(rng.integers(20, 80)), int(rng.integers(20, 80))
    blocked = rng.random((h, w)) < rng.uniform(0.0, 0.15)
    r0, c0 = int(rng.integers(0, h)), int(rng.integers(0, w))
    blocked[r0, c0] = False
    thetas = np.concatenate([rng.uniform(-np.pi, 3 * np.pi, 60), np.arange(16) * np.pi / 8])  # incl. axes, diagonals
    max_range = float(rng.uniform(0, 100))  # often past the map edge
    rows, cols, off, hits = cast_rays(blocked, r0, c0, thetas, max_range)
    assert off[-1] == len(rows) == len(cols)
    for i, th in enumerate(thetas):
        seen, hit = reference_ray(blocked, r0, c0, float(th), max_range)
        got = list(zip(rows[off[i]:off[i + 1]].tolist(), cols[off[i]:off[i + 1]].tolist()))
        assert got == seen, f"ray {i} theta={th:.4f}"
        assert tuple(hits[i].tolist()) == ((-1, -1) if hit is None else hit)


def test_trace_ray_edge_cases():
    blocked = np.zeros((10, 10), bool)
    blocked[5, 5] = True
    br, bc = np.empty(20, np.int32), np.empty(20, np.int32)
    assert trace_ray(blocked, 5, 5, 5, 9, br, bc) == (0, 5, 5)  # starting on a blocked cell
    n, hr, hc = trace_ray(blocked, 2, 2, 2, 2, br, bc)  # zero-length ray: its own cell
    assert (n, hr, hc) == (1, -1, -1) and (br[0], bc[0]) == (2, 2)
    n, hr, hc = trace_ray(blocked, 5, 2, 5, 30, br, bc)  # blocked at (5, 5)
    assert (n, hr, hc) == (3, 5, 5) and bc[:n].tolist() == [2, 3, 4]
    n, hr, hc = trace_ray(blocked, 1, 1, 1, 30, br, bc)  # leaves the map: no hit
    assert (n, hr, hc) == (9, -1, -1)
    assert ray_end(10, 10, 0.0, 5.0) == (5, 10)  # yaw 0 = up the map (row decreases)
    assert ray_end(10, 10, np.pi / 2, 5.0) == (10, 15)  # yaw 90 = right (col increases)
    with pytest.raises(ValueError, match="max_range"):
        cast_rays(blocked, 0, 0, np.zeros(1), -1.0)


def test_wall_blocks_view():
    blocked = np.zeros((30, 30), bool)
    blocked[:, 20] = True
    rows, cols, off, hits = cast_rays(blocked, 15, 10, cone_thetas(90, 90, 25), 25)
    assert cols.max() == 19  # nothing behind the wall at column 20
    assert (hits[:, 1] == 20).sum() > 0


def test_cone_thetas_cover_the_arc():
    t = cone_thetas(90, 90, 100, oversample=2)
    assert np.rad2deg(t.min()) == pytest.approx(45) and np.rad2deg(t.max()) == pytest.approx(135)
    assert np.diff(t).max() * 100 <= 0.5 + 1e-9


def test_cone_reference_line_agrees_with_the_exact_definition():
    """The vision-cone reference walks lines by a closed-form integer rule (not the kernel's
    error-term loop); it must give the exact-arithmetic digital line above, cell for cell,
    including the half-way ties, and so must the kernel."""
    from benchmark.aggregators.reference import digital_line

    rng = np.random.default_rng(1)
    blocked = np.zeros((90, 90), bool)
    br, bc = np.empty(200, np.int32), np.empty(200, np.int32)
    ties = 0
    for _ in range(2000):
        r0, c0, r1, c1 = (int(v) for v in rng.integers(0, 90, 4))
        exact = line_cells(r0, c0, r1, c1)
        assert digital_line(r0, c0, r1, c1) == exact
        n, _, _ = trace_ray(blocked, r0, c0, r1, c1, br, bc)
        assert list(zip(br[:n].tolist(), bc[:n].tolist())) == exact
        n, d = max(abs(r1 - r0), abs(c1 - c0)), min(abs(r1 - r0), abs(c1 - c0))
        ties += n > 0 and any((2 * d * i) % (2 * n) == n for i in range(n + 1))  # d*i/n ends in .5
    assert ties > 10  # the random lines include half-way ties


@pytest.mark.parametrize("seed", range(6))
def test_cones_reach_equals_the_union_of_reference_rays(seed):
    """benchmark.aggregators.vision_cone.cones_reach (coverage's walk: neighbouring rays share
    their cells through the path tables) visits exactly the cells of every reference ray, at
    the coverage's quarter-pixel spacing, with views off the map and on blocked cells, and
    at ranges the path tables do not hold (walked whole)."""
    from benchmark.aggregators.vision_cone import cones_reach

    rng = np.random.default_rng(200 + seed)
    h, w = int(rng.integers(30, 90)), int(rng.integers(30, 90))
    blocked = rng.random((h, w)) < 0.06
    n_views = 6
    rows, cols = rng.integers(0, h, n_views), rng.integers(0, w, n_views)
    rows[0] = -3  # off the map: sees nothing
    blocked[rows[1], cols[1]] = True  # standing on a blocked cell: sees nothing
    max_range = float(rng.uniform(5, 60)) if seed < 5 else float(math.ceil(math.hypot(h, w)) + 2)
    fov = (90.0, 90.0, 45.0, 180.0, 360.0, 360.0)[seed]
    yaws = rng.uniform(-180, 540, n_views)
    offsets = cone_thetas(0.0, fov, max_range, 4.0)
    groups = rng.integers(0, 3, n_views)
    groups[2:4] = 1  # a group of two views
    want = np.zeros((h, w), bool)
    per_group = np.zeros((4, h, w), bool)  # group 3: no views
    for v in range(n_views):
        if 0 <= rows[v] < h and 0 <= cols[v] < w:
            for th in cone_thetas(float(yaws[v]), fov, max_range, 4.0):
                for r, c in reference_ray(blocked, int(rows[v]), int(cols[v]), float(th), max_range)[0]:
                    want[r, c] = True
                    per_group[groups[v], r, c] = True
    got = cones_reach(blocked, rows, cols, np.deg2rad(yaws), offsets, max_range)
    assert want.any() and not want[rows[1], cols[1]]
    assert (got == want).all()
    # in one walk, each group's views' cells apart
    grouped = cones_reach(blocked, rows, cols, np.deg2rad(yaws), offsets, max_range, groups, 4)
    assert grouped.shape == (4, h, w) and (grouped == per_group).all() and not grouped[3].any()
    if seed == 5:  # whole-map 360 degree cones: cells two groups see
        assert (grouped.sum(0) > 1).any()


def test_cone_end_is_ray_end_on_every_heading():
    """The angle-sum end cell, ray by ray (cone_end) and a view's rays at once (cone_ends),
    equals ray_end's: on random views and ranges, and on headings whose end lies within
    rounding of a cell boundary (cos or sin times the range a half integer: there the
    formula's last bit and the cosine's differ, and only the fallback to ray_end gives the
    same cell), on huge and non-finite headings."""
    from numba import njit

    from envs.maps.rays import cone_end, cone_ends

    @njit
    def both(r0, c0, yaw, offs, rng):
        out = np.empty((offs.shape[0], 4), np.int64)
        cy, sy = np.cos(yaw), np.sin(yaw)
        for t in range(offs.shape[0]):
            out[t, 0], out[t, 1] = cone_end(r0, c0, yaw, cy, sy, offs[t], np.cos(offs[t]), np.sin(offs[t]), rng)
            out[t, 2], out[t, 3] = ray_end(r0, c0, yaw + offs[t], rng)
        return out

    def every(r0, c0, yaw, offs, rng):
        out = both(r0, c0, yaw, offs, rng)
        er, ec, exact = np.empty(len(offs), np.int64), np.empty(len(offs), np.int64), np.empty(len(offs), bool)
        cone_ends(r0, c0, yaw, offs, np.cos(offs), np.sin(offs), rng, er, ec, exact)
        assert np.array_equal(np.stack([er + r0, ec + c0], 1), out[:, 2:])
        return out

    gen = np.random.default_rng(0)
    n = 0
    for _ in range(300):
        rng = float(gen.choice([gen.uniform(0.5, 400), float(gen.integers(1, 300)), gen.integers(1, 300) + 0.5]))
        offs = cone_thetas(0.0, float(gen.uniform(1, 360)), rng, float(gen.choice([0.5, 2.0, 4.0])))
        got = every(int(gen.integers(-5, 500)), int(gen.integers(-5, 500)), float(gen.uniform(-13, 13)), offs, rng)
        assert np.array_equal(got[:, :2], got[:, 2:])
        n += len(offs)
    near = 0
    for target in (np.pi / 3, 2 * np.pi / 3, np.pi / 6, 5 * np.pi / 6, -np.pi / 3, np.arccos(1.5 / 7.0)):
        for rng in (1.0, 3.0, 7.0, 121.0):
            offs = np.linspace(-1.2, 1.2, 4001)
            yaws = target - offs  # yaw + offset lands on (or one bit off) the target heading
            for yaw in yaws[::40]:
                got = every(10, 10, float(yaw), target - yaw + np.array([0.0, 1e-16, -1e-16]), rng)
                assert np.array_equal(got[:, :2], got[:, 2:])
                fr = 10.5 - np.cos(yaw + (target - yaw)) * rng
                near += abs(fr - np.round(fr)) < 1e-9
    assert near > 100  # the boundary cases were met
    for yaw in (2e3, -5e6, 1e12, 3e15, np.inf, np.nan):  # beyond the bound: ray_end itself
        got = every(50, 50, yaw, cone_thetas(0.0, 90.0, 400.0), 400.0)
        assert np.array_equal(got[:, :2], got[:, 2:])
    assert n > 50_000


def test_path_helpers_equal_their_plain_branching_form():
    """The ray path tables' helpers, written without a branch on their array (numba counts a
    reference to an array a branching helper reads), against the plain if/else they replace:
    every case of a small list; and the paths of a cone's ends, read without a bounds test once
    the tables' reach is checked, and without tables."""
    from numba import njit

    from envs.maps.ray_paths import (
        _no_paths,
        after_differences,
        after_neighbour_list,
        end_paths,
        ray_paths,
    )

    @njit
    def helpers(i, e, dj, pstop, m, whole):
        return after_differences(i, e, dj, pstop, m), after_neighbour_list(whole, i, e, dj, pstop, m)

    dj = np.array([0, 9, 2, 9, 3, 9, 5, 9], np.int16)  # pairs (index, minor): indices 0, 2, 3, 5
    n = 0
    for e in range(0, 5):
        for i in range(0, e + 1):
            for pstop in range(0, 7):
                for m in range(0, 7):
                    for whole in (False, True):
                        on = i < e and dj[2 * i] == pstop
                        want_d = ((pstop, -1) if on else (0, pstop)) if pstop < m else (m, -1)
                        want_n = (0, m) if whole or pstop >= m else (pstop, -1) if on else (0, pstop)
                        assert helpers(i, e, dj, pstop, m, whole) == (want_d, want_n)
                        n += on
    assert n > 0
    assert helpers(0, 0, np.zeros(0, np.int16), 2, 5, False) == ((0, 2), (0, 2))  # no list at all

    # the paths of a cone's ends: every end within the tables' reach, read as the table holds it
    k, slot = ray_paths(6.0)[:2]
    inside = np.array([(er, ec) for er in range(-k, k + 1) for ec in range(-k, k + 1)], np.int64)
    got = np.empty(len(inside), np.int64)
    end_paths(inside[:, 0].copy(), inside[:, 1].copy(), 6.0, k, slot, got)
    assert np.array_equal(got, slot[inside[:, 0] + k, inside[:, 1] + k])
    assert (got >= 0).any() and (got < 0).any()
    # rays of r px end within ceil(r) px: tables of reach k serve rays up to k px, not beyond
    end_paths(inside[:1, 0].copy(), inside[:1, 1].copy(), float(k), k, slot, got)
    with pytest.raises(ValueError, match="shorter range"):
        end_paths(inside[:1, 0].copy(), inside[:1, 1].copy(), k + 0.5, k, slot, got)
    none_k, none_slot = _no_paths()[:2]  # no tables: no end has a path
    end_paths(inside[:, 0].copy(), inside[:, 1].copy(), 6.0, none_k, none_slot, got)
    assert (got == -1).all()
