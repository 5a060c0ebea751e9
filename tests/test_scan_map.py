"""Scan maps (envs/maps/scan.py): known answers on hand-made maps and real houses, and the fast
mapper against its pure-Python reference (its own line walk, sets and a dict)."""

import copy
import math

import numpy as np
import pytest

from envs.maps.gridmap import GridMap
from envs.maps.ros import read_ros_map
from envs.maps.scan import (
    FREE,
    OCCUPIED,
    UNKNOWN,
    ScanMapper,
    ScanSettings,
    house_wall_height,
    robot_scan_map,
    scan_map,
    scan_map_reference,
    scan_obstacles,
    write_scan_map,
)
from envs.maps.scene import ObjectFootprint, Scene, rasterise_house
from envs.maps.trajectory import trajectory
from envs.world.house import House
from tests.maps import pose_at, two_rooms_grid

INF = math.inf


def _lifted(house: House, by: float) -> House:
    """The same house with every object raised ``by`` metres (nothing stands on the floor)."""
    data = copy.deepcopy(house.data)
    for o in data.get("objects", []):
        o["position"]["y"] = float(o["position"].get("y", 0.0)) + by
    return House(house.id, data)


def _every_room_visited(scene, poses) -> bool:
    r, c = scene.grid.world_to_cell(poses[:, 0], poses[:, 1])
    have = set(scene.instances[r, c].tolist())
    return all(k in have for k in np.unique(scene.instances[scene.instances >= 0]))


def _acceptance(house: House) -> None:
    """Infinite range, no noise, every object's base above the 0.25 m scan plane, a trajectory
    through every room: the scan map's free cells are exactly the floor plan's walkable cells
    (rasterised with max_object_base = the scan height), and what no beam reached is unknown."""
    from benchmark.viewpoints import Autotrace

    h = _lifted(house, 0.3)
    scene = rasterise_house(h, max_object_base=0.25)
    poses = Autotrace(offset=0.3, spacing=0.5).generate(scene)
    assert _every_room_visited(scene, poses)
    settings = ScanSettings(height=0.25, max_range=INF, angular_step=0.5, spacing=0.25)
    m, traj = robot_scan_map(scene, poses, settings, house_wall_height(h))
    assert len(traj) > len(poses)
    walk = scene.grid.walkable
    # tolerance at wall edges: none needed (0 cells differ) on these houses
    assert np.array_equal(m.free, walk)
    assert np.array_equal(m.occupancy == UNKNOWN, (m.log_odds == 0) | ((m.occupancy != FREE) & (m.occupancy != OCCUPIED)))
    assert (m.occupancy[m.log_odds == 0] == UNKNOWN).all()
    # cells outside the outer walls: no beam reaches them
    assert (m.occupancy[scene.rooms < 0] != FREE).all()
    assert (m.log_odds == 0).sum() > 0


def test_acceptance_shared_house(shared_houses):
    _acceptance(shared_houses[0])


def test_acceptance_generated_houses():
    from envs.datasets.synthetic import SyntheticEnv

    env = SyntheticEnv(n_houses=2)
    for hid in env.house_ids():
        _acceptance(env.house(hid))


def test_furniture_at_the_plane_free_is_inside_walkable(shared_houses):
    """With furniture cutting the plane (height 0.05 m: below every object's top in the first
    houses), no free cell is ever off the floor plan's walkable cells; the walkable cells left
    unknown are those behind furniture, at most 1 % here."""
    from benchmark.viewpoints import Autotrace

    h = shared_houses[0]
    scene = rasterise_house(h, max_object_base=0.05)
    assert all(o.top > 0.05 for o in scene.objects)
    obstacles = scan_obstacles(scene, 0.05, house_wall_height(h))
    assert np.array_equal(obstacles, ~scene.grid.walkable)
    poses = Autotrace(offset=0.5, spacing=1.0).generate(scene)
    m = scan_map(obstacles, scene.grid, trajectory(scene.grid.walkable, scene.grid, poses, 0.5),
                 ScanSettings(height=0.05, max_range=INF))
    walk = scene.grid.walkable
    assert not (m.free & ~walk).any()
    assert (walk & ~m.free).sum() <= 0.01 * walk.sum()


