"""The reachable area (issue #30 item 2): free space not 4-connected to the robot's start or
views is no room for any method and is not scored. Hand-made maps with known answers, random
maps against a breadth-first flood fill that shares no code with the fast path, and the
environments (synthetic, shared ProcTHOR houses, a map folder with poses)."""

from __future__ import annotations

import warnings
from collections import deque

import numpy as np
import pytest
from PIL import Image

from envs.datasets.maps import MapsEnv
from envs.datasets.procthor import ProcTHOREnv
from envs.datasets.synthetic import SyntheticEnv
from envs.maps.gridmap import GridMap
from envs.maps.reachable import reachable_mask, restrict_scene, seed_cells, start_points
from envs.maps.scene import Scene

#: 0.5 m/px, origin (0, 3): cell (r, c) has its centre at x = 0.25 + 0.5 c, z = 2.75 - 0.5 r
RES, ORIGIN = 0.5, (0.0, 3.0)
#: three components: A (4 cells, top-left), B (7 cells, right), C (1 cell at (4, 3), touching B
#: only diagonally, at (3, 4): 4-connectivity keeps it apart); 12 walkable cells
MAP = np.array([[1, 1, 0, 0, 1, 1],
                [1, 1, 0, 0, 1, 1],
                [0, 0, 0, 0, 1, 1],
                [0, 0, 0, 0, 1, 0],
                [0, 0, 0, 1, 0, 0],
                [0, 0, 0, 0, 0, 0]], bool)


def _flood(walk: np.ndarray, seeds) -> np.ndarray:
    """Breadth-first search over 4-neighbours from each seed (the obviously correct way)."""
    out = np.zeros(walk.shape, bool)
    todo = deque((int(r), int(c)) for r, c in seeds if walk[r, c])
    for r, c in todo:
        out[r, c] = True
    while todo:
        r, c = todo.popleft()
        for rr, cc in ((r - 1, c), (r + 1, c), (r, c - 1), (r, c + 1)):
            if 0 <= rr < walk.shape[0] and 0 <= cc < walk.shape[1] and walk[rr, cc] and not out[rr, cc]:
                out[rr, cc] = True
                todo.append((rr, cc))
    return out


def test_components_by_seed_and_the_largest_without_one():
    a = np.zeros(MAP.shape, bool)
    a[0:2, 0:2] = True
    assert np.array_equal(reachable_mask(MAP, np.array([[1, 0]])), a)
    b = MAP & ~a
    b[4, 3] = False
    assert b.sum() == 7 and np.array_equal(reachable_mask(MAP, None), b)  # the largest: B, 7 cells
    assert np.array_equal(reachable_mask(MAP, np.zeros((0, 2))), b)
    # diagonal contact is no connection: the single cell (4, 3) is a component of its own
    c = np.zeros(MAP.shape, bool)
    c[4, 3] = True
    assert np.array_equal(reachable_mask(MAP, [[4, 3]]), c)
    assert np.array_equal(reachable_mask(MAP, [[4, 3], [0, 0]]), a | c)
    # a seed on an obstacle counts for nothing (here: the largest component instead)
    assert np.array_equal(reachable_mask(MAP, [[5, 5]]), b)
    # a tie goes to the component met first in raster order
    tie = np.array([[0, 0, 1], [1, 0, 1], [1, 0, 0]], bool)
    assert reachable_mask(tie).tolist() == [[0, 0, 1], [0, 0, 1], [0, 0, 0]]
    assert not reachable_mask(np.zeros((3, 3), bool)).any()


def test_seeds_snap_to_the_nearest_free_cell_within_a_metre():
    grid = GridMap(MAP, RES, ORIGIN)
    # (x, z) = (0.25, 2.75) is cell (0, 0), free: kept as it is
    assert seed_cells(grid, [[0.25, 2.75]]).tolist() == [[0, 0]]
    # cell (2, 1) centre (0.75, 1.75) is blocked; nearest free cell (1, 1), 0.5 m away: snapped
    assert seed_cells(grid, [[0.75, 1.75, 90.0]]).tolist() == [[1, 1]]
    # cell (5, 0) centre (0.25, 0.25): the nearest free cell (4, 3) is sqrt(1 + 9) * 0.5 = 1.58 m away
    assert seed_cells(grid, [[0.25, 0.25]]).tolist() == []
    assert seed_cells(grid, [[0.25, 0.25]], snap_m=1.6).tolist() == [[4, 3]]
    # off the map and non-finite points are dropped
    assert seed_cells(grid, [[-5.0, 2.0], [np.nan, 1.0]]).tolist() == []
    with pytest.raises(ValueError, match="seed points must be an"):
        seed_cells(grid, np.zeros((2, 2, 2)))


