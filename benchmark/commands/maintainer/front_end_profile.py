"""``python -m benchmark.commands.maintainer.front_end_profile``: the SLAM front end's CPU per house, split.

On the first ``--n`` shared ProcTHOR houses (autotrace views, the route with a node every 0.5 m, each
level's scanner and settings as :mod:`benchmark.commands.maintainer.slam_levels` makes them), each
level's :class:`benchmark.conditions.slam.OdometrySlam` estimate is made ``--repeat`` times and the
process CPU time of its parts is taken: the compiled chain (laser odometry and the estimate,
``front_end._chain``), the loop-closure search (``front_end._closures``: candidates, their matches and
place recognition), the rest of the front end (the scans), and the pose-graph solve. Printed: ms per
house (the best of the repeats, summed over houses, divided by their number) per level and part.

``--save PATH`` writes every house's and level's results (odometry edges, keyframes, closures, their
relative poses and information, the final estimate) to an ``.npz``; ``--compare PATH`` checks them
against such a file (the largest difference per array; exit 1 if any exceeds ``--tol``): what a
change of the front end that must not change its results is checked with.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from benchmark.commands.errors import cli_errors, one_line
from benchmark.paths import procthor_houses

PARTS = ("scans", "chain", "closures", "solve")


class _Clock:
    """Process CPU seconds spent in wrapped functions, by part."""

    def __init__(self):
        self.spent = dict.fromkeys(PARTS, 0.0)

    def wrap(self, part: str, fn):
        def timed(*args, **kwargs):
            t = time.process_time()
            try:
                return fn(*args, **kwargs)
            finally:
                self.spent[part] += time.process_time() - t
        return timed


def profile(n: int, levels: tuple[str, ...], repeat: int, houses: Path):
    """({level: {part: best CPU seconds summed over houses}}, {array name: array}) over the first ``n`` houses."""
    from benchmark.commands.maintainer.slam_levels import level_scanner, level_settings
    from benchmark.conditions import front_end, slam
    from benchmark.conditions.slam import OdometrySlam
    from benchmark.viewpoints import Autotrace
    from envs.datasets.house_files import load_houses
    from envs.maps.scan import house_wall_height, scan_obstacles
    from envs.maps.scene import rasterise_house

    totals = {level: dict.fromkeys(PARTS, 0.0) for level in levels}
    arrays: dict[str, np.ndarray] = {}
    originals = (front_end._chain, front_end._closures, front_end.run_front_end, slam.solve)
    try:
        for h, house in enumerate(load_houses(houses, 0, n)):
            scene = rasterise_house(house)
            poses = Autotrace().generate(scene)
            wall = house_wall_height(house)
            for level in levels:
                settings = level_scanner(level)
                obstacles = scan_obstacles(scene, settings.height, wall, settings.legs, settings.leg_size)
                best = dict.fromkeys(PARTS, np.inf)
                for _ in range(repeat):
                    clock = _Clock()
                    front_end._chain = clock.wrap("chain", originals[0])
                    front_end._closures = clock.wrap("closures", originals[1])
                    out = {}

                    def run(*args, _clock=clock, _out=out, **kwargs):
                        t = time.process_time()
                        fe = originals[2](*args, **kwargs)
                        _clock.spent["scans"] += time.process_time() - t
                        _out["fe"] = fe
                        return fe

                    slam.run_front_end = run
                    slam.solve = clock.wrap("solve", originals[3])
                    est = OdometrySlam(**level_settings(level)).estimate(scene.grid, poses, str(h), settings.spacing,
                                                                         obstacles)
                    clock.spent["scans"] -= clock.spent["chain"] + clock.spent["closures"]
                    for part in PARTS:
                        best[part] = min(best[part], clock.spent[part])
                for part in PARTS:
                    totals[level][part] += best[part]
                fe = out["fe"]
                for name in ("z", "sqrt_info", "laser", "dead", "keyframes", "closures", "closure_z",
                             "closure_sqrt_info", "wrong", "place"):
                    arrays[f"{h}/{level}/{name}"] = np.asarray(getattr(fe, name))
                arrays[f"{h}/{level}/estimate"] = np.asarray(est.estimate)
    finally:
        front_end._chain, front_end._closures, slam.run_front_end, slam.solve = originals
    return totals, arrays


def compare(arrays: dict[str, np.ndarray], saved: dict[str, np.ndarray], tol: float) -> tuple[list[str], bool]:
    """(one line per array that differs, whether every array is within ``tol``)."""
    lines, ok = [], True
    for name in sorted(set(arrays) | set(saved)):
        if name not in arrays or name not in saved:
            lines.append(f"{name}: only in {'the saved file' if name in saved else 'this run'}")
            ok = False
            continue
        a, b = arrays[name], saved[name]
        if a.shape != b.shape:
            lines.append(f"{name}: shape {a.shape} against the saved {b.shape}")
            ok = False
            continue
        if a.size == 0:
            continue
        diff = float(np.max(np.abs(a.astype(np.float64) - b.astype(np.float64))))
        if diff > 0:
            lines.append(f"{name}: differs by {diff:.3g}")
            ok = ok and diff <= tol
    return lines, ok


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--houses", type=Path, default=procthor_houses(), help=".json/.jsonl/.jsonl.gz house file")
    ap.add_argument("--n", type=int, default=10, help="first N houses")
    ap.add_argument("--levels", nargs="+", default=["slam_1", "slam_3", "slam_5"],
                    help="corruption levels (conf/corruption names)")
    ap.add_argument("--repeat", type=int, default=3, help="runs per house and level; the fastest is kept")
    ap.add_argument("--save", type=Path, default=None, help="write the results to this .npz")
    ap.add_argument("--compare", type=Path, default=None, help="check the results against this .npz")
    ap.add_argument("--tol", type=float, default=1e-9, help="largest difference --compare accepts")
    a = ap.parse_args(argv)
    try:
        if a.n < 1:
            raise ValueError(f"--n {a.n}: expected at least 1 house")
        if a.repeat < 1:
            raise ValueError(f"--repeat {a.repeat}: expected at least 1")
        if a.compare is not None and not a.compare.is_file():
            raise ValueError(f"--compare {a.compare}: no such file; expected an .npz written by --save")
        from benchmark.commands.maintainer.slam_levels import level_settings

        for level in a.levels:
            level_settings(level)
        totals, arrays = profile(a.n, tuple(a.levels), a.repeat, a.houses)
    except cli_errors() as e:
        print(f"error: {one_line(e)}", file=sys.stderr)
        return 2
    print(f"front end CPU, ms per house (best of {a.repeat}, {a.n} houses)")
    print(f"{'level':10s}" + "".join(f"{p:>10s}" for p in PARTS) + f"{'front end':>11s}")
    for level, spent in totals.items():
        fe = spent["scans"] + spent["chain"] + spent["closures"]
        print(f"{level:10s}" + "".join(f"{1000 * spent[p] / a.n:10.1f}" for p in PARTS) + f"{1000 * fe / a.n:11.1f}")
    if a.save is not None:
        np.savez_compressed(a.save, **arrays)
    if a.compare is not None:
        with np.load(a.compare) as saved:
            lines, ok = compare(arrays, dict(saved), a.tol)
        print("\n".join(lines) if lines else "results identical to the saved ones")
        if not ok:
            return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
