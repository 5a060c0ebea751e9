"""A robot run through the example building (``benchmark.commands.segment_example``) for the
bag tests: its map, the autotrace route with one view per pose (each labelled with the class
of the room it stands in, or a small image of that class's colour), written as files for
``roomseg-segment`` and as bags, and a colour classifier for the images."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from benchmark.commands.bag_example import example_run
from benchmark.commands.segment_example import FREE_THRESH, OCCUPIED_THRESH
from envs.bags.synthetic import RobotRun
from envs.maps.gridmap import GridMap
from envs.maps.ros import write_ros_map
from envs.world.classes import PAPER_CLASSES, class_colors

RES, ORIGIN = 0.05, (-3.25, 1.5)
T0 = 1_700_000_000_000_000_000
STEP_NS = 100_000_000
CLASSES_ARG = "classes=[" + ",".join(PAPER_CLASSES) + "]"
COLOURS = np.array(class_colors(PAPER_CLASSES), np.uint8)


@dataclass
class House:
    grid: GridMap
    image: np.ndarray
    occupancy: np.ndarray
    poses: np.ndarray  # (N, 3) world x, z, yaw
    route: np.ndarray  # (N, 3) ROS x, y, theta
    labels: list[str]
    stamps: np.ndarray

    def run(self, **kw) -> RobotRun:
        kw.setdefault("labels", self.labels)
        kw.setdefault("classes", PAPER_CLASSES)
        return RobotRun(self.occupancy, RES, ORIGIN, self.route, self.stamps, **kw)

    def view_image(self, i: int, size: tuple[int, int] = (12, 16)) -> np.ndarray:
        """A small image filled with the view's class colour (with a gradient row, so that
        raw and PNG transport are checked pixel for pixel)."""
        img = np.empty((*size, 3), np.uint8)
        img[:] = COLOURS[PAPER_CLASSES.index(self.labels[i])]
        img[0, :, 0] = np.arange(size[1], dtype=np.uint8) * 7
        return img


def house() -> House:
    r = example_run(resolution=RES, ros_origin=ORIGIN)
    assert r.stamps[0] == T0 and r.stamps[1] - r.stamps[0] == STEP_NS
    return House(r.grid, r.image, r.occupancy, r.poses, r.route, r.labels, r.stamps)


def write_files(h: House, d: Path) -> list[str]:
    """The same run as files; returns the ``roomseg-segment`` arguments that read them."""
    d.mkdir(parents=True, exist_ok=True)
    write_ros_map(d / "map.yaml", h.image, RES, (*ORIGIN, 0.0), occupied_thresh=OCCUPIED_THRESH,
                  free_thresh=FREE_THRESH, image_name="map.pgm")
    (d / "poses.csv").write_text("id,x,y,theta\n" + "".join(
        f"v{i},{float(a)!r},{float(b)!r},{float(t)!r}\n" for i, (a, b, t) in enumerate(h.route)))
    (d / "labels.csv").write_text("id,label\n" + "".join(f"v{i},{lab}\n" for i, lab in enumerate(h.labels)))
    return [f"map={d}/map.yaml", f"poses={d}/poses.csv", "frame=ros", f"labels={d}/labels.csv", CLASSES_ARG]


class ColourClassifier:
    """Class = the paper class whose colour is nearest the image's median colour (the test
    images are filled with their class's colour): an image classifier with a known answer."""

    def __init__(self, classes=None, **_labels_file_options):
        self.classes = tuple(classes or PAPER_CLASSES)
        self.seen = 0

    def predict_proba(self, observations):
        out = np.zeros((len(observations), len(self.classes)))
        for i, o in enumerate(observations):
            med = np.median(o.image.reshape(-1, 3), axis=0)
            k = int(np.argmin(((COLOURS.astype(float) - med) ** 2).sum(1)))
            out[i, self.classes.index(PAPER_CLASSES[k])] = 1.0
        return out
