"""``python -m benchmark.commands.map_stats``: an occupancy map's statistics (wall thickness, free
speckle per m^2, clutter blobs, unknown share inside the outline, wall straightness;
:mod:`envs.maps.map_stats`), for any map, or simulated robot maps beside real laser maps.

* ``map_stats MAP [MAP ...]``: one row per map: a ROS ``map_server`` YAML (read in trinary mode), or
  an image (PNG, PGM) read by grey thresholds (``--free-min``, ``--occupied-max``) at
  ``--resolution`` metres per pixel.
* ``map_stats --calibrate``: the four real laser maps of ``../shared/data/real_maps`` (``--real-dir``),
  cleaned by their authors, and the raw maps the project's own mapper builds from the four corrected
  CARMEN logs of ``../shared/data/real_logs`` (``--real-logs-dir``; :mod:`envs.logs.raw_map`: the scan
  mapper's update rule on the logged ranges at the logged poses, nothing edited), beside the scan maps the simulated robot builds at each severity of the ``scan`` family
  (``conf/corruption/scan_k.yaml``, along the route each level sets: ``scan_0`` the autotrace
  views, ``scan_1..5`` a frontier mapping run) and the ``slam`` family (``slam_k``, autotrace
  views) on the first ``--n`` shared houses (0.05 m per pixel), means over houses; ``--figure PATH`` draws the real
  maps beside house 0's simulated ones.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from benchmark.commands.errors import cli_errors, one_line
from benchmark.paths import data_dir, procthor_houses

#: the real maps and their grey thresholds (free_min, occupied_max): the Intel map is a grey-level
#: map (255 free, 230 unknown, darker occupied), the others ROS trinary PNGs (254 / 205 / 0).
REAL_MAPS = {"intel_map.png": (240, 200), "Freiburg79_scan.png": (250, 50), "Freiburg101_scan.png": (250, 50),
             "lab_c_scan.png": (250, 50)}
REAL_RESOLUTION = 0.05
COLUMNS = ["free_m2", "wall_thickness_m", "speckle_per_m2", "clutter_per_m2", "clutter_median_m2", "unknown_inside",
           "wall_straight"]


def read_occupancy(path: Path, resolution: float, free_min: int, occupied_max: int) -> tuple[np.ndarray, float]:
    """(trinary occupancy, metres per cell) of a ROS YAML map or an image."""
    from envs.maps.images import read_image
    from envs.maps.map_stats import occupancy_from_grey

    if path.suffix.lower() in (".yaml", ".yml"):
        from envs.maps.ros import read_ros_map

        m = read_ros_map(path, mode="trinary")
        return np.asarray(m.occupancy, np.int8), float(m.resolution)
    return occupancy_from_grey(read_image(path, "the map", mode="L"), free_min, occupied_max), resolution


def simulated_maps(n: int) -> tuple[list[dict], dict[str, np.ndarray]]:
    """(rows of statistics per (house, level), {level: house 0's occupancy}) for scan_0..5, slam_1..5."""

    from benchmark.commands.maintainer.slam_levels import (
        level_mapping,
        level_scanner,
        level_settings,
    )
    from benchmark.conditions.exploration import exploration_route
    from benchmark.conditions.slam import OdometrySlam
    from benchmark.viewpoints import Autotrace
    from envs.datasets.house_files import load_houses
    from envs.maps.map_stats import map_stats
    from envs.maps.scan import house_wall_height, scan_map, scan_obstacles
    from envs.maps.scene import rasterise_house
    from envs.maps.slam_map import scan_map_at_estimate
    from envs.maps.trajectory import trajectory

    scanners = {"scan_0": ("views", level_scanner("clean"))}
    for k in range(1, 6):
        scanners[f"scan_{k}"] = level_mapping(f"scan_{k}")
    rows, first = [], {}
    for hid, house in enumerate(load_houses(procthor_houses(), 0, n)):
        scene = rasterise_house(house)
        wall = house_wall_height(house)
        poses = Autotrace().generate(scene)
        routes = {"views": poses}
        res = scene.grid.resolution
        for level, (route, settings) in scanners.items():
            if route not in routes:  # mapping.route=explore: the frontier mapping run
                routes[route] = exploration_route(scene)
            obstacles = scan_obstacles(scene, settings.height, wall, settings.legs, settings.leg_size)
            occ = scan_map(obstacles, scene.grid,
                           trajectory(scene.grid.walkable, scene.grid, routes[route], settings.spacing),
                           settings).occupancy
            rows.append({"map": level, "house": hid, **map_stats(occ, res)})
            first.setdefault(level, occ)
        for k in range(1, 6):
            settings = level_scanner(f"slam_{k}")
            obstacles = scan_obstacles(scene, settings.height, wall, settings.legs, settings.leg_size)
            est = OdometrySlam(**level_settings(f"slam_{k}")).estimate(scene.grid, poses, str(hid), settings.spacing)
            occ = scan_map_at_estimate(obstacles, scene.grid, est.true, est.estimate, settings).occupancy
            rows.append({"map": f"slam_{k}", "house": hid, **map_stats(occ, res)})
            first.setdefault(f"slam_{k}", occ)
    return rows, first


def draw(maps: dict[str, np.ndarray], out: Path) -> None:
    """Panels, 4 per row: free white, occupied black, unknown grey."""
    from benchmark.reports.plotting import occupancy_panels

    occupancy_panels(maps, out, cols=4, panel_in=3.2, dpi=90, fontsize=9)


def main(argv: list[str] | None = None) -> int:
    from envs.maps.map_stats import map_stats

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("maps", nargs="*", type=Path, help="ROS map YAML files or map images")
    ap.add_argument("--resolution", type=float, default=0.05, help="metres per pixel of an image map")
    ap.add_argument("--free-min", type=int, default=250, help="grey level at or above which a pixel is free")
    ap.add_argument("--occupied-max", type=int, default=50, help="grey level at or below which a pixel is occupied")
    ap.add_argument("--calibrate", action="store_true", help="the real maps beside simulated ones")
    ap.add_argument("--real-dir", type=Path, default=None, help="folder of the real maps (../shared/data/real_maps)")
    ap.add_argument("--real-logs-dir", type=Path, default=None,
                    help="folder of the real CARMEN logs whose raw maps join --calibrate (../shared/data/real_logs)")
    ap.add_argument("--n", type=int, default=5, help="shared houses for the simulated maps")
    ap.add_argument("--figure", type=Path, default=None, help="PNG of the real and simulated maps (with --calibrate)")
    ap.add_argument("--out", type=Path, default=None,
                    help="also write the table to this Markdown file, headed by the command that made it "
                         "(make docs-numbers: results/published/map_calibration.md, which "
                         "docs/robot-conditions.md includes)")
    a = ap.parse_args(argv)
    try:
        if not a.maps and not a.calibrate:
            raise ValueError("no maps given: expected map files, or --calibrate")
        if a.n < 1:
            raise ValueError(f"--n {a.n}: expected at least 1 house")
        rows, panels = [], {}
        for path in a.maps:
            occ, res = read_occupancy(path, a.resolution, a.free_min, a.occupied_max)
            rows.append({"map": str(path), **map_stats(occ, res)})
        if a.calibrate:
            real = a.real_dir or data_dir() / "real_maps"
            for name, (free_min, occupied_max) in REAL_MAPS.items():
                if not (real / name).is_file():
                    raise FileNotFoundError(f"real map not found: {real / name} (set --real-dir)")
                occ, res = read_occupancy(real / name, REAL_RESOLUTION, free_min, occupied_max)
                rows.append({"map": name, **map_stats(occ, res)})
                panels[name] = occ
            from benchmark.commands.real_logs import maps_rows

            rows.extend(maps_rows(a.real_logs_dir or data_dir() / "real_logs", None))
            sim, first = simulated_maps(a.n)
            means = pd.DataFrame(sim).groupby("map", sort=False)[COLUMNS].mean().reset_index()
            rows.extend(means.to_dict("records"))
            panels.update({k: first[k] for k in ("scan_1", "scan_3", "scan_5", "slam_1", "slam_3", "slam_5")})
            if a.figure is not None:
                draw(panels, a.figure)
    except cli_errors() as e:
        print(f"error: {one_line(e)}", file=sys.stderr)
        return 2
    text = pd.DataFrame(rows)[["map", *COLUMNS]].to_markdown(index=False, floatfmt=".3f")
    if a.calibrate:
        text += (f"\n\nReal maps at {REAL_RESOLUTION} m/px (the *.png maps cleaned by their authors; '(raw)': the "
                 f"project's mapper on the corrected CARMEN log, 10 m max range, nothing edited); simulated: means over {a.n} shared houses (autotrace "
                 f"views, 0.05 m/px). wall_thickness_m mean; speckle and clutter per m^2 of free space; "
                 f"clutter_median_m2 median blob area; unknown_inside share of the outline; wall_straight share of "
                 f"wall skeleton on straight segments >= 1 m.")
    print(text)
    if a.out is not None:
        from benchmark.reports.published import write_published

        command = ["python -m benchmark.commands.map_stats", *(str(m) for m in a.maps)]
        defaults = {"resolution": 0.05, "free_min": 250, "occupied_max": 50}
        command += [f"--{k.replace('_', '-')} {getattr(a, k):g}" for k, v in defaults.items()
                    if a.maps and getattr(a, k) != v]
        if a.calibrate:
            command += ["--calibrate", f"--n {a.n}"] + ([f"--real-dir {a.real_dir}"] if a.real_dir else [])
            command += [f"--real-logs-dir {a.real_logs_dir}"] if a.real_logs_dir else []
        err = write_published(a.out, " ".join([*command, f"--out {a.out}"]), text)
        if err is not None:
            print(f"error: {err}", file=sys.stderr)
            return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
