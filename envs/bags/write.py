"""The segmentation written back as a bag RViz and Foxglove show on the robot's map.

Topics (all stamped with the map's stamp, in the map's frame):

* ``/map`` (``nav_msgs/OccupancyGrid``): the input map as read;
* ``/segmentation`` (``nav_msgs/OccupancyGrid``): cell = class index (segment id in
  geometry mode), -1 where none (as ``segmentation.yaml``; only with at most 101 values):
  the numbers, for programs (values 0-6 all look white in RViz's Map display);
* ``/segmentation_rviz`` (``nav_msgs/OccupancyGrid``, written with ``/segmentation``): for
  the eye, in RViz's Map display with Color Scheme ``costmap`` (Foxglove: color mode
  costmap): class / segment ``k`` is the cell value :data:`RVIZ_VALUES` ``[k]`` (taken in turn
  beyond its length), colours that palette shows apart (blue, green, magenta, yellow, cyan,
  red, orange, purple, ...); cells with none are 0, which that scheme leaves transparent;
* ``/rooms`` (``visualization_msgs/MarkerArray``): per room segment a ``LINE_STRIP`` per
  polygon ring (namespace ``rooms``, the exterior then the holes; the class's colour, that of
  ``/segmentation_rviz`` when the caller passes :func:`rviz_colors`) and a
  ``TEXT_VIEW_FACING`` label (namespace ``room_names``: class name and area) at a point
  inside the room.

Formats: a ROS 1 ``.bag`` (``ros1``) or one MCAP file (``mcap``: ROS 2 CDR messages,
``ros2 bag play`` / Foxglove open it). The file is written beside its final name and renamed
when complete; a write that fails (a full disk) is an ``OSError`` naming that file.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from envs.bags.source import require_rosbags

FORMATS = ("ros1", "mcap")
#: ``/segmentation_rviz`` cell values in class order: far apart in RViz's ``costmap`` palette
#: (1 blue, 101 green, 100 magenta, -2 yellow, 99 cyan, 98 red, -65 orange, 50 purple, then
#: steps of the blue-red and red-yellow ramps).
RVIZ_VALUES = (1, 101, 100, -2, 99, 98, -65, 50, 25, 75, -96, -33, 12, 62, -112, -17)
#: Line width of room outlines and height of their names, metres.
LINE_M, TEXT_M = 0.05, 0.4


def costmap_rgb(value: int) -> tuple[int, int, int]:
    """The colour RViz's Map display gives an OccupancyGrid cell ``value`` (-128..127) with
    Color Scheme ``costmap`` (rviz ``map_display.cpp``, ``makeCostmapPalette``; 0 is
    transparent there, given here as black)."""
    u = int(value) & 0xFF
    if u == 0:
        return (0, 0, 0)
    if u <= 98:
        v = 255 * u // 100
        return (v, 0, 255 - v)
    if u == 99:
        return (0, 255, 255)
    if u == 100:
        return (255, 0, 255)
    if u <= 127:
        return (0, 255, 0)
    if u <= 254:
        return (255, 255 * (u - 128) // (254 - 128), 0)
    return (0x70, 0x89, 0x86)


def rviz_values(labels: np.ndarray) -> np.ndarray:
    """``/segmentation_rviz``'s cells: class / segment ``k`` -> ``RVIZ_VALUES[k % len]``, none -> 0."""
    v = np.asarray(RVIZ_VALUES, np.int64)
    return np.where(labels >= 0, v[np.maximum(labels, 0) % len(v)], 0)


def rviz_colors(n: int) -> list[tuple[int, int, int]]:
    """The colours of classes 0 .. n-1 in ``/segmentation_rviz`` (for the room outlines)."""
    return [costmap_rgb(RVIZ_VALUES[k % len(RVIZ_VALUES)]) for k in range(n)]


def _typestore(fmt: str):
    require_rosbags()
    from rosbags.typesys import Stores, get_typestore  # noqa: PLC0415

    return get_typestore(Stores.ROS1_NOETIC if fmt == "ros1" else Stores.ROS2_HUMBLE)


