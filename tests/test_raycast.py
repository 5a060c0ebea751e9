import numpy as np
import pytest

from benchmark.aggregators.reference import walk_ray
from envs.raycast import cast_rays, cone_thetas


@pytest.mark.parametrize("seed", range(6))
def test_cast_rays_equals_python_bresenham(seed):
    rng = np.random.default_rng(seed)
    blocked = rng.random((50, 70)) < 0.08
    r0, c0 = int(rng.integers(0, 50)), int(rng.integers(0, 70))
    blocked[r0, c0] = False
    thetas = rng.uniform(0, 2 * np.pi, 40)
    rng_px = float(rng.uniform(5, 60))
    rows, cols, off, hits = cast_rays(blocked, r0, c0, thetas, rng_px)
    for i, th in enumerate(thetas):
        seen, hit = walk_ray(blocked, r0, c0, th, rng_px)
        got = list(zip(rows[off[i]:off[i + 1]].tolist(), cols[off[i]:off[i + 1]].tolist()))
        assert got == seen
        assert (tuple(hits[i]) == (-1, -1)) if hit is None else (tuple(hits[i]) == hit)


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