def _snap_reference(walk, rows, cols, resolution, snap_m):
    """seed_cells' rule over the whole map: SciPy's feature transform of the non-walkable cells."""
    from scipy import ndimage

    dist, (nr, nc) = ndimage.distance_transform_edt(~walk, return_indices=True)
    on = walk[rows, cols]
    keep = on | (dist[rows, cols] * resolution <= snap_m + 1e-9)
    return np.stack([np.where(on, rows, nr[rows, cols])[keep], np.where(on, cols, nc[rows, cols])[keep]], 1)


@pytest.mark.parametrize("seed", range(6))
def test_snapping_in_a_window_equals_the_whole_maps_transform(seed, monkeypatch):
    """Points off the walkable cells snap to the cell SciPy's whole-map transform names: found
    in a window of the snap distance when one cell is nearest, and by that transform itself
    when two are (a point between two equally near cells, which the window cannot decide)."""
    import envs.maps.reachable as reachable

    rng = np.random.default_rng(seed)
    h, w = (int(v) for v in rng.integers(20, 90, 2))
    walk = rng.random((h, w)) < rng.uniform(0.02, 0.6)
    grid = GridMap(walk, 0.1, (0.0, h * 0.1))
    rows, cols = rng.integers(0, h, 60), rng.integers(0, w, 60)
    x, z = grid.pixel_to_world(rows, cols)
    calls = []
    real = reachable.ndimage.distance_transform_edt
    monkeypatch.setattr(reachable.ndimage, "distance_transform_edt", lambda *a, **k: calls.append(1) or real(*a, **k))
    for snap in (0.05, 0.35, 1.0, 3.0):
        want = _snap_reference(walk, rows, cols, 0.1, snap)
        for i in range(len(rows)):  # one point at a time: most have one nearest cell
            got = seed_cells(grid, np.c_[x[i:i + 1], z[i:i + 1]], snap_m=snap)
            ref = _snap_reference(walk, rows[i:i + 1], cols[i:i + 1], 0.1, snap)
            assert got.tolist() == ref.tolist()
        assert seed_cells(grid, np.c_[x, z], snap_m=snap).tolist() == want.tolist()
    # a point with two equally near walkable cells goes to the whole map's transform
    tie = np.zeros((9, 9), bool)
    tie[4, 2] = tie[4, 6] = True
    g = GridMap(tie, 0.1, (0.0, 0.9))
    calls.clear()
    px, pz = g.pixel_to_world(np.array([4]), np.array([4]))
    assert seed_cells(g, np.c_[px, pz]).tolist() == _snap_reference(tie, np.array([4]), np.array([4]), 0.1, 1.0).tolist()
    assert calls, "a tie must be settled by the whole map's transform"
    calls.clear()
    tie[4, 6] = False
    assert seed_cells(g, np.c_[px, pz]).tolist() == [[4, 2]] and not calls
    # exactly at the snap distance (0.2 m) it snaps; a hair nearer a limit, it is dropped
    assert seed_cells(g, np.c_[px, pz], snap_m=0.2).tolist() == [[4, 2]]
    assert seed_cells(g, np.c_[px, pz], snap_m=0.19).tolist() == [] and not calls


@pytest.mark.parametrize("seed", range(10))
def test_random_maps_agree_with_a_flood_fill(seed):
    rng = np.random.default_rng(seed)
    walk = rng.random((rng.integers(5, 30), rng.integers(5, 30))) < rng.uniform(0.35, 0.65)
    cells = np.argwhere(walk)
    if not len(cells):
        return
    pick = cells[rng.choice(len(cells), size=min(3, len(cells)), replace=False)]
    assert np.array_equal(reachable_mask(walk, pick), _flood(walk, pick))
    # without seeds: a component of the largest size, the first in raster order among those
    lab = np.zeros(walk.shape, int)
    comps = []
    for r, c in np.argwhere(walk):
        if not lab[r, c]:
            m = _flood(walk, [(r, c)])
            comps.append(m)
            lab[m] = len(comps)
    best = max(comps, key=lambda m: (m.sum(), -np.flatnonzero(m)[0]))
    assert np.array_equal(reachable_mask(walk), best)


def _scene(walk: np.ndarray) -> Scene:
    rooms = np.where(walk, 0, -1).astype(np.int32)
    rooms[:, 3:][walk[:, 3:]] = 1
    return Scene("h", GridMap(walk, RES, ORIGIN), rooms, rooms.copy(), np.array([2, 3]), ["r0", "r1"],
                 walls=np.zeros(walk.shape, bool))


