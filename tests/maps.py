"""Hand-made maps shared by the tests."""

import numpy as np

from envs.maps.gridmap import GridMap
from envs.maps.scene import Scene


def rect_grid(h=40, w=60, res=0.05):
    walk = np.zeros((h, w), bool)
    walk[2:-2, 2:-2] = True
    return GridMap(walk, res, (0.0, h * res))


def l_grid(res=0.05):
    walk = np.zeros((60, 60), bool)
    walk[2:58, 2:22] = True
    walk[38:58, 2:58] = True
    return GridMap(walk, res, (0.0, 60 * res))


def two_rooms_grid(res=0.05, door=(18, 22)):
    """Two 36 x 36 rooms side by side, a 2-px wall at columns 38-39 with a door at rows door."""
    walk = np.zeros((40, 78), bool)
    walk[2:38, 2:76] = True
    walk[:, 38:40] = False
    walk[door[0]:door[1], 38:40] = True
    return GridMap(walk, res, (0.0, 40 * res))


def two_rooms_scene(res=0.05):
    grid = two_rooms_grid(res)
    rooms = np.full(grid.shape, -1, np.int32)
    rooms[2:38, 2:39] = 0
    rooms[2:38, 39:76] = 1
    inst = np.where(grid.walkable, rooms, -1).astype(np.int32)
    walls = ~grid.walkable & (rooms >= 0)
    return Scene("two", grid, rooms, inst, np.array([5, 2]), ["room|0", "room|1"], walls=walls,
                 objects=[], object_map=np.full(grid.shape, -1, np.int32))


def pose_at(grid, r, c, yaw):
    x, z = grid.pixel_to_world(r, c)
    return [float(x), float(z), float(yaw)]
