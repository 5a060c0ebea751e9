"""``python -m benchmark.commands.draw_robot_map``: one shared house's floor-plan map beside
the scan map along its autotrace trajectory and the map a frontier-exploring robot built,
with the path it drove and its views (:mod:`benchmark.reports.robot_map`).

Example (the figure in ``docs/robot-conditions.md``)::

    python -m benchmark.commands.draw_robot_map --house 3 --out results/figures/robot_map.png
"""

from __future__ import annotations

import sys
from pathlib import Path

from benchmark.commands import cli
from benchmark.commands.errors import cli_errors, one_line
from benchmark.paths import procthor_houses


def draw(houses: Path, index: int, budget: float, out: Path) -> str:
    """Draw the figure; returns a one-line summary."""
    from benchmark.conditions.coverage import view_coverage
    from benchmark.conditions.exploration import Frontier
    from benchmark.reports.robot_map import draw_robot_map
    from benchmark.viewpoints import Autotrace
    from envs.datasets.house_files import load_houses
    from envs.maps.scan import ScanSettings, house_wall_height, robot_scan_map
    from envs.maps.scene import rasterise_house
    from envs.render.floorplan import occluders

    found = load_houses(houses, index, index + 1)
    if not found:
        raise ValueError(f"--house {index}: {houses} has no house at that index")
    house = found[0]
    scene = rasterise_house(house, resolution=0.05)
    scan, traj = robot_scan_map(scene, Autotrace().generate(scene), ScanSettings(), house_wall_height(house))
    frontier = Frontier(budget=budget)
    e = frontier.explore(scene)
    cov = view_coverage(scene, e.poses, 90.0, 6.0, occluders(scene, 1.2))
    walk = scene.grid.walkable
    agree = float((scan.free & walk).sum() / walk.sum())
    titles = (f"{house.id}: floor plan (ground truth)",
              f"scan map along the autotrace trajectory ({len(traj)} scans, 0.25 m plane, 10 m range): "
              f"{100 * agree:.0f} % of walkable free",
              f"frontier exploration, {budget:g} m budget: {e.length:.1f} m driven, {len(e.poses)} views, "
              f"area {100 * cov['coverage_area']:.0f} %, rooms {cov['rooms_seen']}/{cov['rooms']}")
    paths = draw_robot_map(scene, scan, traj, e.scan_map, e.path, e.poses, out,
                           tuple(t if len(t) < 70 else t.replace(": ", ":\n", 1) for t in titles))
    return f"{', '.join(map(str, paths))}: {titles[1]}; {titles[2]}"


def main(argv: list[str] | None = None) -> int:
    ap = cli.ArgumentParser(from_root=True, description=__doc__.split("\n\n")[0])
    ap.add_argument("--houses", type=Path, default=procthor_houses(), help=".json/.jsonl/.jsonl.gz house file")
    ap.add_argument("--house", type=int, default=3, help="index of the house in the file")
    ap.add_argument("--budget", type=float, default=40.0, help="frontier path-length budget, metres")
    ap.add_argument("--out", type=Path, default=Path("results/figures/robot_map.png"))
    a = ap.parse_args(argv)
    try:
        print(draw(a.houses, a.house, a.budget, a.out))
    except cli_errors() as e:
        print(f"error: {one_line(e)}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
