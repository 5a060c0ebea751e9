"""``python -m benchmark.commands.maintainer.slam_levels``: what each SLAM severity (``corruption=slam_k``) and
lost-robot level (``corruption=lost_k``: wrong loop closures; ``kidnap_k``: carried) does to a robot's trajectory and map, on the shared houses.

Per house: the autotrace views (the default viewpoints), the route through them with a node every
0.5 m, and for each level the :class:`benchmark.conditions.slam.OdometrySlam` estimate with that level's
settings (read from ``conf/corruption/<level>.yaml`` over ``conf/pose_error/odometry.yaml``), and
the scan map inserted at it (the level's scanner: 0.25 m plane, 10 m, 1 degree beams, no range
noise, legged furniture as legs). The ``clean`` row is the first level's scanner at the true poses.
Columns (means over houses): the route (m), loop closures found, wrong ones, ATE RMSE after rigid
alignment (m) of dead reckoning and of the pose-graph estimate, that ATE per 100 m of route, the
views' mean position error in the world frame (m), and the map's free-space IoU with the floor
plan's walkable cells brought into the map's frame (``map_free_iou``; severity 0 is the scan map at
the true poses). ``--figure PATH`` draws one house's maps at every level.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from benchmark.commands.errors import cli_errors, one_line
from benchmark.paths import CONF_DIR, procthor_houses

LEVELS = ("slam_1", "slam_2", "slam_3", "slam_4", "slam_5", "lost_1", "lost_2", "lost_3", "kidnap_1", "kidnap_2")


def level_settings(level: str) -> dict:
    """The ``pose_error`` settings of ``conf/corruption/<level>.yaml`` over the odometry defaults."""
    from omegaconf import OmegaConf

    base = OmegaConf.load(Path(CONF_DIR) / "pose_error" / "odometry.yaml")
    path = Path(CONF_DIR) / "corruption" / f"{level}.yaml"
    if not path.is_file():
        raise ValueError(f"level {level!r}: no {path}; expected one of {', '.join(LEVELS)}")
    node = OmegaConf.to_container(OmegaConf.merge(base, OmegaConf.load(path).get("pose_error", {})), resolve=True)
    node.pop("_target_", None)
    return node


def level_mapping(level: str):
    """(``mapping.route``, :class:`envs.maps.scan.ScanSettings`) of ``conf/corruption/<level>.yaml``'s
    ``mapping`` over ``conf/mapping/scan.yaml`` (``clean``: the defaults): where the mapping robot
    drives (``views`` or ``explore``) and its scanner."""
    from omegaconf import OmegaConf

    from envs.maps.scan import ScanSettings

    base = OmegaConf.load(Path(CONF_DIR) / "mapping" / "scan.yaml")
    path = Path(CONF_DIR) / "corruption" / f"{level}.yaml"
    over = OmegaConf.load(path).get("mapping", {}) if level != "clean" and path.is_file() else {}
    node = OmegaConf.to_container(OmegaConf.merge(base, over), resolve=True)
    node.pop("_target_", None)
    route = str(node.pop("route", "views"))
    return route, ScanSettings(**node).check()


def level_scanner(level: str):
    """The scanner of :func:`level_mapping`."""
    return level_mapping(level)[1]


def measure(scene, house_id: str, levels: tuple[str, ...], wall: float = 2.6) -> tuple[list[dict], dict[str, np.ndarray]]:
    """(one row per level, {level: (H, W) int8 occupancy of its map}) for one house."""
    from benchmark.conditions.alignment import align_rigid, to_map_frame
    from benchmark.conditions.pose_error import pose_error_stats
    from benchmark.conditions.slam import OdometrySlam
    from benchmark.viewpoints import Autotrace
    from envs.maps.scan import scan_map, scan_obstacles
    from envs.maps.slam_map import scan_map_at_estimate

    poses = Autotrace().generate(scene)
    walk = scene.grid.walkable
    rows, maps = [], {}
    for level in ("clean", *levels):
        settings = level_scanner(levels[0] if level == "clean" and levels else level)
        obstacles = scan_obstacles(scene, settings.height, wall, settings.legs, settings.leg_size)
        slam = OdometrySlam(**({} if level == "clean" else level_settings(level)))
        est = slam.estimate(scene.grid, poses, house_id, settings.spacing)
        if level == "clean":
            m = scan_map(obstacles, scene.grid, est.true, settings)
            aligned = walk
        else:
            m = scan_map_at_estimate(obstacles, scene.grid, est.true, est.estimate, settings)
            theta, t = align_rigid(est.estimate[:, :2], est.true[:, :2])
            aligned = to_map_frame(walk.astype(np.int8), scene.grid, theta, t, fill=0).astype(bool)
        union = int((m.free | aligned).sum())
        st = est.stats()
        rows.append({"house": house_id, "level": level, "route_m": st["route_m"], "loop_closures": st["loop_closures"],
                     "wrong_closures": st["wrong_closures"], "kidnapped_m": st["kidnapped_m"], "odometry_ate_m": st["odometry_ate_rmse_m"],
                     "tracking_lost": st["slam_tracking_lost"], "relocalised": st["slam_relocalised"],
                     "ate_rmse_m": st["ate_rmse_m"], "ate_per_100m": 100 * st["ate_rmse_m"] / max(st["route_m"], 1e-9),
                     "view_error_m": pose_error_stats(poses, est.views)["pose_error_mean_m"],
                     "map_free_iou": float((m.free & aligned).sum() / union) if union else 1.0})
        maps[level] = m.occupancy
    return rows, maps


def draw(maps: dict[str, np.ndarray], out: Path) -> None:
    """One panel per level, 3 a row: free white, occupied black, unknown grey."""
    from benchmark.reports.plotting import occupancy_panels

    titles = {(level if level != "clean" else "true poses (severity 0)"): occ for level, occ in maps.items()}
    occupancy_panels(titles, out, cols=min(len(maps), 3), panel_in=4, dpi=80)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--houses", type=Path, default=procthor_houses(), help=".json/.jsonl/.jsonl.gz house file")
    ap.add_argument("--n", type=int, default=10, help="first N houses")
    ap.add_argument("--levels", nargs="+", default=list(LEVELS), help="corruption levels (conf/corruption names)")
    ap.add_argument("--figure", type=Path, default=None, help="PNG of the first house's maps at every level")
    ap.add_argument("--out", type=Path, default=None,
                    help="also write the table to this Markdown file, headed by the command that made it "
                         "(make docs-numbers: results/published/slam_levels.md, which docs/robot-conditions.md "
                         "includes)")
    a = ap.parse_args(argv)
    try:
        if a.n < 1:
            raise ValueError(f"--n {a.n}: expected at least 1 house")
        for level in a.levels:
            level_settings(level)
        from envs.datasets.house_files import load_houses
        from envs.maps.scan import house_wall_height
        from envs.maps.scene import rasterise_house

        rows, figure_maps = [], None
        for k, house in enumerate(load_houses(a.houses, 0, a.n)):
            r, maps = measure(rasterise_house(house), str(k), tuple(a.levels), house_wall_height(house))
            rows.extend(r)
            figure_maps = maps if figure_maps is None else figure_maps
        if a.figure is not None:
            draw(figure_maps, a.figure)
    except cli_errors() as e:
        print(f"error: {one_line(e)}", file=sys.stderr)
        return 2
    df = pd.DataFrame(rows)
    order = list(dict.fromkeys(df["level"]))
    cols = ["route_m", "loop_closures", "wrong_closures", "kidnapped_m", "tracking_lost", "relocalised", "odometry_ate_m", "ate_rmse_m", "ate_per_100m",
            "view_error_m", "map_free_iou"]
    text = (df.groupby("level", sort=False)[cols].mean().loc[order].reset_index().to_markdown(index=False,
                                                                                               floatfmt=".3f")
            + f"\n\nMeans over {df['house'].nunique()} houses; autotrace views, a node every 0.5 m, each level's "
              f"scanner. ATE: RMSE (m) after rigid alignment; ate_per_100m in metres per 100 m of route.")
    print(text)
    if a.out is not None:
        from benchmark.reports.published import write_published

        command = ["python -m benchmark.commands.maintainer.slam_levels", f"--n {a.n}"]
        if Path(a.houses) != procthor_houses():
            command.append(f"--houses {a.houses}")
        if list(a.levels) != list(LEVELS):
            command.append("--levels " + " ".join(a.levels))
        err = write_published(a.out, " ".join([*command, f"--out {a.out}"]), text)
        if err is not None:
            print(f"error: {err}", file=sys.stderr)
            return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