def _room_in_big_map():
    """A 20 x 30 px room (walls 1 px) inside a 40 x 50 px map of 0.05 m cells."""
    walk = np.zeros((40, 50), bool)
    walk[11:29, 11:39] = True
    grid = GridMap(walk, 0.05, (0.0, 2.0))
    obstacles = np.zeros((40, 50), bool)
    obstacles[10, 10:40] = obstacles[29, 10:40] = True
    obstacles[10:30, 10] = obstacles[10:30, 39] = True
    return grid, obstacles


def test_unreached_cells_are_unknown_and_the_room_is_mapped():
    grid, obstacles = _room_in_big_map()
    poses = np.array([pose_at(grid, 20, 20, 0.0), pose_at(grid, 20, 30, 0.0)] * 2)
    m = scan_map(obstacles, grid, poses, ScanSettings(max_range=INF, angular_step=0.25))
    inside = np.zeros(grid.shape, bool)
    inside[11:29, 11:39] = True
    wall = obstacles
    outside = ~inside & ~wall
    assert (m.occupancy[outside] == UNKNOWN).all() and (m.log_odds[outside] == 0).all()
    # 4 scans see every cell of the empty room: all free; every wall cell facing the room is hit
    assert (m.occupancy[inside] == FREE).all()
    assert (m.occupancy[10, 11:39] == OCCUPIED).all() and (m.occupancy[29, 11:39] == OCCUPIED).all()
    assert m.free.sum() == inside.sum()
    # 3 scans: every room cell seen but not yet free (3 x -0.4 = -1.2; free below logit(0.196) = -1.41)
    m3 = scan_map(obstacles, grid, poses[:3], ScanSettings(max_range=INF, angular_step=0.25))
    assert (m3.log_odds[inside] == np.float32(-1.2)).all() and m3.free.sum() == 0


def test_max_range_limits_what_is_seen():
    grid, obstacles = _room_in_big_map()
    poses = np.array([pose_at(grid, 20, 20, 0.0)] * 4)
    m = scan_map(obstacles, grid, poses, ScanSettings(max_range=0.3, angular_step=0.5))
    rr, cc = np.nonzero(m.log_odds != 0)
    # nothing further than 0.3 m (6 px) from the scan cell, up to the line's end rounding
    assert np.hypot(rr - 20, cc - 20).max() <= 6.0 + 1.0
    assert (m.occupancy == OCCUPIED).sum() == 0  # every wall is further than 0.3 m


def test_scan_obstacles_objects_and_doors():
    """A table top above the plane does not block; a box standing on the floor does; a door
    opening never blocks (the generated house's wall layer, doors cut out)."""
    walk = np.zeros((40, 40), bool)
    walk[1:-1, 1:-1] = True
    grid = GridMap(walk, 0.05, (0.0, 2.0))
    rooms = np.where(walk, 0, -1).astype(np.int32)
    table = ObjectFootprint("t", "a", "DiningTable", (0.5, 1.5), 0.0, (0.4, 0.05, 0.4), base=0.7, top=0.75)
    box = ObjectFootprint("b", "a", "Box", (1.5, 0.5), 30.0, (0.4, 0.4, 0.4), base=0.0, top=0.4)
    low = ObjectFootprint("r", "a", "Rug", (1.5, 1.5), 0.0, (0.4, 0.01, 0.4), base=0.0, top=0.01)
    scene = Scene("s", grid, rooms, rooms, np.array([0]), ["r"], walls=np.zeros((40, 40), bool),
                  objects=[table, box, low], object_map=np.full((40, 40), -1, np.int32))
    obs = scan_obstacles(scene, 0.25)
    r, c = grid.world_to_cell(0.5, 1.5)
    assert not obs[r, c]  # under the table
    r, c = grid.world_to_cell(1.5, 0.5)
    assert obs[r, c]  # the box
    r, c = grid.world_to_cell(1.5, 1.5)
    assert not obs[r, c]  # the rug is below the plane
    rr, cc = np.mgrid[:40, :40]
    x, z = grid.pixel_to_world(rr, cc)
    assert np.array_equal(obs & (rooms >= 0), box.contains(x, z) & (rooms >= 0))
    assert obs[rooms < 0].all()
    # at 0.72 m the table top is cut, the box is not
    obs2 = scan_obstacles(scene, 0.72)
    assert np.array_equal(obs2 & (rooms >= 0), table.contains(x, z) & (rooms >= 0))


