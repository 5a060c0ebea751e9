"""``python -m benchmark.commands.coverage``: the command-line front of :mod:`benchmark.viewpoints`."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from benchmark.commands import cli
from benchmark.paths import procthor_houses
from benchmark.viewpoints import Autotrace, room_coverage


def main(argv: list[str] | None = None) -> int:
    """Autotrace on a house file: poses per house and how many rooms get at least one pose."""

    from envs.datasets.house_files import load_houses
    from envs.maps.scene import rasterise_house

    default = procthor_houses()
    ap = cli.ArgumentParser(from_root=True, description="autotrace room coverage on a house file")
    ap.add_argument("--houses", type=Path, default=default)
    ap.add_argument("--range", default="0:150", help="house index range a:b")
    ap.add_argument("--offset", type=float, default=0.5, help="metres")
    ap.add_argument("--spacing", type=float, default=1.0, help="metres")
    a = ap.parse_args(argv)
    start, stop = map(int, a.range.split(":"))
    at = Autotrace(offset=a.offset, spacing=a.spacing)
    n_poses, covered, total = [], 0, 0
    for house in load_houses(a.houses, start, stop):
        scene = rasterise_house(house)
        poses = at.generate(scene)
        n_poses.append(len(poses))
        got, n, missed = room_coverage(scene, poses)
        covered, total = covered + got, total + n
        for k, clearance in missed:
            print(f"{house.id}: room {k} ({scene.classes[scene.instance_classes[k]]}) has no pose; "
                  f"largest clearance {clearance:.2f} m (offset {a.offset} m)")
    print(f"{len(n_poses)} houses: {np.mean(n_poses):.0f} poses per house (min {min(n_poses)}, max {max(n_poses)}); "
          f"{covered} of {total} rooms have at least one pose")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
