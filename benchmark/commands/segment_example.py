"""``python -m benchmark.commands.segment_example OUT``: write example inputs for
``roomseg-segment`` (the map the tests use), then print the command that segments them.

A building of ``nx`` x ``ny`` square rooms (``room_m`` metres a side) with 0.1 m walls and a
1.0 m door in the middle of every wall between two rooms, drawn as a ROS ``map_server`` map
(trinary: free 254, walls 0, unknown 205 outside; ``origin`` not at zero) with:

* ``map.yaml`` + ``map.pgm``: the occupancy map;
* ``poses.csv``: ``id, x, y, theta``: 16 views per room: 4 spots (a quarter of the side in
  from each corner) x 4 headings (0, 90, 180, 270 degrees project yaw), in the ROS frame
  (metres, radians counter-clockwise from +x);
* no wall between the two top-right rooms (an open-plan border: the geometric segmenters
  cannot find it, the views' labels can);
* ``labels.csv``: ``id, label``: each view's room class;
* ``gt.png`` (+ ``gt.json``): the ground-truth class map (``write_label_png``; rooms =
  the free pixels inside each room's walls, doorways go to the room on their left/lower
  side) for ``gt=... gt_format=label``.

Room classes cycle through the paper's seven so that no two neighbouring rooms share one
(room (i, j), column i from the left and row j from the bottom, has class
``(i + 3 j) mod 7``).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from benchmark.commands import cli
from envs.atomic import atomic_write_text
from envs.maps.frames import ros_origin_to_grid_origin, world_to_ros
from envs.maps.gridmap import GridMap
from envs.maps.label_png import write_label_png
from envs.maps.ros import write_ros_map_rows
from envs.maps.scene import MAX_MAP_PIXELS
from envs.world.classes import PAPER_CLASSES

#: ROS map thresholds written to the example YAML (ROS map_saver's).
FREE_THRESH, OCCUPIED_THRESH = 0.196, 0.65
#: Pixel values of the example image: free, wall, unknown (ROS map_saver's).
FREE, WALL, UNKNOWN = 254, 0, 205
WALL_M, DOOR_M, MARGIN_M = 0.1, 1.0, 0.5
HEADINGS_DEG = (0, 90, 180, 270)
#: View positions in each room, as fractions of the room side from its bottom-left corner.
SPOTS = ((0.25, 0.25), (0.75, 0.25), (0.25, 0.75), (0.75, 0.75))


@dataclass(frozen=True)
class Example:
    """What :func:`write_example` wrote and the answers a test can check.

    Attributes:
        map_yaml, poses, labels, gt: the files.
        grid: the map as read back (walkable = free pixels).
        rooms: (H, W) int32 room index of each free pixel, -1 elsewhere (door pixels go to
            the room on their left / lower side).
        room_classes: class index of each room (into ``PAPER_CLASSES``).
        ros_origin: the YAML's origin (x, y, yaw).
    """

    map_yaml: Path
    poses: Path
    labels: Path
    gt: Path
    grid: GridMap
    rooms: np.ndarray
    room_classes: np.ndarray
    ros_origin: tuple[float, float, float]


def room_class(i: int, j: int) -> int:
    """Class index of room (column i, row j from the bottom)."""
    return (i + 3 * j) % len(PAPER_CLASSES)


def _check(nx: int, ny: int, room_m: float, resolution: float) -> None:
    if nx < 1 or ny < 1 or room_m < 4 * WALL_M + DOOR_M or resolution <= 0:
        raise ValueError(f"example building needs nx, ny >= 1, room_m >= {4 * WALL_M + DOOR_M} m and a resolution "
                         f"> 0, got {nx}, {ny}, {room_m}, {resolution}")


def example_shape(nx: int = 3, ny: int = 2, room_m: float = 4.0, resolution: float = 0.05) -> tuple[int, int]:
    """(H, W) pixels of the example building's map (arguments as :func:`example_map`)."""
    _check(nx, ny, room_m, resolution)
    return int(round((ny * room_m + 2 * MARGIN_M) / resolution)), int(round((nx * room_m + 2 * MARGIN_M) / resolution))


