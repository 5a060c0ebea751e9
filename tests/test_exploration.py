"""Exploration viewpoints (benchmark/conditions/exploration.py): frontier and random walk on hand-made
maps with known answers; the frontier's fast path against its pure-Python reference."""

import dataclasses
import math

import numpy as np
import pytest

from benchmark.conditions.coverage import view_coverage
from benchmark.conditions.exploration import (
    Frontier,
    RandomWalk,
    explore_frontier_reference,
    heading_offsets,
    start_cell,
)
from envs.maps.gridmap import GridMap
from envs.maps.scene import Scene


def two_room_scene(start=(0.5, 1.5, 270.0)) -> Scene:
    """Two 3 x 3 m rooms (0.05 m cells) side by side, a 0.1 m wall between them at x = 3.0-3.1 m
    with a 0.8 m door in its middle; the robot starts in the left room at x = 0.5 m facing -x."""
    h, w = 64, 126
    rooms = np.full((h, w), -1, np.int32)
    rooms[2:62, 2:62] = 0
    rooms[2:62, 62:124] = 1
    walls = np.zeros((h, w), bool)
    walls[2:62, 60:62] = True  # wall columns 60-61 (x = 3.0-3.1 m)
    walls[23:39, 60:62] = False  # door: rows 23-38 (0.8 m)
    walls[[1, 62], 1:125] = True
    walls[1:63, [1, 124]] = True
    walk = (rooms >= 0) & ~walls
    grid = GridMap(walk, 0.05, (0.0, h * 0.05))
    inst = np.where(walk, rooms, -1).astype(np.int32)
    return Scene("two-rooms", grid, rooms, inst, np.array([5, 2]), ["room|0", "room|1"], walls=walls,
                 objects=[], object_map=np.full((h, w), -1, np.int32), start=start)


def _rooms_of(scene, poses):
    r, c = scene.grid.world_to_cell(poses[:, 0], poses[:, 1])
    return set(scene.instances[r, c].tolist())


def test_frontier_enough_budget_sees_both_rooms():
    scene = two_room_scene()
    f = Frontier(budget=30.0)
    e = f.explore(scene)
    assert e.stop == "explored" and e.length < 30.0
    assert _rooms_of(scene, e.poses) == {0, 1}
    cov = view_coverage(scene, e.poses, 90.0, 6.0, ~scene.grid.walkable)
    assert cov["coverage_rooms"] == 1.0 and cov["rooms_seen"] == 2
    assert cov["coverage_area"] > 0.95
    # the robot's own map: every walkable cell of both rooms known free
    assert e.scan_map.free[scene.grid.walkable].mean() > 0.99
    # the path: 8-connected steps on walkable cells, starting at the start
    r, c = scene.grid.world_to_cell(e.path[:, 0], e.path[:, 1])
    assert scene.grid.walkable[r, c].all()
    assert (np.abs(np.diff(np.column_stack([r, c]), axis=0)).max(axis=1) == 1).all()
    steps = np.hypot(*np.diff(e.path, axis=0).T).sum()
    assert steps == pytest.approx(e.length)
    assert (r[0], c[0]) == tuple(scene.grid.world_to_cell(0.5, 1.5))


def test_frontier_small_budget_sees_only_the_first_room():
    scene = two_room_scene()
    e = Frontier(budget=1.0).explore(scene)
    assert e.stop == "budget" and e.length <= 1.0
    assert _rooms_of(scene, e.poses) == {0}
    cov = view_coverage(scene, e.poses, 90.0, 6.0, ~scene.grid.walkable)
    assert cov["coverage_rooms"] == 0.5 and cov["rooms_seen"] == 1


def test_frontier_captures_every_spacing_around_the_motion():
    scene = two_room_scene()
    e = Frontier(budget=6.0, spacing=1.0, n_headings=3, heading_spread=180.0).explore(scene)
    assert len(e.poses) % 3 == 0
    caps = e.poses.reshape(-1, 3, 3)
    # three headings per capture: -90, 0, +90 around the direction of motion
    rel = np.mod(caps[:, :, 2] - caps[:, 1:2, 2] + 180, 360) - 180
    np.testing.assert_allclose(rel, np.tile([-90.0, 0.0, 90.0], (len(caps), 1)), atol=1e-9)
    assert caps[0, 1, 2] == pytest.approx(270.0)  # the start's own yaw at the start
    # capture k at the first cell at or past k metres (a step is at most sqrt(2) x 0.05 m)
    odo = e.travelled.reshape(-1, 3)[:, 0]
    k = np.arange(len(odo))
    assert (odo >= k - 1e-9).all() and (odo < k + math.sqrt(2) * 0.05).all()


