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


def map_stamp_ns(value) -> int | None:
    """``bag_options.map_stamp`` (seconds, or None) as nanoseconds.

    Raises:
        BagError: a value that is not a finite number of seconds (NaN, inf, text), one line
            naming the option."""
    if value is None:
        return None
    try:
        s = float(value)
    except (TypeError, ValueError):
        s = math.nan
    if isinstance(value, bool) or not math.isfinite(s) or s < 0:
        raise BagError(f"bag_options.map_stamp={value!r}; expected seconds since the epoch (a finite number >= 0, "
                       f"e.g. one of the map stamps roomseg bag-info lists), or null for the last map")
    return int(round(s * 1e9))


def stamps_text(stamps: list[int], most: int = 12) -> str:
    """Stamps as ``[a s, b s, ...]`` for messages: all of them up to ``most``, else the first
    and last few with the count left out between."""
    text = [stamp_s(int(s)) for s in stamps]
    if len(text) > most:
        half = most // 2
        text = text[:half] + [f"... ({len(text) - 2 * half} more)"] + text[-half:]
    return "[" + ", ".join(text) + "]"


def map_before(stamps: list[int], want_ns: int | None, where: str) -> int:
    """The index of the map a run uses among the map messages' stamps (in bag order): the last
    one, or the last at or before ``want_ns`` (``bag_options.map_stamp``).

    Raises:
        BagError: no map at all, or no map at or before ``want_ns`` (one line listing the map
            stamps: a later map is never taken in its place)."""
    if not stamps:
        raise BagError(f"{where}: no OccupancyGrid message")
    if want_ns is None:
        return len(stamps) - 1
    ok = [i for i, s in enumerate(stamps) if s <= want_ns]
    if not ok:
        raise BagError(f"{where}: bag_options.map_stamp={want_ns / 1e9:.9f} is before every map; the map stamps are "
                       f"{stamps_text(stamps)}; expected a stamp at or after the first map")
    return max(ok, key=lambda i: (stamps[i], i))


def map_frame_of(m: MapMessage, given: str | None, where: str) -> str:
    """The frame the views' poses are taken in: the map message's own frame.
    ``bag_options.map_frame`` names it for a map message without a frame, or repeats it.

    Raises:
        BagError: ``given`` differs from the frame the map message names (the views would be
            placed in another frame than the map is drawn in, off by that frame's drift, and
            the output map relabelled), one line naming both."""
    given = (given or "").strip().lstrip("/") or None
    own = m.frame.strip().lstrip("/")
    if given is not None and own and given != own:
        raise BagError(f"{where}: bag_options.map_frame={given} but the map is in frame {own!r}; views placed in "
                       f"{given!r} would be off the map by the transform between the two (odometry drift), so "
                       f"expected map_frame={own} or unset (record tf {own} -> ... -> the camera, or a pose topic "
                       f"in {own!r})")
    return given or own or "map"


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
