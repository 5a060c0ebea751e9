"""The robot's route through its views (envs/maps/trajectory.py): known answers on hand-made
maps; the numba Dijkstra against SciPy's csgraph Dijkstra on an explicit graph."""

import math

import numpy as np
import pytest
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from envs.maps.gridmap import GridMap
from envs.maps.trajectory import route, shortest_path, trajectory, view_distances
from tests.maps import pose_at, two_rooms_grid


def _open_grid(h=40, w=60):
    walk = np.zeros((h, w), bool)
    walk[1:-1, 1:-1] = True
    return GridMap(walk, 0.05, (0.0, h * 0.05))


def test_straight_segment_and_samples():
    grid = _open_grid()
    a, b = pose_at(grid, 20, 5, 270.0), pose_at(grid, 20, 45, 10.0)  # 2.0 m along +x
    poses = np.array([a, b])
    r = route(grid.walkable, grid, poses)
    assert len(r.points) == 2 and r.length == pytest.approx(2.0)
    traj = trajectory(grid.walkable, grid, poses, 0.5)
    # samples at 0, 0.5, ..., 2.0 m (yaw 90: +x), views at 0 and 2.0 m with their own yaw
    assert len(traj) == 5 + 2
    samples = traj[np.isclose(traj[:, 2], 90.0)]
    np.testing.assert_allclose(samples[:, 0] - a[0], [0, 0.5, 1.0, 1.5, 2.0], atol=1e-9)
    np.testing.assert_allclose(samples[:, 1], a[1])
    assert traj[1].tolist() == a and traj[-1].tolist() == b  # at equal distance the sample comes first
    np.testing.assert_allclose(view_distances(grid.walkable, grid, poses), [0.0, 2.0])


def test_views_in_place_and_straight_line_distances():
    grid = _open_grid()
    poses = np.array([pose_at(grid, 30, 10, y) for y in (0, 90, 180)] + [pose_at(grid, 10, 10, 0)]
                     + [pose_at(grid, 10, 40, 0)])
    d = view_distances(grid.walkable, grid, poses)
    np.testing.assert_allclose(d, [0, 0, 0, 1.0, 2.5])


def test_path_around_a_wall_goes_through_the_door():
    grid = two_rooms_grid()  # wall at columns 38-39, door rows 18-21
    poses = np.array([pose_at(grid, 5, 20, 0.0), pose_at(grid, 5, 60, 0.0)])
    r = route(grid.walkable, grid, poses)
    cells = np.column_stack(grid.world_to_cell(r.points[:, 0], r.points[:, 1]))
    assert grid.walkable[cells[:, 0], cells[:, 1]].all()
    assert ((cells[:, 1] == 38) & (cells[:, 0] >= 18) & (cells[:, 0] < 22)).any()
    steps = np.abs(np.diff(cells, axis=0)).max(axis=1)
    assert (steps == 1).all()  # 8-connected unit steps
    target = np.zeros(grid.shape, bool)
    target[5, 60] = True
    _, length = shortest_path(grid.walkable, (5, 20), target)
    assert r.length == pytest.approx(length * grid.resolution)
    assert r.driven[1:].all()
    traj = trajectory(grid.walkable, grid, poses, 0.25)
    tr, tc = grid.world_to_cell(traj[:, 0], traj[:, 1])
    assert grid.walkable[tr, tc].all()


def test_unreachable_view_is_a_jump():
    walk = np.zeros((20, 40), bool)
    walk[2:18, 2:18] = True
    walk[2:18, 22:38] = True  # no door
    grid = GridMap(walk, 0.05, (0.0, 1.0))
    poses = np.array([pose_at(grid, 10, 5, 0.0), pose_at(grid, 10, 30, 0.0)])
    r = route(grid.walkable, grid, poses)
    assert r.driven.tolist() == [False, False]
    assert r.length == pytest.approx(25 * 0.05)
    traj = trajectory(grid.walkable, grid, poses, 0.1)
    assert len(traj) == 2  # nothing between: only the views


