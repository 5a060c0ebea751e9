"""View coverage (benchmark/conditions/coverage.py): hand-made maps where a view sees a known set of cells."""

import math

import numpy as np
import pytest

from benchmark.conditions.coverage import view_coverage, visible_cells
from envs.maps.gridmap import GridMap
from envs.maps.scene import Scene
from tests.maps import pose_at
from tests.test_exploration import two_room_scene


def _scene(walk: np.ndarray, rooms: np.ndarray | None = None) -> Scene:
    grid = GridMap(walk, 0.05, (0.0, walk.shape[0] * 0.05))
    rooms = np.where(walk, 0, -1).astype(np.int32) if rooms is None else rooms
    inst = np.where(walk, rooms, -1).astype(np.int32)
    return Scene("h", grid, rooms, inst, np.arange(int(inst.max()) + 1), [f"r{k}" for k in range(int(inst.max()) + 1)])


def test_full_circle_in_a_convex_room_sees_exactly_the_room():
    walk = np.zeros((50, 70), bool)
    walk[5:45, 8:60] = True
    scene = _scene(walk)
    seen = visible_cells(scene, np.array([pose_at(scene.grid, 12, 20, 0.0)]), 360.0, math.inf, ~walk)
    np.testing.assert_array_equal(seen, walk)
    cov = view_coverage(scene, np.array([pose_at(scene.grid, 12, 20, 0.0)]), 360.0, math.inf, ~walk)
    assert cov == {"coverage_area": 1.0, "coverage_rooms": 1.0, "rooms_seen": 1, "rooms": 1}


def test_corridor_view_sees_its_range():
    walk = np.zeros((3, 60), bool)
    walk[1, 1:59] = True
    scene = _scene(walk)
    pose = np.array([pose_at(scene.grid, 1, 10, 90.0)])  # facing +x along the corridor
    seen = visible_cells(scene, pose, 90.0, 1.0, ~walk)  # 1.0 m = 20 cells
    want = np.zeros_like(walk)
    want[1, 10:31] = True
    np.testing.assert_array_equal(seen, want)
    cov = view_coverage(scene, pose, 90.0, 1.0, ~walk)
    assert cov["coverage_area"] == pytest.approx(21 / 58)


def test_cone_matches_its_geometry_away_from_its_edges():
    walk = np.zeros((100, 100), bool)
    walk[1:99, 1:99] = True
    scene = _scene(walk)
    r0, c0 = 80, 50
    seen = visible_cells(scene, np.array([pose_at(scene.grid, r0, c0, 0.0)]), 90.0, 2.0, ~walk)  # facing -row
    rr, cc = np.mgrid[:100, :100]
    dist = np.hypot(rr - r0, cc - c0)  # pixels
    ang = np.degrees(np.abs(np.arctan2(cc - c0, -(rr - r0))))
    inside = (dist <= 40 - 1.5) & (ang <= 45 - 5) & walk
    outside = (dist > 40 + 1.5) | ((ang > 45 + 5) & (dist > 3))
    assert seen[inside].all()
    assert not seen[outside].any()


def test_rooms_are_seen_from_inside_only():
    scene = two_room_scene()
    g = scene.grid
    # in the left room, 2 m from the door, looking through it into the right room
    r, c = g.world_to_cell(1.0, 1.6)
    look = np.array([pose_at(g, int(r), int(c), 90.0)])
    seen = visible_cells(scene, look, 90.0, 6.0, ~g.walkable)
    right = scene.instances == 1
    assert seen[right].mean() > 0.3  # a large wedge of the right room ...
    cov = view_coverage(scene, look, 90.0, 6.0, ~g.walkable)
    assert cov["rooms_seen"] == 1 and cov["coverage_rooms"] == 0.5  # ... is not "seeing" it
    walk_cells = g.walkable.sum()
    assert cov["coverage_area"] == pytest.approx(seen[g.walkable].sum() / walk_cells)
    r2, c2 = g.world_to_cell(4.5, 1.6)
    both = np.vstack([look, [pose_at(g, int(r2), int(c2), 0.0)]])
    assert view_coverage(scene, both, 90.0, 6.0, ~g.walkable)["coverage_rooms"] == 1.0


def test_min_room_share():
    walk = np.zeros((40, 40), bool)
    walk[1:39, 1:39] = True
    scene = _scene(walk)
    pose = np.array([pose_at(scene.grid, 20, 20, 0.0)])
    share = view_coverage(scene, pose, 30.0, 0.5, ~walk)["coverage_area"]
    assert 0 < share < 0.05
    assert view_coverage(scene, pose, 30.0, 0.5, ~walk, min_room_share=0.1)["rooms_seen"] == 0
    assert view_coverage(scene, pose, 30.0, 0.5, ~walk, min_room_share=share)["rooms_seen"] == 1


def test_no_views_and_bad_settings():
    walk = np.ones((10, 10), bool)
    scene = _scene(walk)
    assert view_coverage(scene, np.zeros((0, 3)), 90.0, 5.0, ~walk)["coverage_area"] == 0.0
    for kw, key in ((dict(fov=0.0), "fov"), (dict(max_range=0.0), "max_range")):
        args = {"fov": 90.0, "max_range": 5.0, **kw}
        with pytest.raises(ValueError, match=key) as e:
            view_coverage(scene, np.zeros((1, 3)), args["fov"], args["max_range"], ~walk)
        assert "\n" not in str(e.value)