def example_rows(nx: int = 3, ny: int = 2, room_m: float = 4.0, resolution: float = 0.05,
                 ros_origin: tuple[float, float] = (-3.25, 1.5), open_plan: bool = True, rows: int = 256,
                 with_rooms: bool = True) -> Iterator[tuple[np.ndarray, np.ndarray | None]]:
    """The example building's image and room index by bands of ``rows`` rows, top band first
    (arguments as :func:`example_map`): memory per band, never per map, so a 16000 x 16000 px
    map is drawn in a few tens of MB. Each pixel is decided from its column's and its row's
    coordinates alone, so the bands put together are :func:`example_map`'s arrays whatever
    ``rows`` is.

    Yields:
        (image (h, W) uint8 ROS pixel values, rooms (h, W) int32 or None without
        ``with_rooms``), h <= ``rows``.
    """
    H, W = example_shape(nx, ny, room_m, resolution)
    if rows < 1:
        raise ValueError(f"example rows: band height {rows}; expected >= 1")
    x0, z0 = ros_origin_to_grid_origin(ros_origin, H, resolution)
    bx, by = ros_origin[0] + MARGIN_M, ros_origin[1] + MARGIN_M  # building's bottom-left, world metres
    # pixel-centre coordinates relative to the building corner, in metres: (1, W) per column
    U = (x0 + (np.arange(W) + 0.5) * resolution - bx)[None, :]
    # per column: inside along x, distance to the nearest vertical wall line (multiples of room_m)
    in_u = (U > 0) & (U < nx * room_m)
    wall_u = np.abs(U - np.round(U / room_m) * room_m) < WALL_M / 2  # vertical walls (x = k room_m)
    ku = np.round(U / room_m)
    mid_v = np.abs((U % room_m) - room_m / 2) < DOOR_M / 2  # along a horizontal wall, its middle
    inner_u = (ku > 0) & (ku < nx)
    bld_u = (U > -WALL_M / 2) & (U < nx * room_m + WALL_M / 2)
    gap_u = wall_u & (ku == nx - 1)
    ci = np.clip(np.floor(U / room_m), 0, nx - 1).astype(np.int64)
    ci_door = np.clip(ku - 1, 0, nx - 1)
    for r0 in range(0, H, rows):
        # (h, 1) per row of this band
        V = (z0 - (np.arange(r0, min(r0 + rows, H)) + 0.5) * resolution - by)[:, None]
        inside = in_u & (V > 0) & (V < ny * room_m)
        wall_v = np.abs(V - np.round(V / room_m) * room_m) < WALL_M / 2  # horizontal walls
        kv = np.round(V / room_m)
        mid_u = np.abs((V % room_m) - room_m / 2) < DOOR_M / 2  # along a vertical wall, its middle
        # door openings: on internal walls, within DOOR_M/2 of the wall segment's middle
        door_u = wall_u & mid_u & inner_u & ~wall_v
        door_v = wall_v & mid_v & ((kv > 0) & (kv < ny)) & ~wall_u
        wall = inside & ((wall_u & ~door_u) | (wall_v & ~door_v))
        if open_plan and nx >= 2:  # no wall between the two top-right rooms (open plan), except at its ends
            wall &= ~(gap_u & ((V > (ny - 1) * room_m + WALL_M / 2) & (V < ny * room_m - WALL_M / 2)))
        building = bld_u & (V > -WALL_M / 2) & (V < ny * room_m + WALL_M / 2)
        free = inside & ~wall
        img = np.full(free.shape, UNKNOWN, np.uint8)
        img[free] = FREE
        img[wall | (building & ~inside)] = WALL
        if not with_rooms:
            yield img, None
            continue
        cj = np.clip(np.floor(V / room_m), 0, ny - 1).astype(np.int64)
        # a door pixel lies on a wall line: give it to the room left of / below the wall
        cii = np.where(door_u, ci_door, ci).astype(np.int64)
        cjj = np.where(door_v, np.clip(kv - 1, 0, ny - 1), cj).astype(np.int64)
        yield img, np.where(free, cii + nx * cjj, -1).astype(np.int32)