def test_door_openings_never_block():
    from envs.datasets.synthetic import SyntheticEnv

    env = SyntheticEnv(n_houses=1)
    house = env.house(env.house_ids()[0])
    scene = env.scene(house.id)
    obs = scan_obstacles(scene, 0.25, house_wall_height(house))
    n_doors = 0
    for door in house.data["doors"]:
        wall = next(w for w in house.data["walls"] if w["id"] == door["wall0"])
        p = [(float(q["x"]), float(q["z"])) for q in wall["polygon"] if abs(float(q["y"])) < 1e-9]
        (x0, z0), (x1, z1) = p[0], p[-1]
        t = (float(door["holePolygon"][0]["x"]) + float(door["holePolygon"][-1]["x"])) / 2
        length = math.hypot(x1 - x0, z1 - z0)
        x, z = x0 + (x1 - x0) * t / length, z0 + (z1 - z0) * t / length
        r, c = scene.grid.world_to_cell(x, z)
        assert not obs[r, c], f"door {door['id']} blocks the scan"
        n_doors += 1
    assert n_doors >= 3


@pytest.mark.parametrize("settings", [
    ScanSettings(),
    ScanSettings(range_noise=0.05, seed=3),
    ScanSettings(dropout=0.3, range_noise=0.1, max_range=1.0, seed=1),
    ScanSettings(max_range=INF, range_noise=0.2, angular_step=2.5),
    ScanSettings(max_range=0.6, angular_step=7.0, log_odds_hit=2.0, log_odds_miss=-1.0),
    ScanSettings(grazing_dropout=0.7, range_noise=0.05, seed=2),
    ScanSettings(grazing_dropout=1.0, dropout=0.2, max_range=INF, angular_step=2.0, seed=5),
    ScanSettings(people=4, person_radius=0.15, range_noise=0.05, seed=6),
    ScanSettings(people=2, grazing_dropout=0.5, max_range=INF, angular_step=3.0, seed=7),
])
def test_fast_equals_reference_hand_made(settings):
    grid = two_rooms_grid()
    obstacles = ~grid.walkable
    poses = np.array([pose_at(grid, 20, 10, 0), pose_at(grid, 20, 10, 90), pose_at(grid, 10, 60, 30),
                      pose_at(grid, 30, 20, 200), pose_at(grid, 19, 38, 0), pose_at(grid, 0, 0, 0),
                      pose_at(grid, 30, 20, 10)])
    fast = scan_map(obstacles, grid, poses, settings)
    ref = scan_map_reference(obstacles, grid, poses, settings)
    assert fast.n_scans == ref.n_scans == 6  # the pose on an obstacle scans nothing
    np.testing.assert_array_equal(fast.log_odds, ref.log_odds)
    np.testing.assert_array_equal(fast.occupancy, ref.occupancy)


@pytest.mark.parametrize("settings", [ScanSettings(max_range=4.0, angular_step=2.0),
                                      ScanSettings(max_range=4.0, angular_step=2.0, range_noise=0.1, dropout=0.2)])
def test_fast_equals_reference_shared_house(shared_houses, settings):
    from benchmark.viewpoints import Autotrace

    scene = rasterise_house(shared_houses[1])
    traj = trajectory(scene.grid.walkable, scene.grid, Autotrace().generate(scene), 0.5)[:40]
    obstacles = scan_obstacles(scene, 0.25)
    fast = scan_map(obstacles, scene.grid, traj, settings)
    ref = scan_map_reference(obstacles, scene.grid, traj, settings)
    np.testing.assert_array_equal(fast.log_odds, ref.log_odds)
    np.testing.assert_array_equal(fast.occupancy, ref.occupancy)


