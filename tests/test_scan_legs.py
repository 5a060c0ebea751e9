"""What a 2D laser sees of furniture (issue 37, item 4): with ``legs`` a table is four leg dots at
scan height, the scan passes between them, and the map shows the dots."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from envs.maps.scan import ScanSettings, leg_centres, scan_map, scan_obstacles
from envs.maps.scene import ObjectFootprint
from tests.maps import pose_at, two_rooms_scene


def _scene_with_table(object_type="DiningTable", yaw=0.0):
    scene = two_rooms_scene()
    x, z = scene.grid.pixel_to_world(20, 20)  # the left room's centre
    table = ObjectFootprint("t", "DiningTable_1", object_type, (float(x), float(z)), yaw, (1.0, 0.75, 0.6), 0.0, 0.75)
    scene.objects = [table]
    return scene, table


@pytest.mark.parametrize("yaw", [0.0, 30.0])
def test_a_table_is_four_leg_dots_at_its_corners(yaw):
    scene, table = _scene_with_table(yaw=yaw)
    box = table.contains(*scene.grid.pixel_to_world(*np.mgrid[0:40, 0:78]))
    near = ndimage.binary_dilation(box, iterations=2)  # the table and a cell or two around it, far from walls
    solid = scan_obstacles(scene, 0.25) & box
    legs = scan_obstacles(scene, 0.25, legs=True, leg_size=0.05) & near
    assert solid.sum() == box.sum()  # without legs: the whole footprint
    labels, n = ndimage.label(legs, structure=np.ones((3, 3)))
    assert n == 4 and legs.sum() <= 4 * 4
    # each dot holds its leg's centre, in a corner of the box
    for cx, cz in leg_centres(table, 0.05):
        r, c = scene.grid.world_to_cell(cx, cz)
        assert legs[int(r), int(c)]
    # a sofa stands on its whole box
    sofa = ObjectFootprint("s", "Sofa_1", "Sofa", table.center, yaw, (1.0, 0.8, 0.8), 0.0, 0.8)
    scene.objects = [sofa]
    seat = sofa.contains(*scene.grid.pixel_to_world(*np.mgrid[0:40, 0:78]))
    assert (scan_obstacles(scene, 0.25, legs=True) & seat).sum() == seat.sum()


def test_the_map_shows_leg_dots_and_free_floor_under_the_table():
    scene, table = _scene_with_table()
    grid = scene.grid
    scans = np.array([pose_at(grid, r, c, 0.0) for r, c in ((6, 6), (6, 34), (34, 6), (34, 34), (20, 6))])
    s = ScanSettings(legs=True, max_range=5.0)
    m = scan_map(scan_obstacles(scene, 0.25, legs=True), grid, scans, s)
    box = table.contains(*grid.pixel_to_world(*np.mgrid[0:40, 0:78]))
    occupied = (m.occupancy == 100) & ndimage.binary_dilation(box, iterations=2)
    _, n = ndimage.label(occupied, structure=np.ones((3, 3)))
    assert n == 4
    assert (m.free & box).sum() > 0.8 * box.sum()  # the laser passes between the legs
    solid = scan_map(scan_obstacles(scene, 0.25), grid, scans, ScanSettings(max_range=5.0))
    assert (solid.free & box).sum() == 0  # a box: an occupied outline around an unknown inside


def test_leg_settings_are_checked_in_one_line():
    with pytest.raises(ValueError, match="leg_size"):
        ScanSettings(leg_size=0.0).check()
    with pytest.raises(ValueError, match="legs"):
        ScanSettings(legs="yes").check()
    with pytest.raises(ValueError, match="door_closed"):
        ScanSettings(door_closed=1.5).check()


def test_a_closed_door_splits_the_free_space():
    from envs.maps.scan import closed_doors, robot_scan_map

    scene = two_rooms_scene()
    door = np.zeros(scene.grid.shape, bool)
    door[18:22, 38:40] = True  # the opening between the two rooms (tests/maps.py)
    scene.doors = {"door|0|1": np.argwhere(door)}
    grid = scene.grid
    # four views in each room (a cell needs 4 scans to become free)
    views = np.array([pose_at(grid, r, c, 0.0) for c0 in (20, 57) for r, c in ((12, c0 - 6), (12, c0 + 6),
                                                                               (28, c0 + 6), (28, c0 - 6))])
    parts = {}
    for p in (0.0, 1.0):
        m, _ = robot_scan_map(scene, views, ScanSettings(door_closed=p, max_range=5.0))
        _, parts[p] = ndimage.label(m.free)
        assert not (m.free & door).any() or p == 0.0
    assert parts[0.0] == 1 and parts[1.0] == 2
    np.testing.assert_array_equal(closed_doors(scene, 1.0), door)
    assert not closed_doors(scene, 0.0).any()
    # the draw is per door: the same door is closed for every probability above its draw
    u = [closed_doors(scene, q, seed=5).any() for q in np.linspace(0, 1, 11)]
    assert u == sorted(u)


@pytest.mark.slow
@pytest.mark.shared_data
def test_shared_houses_record_their_door_openings(shared_scenes):
    scene = shared_scenes[0]
    assert scene.doors and all(len(c) for c in scene.doors.values())
    closed = np.zeros(scene.grid.shape, bool)
    for cells in scene.doors.values():
        closed[cells[:, 0], cells[:, 1]] = True
    # the openings were cut out of the walls, and the floor plan's walkable cells pass through them
    assert not (closed & scene.walls).any() and (closed & scene.grid.walkable).any()


def test_grazing_beams_drop_out_and_head_on_ones_do_not():
    from envs.maps.scan import surface_normals
    from tests.maps import rect_grid

    grid = rect_grid(40, 200)  # a 1.8 m x 9.8 m corridor
    obstacles = ~grid.walkable
    n = surface_normals(obstacles)
    np.testing.assert_array_equal(n[1, 50], [3, 0])  # the top wall faces the corridor (rows grow downwards)
    np.testing.assert_array_equal(n[38, 50], [-3, 0])
    pose = np.array([pose_at(grid, 20, 100, 0.0)])
    hits = {}
    for g in (0.0, 1.0):
        counts = []
        for seed in range(5):
            m = scan_map(obstacles, grid, pose, ScanSettings(grazing_dropout=g, max_range=20.0, angular_step=0.5,
                                                              seed=seed))
            counts.append(int((m.occupancy == 100).sum()))
            # the beams straight up and down hit the walls head on: never dropped
            assert m.occupancy[1, 100] == 100 and m.occupancy[38, 100] == 100
        hits[g] = np.mean(counts)
    assert hits[1.0] < 0.8 * hits[0.0]
    with pytest.raises(ValueError, match="grazing_dropout"):
        ScanSettings(grazing_dropout=2.0).check()


def test_people_leave_transient_hits_that_later_scans_clear():
    from tests.maps import rect_grid

    grid = rect_grid(60, 60)  # an empty 2.8 m square room
    obstacles = ~grid.walkable
    inside = np.zeros(grid.shape, bool)
    inside[6:-6, 6:-6] = True
    pose = pose_at(grid, 30, 30, 0.0)
    one = scan_map(obstacles, grid, np.array([pose]), ScanSettings(people=3, seed=1))
    none = scan_map(obstacles, grid, np.array([pose]), ScanSettings(seed=1))
    hits_one = int(((one.occupancy == 100) & inside).sum())
    assert hits_one > 0 and not ((none.occupancy == 100) & inside).any()  # the people, seen once
    # twenty scans from the same place, the people elsewhere each time: their hits are cleared
    many = scan_map(obstacles, grid, np.array([pose] * 20), ScanSettings(people=3, seed=1))
    assert ((many.occupancy == 100) & inside).sum() < hits_one and (many.free & inside).sum() > 0.9 * inside.sum()
    with pytest.raises(ValueError, match="people"):
        ScanSettings(people=-1).check()
