"""``nav_msgs/OccupancyGrid`` -> :class:`envs.maps.gridmap.GridMap`.

An OccupancyGrid stores row 0 at the bottom (``info.origin`` is the world pose of cell (0, 0)'s
outer corner, as a ``map_server`` map's ``origin``); the project's grid has row 0 on top, so
the rows are flipped and the origin converted with :func:`envs.maps.frames.ros_origin_to_grid_origin`
(the same grid ``read_ros_map`` gives for that map saved by ``map_saver``). Cell values: -1
unknown, 0..100 occupancy probability in percent. Walkable = ``0 <= v <= free_max``
(``map_saver``'s ``free`` threshold, 25 by default: the cells it writes as free, 254); unknown
cells are walkable only with ``unknown_as="free"``. The resolution is a float32 in the message;
it is read as the shortest decimal that gives that float32 (0.05, not 0.0500000007), as the
``map_server`` YAML it came from said.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from envs.bags.source import BagError, stamp_s
from envs.maps.frames import ros_origin_to_grid_origin
from envs.maps.gridmap import GridMap

#: ``map_saver``'s default: cells 0..25 are free.
FREE_MAX = 25


@dataclass(frozen=True)
class MapMessage:
    """One OccupancyGrid: the values (H, W) int8 with row 0 on top, metres per cell, the ROS
    origin (x, y, yaw), its frame and stamp (ns)."""

    values: np.ndarray
    resolution: float
    ros_origin: tuple[float, float, float]
    frame: str
    stamp_ns: int

    @property
    def geometry(self) -> tuple:
        """What must not change between two maps of one run: size, resolution, origin."""
        return (self.values.shape, round(self.resolution, 9), tuple(round(v, 6) for v in self.ros_origin))

    def shape_text(self) -> str:
        """``W x H cells, res m, origin [x, y]`` for messages."""
        h, w = self.values.shape
        return f"{w} x {h} cells, {round(self.resolution, 9)} m, origin {[round(v, 6) for v in self.ros_origin[:2]]}"


def quaternion_yaw(q: Any) -> float:
    """Yaw (radians, about +z) of a ``geometry_msgs/Quaternion``."""
    x, y, z, w = float(q.x), float(q.y), float(q.z), float(q.w)
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def map_message(msg: Any, where: str, stamp_ns: int) -> MapMessage:
    """Read one OccupancyGrid message (``where``: ``file topic`` for messages).

    Raises:
        BagError: zero size, a data length that is not width x height, a non-positive
            resolution or a rotated origin (one line naming the topic and stamp).
    """
    info = msg.info
    w, h = int(info.width), int(info.height)
    # the field is a float32: take the shortest decimal that gives it (0.05, not 0.0500000007)
    res = float(np.format_float_positional(np.float32(info.resolution), unique=True, trim="-"))
    data = np.asarray(msg.data, dtype=np.int8)
    at = f"{where} at {stamp_s(stamp_ns)}"
    if w <= 0 or h <= 0:
        raise BagError(f"{at}: OccupancyGrid is {w} x {h} cells; expected a non-empty map")
    if data.size != w * h:
        raise BagError(f"{at}: OccupancyGrid has {data.size} cells of data for {w} x {h}; expected {w * h}")
    if not (math.isfinite(res) and res > 0):
        raise BagError(f"{at}: OccupancyGrid resolution {res!r}; expected a positive number of metres per cell")
    p, q = info.origin.position, info.origin.orientation
    yaw = quaternion_yaw(q)
    if abs(yaw) > 1e-6:
        raise BagError(f"{at}: OccupancyGrid origin is rotated by {math.degrees(yaw):.3f} degrees; expected an "
                       f"axis-aligned map (yaw 0)")
    values = data.reshape(h, w)[::-1].copy()
    return MapMessage(values, res, (float(p.x), float(p.y), 0.0), str(msg.header.frame_id).lstrip("/"), stamp_ns)


def grid_from_map(m: MapMessage, unknown_as: str = "obstacle", free_max: int = FREE_MAX) -> GridMap:
    """The walkable grid of a map message (see the module doc)."""
    if unknown_as not in ("obstacle", "free"):
        raise ValueError(f"unknown_as={unknown_as!r}; expected obstacle or free")
    v = m.values
    walkable = (v >= 0) & (v <= int(free_max))
    if unknown_as == "free":
        walkable |= v < 0
    h = v.shape[0]
    return GridMap(walkable, m.resolution, ros_origin_to_grid_origin(m.ros_origin[:2], h, m.resolution))