def test_restrict_scene_cuts_the_grid_and_the_ground_truth_and_keeps_the_rest():
    s = _scene(MAP)
    out = restrict_scene(s, "start", np.array([[0.25, 2.75]]), warn_share=1.0)
    keep = reachable_mask(MAP, [[0, 0]])
    assert np.array_equal(out.grid.walkable, keep) and out.grid.resolution == RES and out.grid.origin == ORIGIN
    assert np.array_equal(out.instances, np.where(keep, s.instances, -1))
    assert out.rooms is s.rooms and out.walls is s.walls and out.room_ids == s.room_ids
    assert s.grid.walkable.sum() == 12  # the input is untouched
    assert restrict_scene(s, "all", np.array([[0.25, 2.75]])) is s
    largest = restrict_scene(s, "largest", np.array([[0.25, 2.75]]), warn_share=1.0)  # seeds ignored
    assert np.array_equal(largest.grid.walkable, reachable_mask(MAP))
    # start without seeds: the largest
    assert np.array_equal(restrict_scene(s, "start", None, warn_share=1.0).grid.walkable, reachable_mask(MAP))
    # removing more than warn_share of the walkable cells says so, naming the house
    with pytest.warns(UserWarning, match=r"house 'h': the reachable area .* leaves out 66.7 % of the walkable"):
        restrict_scene(s, "start", np.array([[0.25, 2.75]]))
    with pytest.raises(ValueError, match="reachable rule is 'near'; expected one of"):
        restrict_scene(s, "near")
    # nothing to remove: the same scene
    one = np.zeros((3, 3), bool)
    one[1, :] = True
    assert restrict_scene(_scene(one), "largest") is not None
    assert restrict_scene(_scene(one), "largest").grid.walkable.sum() == 3


def test_start_points_from_house_data():
    assert start_points({"metadata": {"agent": {"position": {"x": 1.5, "y": 0.9, "z": -2}}}}).tolist() == [[1.5, -2]]
    for bad in ({}, {"metadata": {}}, {"metadata": {"agent": {"position": {"x": "a", "z": 1}}}},
                {"metadata": {"agent": {"position": {"x": float("nan"), "z": 1}}}}):
        assert start_points(bad) is None


def test_synthetic_houses_start_on_the_coffee_table_and_stay_whole():
    env, whole = SyntheticEnv(n_houses=3), SyntheticEnv(n_houses=3, reachable="all")
    for hid in env.house_ids():
        s, w = env.scene(hid), whole.scene(hid)
        # generated houses are one 4-connected free space: nothing removed
        assert np.array_equal(s.grid.walkable, w.grid.walkable) and np.array_equal(s.instances, w.instances)
        x, z = start_points(env.house(hid).data)[0]
        r, c = s.grid.world_to_cell(x, z)
        d = np.hypot(*(np.argwhere(s.grid.walkable) - [r, c]).T).min() * s.grid.resolution
        assert d <= 1.0  # the start (the living room's centre) is within a metre of free space


@pytest.mark.slow
def test_shared_procthor_houses_keep_the_start_component(procthor_file):
    """On the 150 shared houses: the scene's free space is exactly the 4-connected component of
    the start pose in the rasterised map, and the ground truth scored follows it."""
    env = ProcTHOREnv(path=str(procthor_file))
    whole = ProcTHOREnv(path=str(procthor_file), reachable="all")
    changed = 0
    for hid in env.house_ids():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)
            s = env.scene(hid)
        w = whole.scene(hid)
        x, z = start_points(env.house(hid).data)[0]
        start = seed_cells(w.grid, [[x, z]])
        assert len(start) == 1, hid
        assert np.array_equal(s.grid.walkable, _flood(w.grid.walkable, start)), hid
        assert np.array_equal(s.instances, np.where(s.grid.walkable, w.instances, -1)), hid
        changed += int(s.grid.walkable.sum() != w.grid.walkable.sum())
    assert changed > 0  # furniture does enclose free pockets in real houses


def test_a_map_folder_takes_its_seeds_from_the_poses_file(tmp_path):
    # two rooms with no door between them: the smaller one (left) holds the views
    img = np.zeros((24, 50), np.uint8)
    img[2:22, 2:16] = 255
    img[2:22, 18:48] = 255
    Image.fromarray(img).save(tmp_path / "m.png")
    Image.fromarray(img).save(tmp_path / "m_gt.png")
    # ROS frame: bottom-left corner at (0, 0), 0.05 m/px: column 8, row 10 is x = 0.425, y = 0.675
    (tmp_path / "m_poses.csv").write_text("x,y,theta\n0.425,0.675,0\n")
    common = dict(maps="{id}.png", image_resolution=0.05, gt_format="rooms_white", poses="{id}_poses.csv")
    with pytest.warns(UserWarning, match="leaves out 68.2 %"):  # 600 of 880 free cells
        s = MapsEnv(str(tmp_path), **common).scene("m")
    assert s.grid.walkable.sum() == 280 and s.grid.walkable[10, 8] and not s.grid.walkable[10, 30]
    assert set(np.unique(s.instances).tolist()) == {-1, 0}
    with pytest.warns(UserWarning, match="the largest component"):
        big = MapsEnv(str(tmp_path), **{**common, "poses": None}).scene("m")  # no poses: the largest
    assert big.grid.walkable.sum() == 600 and big.grid.walkable[10, 30]
    assert MapsEnv(str(tmp_path), **{**common, "reachable": "all"}).scene("m").grid.walkable.sum() == 880