def test_incremental_equals_all_at_once():
    grid = two_rooms_grid()
    poses = np.array([pose_at(grid, 5 + 3 * i, 5 + 6 * i, 10 * i) for i in range(10)])
    s = ScanSettings(range_noise=0.08, dropout=0.2, seed=7)
    mapper = ScanMapper(~grid.walkable, grid, s)
    for chunk in (poses[:3], poses[3:4], poses[4:]):
        mapper.add(chunk)
    whole = scan_map(~grid.walkable, grid, poses, s)
    np.testing.assert_array_equal(mapper.result().log_odds, whole.log_odds)


def test_repeated_scans_from_one_cell_count_each_time():
    """Scans repeated from one cell (views turning in place) add their evidence each time,
    as the reference (which traces every scan) does."""
    grid = two_rooms_grid()
    poses = np.array([pose_at(grid, 20, 10, yaw) for yaw in (0, 120, 240)] + [pose_at(grid, 20, 12, 0)])
    fast = scan_map(~grid.walkable, grid, poses, ScanSettings())
    ref = scan_map_reference(~grid.walkable, grid, poses, ScanSettings())
    np.testing.assert_array_equal(fast.log_odds, ref.log_odds)
    one = scan_map(~grid.walkable, grid, poses[:1], ScanSettings())
    r, c = 20, 11
    assert one.log_odds[r, c] == pytest.approx(-0.4) and fast.log_odds[r, c] == pytest.approx(-1.6)


def test_range_noise_moves_where_beams_end():
    """Noisy ranges put hits in front of a wall and free evidence behind it (long readings
    walk through); zero noise puts every hit on the wall. Seeded: the same map twice."""
    walk = np.zeros((61, 80), bool)
    walk[1:60, 1:79] = True
    obstacles = ~walk
    obstacles[:, 40] = True  # a 1-px wall at column 40, free space behind it
    grid = GridMap(walk & ~obstacles, 0.05, (0.0, 61 * 0.05))
    poses = np.array([pose_at(grid, 30, 30, 0)] * 6)  # 0.5 m from the wall, 1.5 m from the others
    clean = scan_map(obstacles, grid, poses, ScanSettings(max_range=1.0))
    assert (clean.log_odds[:, 41:] == 0).all()
    assert clean.occupancy[clean.occupancy == OCCUPIED].size > 0
    hit_cols = np.nonzero((clean.occupancy == OCCUPIED).any(axis=0))[0]
    assert set(hit_cols.tolist()) == {40}
    s = ScanSettings(max_range=1.0, range_noise=0.1, seed=5)
    noisy = scan_map(obstacles, grid, poses, s)
    assert (noisy.log_odds[:, 41:] < 0).any()  # long readings: free evidence behind the wall
    assert (noisy.log_odds[:, 31:40] > 0).any()  # short readings: hits in front of it
    np.testing.assert_array_equal(noisy.log_odds, scan_map(obstacles, grid, poses, s).log_odds)
    assert not np.array_equal(noisy.log_odds, scan_map(obstacles, grid, poses, s.replace(seed=6)).log_odds)


def test_dropout_drops_evidence():
    grid = two_rooms_grid()
    poses = np.array([pose_at(grid, 20, 20, 0)])
    full = scan_map(~grid.walkable, grid, poses, ScanSettings(angular_step=0.5))
    some = scan_map(~grid.walkable, grid, poses, ScanSettings(angular_step=0.5, dropout=0.9))
    hits_full = (full.log_odds > 0).sum()
    hits_some = (some.log_odds > 0).sum()
    assert 0 < hits_some < 0.3 * hits_full
    assert ((some.log_odds != 0) <= (full.log_odds != 0)).all()  # dropout only removes evidence


def test_write_scan_map_round_trip(tmp_path):
    grid, obstacles = _room_in_big_map()
    poses = np.array([pose_at(grid, 20, 20, 0.0)] * 4 + [pose_at(grid, 15, 30, 0.0)])
    m = scan_map(obstacles, grid, poses, ScanSettings(max_range=INF))
    assert {-1, 0, 100} <= set(np.unique(m.occupancy).tolist())
    y = write_scan_map(tmp_path / "scan.yaml", m, grid)
    back = read_ros_map(y)
    np.testing.assert_array_equal(back.occupancy, m.occupancy)
    assert back.free_thresh == 0.196 and back.occupied_thresh == 0.65
    assert back.grid.origin == pytest.approx(grid.origin)
    from PIL import Image

    img = np.asarray(Image.open(tmp_path / "scan.pgm"))
    assert set(np.unique(img).tolist()) == {0, 205, 254}
    write_scan_map(tmp_path / "scan2.yaml", m, grid, image_name="scan2.png")
    np.testing.assert_array_equal(read_ros_map(tmp_path / "scan2.yaml").occupancy, m.occupancy)


