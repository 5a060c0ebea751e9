import numpy as np
import pytest

from envs.maps.gridmap import GridMap, pixel_direction_to_yaw, yaw_to_pixel_direction


def make(h=20, w=30, res=0.1, origin=(1.0, 5.0)):
    return GridMap(np.ones((h, w), bool), res, origin)


def test_pixel_centres_hand_computed():
    g = make()
    # pixel (0, 0) centre is half a pixel right of and below the origin corner
    x, z = g.pixel_to_world(0, 0)
    assert (x, z) == pytest.approx((1.05, 4.95))
    x, z = g.pixel_to_world(3, 7)
    assert (x, z) == pytest.approx((1.0 + 0.75, 5.0 - 0.35))


def test_round_trip_and_cells():
    g = make()
    rng = np.random.default_rng(0)
    r = rng.integers(0, 20, 100)
    c = rng.integers(0, 30, 100)
    x, z = g.pixel_to_world(r, c)
    rr, cc = g.world_to_cell(x, z)
    assert np.array_equal(rr, r) and np.array_equal(cc, c)
    fr, fc = g.world_to_pixel(x, z)
    assert np.allclose(fr, r + 0.5) and np.allclose(fc, c + 0.5)


def test_cell_of_one_point_is_world_to_cell():
    """The scalar cell (plain floats, Python ints) equals the array one, on pixel corners and
    edges (where floor decides) as well as anywhere, and off the map."""
    rng = np.random.default_rng(1)
    for g in (make(), make(res=0.05, origin=(-3.3, 2.7)), make(res=0.02, origin=(0.1, 0.3))):
        x = np.r_[rng.uniform(-5, 8, 300), g.origin[0] + np.arange(-3, 40) * g.resolution]
        z = np.r_[rng.uniform(-5, 8, 300), g.origin[1] - np.arange(-3, 40) * g.resolution]
        rows, cols = g.world_to_cell(x, z)
        got = [g.cell_of(a, b) for a, b in zip(x, z)]
        assert got == list(zip(rows.tolist(), cols.tolist()))
        assert all(type(v) is int for rc in got for v in rc)


def test_axes_orientation():
    g = make()
    r0, c0 = g.world_to_cell(2.0, 3.0)
    r1, c1 = g.world_to_cell(2.5, 3.0)  # +x -> right
    assert r1 == r0 and c1 > c0
    r2, c2 = g.world_to_cell(2.0, 3.5)  # +z -> up (smaller row)
    assert r2 < r0 and c2 == c0


def test_yaw_directions():
    dr, dc = yaw_to_pixel_direction([0, 90, 180, 270])
    assert np.allclose(dr, [-1, 0, 1, 0], atol=1e-12)
    assert np.allclose(dc, [0, 1, 0, -1], atol=1e-12)
    assert np.allclose(pixel_direction_to_yaw(dr, dc), [0, 90, 180, 270])


def test_extent_and_bounds():
    g = make()
    assert g.extent == pytest.approx((1.0, 4.0, 3.0, 5.0))
    assert g.is_walkable(np.array([0, 19, 20, -1]), np.array([0, 29, 0, 0])).tolist() == [True, True, False, False]


@pytest.mark.parametrize("kw,msg", [
    (dict(walkable=np.zeros((0, 0), bool)), "empty"),
    (dict(walkable=np.zeros(5, bool)), "2-D"),
    (dict(resolution=0.0), "resolution"),
    (dict(origin=(np.nan, 0.0)), "origin"),
])
def test_bad_maps(kw, msg):
    args = dict(walkable=np.ones((3, 3), bool), resolution=0.1, origin=(0.0, 0.0))
    args.update(kw)
    with pytest.raises(ValueError, match=msg):
        GridMap(**args)
