"""``python -m benchmark.commands.bag_example OUT``: example robot recordings for
``roomseg-segment bag=...`` (the example building of ``benchmark.commands.segment_example``).

A robot drives the building's autotrace route (``benchmark.viewpoints.Autotrace``: 1 m
between points, 3 headings 90 degrees apart), one view every 0.1 s, and at each view
publishes the class of the room it stands in. Written into ``OUT``:

* the example's files (``map.yaml`` + ``map.pgm``, ``gt.png`` + ``gt.json``; see
  ``segment_example``) for scoring with ``gt=OUT/gt.png gt_format=label``;
* ``run.bag``: ROS 1; ``/map`` (OccupancyGrid), ``/tf`` (map -> odom -> base_link),
  ``/tf_static`` (base_link -> camera_link -> camera_optical_frame), ``/room_label``
  (``std_msgs/String``, no header: placed at base_link);
* ``run_mcap/``: ROS 2, MCAP storage; the same, with the labels as
  ``vision_msgs/Classification`` on ``/room_class`` stamped in ``camera_optical_frame``.

The tf tree and what it leaves out: :mod:`envs.bags.synthetic`.
"""

from __future__ import annotations

import argparse
import shutil
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

#: Where the example's views start and how far apart they are.
T0_NS, STEP_NS = 1_700_000_000_000_000_000, 100_000_000


@dataclass
class ExampleRun:
    """The run: the map image (ROS pixel values) and cell values, the grid, the views' world
    poses (N, 3) and ROS route (N, 3), their class names and stamps."""

    image: np.ndarray
    occupancy: np.ndarray
    grid: object
    poses: np.ndarray
    route: np.ndarray
    labels: list
    stamps: np.ndarray
    resolution: float
    ros_origin: tuple[float, float]


def example_run(nx: int = 3, ny: int = 2, room_m: float = 4.0, resolution: float = 0.05,
                ros_origin: tuple[float, float] = (-3.25, 1.5)) -> ExampleRun:
    from benchmark.commands.segment_example import FREE, WALL, example_map  # noqa: PLC0415
    from benchmark.viewpoints import Autotrace  # noqa: PLC0415
    from envs.maps.frames import world_to_ros  # noqa: PLC0415
    from envs.maps.gridmap import GridMap  # noqa: PLC0415
    from envs.world.classes import PAPER_CLASSES  # noqa: PLC0415

    img, rooms, classes, gorigin, _ = example_map(nx, ny, room_m, resolution, ros_origin)
    grid = GridMap(img == FREE, resolution, gorigin)
    occ = np.where(img == FREE, 0, np.where(img == WALL, 100, -1)).astype(np.int8)
    poses = Autotrace().generate(grid)
    x, y, th = world_to_ros(poses[:, 0], poses[:, 1], poses[:, 2])
    r, c = grid.world_to_cell(poses[:, 0], poses[:, 1])
    labels = [PAPER_CLASSES[classes[rooms[a, b]]] for a, b in zip(r, c)]
    route = np.column_stack([x, y, th]).astype(float)
    stamps = T0_NS + np.arange(len(route), dtype=np.int64) * STEP_NS
    return ExampleRun(img, occ, grid, poses, route, labels, stamps, resolution, tuple(ros_origin))


def write_bag_example(out: str | Path) -> dict[str, Path]:
    """Write the example (see the module doc) into ``out``; returns the bags' paths."""
    from benchmark.commands.segment_example import write_example  # noqa: PLC0415
    from envs.bags.synthetic import RobotRun, write_robot_bag  # noqa: PLC0415
    from envs.world.classes import PAPER_CLASSES  # noqa: PLC0415

    out = Path(out)
    write_example(out)
    run = example_run()
    paths = {"ros1": out / "run.bag", "mcap": out / "run_mcap"}
    for fmt, label_type in (("ros1", "string"), ("mcap", "classification")):
        p = paths[fmt]
        if p.is_dir():
            shutil.rmtree(p)
        elif p.exists():
            p.unlink()
        write_robot_bag(p, fmt, RobotRun(run.occupancy, run.resolution, run.ros_origin, run.route, run.stamps,
                                         labels=run.labels, classes=PAPER_CLASSES, label_type=label_type))
    return paths


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out", help="output folder (created)")
    a = ap.parse_args(argv)
    try:
        paths = write_bag_example(a.out)
    except ImportError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    print(f"wrote {paths['ros1']} and {paths['mcap']}; then:\n"
          f"  roomseg-segment bag={paths['ros1']} out={Path(a.out) / 'segmented'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