def _classes_centres(nx: int, ny: int, room_m: float, ros_origin: tuple[float, float]):
    bx, by = ros_origin[0] + MARGIN_M, ros_origin[1] + MARGIN_M
    classes = np.array([room_class(k % nx, k // nx) for k in range(nx * ny)], np.int64)
    centres = np.array([(bx + (k % nx + 0.5) * room_m, by + (k // nx + 0.5) * room_m) for k in range(nx * ny)])
    return classes, centres


def example_map(nx: int = 3, ny: int = 2, room_m: float = 4.0, resolution: float = 0.05,
                ros_origin: tuple[float, float] = (-3.25, 1.5), open_plan: bool = True):
    """The example building as arrays (the bands of :func:`example_rows` put together).

    Args:
        nx, ny: rooms across (x) and up (y).
        room_m: room side, metres (wall centre to wall centre).
        resolution: metres per pixel.
        ros_origin: ROS ``origin`` (x, y) of the map's bottom-left corner, metres.
        open_plan: leave out the wall between the two top-right rooms (an open-plan border
            that only the views' labels can find).

    Returns:
        (image (H, W) uint8 ROS pixel values, rooms (H, W) int32, room classes (R,),
        grid origin (x0, z0), room centres (R, 2) world x, y metres).
    """
    H, _ = example_shape(nx, ny, room_m, resolution)
    bands = list(example_rows(nx, ny, room_m, resolution, ros_origin, open_plan))
    img = np.concatenate([b[0] for b in bands])
    rooms = np.concatenate([b[1] for b in bands])
    classes, centres = _classes_centres(nx, ny, room_m, ros_origin)
    return img, rooms, classes, ros_origin_to_grid_origin(ros_origin, H, resolution), centres


@dataclass(frozen=True)
class ExampleInputs:
    """What :func:`write_example_inputs` wrote: ``map_yaml`` (+ ``map.pgm``), ``poses``,
    ``labels`` (paths); ``shape`` (H, W) pixels; ``views`` how many poses."""

    map_yaml: Path
    poses: Path
    labels: Path
    shape: tuple[int, int]
    views: int


def write_example_inputs(out: str | Path, nx: int = 3, ny: int = 2, room_m: float = 4.0, resolution: float = 0.05,
                         ros_origin: tuple[float, float] = (-3.25, 1.5), open_plan: bool = True) -> ExampleInputs:
    """Write the example's map, poses and labels into ``out`` (created), not its ground truth:
    the map by bands of rows, so memory stays a few tens of MB whatever the map's size (80 x 80
    rooms of 10 m at 0.05 m/px: 16020 x 16020 px). The same bytes as :func:`write_example`."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    shape = example_shape(nx, ny, room_m, resolution)
    origin3 = (float(ros_origin[0]), float(ros_origin[1]), 0.0)
    bands = (img for img, _ in example_rows(nx, ny, room_m, resolution, ros_origin, open_plan, with_rooms=False))
    yaml_path = write_ros_map_rows(out / "map.yaml", shape, bands, resolution, origin3,
                                   occupied_thresh=OCCUPIED_THRESH, free_thresh=FREE_THRESH, image_name="map.pgm")
    classes, centres = _classes_centres(nx, ny, room_m, ros_origin)
    lines_p, lines_l = ["id,x,y,theta"], ["id,label"]
    for k, (cx, cy) in enumerate(centres):
        for s, (fx, fy) in enumerate(SPOTS):
            for yaw in HEADINGS_DEG:
                x, y, theta = world_to_ros(cx + (fx - 0.5) * room_m, cy + (fy - 0.5) * room_m, yaw)
                vid = f"r{k:03d}_s{s}_h{yaw:03d}"
                lines_p.append(f"{vid},{float(x):.4f},{float(y):.4f},{float(theta):.6f}")
                lines_l.append(f"{vid},{PAPER_CLASSES[classes[k]]}")
    atomic_write_text(out / "poses.csv", "\n".join(lines_p) + "\n")
    atomic_write_text(out / "labels.csv", "\n".join(lines_l) + "\n")
    return ExampleInputs(map_yaml=yaml_path, poses=out / "poses.csv", labels=out / "labels.csv", shape=shape,
                         views=len(lines_p) - 1)


def write_example(out: str | Path, nx: int = 3, ny: int = 2, room_m: float = 4.0, resolution: float = 0.05,
                  ros_origin: tuple[float, float] = (-3.25, 1.5), open_plan: bool = True) -> Example:
    """Write the example inputs into ``out`` (created); see the module doc. Holds map-sized
    answers (room index, ground truth): for a map too large for that, use
    :func:`write_example_inputs`.

    Returns:
        An :class:`Example` with the paths and the rooms' answers.
    """
    out = Path(out)
    ins = write_example_inputs(out, nx, ny, room_m, resolution, ros_origin, open_plan)
    img, rooms, classes, grid_origin, _ = example_map(nx, ny, room_m, resolution, ros_origin, open_plan)
    origin3 = (float(ros_origin[0]), float(ros_origin[1]), 0.0)
    grid = GridMap(img == FREE, resolution, grid_origin)
    semantic = np.where(rooms >= 0, classes[np.maximum(rooms, 0)], -1)
    gt = write_label_png(out / "gt.png", semantic, PAPER_CLASSES, walkable=grid.walkable, resolution=resolution,
                         origin=grid_origin, legend=False)
    return Example(map_yaml=ins.map_yaml, poses=ins.poses, labels=ins.labels, gt=gt, grid=grid,
                   rooms=rooms, room_classes=classes, ros_origin=origin3)


def _rooms(text: str) -> tuple[int, int]:
    try:
        a, b = (int(t) for t in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"--rooms {text!r}: expected NXxNY, e.g. 3x2") from None
    return a, b


def main(argv: list[str] | None = None) -> int:
    ap = cli.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out", type=Path, help="folder to write the example inputs into")
    ap.add_argument("--rooms", type=_rooms, default=(3, 2), help="rooms across x up, e.g. 3x2 (default)")
    ap.add_argument("--room-m", type=float, default=4.0, help="room side, metres (default 4)")
    ap.add_argument("--resolution", type=float, default=0.05, help="metres per pixel (default 0.05)")
    ap.add_argument("--no-gt", action="store_true",
                    help="map, poses and labels only, written by bands of rows in tens of MB at any size "
                         "(80x80 rooms of 10 m: 16020 x 16020 px); no gt.png")
    a = ap.parse_args(argv)
    try:
        if a.no_gt:
            ins = write_example_inputs(a.out, *a.rooms, room_m=a.room_m, resolution=a.resolution)
            shape, gt = ins.shape, None
        else:
            ex = write_example(a.out, *a.rooms, room_m=a.room_m, resolution=a.resolution)
            shape, gt = ex.grid.shape, ex.gt
    except (ValueError, OSError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    h, w = shape
    d = a.out
    n_rooms = a.rooms[0] * a.rooms[1]
    print(f"wrote {d / 'map.yaml'} ({w} x {h} px, {a.resolution} m/px, {n_rooms} rooms), {d / 'poses.csv'} and "
          f"{d / 'labels.csv'} ({n_rooms * len(SPOTS) * len(HEADINGS_DEG)} views)" + (f", {gt}" if gt else ""))
    print(f"segment it: roomseg-segment map={d}/map.yaml poses={d}/poses.csv frame=ros labels={d}/labels.csv "
          + (f"gt={d}/gt.png gt_format=label " if gt else "")
          + (f"max_map_pixels={h * w} " if h * w > MAX_MAP_PIXELS else "") + f"out={d}/segmented")
    return 0


if __name__ == "__main__":
    sys.exit(main())