def _header(T, stamp_ns: int, frame: str, ros1: bool):
    st = T["builtin_interfaces/msg/Time"](sec=int(stamp_ns // 1_000_000_000), nanosec=int(stamp_ns % 1_000_000_000))
    if ros1:
        return T["std_msgs/msg/Header"](seq=0, stamp=st, frame_id=frame)
    return T["std_msgs/msg/Header"](stamp=st, frame_id=frame)


def _grid_msg(T, values_top_row_first: np.ndarray, resolution: float, ros_origin, stamp_ns: int, frame: str, ros1: bool):
    h, w = values_top_row_first.shape
    P, Q = T["geometry_msgs/msg/Point"], T["geometry_msgs/msg/Quaternion"]
    pose = T["geometry_msgs/msg/Pose"](position=P(x=float(ros_origin[0]), y=float(ros_origin[1]), z=0.0),
                                        orientation=Q(x=0.0, y=0.0, z=0.0, w=1.0))
    st = T["builtin_interfaces/msg/Time"](sec=int(stamp_ns // 1_000_000_000), nanosec=int(stamp_ns % 1_000_000_000))
    info = T["nav_msgs/msg/MapMetaData"](map_load_time=st, resolution=float(resolution), width=int(w), height=int(h),
                                          origin=pose)
    data = np.ascontiguousarray(values_top_row_first[::-1]).astype(np.int8).ravel()
    return T["nav_msgs/msg/OccupancyGrid"](header=_header(T, stamp_ns, frame, ros1), info=info, data=data)


def _color(T, rgb: Sequence[int], a: float = 1.0):
    return T["std_msgs/msg/ColorRGBA"](r=rgb[0] / 255.0, g=rgb[1] / 255.0, b=rgb[2] / 255.0, a=float(a))


def _marker(T, ros1: bool, header, ns: str, mid: int, mtype: int, points, color, text: str = "",
            position=(0.0, 0.0), scale=(LINE_M, 0.0, 0.0)):
    P, Q, V = T["geometry_msgs/msg/Point"], T["geometry_msgs/msg/Quaternion"], T["geometry_msgs/msg/Vector3"]
    M = T["visualization_msgs/msg/Marker"]
    kw: dict[str, Any] = dict(
        header=header, ns=ns, id=int(mid), type=int(mtype), action=0,
        pose=T["geometry_msgs/msg/Pose"](position=P(x=float(position[0]), y=float(position[1]), z=0.0),
                                         orientation=Q(x=0.0, y=0.0, z=0.0, w=1.0)),
        scale=V(x=float(scale[0]), y=float(scale[1]), z=float(scale[2])), color=color,
        lifetime=T["builtin_interfaces/msg/Duration"](sec=0, nanosec=0), frame_locked=False,
        points=[P(x=float(x), y=float(y), z=0.0) for x, y in points], colors=[], text=text,
        mesh_resource="", mesh_use_embedded_materials=False)
    if not ros1:
        kw["texture_resource"] = ""
        kw["texture"] = T["sensor_msgs/msg/CompressedImage"](header=header, format="", data=np.zeros(0, np.uint8))
        kw["uv_coordinates"] = []
        kw["mesh_file"] = T["visualization_msgs/msg/MeshFile"](filename="", data=np.zeros(0, np.uint8))
    fields = {f[0] for f in T["visualization_msgs/msg/Marker"].__dataclass_fields__.items()}
    return M(**{k: v for k, v in kw.items() if k in fields})


def room_markers(T, ros1: bool, rooms: dict, stamp_ns: int, frame: str,
                 colors: dict[str | None, tuple[int, int, int]]):
    """A ``MarkerArray`` of the rooms of a GeoJSON FeatureCollection (ROS ``x, y`` metres)."""
    import shapely.geometry  # noqa: PLC0415

    header = _header(T, stamp_ns, frame, ros1)
    markers, mid = [], 0
    for f in rooms["features"]:
        props = f["properties"]
        cls = props.get("class")
        col = _color(T, colors.get(cls, (200, 200, 200)))
        geom = shapely.geometry.shape(f["geometry"])
        polys = list(geom.geoms) if geom.geom_type == "MultiPolygon" else [geom]
        for poly in polys:
            for ring in [poly.exterior, *poly.interiors]:
                markers.append(_marker(T, ros1, header, "rooms", mid, 4, list(ring.coords), col))  # LINE_STRIP
                mid += 1
        inside = geom.representative_point()
        name = (cls or f"segment {props['segment']}").replace("_", " ")
        markers.append(_marker(T, ros1, header, "room_names", int(props["segment"]), 9, [], _color(T, (0, 0, 0)),
                               text=f"{name} {props['area_m2']:.1f} m2", position=(inside.x, inside.y),
                               scale=(0.0, 0.0, TEXT_M)))  # TEXT_VIEW_FACING
    return T["visualization_msgs/msg/MarkerArray"](markers=markers)


def write_segmentation_bag(path: str | Path, fmt: str, frame: str, stamp_ns: int, resolution: float, ros_origin,
                           occupancy: np.ndarray, segmentation: np.ndarray | None, rooms: dict,
                           colors: dict[str | None, tuple[int, int, int]]) -> Path:
    """Write the bag (see the module doc).

    Args:
        path: the output file (``.bag`` for ``ros1``, ``.mcap`` for ``mcap``).
        fmt: ``ros1`` or ``mcap``.
        frame: the map frame; stamp_ns: the messages' stamp and record time (ns).
        resolution, ros_origin: the map's metres per cell and ROS origin (x, y[, yaw]).
        occupancy: (H, W) int8 the input map's cell values (-1, 0..100), row 0 on top.
        segmentation: (H, W) int class index / segment id, -1 none, row 0 on top, or None.
        rooms: the GeoJSON FeatureCollection of ``rooms.geojson``.
        colors: RGB per class name (None: geometry mode's rooms).

    Returns:
        The path written.
    """
    if fmt not in FORMATS:
        raise ValueError(f"bag_options.out_format={fmt!r}; expected one of {list(FORMATS)}, auto or none")
    path = Path(path)
    T = _typestore(fmt).types
    ros1 = fmt == "ros1"
    msgs = [("/map", "nav_msgs/msg/OccupancyGrid",
             _grid_msg(T, occupancy, resolution, ros_origin, stamp_ns, frame, ros1))]
    if segmentation is not None:
        msgs.append(("/segmentation", "nav_msgs/msg/OccupancyGrid",
                     _grid_msg(T, np.where(segmentation < 0, -1, segmentation), resolution, ros_origin, stamp_ns,
                               frame, ros1)))
        msgs.append(("/segmentation_rviz", "nav_msgs/msg/OccupancyGrid",
                     _grid_msg(T, rviz_values(segmentation), resolution, ros_origin, stamp_ns, frame, ros1)))
    msgs.append(("/rooms", "visualization_msgs/msg/MarkerArray", room_markers(T, ros1, rooms, stamp_ns, frame, colors)))
    store = _typestore(fmt)
    work = Path(tempfile.mkdtemp(prefix=f".{path.name}.", dir=path.parent))
    try:
        if ros1:
            from rosbags.rosbag1 import Writer  # noqa: PLC0415

            tmp = work / path.name
            with Writer(tmp) as w:
                for topic, typ, msg in msgs:
                    c = w.add_connection(topic, typ, typestore=store, latching=1)
                    w.write(c, stamp_ns, store.serialize_ros1(msg, typ))
        else:
            from rosbags.rosbag2 import StoragePlugin, Writer  # noqa: PLC0415

            folder = work / "bag"
            with Writer(folder, version=9, storage_plugin=StoragePlugin.MCAP) as w:
                for topic, typ, msg in msgs:
                    c = w.add_connection(topic, typ, typestore=store)
                    w.write(c, stamp_ns, store.serialize_cdr(msg, typ))
            found = sorted(folder.glob("*.mcap"))
            if len(found) != 1:
                raise RuntimeError(f"{path}: the MCAP writer made {len(found)} files; expected one")
            tmp = found[0]
        os.replace(tmp, path)
    except OSError as e:
        if e.filename:
            raise
        # a failed write (a full disk) names no file: name the one being written
        raise OSError(e.errno, e.strerror or str(e), str(path)) from None
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return path