def _csgraph_lengths(passable, start):
    """Dijkstra distances (cells) over an explicit 8-connected graph without corner cutting."""
    h, w = passable.shape
    rows, cols, wts = [], [], []
    for r in range(h):
        for c in range(w):
            if not passable[r, c]:
                continue
            for dr in (-1, 0, 1):
                for dc in (-1, 0, 1):
                    rr, cc = r + dr, c + dc
                    if (dr or dc) and 0 <= rr < h and 0 <= cc < w and passable[rr, cc]:
                        if dr and dc and not (passable[rr, c] and passable[r, cc]):
                            continue
                        rows.append(r * w + c)
                        cols.append(rr * w + cc)
                        wts.append(math.hypot(dr, dc))
    g = coo_matrix((wts, (rows, cols)), shape=(h * w, h * w)).tocsr()
    return dijkstra(g, indices=start[0] * w + start[1]).reshape(h, w)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_shortest_path_matches_csgraph(seed):
    rng = np.random.default_rng(seed)
    passable = rng.random((30, 35)) > 0.3
    passable[0, 0] = True
    ref = _csgraph_lengths(passable, (0, 0))
    for target_cell in [tuple(x) for x in np.argwhere(passable)[rng.choice(int(passable.sum()), 25)]]:
        target = np.zeros(passable.shape, bool)
        target[target_cell] = True
        path, length = shortest_path(passable, (0, 0), target)
        want = ref[target_cell]
        if math.isinf(want):
            assert len(path) == 0 and math.isinf(length)
            continue
        assert length == pytest.approx(want)
        assert tuple(path[0]) == (0, 0) and tuple(path[-1]) == target_cell
        assert passable[path[:, 0], path[:, 1]].all()
        steps = np.diff(path, axis=0)
        assert (np.abs(steps).max(axis=1) == 1).all()
        assert sum(math.hypot(*s) for s in steps) == pytest.approx(want)
    # several targets: the nearest one
    targets = passable & (rng.random(passable.shape) > 0.9)
    path, length = shortest_path(passable, (0, 0), targets)
    finite = np.where(targets, ref, np.inf)
    assert length == pytest.approx(finite.min())


def test_trajectory_bad_spacing():
    grid = _open_grid()
    with pytest.raises(ValueError, match="spacing"):
        trajectory(grid.walkable, grid, np.array([pose_at(grid, 5, 5, 0)]), 0.0)


def test_routes_are_kept_by_their_inputs_content(monkeypatch):
    """route() keeps a route per process by a digest of what it reads: the same inputs give
    the kept route (equal to one computed afresh, read-only), a changed walkable mask, grid
    placement or pose gives its own, and the kept bytes stay under the cap."""
    from envs.maps import trajectory as tr

    monkeypatch.setattr(tr, "_ROUTES", type(tr._ROUTES)())
    grid = two_rooms_grid()
    poses = np.array([pose_at(grid, 20, 10, 0.0), pose_at(grid, 20, 60, 0.0)])
    a = route(grid.walkable, grid, poses)
    assert route(grid.walkable.copy(), grid, poses.copy()) is a  # the same content: the kept route
    fresh = tr._route(grid.walkable, grid, poses)
    for name in ("points", "view_index", "driven", "travelled"):
        assert np.array_equal(getattr(a, name), getattr(fresh, name))
        assert not getattr(a, name).flags.writeable
    shut = grid.walkable.copy()
    shut[:, 38:42] = False  # the door closed: the second view is a jump, not a drive
    b = route(shut, grid, poses)
    assert b is not a and not b.driven[-1] and a.driven[-1]
    moved = GridMap(grid.walkable, grid.resolution, (grid.origin[0] + grid.resolution, grid.origin[1]))
    assert route(grid.walkable, moved, poses) is not a
    assert route(grid.walkable, grid, poses + [0.0, 0.0, 90.0]) is not a  # yaw is part of the key
    monkeypatch.setattr(tr, "ROUTE_MEMO_BYTES", tr._route_bytes(a))
    route(grid.walkable, grid, poses + [grid.resolution, 0.0, 0.0])
    assert sum(tr._route_bytes(r) for r in tr._ROUTES.values()) <= tr._route_bytes(a)
