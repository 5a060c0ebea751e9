"""``python -m benchmark.commands.maintainer.bag_memory``: peak memory of ``roomseg-segment bag=...`` on a
long recording (issue 36: a one-hour bag with 30,000 images in under 1 GB).

Writes a ROS 1 bag (or MCAP) of a robot driving the autotrace route of the example building
(``benchmark.commands.segment_example``; 4 x 3 rooms of 5 m by default) for ``--hours`` with
``--images`` JPEG camera images (``--size`` pixels, each filled with the colour of the class of
the room the robot stands in, with a gradient), a tf tree at every image (map -> odom ->
base_link -> camera, :mod:`envs.bags.synthetic`) and CameraInfo; then runs ``roomseg-segment
bag=...`` in a child process and prints the child's peak resident memory (``ru_maxrss``), its
time, the views kept, and the same for a bag of ``--small`` images as the baseline (what
Python, NumPy, numba and Hydra take before any image). The classifier is
:class:`ClassColourClassifier`, which reads the class back from the painted colour (this
measures the bag path, not a network's memory: a CNN adds its weights once, as for files).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from envs.world.classes import PAPER_CLASSES, class_colors

COLOURS = np.array(class_colors(PAPER_CLASSES), np.uint8)


class ClassColourClassifier:
    """Class = the paper class whose colour is nearest the image's median colour (the
    measurement's images are painted with their room's class colour)."""

    def __init__(self, classes=None, **_unused):
        self.classes = tuple(classes or PAPER_CLASSES)

    def predict_proba(self, observations):
        out = np.zeros((len(observations), len(self.classes)))
        for i, o in enumerate(observations):
            med = np.median(o.image.reshape(-1, 3), axis=0)
            k = int(np.argmin(((COLOURS.astype(float) - med) ** 2).sum(1)))
            if PAPER_CLASSES[k] in self.classes:
                out[i, self.classes.index(PAPER_CLASSES[k])] = 1.0
            else:
                out[i] = 1.0 / len(self.classes)
        return out


def long_route(n: int, nx: int, ny: int, room_m: float):
    """``n`` poses along the autotrace route of the example building, evenly in time:
    (occupancy (H, W) int8, route (n, 3) ROS x, y, theta, class name per pose)."""
    from benchmark.commands.segment_example import FREE, WALL, example_map  # noqa: PLC0415
    from benchmark.viewpoints import Autotrace  # noqa: PLC0415
    from envs.maps.frames import world_to_ros  # noqa: PLC0415
    from envs.maps.gridmap import GridMap  # noqa: PLC0415

    img, rooms, classes, gorigin, _ = example_map(nx, ny, room_m, 0.05, (-3.25, 1.5))
    grid = GridMap(img == FREE, 0.05, gorigin)
    occ = np.where(img == FREE, 0, np.where(img == WALL, 100, -1)).astype(np.int8)
    p = Autotrace().generate(grid)
    x, y, th = world_to_ros(p[:, 0], p[:, 1], p[:, 2])
    key = np.column_stack([x, y, np.unwrap(th)])
    s = np.linspace(0, len(key) - 1, n)
    route = np.column_stack([np.interp(s, np.arange(len(key)), key[:, k]) for k in range(3)])
    from envs.maps.frames import ros_to_world  # noqa: PLC0415

    wx, wz, _ = ros_to_world(route[:, 0], route[:, 1], route[:, 2])
    r, c = grid.world_to_cell(wx, wz)
    room = rooms[np.clip(r, 0, rooms.shape[0] - 1), np.clip(c, 0, rooms.shape[1] - 1)]
    names = [PAPER_CLASSES[classes[k]] if k >= 0 else "" for k in room]
    return occ, route, names


def write_long_bag(path: Path, fmt: str, n: int, hours: float, size: tuple[int, int], nx: int, ny: int,
                   room_m: float) -> Path:
    from envs.bags.synthetic import RobotRun, write_robot_bag  # noqa: PLC0415

    occ, route, names = long_route(n, nx, ny, room_m)
    stamps = 1_700_000_000_000_000_000 + np.round(np.arange(n) * (hours * 3600e9 / n)).astype(np.int64)
    h, w = size
    grad = np.linspace(0, 60, w).astype(np.uint8)

    def image(i: int) -> np.ndarray:
        img = np.empty((h, w, 3), np.uint8)
        img[:] = COLOURS[PAPER_CLASSES.index(names[i])] if names[i] else 0
        img[: h // 8] = grad[None, :, None]
        return img

    run = RobotRun(occ, 0.05, (-3.25, 1.5), route, stamps, image=image, image_format="jpeg", hfov_deg=90.0)
    return write_robot_bag(path, fmt, run)


def measure(bag: Path, out: Path) -> dict:
    """Run ``roomseg-segment bag=...`` in a child; its peak RSS (MiB), wall time and summary."""
    cmd = [sys.executable, "-c",
           "import resource, sys; from benchmark.commands.segment import main; rc = main(sys.argv[1:]); "
           "print('MAXRSS_KB', resource.getrusage(resource.RUSAGE_SELF).ru_maxrss); sys.exit(rc)",
           f"bag={bag}", f"out={out}", "overwrite=true", "off_map=drop", "bag_options.progress=false",
           "classifier._target_=benchmark.commands.maintainer.bag_memory.ClassColourClassifier", "classifier.path=none"]
    t = time.perf_counter()
    p = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t
    if p.returncode != 0:
        raise RuntimeError(f"roomseg-segment failed: {p.stderr.strip().splitlines()[-1] if p.stderr.strip() else p.returncode}")
    kb = int(next(line.split()[1] for line in p.stdout.splitlines() if line.startswith("MAXRSS_KB")))
    s = json.loads((out / "summary.json").read_text())
    return {"peak_rss_mib": round(kb / 1024, 1), "wall_s": round(wall, 1), "n_bag_views": s["n_bag_views"],
            "n_kept_views": s["n_kept_views"], "n_segments": s["n_segments"]}


def _size_mib(p: Path) -> float:
    files = [p] if p.is_file() else [f for f in p.rglob("*") if f.is_file()]
    return round(sum(f.stat().st_size for f in files) / 2**20, 1)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--images", type=int, default=30000)
    ap.add_argument("--small", type=int, default=300, help="images of the baseline bag")
    ap.add_argument("--hours", type=float, default=1.0)
    ap.add_argument("--size", default="240x320", help="image height x width, pixels")
    ap.add_argument("--format", default="ros1", choices=["ros1", "mcap", "sqlite3"])
    ap.add_argument("--rooms", default="4x3")
    ap.add_argument("--room-m", type=float, default=5.0)
    ap.add_argument("--dir", default=None, help="work folder (default: a temporary one, removed)")
    ap.add_argument("--out", default=None, help="also write the lines as markdown here (results/published/bag_memory.md)")
    a = ap.parse_args(argv if argv is not None else sys.argv[1:])
    h, w = (int(v) for v in a.size.lower().split("x"))
    nx, ny = (int(v) for v in a.rooms.lower().split("x"))
    with tempfile.TemporaryDirectory(prefix="bag_memory_") as tmp:
        d = Path(a.dir) if a.dir else Path(tmp)
        d.mkdir(parents=True, exist_ok=True)
        rows, lines = [], []
        for n in (a.small, a.images):
            name = f"run_{n}.bag" if a.format == "ros1" else f"run_{n}"
            t = time.perf_counter()
            bag = write_long_bag(d / name, a.format, n, a.hours * n / a.images, (h, w), nx, ny, a.room_m)
            t_write = time.perf_counter() - t
            r = measure(bag, d / f"out_{n}")
            r.update(images=n, bag_mib=_size_mib(bag), write_s=round(t_write, 1))
            rows.append(r)
            lines.append(f"{n} images ({a.size} JPEG, {a.format}, {r['bag_mib']} MiB bag, "
                         f"{a.hours * n / a.images:.2f} h): peak RSS {r['peak_rss_mib']} MiB, {r['wall_s']} s, "
                         f"{r['n_kept_views']} of {r['n_bag_views']} views kept, {r['n_segments']} segments")
            print(lines[-1], flush=True)
        big, small = rows[1], rows[0]
        lines.append(f"ratio: {big['images'] / small['images']:.0f}x the images -> "
                     f"{big['peak_rss_mib'] / small['peak_rss_mib']:.2f}x the peak memory "
                     f"({big['peak_rss_mib'] - small['peak_rss_mib']:+.1f} MiB)")
        print(lines[-1])
    if a.out:
        from benchmark.reports.published import write_measured  # noqa: PLC0415

        write_measured(Path(a.out), "benchmark.commands.maintainer.bag_memory", argv, "\n".join(f"- {x}" for x in lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
