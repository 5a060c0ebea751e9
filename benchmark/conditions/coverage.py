"""What the robot's views covered: shares of the ground truth inside at least one view's cone.

A view sees the cells its cone's rays visit (:func:`benchmark.aggregators.vision_cone.cones_reach`,
the vision cone's walk, where neighbouring rays share their cells: rays
from the view's cell spanning ``fov`` degrees around its yaw, up to ``max_range`` metres,
stopping before the first ``blocked`` cell; rays spaced at most a quarter pixel apart at
the range: at half a pixel, as the vision-cone aggregator casts them, a fan of digital lines
leaves a few cells unvisited inside the cone, 10 of 1037 on a 90 degree, 40 px test cone,
none at a quarter). The cone sees cells, not objects: what
stands on them (furniture too low to block) does not hide the floor.

* ``coverage_area``: the share of ground-truth walkable cells (``scene.instances >= 0``)
  that some view sees.
* ``coverage_rooms``: the share of ground-truth rooms *seen from inside*: a room counts
  when the views standing in it (their cell is one of the room's walkable cells) see at
  least ``min_room_share`` (default 0.1) of its walkable cells. A view into the next room
  through an open door, or across an open-plan boundary, does not make that room seen: its
  picture is mostly of the room it stands in, and that is the label it carries.
"""

from __future__ import annotations

import math

import numpy as np

from benchmark.aggregators.vision_cone import cones_reach
from envs.maps.rays import cone_thetas
from envs.maps.scene import Scene

#: rays per pixel of arc at the range (see the module docstring).
RAY_OVERSAMPLE = 4.0
#: default share of a room's walkable cells the views must see for the room to count as seen.
MIN_ROOM_SHARE = 0.1


def visible_cells(scene: Scene, poses: np.ndarray, fov: float, max_range: float, blocked: np.ndarray,
                  groups: np.ndarray | None = None, n_groups: int = 1) -> np.ndarray:
    """(H, W) bool cells inside at least one view's cone with line of sight.

    Args:
        scene: the house on its grid.
        poses: (N, 3) x, z (metres), yaw (degrees).
        fov: cone angle, degrees (0 < fov <= 360).
        max_range: metres (> 0, ``math.inf`` allowed).
        blocked: (H, W) bool cells that stop a ray (e.g. :func:`envs.render.floorplan.occluders`).
        groups: (N,) int in ``[0, n_groups)``, or None: the cells of each group's views apart.
        n_groups: the number of groups.

    Returns:
        (H, W) bool; with ``groups``, (n_groups, H, W) bool, one group's cells per plane.
    """
    if not (isinstance(fov, int | float) and 0 < fov <= 360):
        raise ValueError(f"coverage fov = {fov!r}: expected degrees, 0 < fov <= 360")
    if not (isinstance(max_range, int | float) and max_range > 0):
        raise ValueError(f"coverage max_range = {max_range!r}: expected metres > 0 (inf allowed)")
    grid = scene.grid
    poses = np.asarray(poses, np.float64).reshape(-1, 3)
    if np.shape(blocked) != grid.shape:
        raise ValueError(f"coverage blocked mask shape {np.shape(blocked)}: expected the map's {grid.shape}")
    if len(poses) == 0:
        return np.zeros(grid.shape if groups is None else (n_groups, *grid.shape), bool)
    px = math.ceil(math.hypot(*grid.shape)) + 2 if math.isinf(max_range) else max_range / grid.resolution
    rows, cols = grid.world_to_cell(poses[:, 0], poses[:, 1])
    # every cone has the same rays around its heading; neighbouring rays share their cells
    return cones_reach(blocked, rows, cols, np.deg2rad(poses[:, 2]), cone_thetas(0.0, fov, px, RAY_OVERSAMPLE), px,
                       groups, n_groups)


def view_coverage(scene: Scene, poses: np.ndarray, fov: float, max_range: float, blocked: np.ndarray,
                  min_room_share: float = MIN_ROOM_SHARE) -> dict:
    """Coverage of the ground truth by the views (module docstring).

    Args:
        scene: the house on its grid (ground truth: ``scene.instances``).
        poses: (N, 3) x, z (metres), yaw (degrees).
        fov: cone angle, degrees.
        max_range: metres (``math.inf`` allowed).
        blocked: (H, W) bool cells that stop a ray.
        min_room_share: share of a room's walkable cells its own views must see.

    Returns:
        ``{"coverage_area": share in [0, 1], "coverage_rooms": share in [0, 1],
        "rooms_seen": int, "rooms": int}`` (rooms: those with walkable cells).
    """
    if not (isinstance(min_room_share, int | float) and 0 < min_room_share <= 1):
        raise ValueError(f"coverage min_room_share = {min_room_share!r}: expected a share in (0, 1]")
    grid = scene.grid
    poses = np.asarray(poses, np.float64).reshape(-1, 3)
    inst = np.asarray(scene.instances)
    gt = inst >= 0
    n_rooms = int(inst.max()) + 1 if gt.any() else 0
    total = np.bincount(inst[gt], minlength=n_rooms)
    rows, cols = grid.world_to_cell(poses[:, 0], poses[:, 1])
    on_map = grid.in_bounds(rows, cols)
    room_of_view = np.full(len(poses), -1, np.int64)
    room_of_view[on_map] = inst[rows[on_map], cols[on_map]]
    # plane k + 1: the cells the views standing in room k see; plane 0: those of the other views
    reach = visible_cells(scene, poses, fov, max_range, blocked, room_of_view + 1, n_rooms + 1)
    seen = reach.any(axis=0)
    r, c = np.nonzero(gt)
    own = inst[r, c]
    from_inside = np.bincount(own[reach[own + 1, r, c]], minlength=n_rooms)
    got = np.bincount(inst[gt & seen], minlength=n_rooms)
    has = total > 0
    rooms_seen = int((from_inside[has] >= min_room_share * total[has]).sum())
    return {
        "coverage_area": float(got.sum() / total.sum()) if total.sum() else 0.0,
        "coverage_rooms": float(rooms_seen / has.sum()) if has.any() else 0.0,
        "rooms_seen": rooms_seen,
        "rooms": int(has.sum()),
    }


__all__ = ["view_coverage", "visible_cells", "MIN_ROOM_SHARE"]