@pytest.mark.parametrize("changes, key", [
    ({"range_noise": -0.1}, "range_noise"),
    ({"height": 3.0}, "height"),
    ({"height": 0.0}, "height"),
    ({"max_range": 0.0}, "max_range"),
    ({"angular_step": 0}, "angular_step"),
    ({"dropout": 1.0}, "dropout"),
    ({"spacing": 0}, "spacing"),
    ({"free_thresh": 0.6}, "free_thresh"),
    ({"log_odds_min": -1.0}, "log_odds_min"),
    ({"seed": -1}, "seed"),
])
def test_bad_settings_one_line(changes, key):
    with pytest.raises(ValueError) as e:
        ScanSettings(**changes).check()
    msg = str(e.value)
    assert "\n" not in msg and key in msg and repr(next(iter(changes.values()))) in msg and "expected" in msg


def test_scan_height_above_the_house_walls(shared_houses):
    house = shared_houses[0]
    top = house_wall_height(house)
    assert 2.5 < top < 6.0
    scene = rasterise_house(house)
    with pytest.raises(ValueError, match="expected 0 < height < ") as e:
        scan_obstacles(scene, top + 0.1, top)
    assert "\n" not in str(e.value)
    with pytest.raises(ValueError, match="scan height"):
        scan_obstacles(scene, -0.1)


def test_fast_equals_reference_random_maps_large_noise():
    """Random clutter, ranges up to 1 m of noise (long readings walk far past the hit), limited
    and unlimited range: the fast mapper equals the reference on every map."""
    rng = np.random.default_rng(0)
    for trial in range(20):
        h, w = (int(v) for v in rng.integers(20, 60, 2))
        obs = rng.random((h, w)) < rng.uniform(0.02, 0.2)
        grid = GridMap(~obs, 0.05, (0.0, h * 0.05))
        free = np.argwhere(~obs)
        sel = free[rng.choice(len(free), 4)]
        x, z = grid.pixel_to_world(sel[:, 0], sel[:, 1])
        poses = np.column_stack([x, z, np.zeros(4)])
        s = ScanSettings(range_noise=float(rng.choice([0.05, 0.2, 0.5, 1.0])), angular_step=3.0, dropout=0.1,
                         max_range=float(rng.choice([0.5, 1.5, INF])), seed=trial)
        np.testing.assert_array_equal(scan_map(obs, grid, poses, s).log_odds,
                                      scan_map_reference(obs, grid, poses, s).log_odds)


def test_walk_beam_is_trace_ray_then_the_same_line_beyond():
    from envs.maps.rays import trace_ray, walk_beam

    rng = np.random.default_rng(1)
    blocked = rng.random((40, 50)) < 0.08
    empty = np.zeros_like(blocked)
    buf = [np.empty(80, np.int32) for _ in range(6)]
    for _ in range(300):
        r0, c0 = int(rng.integers(0, 40)), int(rng.integers(0, 50))
        r1, c1 = int(rng.integers(-10, 50)), int(rng.integers(-10, 60))
        extra = int(rng.integers(0, 6))
        n, k_hit = walk_beam(blocked, r0, c0, r1, c1, extra, buf[0], buf[1])
        nv, hr, hc = trace_ray(blocked, r0, c0, r1, c1, buf[2], buf[3])
        nl, _, _ = trace_ray(empty, r0, c0, r1, c1, buf[4], buf[5])
        np.testing.assert_array_equal(buf[0][:n], buf[4][:n])  # the same digital line
        if hr < 0:
            assert k_hit == -1 and n == nv == nl
        else:
            assert k_hit == nv and (buf[0][k_hit], buf[1][k_hit]) == (hr, hc)
            assert n == min(k_hit + 1 + extra, nl)
