"""``python -m benchmark.commands.robot_coverage``: what each viewpoint strategy covers, and how
the scan map agrees with the floor plan, on the shared ProcTHOR houses (or generated ones).

Per house and strategy (autotrace; frontier and random walk at each ``--budgets``): views,
metres driven, ``coverage_area`` and ``coverage_rooms`` (:func:`benchmark.conditions.coverage.view_coverage`
with the floor-plan renderer's camera: 90 degree cone, 6 m, tall objects block) and, for the
scan map the robot builds along its views (:func:`envs.maps.scan.robot_scan_map`, default
scanner; the frontier's own map), the share of walkable cells it marks free and the share of
its free cells that are walkable. Then the pose error of the autotrace views under a few
example settings (:class:`benchmark.conditions.pose_error.PoseError`, drift along the autotrace route).
Prints the means over houses as Markdown tables.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pandas as pd

from benchmark.commands import cli
from benchmark.commands.errors import cli_errors, one_line
from benchmark.paths import procthor_houses


def _houses(path: Path, n: int, synthetic: bool):
    from envs.datasets.house_files import load_houses
    from envs.datasets.synthetic import SyntheticEnv

    if synthetic:
        env = SyntheticEnv(n_houses=n)
        return [env.house(hid) for hid in env.house_ids()]
    return load_houses(path, 0, n)


#: example pose-error settings: name -> PoseError arguments.
POSE_ERRORS = {
    "noise 0.05 m, 2 deg": dict(sigma_xy=0.05, sigma_yaw=2.0),
    "drift 0.01 m/m, 0.2 deg/m": dict(drift_xy=0.01, drift_yaw=0.2),
    "drift 0.01 m/m, 0.2 deg/m, closures every 10 m": dict(drift_xy=0.01, drift_yaw=0.2, loop_closure=10.0),
}


def run(houses: list, budgets: list[float]) -> tuple[pd.DataFrame, pd.DataFrame]:
    """(one row per (house, strategy), one row per (house, pose-error setting))."""
    from benchmark.conditions.coverage import view_coverage
    from benchmark.conditions.exploration import Frontier, RandomWalk
    from benchmark.conditions.pose_error import PoseError
    from benchmark.viewpoints import Autotrace
    from envs.maps.scan import ScanSettings, house_wall_height, robot_scan_map
    from envs.maps.scene import rasterise_house
    from envs.maps.trajectory import view_distances
    from envs.render.floorplan import occluders

    rows, errors = [], []
    for house in houses:
        scene = rasterise_house(house)
        blocked = occluders(scene, 1.2)
        walk = scene.grid.walkable
        strategies = [("autotrace", Autotrace())]
        strategies += [(f"frontier {b:g} m", Frontier(budget=b)) for b in budgets]
        strategies += [(f"random walk {b:g} m", RandomWalk(budget=b)) for b in budgets]
        for name, vp in strategies:
            poses = vp.generate(scene)
            last = getattr(vp, "last", None)
            if last is not None and last.scan_map is not None:
                scan = last.scan_map
            else:
                scan, _ = robot_scan_map(scene, poses, ScanSettings(), house_wall_height(house))
            cov = view_coverage(scene, poses, 90.0, 6.0, blocked)
            travelled = last.travelled if last is not None else view_distances(walk, scene.grid, poses)
            if name == "autotrace":
                for label, kw in POSE_ERRORS.items():
                    _, stats = PoseError(**kw)(poses, scene.grid, house.id, travelled)
                    errors.append({"house": house.id, "setting": label, "route m": float(travelled[-1]), **stats})
            rows.append({
                "house": house.id, "strategy": name, "views": len(poses),
                "metres": last.length if last is not None else float(travelled[-1]),
                "coverage_area": cov["coverage_area"], "coverage_rooms": cov["coverage_rooms"],
                "stopped_early": float(last is not None and last.stop != "budget"),
                "walkable_free": float((scan.free & walk).sum() / walk.sum()),
                "free_walkable": float((scan.free & walk).sum() / max(int(scan.free.sum()), 1)),
            })
    return pd.DataFrame(rows), pd.DataFrame(errors)


def report(df: pd.DataFrame, errors: pd.DataFrame) -> str:
    """The command's Markdown: the coverage table (means over houses) with its note, then the
    pose-error table with its note."""
    order = list(dict.fromkeys(df["strategy"]))
    table = df.groupby("strategy", sort=False)[["views", "metres", "coverage_area", "coverage_rooms",
                                               "stopped_early", "walkable_free", "free_walkable"]].mean().loc[order]
    out = [table.reset_index().to_markdown(index=False, floatfmt=".2f"), "",
           f"Means over {df['house'].nunique()} houses. Coverage: 90 degree cone, 6 m, objects 1.2 m tall block; "
           f"rooms seen from inside with at least 10 % of their cells. Scan map: 0.25 m plane, 10 m range, 1 degree "
           f"beams, no noise (frontier: the robot's own map). Autotrace metres: its route through the views. "
           f"stopped_early: share of houses where the exploration ended before its budget (no reachable frontier, "
           f"or a random walk stuck).", ""]
    order = list(dict.fromkeys(errors["setting"]))
    cols = ["route m", "pose_error_mean_m", "pose_error_max_m", "yaw_error_mean_deg", "pose_off_walkable"]
    out += [errors.groupby("setting", sort=False)[cols].mean().loc[order].reset_index().to_markdown(
        index=False, floatfmt=".3f"), "", "Pose error of the autotrace views (means over houses), drift along the "
            "autotrace route."]
    return "\n".join(out) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = cli.ArgumentParser(from_root=True, description=__doc__.split("\n\n")[0])
    ap.add_argument("--houses", type=Path, default=procthor_houses(), help=".json/.jsonl/.jsonl.gz house file")
    ap.add_argument("--n", type=int, default=20, help="first N houses")
    ap.add_argument("--synthetic", action="store_true", help="generated houses instead of the file")
    ap.add_argument("--budgets", type=float, nargs="+", default=[10.0, 20.0, 40.0], help="metres")
    ap.add_argument("--out", type=Path, default=None,
                    help="also write the tables to this Markdown file, headed by the command that made them "
                         "(make docs-numbers: results/published/robot_coverage.md, which "
                         "docs/robot-conditions.md includes)")
    a = ap.parse_args(argv)
    try:
        if a.n < 1 or any(not b > 0 for b in a.budgets):
            raise ValueError(f"--n {a.n} / --budgets {a.budgets}: expected n >= 1 and budgets > 0 metres")
        df, errors = run(_houses(a.houses, a.n, a.synthetic), a.budgets)
        text = report(df, errors)
    except cli_errors() as e:
        print(f"error: {one_line(e)}", file=sys.stderr)
        return 2
    if a.out is not None:
        from benchmark.reports.published import write_published

        err = write_published(a.out, published_command(a), text)
        if err:
            print(f"error: {err}", file=sys.stderr)
            return 2
    print(text)
    return 0


def published_command(a) -> str:  # noqa: ANN001 - the parsed arguments
    """The command line that makes the published file (the defaults left out)."""
    parts = ["python -m benchmark.commands.robot_coverage", f"--n {a.n}"]
    if a.synthetic:
        parts.append("--synthetic")
    elif Path(a.houses) != procthor_houses():
        parts.append(f"--houses {a.houses}")
    if list(a.budgets) != [10.0, 20.0, 40.0]:
        parts.append("--budgets " + " ".join(f"{b:g}" for b in a.budgets))
    if a.out is not None:
        parts.append(f"--out {a.out}")
    return " ".join(parts)


if __name__ == "__main__":
    raise SystemExit(main())