@pytest.mark.parametrize("kw", [dict(budget=30.0), dict(budget=4.0, range_noise=0.05, dropout=0.1, seed=3),
                                dict(budget=12.0, sensor_range=1.5, n_headings=4, heading_spread=360.0)])
def test_frontier_fast_equals_reference_hand_made(kw):
    scene = two_room_scene()
    f = Frontier(**kw)
    fast = f.explore(scene)
    ref = explore_frontier_reference(scene, f)
    assert len(fast.poses) == len(ref.poses) and fast.stop == ref.stop
    np.testing.assert_allclose(fast.poses, ref.poses, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(fast.path, ref.path)
    np.testing.assert_array_equal(fast.scan_map.log_odds, ref.scan_map.log_odds)
    assert fast.length == pytest.approx(ref.length, abs=1e-12)


def test_frontier_fast_equals_reference_shared_house(shared_houses):
    from envs.maps.scene import rasterise_house

    scene = rasterise_house(shared_houses[2])
    f = Frontier(budget=10.0)
    fast = f.explore(scene)
    ref = explore_frontier_reference(scene, f)
    assert len(fast.poses) == len(ref.poses) > 0
    np.testing.assert_allclose(fast.poses, ref.poses, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(fast.scan_map.occupancy, ref.scan_map.occupancy)


def test_frontier_is_deterministic_and_the_house_seeds_the_noise():
    scene = two_room_scene()
    f = Frontier(budget=8.0, range_noise=0.05)
    a, b = f.generate(scene), f.generate(scene)
    np.testing.assert_array_equal(a, b)
    other = dataclasses.replace(scene, house_id="other")
    assert f.settings_for(scene).seed != f.settings_for(other).seed
    assert not np.array_equal(a, f.generate(other))


def test_random_walk_respects_its_budget():
    scene = two_room_scene()
    for budget in (0.5, 3.0, 25.0):
        rw = RandomWalk(budget=budget, spacing=0.5, seed=1)
        e = rw.explore(scene)
        assert e.stop == "budget" and budget - 0.08 < e.length <= budget + 1e-9
        assert e.travelled.max() <= budget + 1e-9
        r, c = scene.grid.world_to_cell(e.poses[:, 0], e.poses[:, 1])
        assert scene.grid.walkable[r, c].all()
        odo = e.travelled.reshape(-1, 3)[:, 0]
        k = np.arange(len(odo))
        assert (odo >= 0.5 * k - 1e-9).all() and (odo < 0.5 * k + math.sqrt(2) * 0.05).all()
        assert len(odo) >= int(np.floor((e.length - math.sqrt(2) * 0.05) / 0.5)) + 1
    a = RandomWalk(budget=10.0, seed=1).generate(scene)
    np.testing.assert_array_equal(a, RandomWalk(budget=10.0, seed=1).generate(scene))
    assert not np.array_equal(a, RandomWalk(budget=10.0, seed=2).generate(scene))


def test_random_walk_runs_are_straight():
    scene = two_room_scene()
    e = RandomWalk(budget=20.0, seed=4).explore(scene)
    r, c = scene.grid.world_to_cell(e.path[:, 0], e.path[:, 1])
    assert (np.abs(np.diff(np.column_stack([r, c]), axis=0)).max(axis=1) == 1).all()
    assert scene.grid.walkable[r, c].all()


def test_start_rules():
    scene = two_room_scene(start=None)
    r, c, yaw = start_cell(scene.grid, None)
    rr, cc = np.nonzero(scene.grid.walkable)
    d = (rr - rr.mean()) ** 2 + (cc - cc.mean()) ** 2
    assert (r, c) == (rr[np.argmin(d)], cc[np.argmin(d)]) and yaw == 0.0
    assert scene.grid.walkable[r, c]
    # a start on a wall cell snaps to the nearest walkable cell
    r, c, yaw = start_cell(scene.grid, (3.05, 0.5, 90.0))  # inside the wall (x 3.0-3.1)
    assert scene.grid.walkable[r, c] and yaw == 90.0
    wr, wc = scene.grid.world_to_cell(3.05, 0.5)
    assert abs(int(wc) - c) == 1 or abs(int(wc) - c) == 2


def test_shared_house_start_from_metadata(shared_houses):
    from envs.maps.scene import rasterise_house

    house = shared_houses[0]
    scene = rasterise_house(house)
    agent = house.data["metadata"]["agent"]
    assert scene.start == (agent["position"]["x"], agent["position"]["z"], agent["rotation"]["y"])
    e = Frontier(budget=5.0).explore(scene)
    assert e.path[0] == pytest.approx(scene.grid.pixel_to_world(*scene.grid.world_to_cell(*scene.start[:2])))


def test_heading_offsets():
    np.testing.assert_allclose(heading_offsets(3, 180.0), [-90, 0, 90])
    np.testing.assert_allclose(heading_offsets(4, 360.0), [-180, -90, 0, 90])
    np.testing.assert_allclose(heading_offsets(1, 180.0), [0])


@pytest.mark.parametrize("cls, kw, key", [
    (Frontier, dict(budget=0), "budget"),
    (Frontier, dict(budget=-3.0), "budget"),
    (Frontier, dict(spacing=0.0), "spacing"),
    (Frontier, dict(n_headings=0), "n_headings"),
    (Frontier, dict(sensor_range=0.0), "viewpoints.sensor_range"),
    (Frontier, dict(scan_height=3.0), "viewpoints.scan_height"),
    (Frontier, dict(scan_spacing=-1.0), "viewpoints.scan_spacing"),
    (Frontier, dict(range_noise=-0.1), "viewpoints.range_noise"),
    (Frontier, dict(min_frontier=-1), "min_frontier"),
    (RandomWalk, dict(budget=0), "budget"),
    (RandomWalk, dict(max_run=0.1, min_run=0.5), "max_run"),
])
def test_bad_settings_one_line(cls, kw, key):
    with pytest.raises(ValueError) as e:
        cls(**kw)
    msg = str(e.value)
    assert "\n" not in msg and key in msg and "expected" in msg and repr(next(iter(kw.values()))) in msg


def test_budget_is_metres_of_path():
    scene = two_room_scene()
    e = Frontier(budget=2.0).explore(scene)
    assert e.length <= 2.0 + 1e-9 and e.length > 2.0 - math.sqrt(2) * 0.05 - 1e-9


def _frontier_reference(known_free, unobserved, min_cells):
    """Frontier cells by shifted masks and SciPy's 8-connected labelling (the code before)."""
    from scipy import ndimage

    nb = np.zeros_like(unobserved)
    nb[1:] |= unobserved[:-1]
    nb[:-1] |= unobserved[1:]
    nb[:, 1:] |= unobserved[:, :-1]
    nb[:, :-1] |= unobserved[:, 1:]
    front = known_free & nb
    if min_cells > 1 and front.any():
        lab, n = ndimage.label(front, structure=np.ones((3, 3), bool))
        size = np.bincount(lab.ravel(), minlength=n + 1)
        size[0] = 0
        front = size[lab] >= min_cells
    return front


def test_frontier_cells_equal_labelling():
    """The compiled frontier (union-find over frontier cells) against SciPy's labelling, on random
    maps with frontiers touching the map's edges, clusters meeting only at a corner, and sizes
    around the limit."""
    from benchmark.conditions.exploration import frontier_cells

    rng = np.random.default_rng(11)
    shapes = [(1, 1), (1, 9), (9, 1), (30, 41), (64, 64)]
    n_front = n_dropped = 0
    for shape in shapes:
        for density in (0.2, 0.5, 0.8):
            known = rng.random(shape) < density
            unobs = ~known & (rng.random(shape) < 0.5)
            for min_cells in (0, 1, 2, 3, 6, 20):
                want = _frontier_reference(known, unobs, min_cells)
                got = frontier_cells(known, unobs, min_cells)
                assert got.dtype == bool and np.array_equal(got, want), (shape, density, min_cells)
                n_front += int(want.sum())
                n_dropped += int(_frontier_reference(known, unobs, 1).sum() - want.sum())
    assert n_front > 1000 and n_dropped > 100
    # two diagonal cells are one cluster of 2 (8-connected); a lone cell is dropped at 2
    known = np.zeros((5, 5), bool)
    known[1, 1] = known[2, 2] = known[4, 0] = True
    unobs = ~known
    assert np.argwhere(frontier_cells(known, unobs, 2)).tolist() == [[1, 1], [2, 2]]
