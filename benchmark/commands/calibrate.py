"""The simulated scanner fitted to the four shared real laser logs (issue 59 item 3).

Each log's FLASER scans at its corrected poses, against the map built from the log's own scans
(:func:`benchmark.conditions.calibration.fit_log`): the share of beams returning nothing, dropout and
grazing dropout, the correlation of dropouts along a scan and over time, the range noise and the
readings shorter or longer than the map, the noise and losses by incidence angle, and the
``ScanSettings`` fields each log gives. With ``--graphs DIR``: the residuals of real scan matching's
odometry edges in the public TORO graphs of Intel and CSAIL after the solve (issue 59 item 5).
With ``--houses N`` (default 5): each SLAM level's relative pose error (Kümmerle et al. 2009,
:mod:`benchmark.conditions.relative_error`) on the first N shared houses. ``--out`` writes the tables to a Markdown file headed by the
command (``make docs-numbers``: ``results/published/calibration.md``, included by
``docs/calibration.md``).

    python -m benchmark.commands.calibrate --out results/published/calibration.md
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from benchmark.commands.errors import cli_errors, one_line

#: the four shared logs (../shared/data/real_logs): the fit set, and nothing else
LOGS = {"Intel": "intel-corrected.log.gz", "ACES": "aces-corrected.log.gz", "CSAIL": "csail-corrected.log.gz",
        "Freiburg 079": "freiburg-079-corrected.log.gz"}
#: metres per cell of the map built from each log
RESOLUTION = 0.02
#: metres; a reading within this of the map's range is the surface the map expects
GATE = 0.3
#: metres; beams the map expects beyond this count as expecting nothing (the longest readings of
#: the four logs are 25-50 m; the beams' walks stay short enough for a few seconds a log)
FIT_RANGE = 40.0
#: the public TORO graphs of buildings of the fit set (M3500, a simulated graph, is no real scan matcher)
GRAPHS = {"Intel": "INTEL_P_toro.graph", "CSAIL": "CSAIL_P_toro.graph"}
#: the SLAM levels measured with the relative pose error
SLAM_LEVELS = ("slam_1", "slam_2", "slam_3", "slam_4", "slam_5")
#: metres along the route of the long relations
LONG_RELATION_M = 5.0


def log_arrays(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """``(poses, ranges, angles, max_reading)`` of a log's FLASER scans: (M, 3) corrected laser
    poses, (M, B) ranges with the log's max-range reading as NaN (no return), (B,) beam angles."""
    from envs.logs.carmen import read_carmen  # noqa: PLC0415

    log = read_carmen(path)
    scans = log.of_kind("FLASER")
    if not scans:
        raise ValueError(f"{path}: no FLASER scans: expected a CARMEN log of front laser scans")
    ranges = log.scan_ranges("FLASER")
    top = float(ranges.max())
    # the log's "nothing returned" reading: its largest value (81.83 / 81.91 on the SICK logs, 50 on ACES)
    ranges = np.where(ranges >= top - 0.005, np.nan, ranges)
    return log.laser_poses("FLASER"), ranges, scans[0].angles(), top


def fit_logs(folder: Path) -> dict:
    """Name -> (:class:`ScanFit`, max-range reading) for each shared log under ``folder``."""
    from benchmark.conditions.calibration import fit_log  # noqa: PLC0415

    out = {}
    for name, file in LOGS.items():
        path = folder / file
        if not path.is_file():
            raise FileNotFoundError(f"real log not found: {path} (expected the shared logs; set --logs)")
        poses, ranges, angles, top = log_arrays(path)
        fit, _ = fit_log(poses, ranges, angles, min(FIT_RANGE, float(np.nanmax(ranges))), RESOLUTION, GATE)
        out[name] = (fit, top)
    return out


def graph_residuals(folder: Path) -> list[dict]:
    """One row per graph of :data:`GRAPHS` under ``folder``: its odometry edges' residuals after a
    least-squares solve (GTSAM, from the file's initial guess)."""
    from benchmark.conditions.calibration import odometry_edge_residuals  # noqa: PLC0415
    from benchmark.conditions.pose_graph import graph_of_file, solve  # noqa: PLC0415
    from envs.logs.g2o import read_toro  # noqa: PLC0415

    rows = []
    for name, file in GRAPHS.items():
        path = folder / file
        if not path.is_file():
            raise FileNotFoundError(f"pose graph not found: {path} (expected {', '.join(GRAPHS.values())})")
        g = read_toro(path)
        states, info = solve(graph_of_file(g), g.initial, kernel="none")
        if not info["converged"]:
            raise RuntimeError(f"{path}: the solve did not converge in 1000 iterations")
        rows.append({"graph": name, **odometry_edge_residuals(g, states)})
    return rows


def level_errors(n_houses: int) -> list[dict]:
    """One row per SLAM level: the relative pose error of its estimate over the first
    ``n_houses`` shared houses (autotrace views, a node every scan spacing), over consecutive nodes
    and over :data:`LONG_RELATION_M` of route, translation and rotation apart."""
    from benchmark.commands.maintainer.slam_levels import level_scanner, level_settings  # noqa: PLC0415
    from benchmark.conditions.odometry import to_se2  # noqa: PLC0415
    from benchmark.conditions.relative_error import (  # noqa: PLC0415
        consecutive_pairs,
        distance_pairs,
        relation_errors,
        relative_motions,
    )
    from benchmark.conditions.slam import OdometrySlam  # noqa: PLC0415
    from benchmark.paths import procthor_houses  # noqa: PLC0415
    from benchmark.viewpoints import Autotrace  # noqa: PLC0415
    from envs.datasets.house_files import load_houses  # noqa: PLC0415
    from envs.maps.scene import rasterise_house  # noqa: PLC0415

    scenes = [rasterise_house(h) for h in load_houses(procthor_houses(), 0, n_houses)]
    rows = []
    for level in SLAM_LEVELS:
        s = level_scanner(level)
        slam = OdometrySlam(**level_settings(level))
        short_t, short_r, long_t, long_r, spacing = [], [], [], [], s.spacing
        for k, scene in enumerate(scenes):
            est = slam.estimate(scene.grid, Autotrace().generate(scene), str(k), s.spacing)
            truth, guess = to_se2(est.true), to_se2(est.estimate)
            for pairs, ts, rs in ((consecutive_pairs(len(truth)), short_t, short_r),
                                  (distance_pairs(truth, LONG_RELATION_M), long_t, long_r)):
                t, r = relation_errors(relative_motions(guess, pairs), relative_motions(truth, pairs))
                ts.append(t)
                rs.append(np.rad2deg(r))
        st, sr, lt, lr = (np.concatenate(v) for v in (short_t, short_r, long_t, long_r))
        rows.append({"level": level, "node spacing (m)": f"{spacing:g}", "relations": len(st),
                     "consecutive: trans (m)": f"{st.mean():.4f} ± {st.std():.4f}",
                     "consecutive: rot (deg)": f"{sr.mean():.3f} ± {sr.std():.3f}",
                     f"{LONG_RELATION_M:g} m: trans (m)": f"{lt.mean():.3f} ± {lt.std():.3f}",
                     f"{LONG_RELATION_M:g} m: rot (deg)": f"{lr.mean():.2f} ± {lr.std():.2f}"})
    return rows


def _f(v: float, digits: int = 3) -> str:
    return "n/a" if not math.isfinite(v) else f"{v:.{digits}f}"


def tables(fits: dict) -> str:
    """The Markdown the command prints and publishes."""
    rows = []
    for name, (f, top) in fits.items():
        rows.append({"log": name, "scans": f.n_scans, "max-range reading (m)": f"{top:g}",
                     "no return": _f(f.no_return_share), "dropout": _f(f.dropout),
                     "grazing_dropout": _f(f.grazing_dropout), "dropout corr. along scan": _f(f.dropout_corr_beam, 2),
                     "dropout corr. over time": _f(f.dropout_corr_scan, 2), "range_noise (m)": _f(f.range_noise),
                     "range bias (m)": _f(f.range_bias), "short readings": _f(f.short_share),
                     "long readings": _f(f.long_share), "longest reading (m)": _f(f.longest_reading, 1)})
    main = pd.DataFrame(rows).to_markdown(index=False, disable_numparse=True)
    inc = []
    names = list(fits)
    for k, b in enumerate(next(iter(fits.values()))[0].by_incidence):
        row = {"incidence (deg)": f"{b['from_deg']:g}-{b['to_deg']:g}"}
        for name in names:
            bb = fits[name][0].by_incidence[k]
            row[f"{name}: sigma (m)"] = _f(bb["range_sigma"])
            row[f"{name}: no return"] = _f(bb["no_return"])
        inc.append(row)
    by_inc = pd.DataFrame(inc).to_markdown(index=False, disable_numparse=True)
    told = []
    for name, (f, _) in fits.items():
        s = f.settings()
        told.append({"log": name, "range_noise": f"{s.range_noise:g}", "dropout": f"{s.dropout:g}",
                     "grazing_dropout": f"{s.grazing_dropout:g}", "max_range at least": _f(f.longest_reading, 1)})
    settings = pd.DataFrame(told).to_markdown(index=False, disable_numparse=True)
    text = (f"{main}\n\nScans: each log's FLASER scans (180 beams over 180 degrees) at its corrected poses; the map: "
            f"each log's own beam ends on {RESOLUTION} m cells. No return: the log's max-range reading. Dropout: "
            f"no return where the map expects a surface within {FIT_RANGE:g} m, the intercept of its line against "
            f"1 - cos(incidence); grazing_dropout its slope over 1 - dropout. Correlations: of neighbouring beams' "
            f"dropouts (beam b and b + 1; one beam in consecutive scans) beyond what incidence explains. "
            f"range_noise: 1.4826 x MAD of measured - expected within {GATE:g} m, less the cells' own "
            f"{RESOLUTION:g} / sqrt(12) m; short / long readings: more than {GATE:g} m before / past the map's "
            f"surface, as shares of the beams returning where the map expects one.\n\n"
            f"By incidence angle (beams the map expects to return):\n\n{by_inc}\n\n"
            f"The ScanSettings fields each log gives (the others it cannot tell):\n\n{settings}")
    return text


def front_end_tables(graphs: list[dict], levels: list[dict]) -> str:
    """The Markdown of the front end's section: real graphs' odometry residuals, levels' relative error."""
    parts = []
    if graphs:
        g = pd.DataFrame([{"graph": r["graph"], "odometry edges": r["edges"], "mean move (m)": f"{r['move_m']:.3f}",
                           "mean turn (deg)": f"{r['turn_deg']:.2f}",
                           "trans residual (m)": f"{r['trans_mean_m']:.4f} ± {r['trans_std_m']:.4f}",
                           "median (m)": f"{r['trans_median_m']:.4f}",
                           "rot residual (deg)": f"{r['rot_mean_deg']:.3f} ± {r['rot_std_deg']:.3f}",
                           "median (deg)": f"{r['rot_median_deg']:.3f}"} for r in graphs])
        parts.append("Real scan matching: the odometry edges (consecutive vertices) of the public TORO graphs "
                     "after a least-squares solve, residual mean ± standard deviation:\n\n"
                     + g.to_markdown(index=False, disable_numparse=True))
    if levels:
        parts.append("The SLAM levels: relative pose error of the solved estimate (Kümmerle et al. 2009; "
                     "translation and rotation apart, mean ± standard deviation over the relations) between "
                     f"consecutive nodes and over {LONG_RELATION_M:g} m of route:\n\n"
                     + pd.DataFrame(levels).to_markdown(index=False, disable_numparse=True))
    return "\n\n".join(parts)


def main(argv: list[str] | None = None) -> int:
    from benchmark.paths import data_dir  # noqa: PLC0415

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--logs", type=Path, default=None, help="folder of the four shared logs "
                    "(default: $ROOMSEG_SHARED_DATA/real_logs, ../shared/data/real_logs)")
    ap.add_argument("--graphs", type=Path, default=None,
                    help=f"folder holding {' and '.join(GRAPHS.values())}: the real front end's residuals "
                         "(default: the data root's real_graphs, where `roomseg data fetch real_graphs` puts them, "
                         "when it is there)")
    ap.add_argument("--houses", type=int, default=5, help="shared houses for the SLAM levels' relative error "
                    "(0: leave the levels out)")
    ap.add_argument("--out", type=Path, default=None,
                    help="also write the tables to this Markdown file, headed by the command that made it "
                         "(make docs-numbers: results/published/calibration.md, which docs/calibration.md includes)")
    a = ap.parse_args(argv)
    try:
        if a.houses < 0:
            raise ValueError(f"--houses {a.houses}: expected 0 or more houses")
        text = tables(fit_logs(a.logs or data_dir() / "real_logs"))
        graphs = a.graphs or (data_dir() / "real_graphs" if (data_dir() / "real_graphs").is_dir() else None)
        if graphs is None:
            print("calibrate: the real pose graphs are absent (roomseg data fetch real_graphs): "
                  "no section on real scan matching", file=sys.stderr)
        front = front_end_tables(graph_residuals(graphs) if graphs else [],
                                 level_errors(a.houses) if a.houses else [])
        if front:
            text += "\n\n" + front
    except cli_errors() as e:
        print(f"error: {one_line(e)}", file=sys.stderr)
        return 2
    print(text)
    if a.out is not None:
        from benchmark.reports.published import write_published  # noqa: PLC0415

        command = ["python -m benchmark.commands.calibrate", *([f"--logs {a.logs}"] if a.logs else []),
                   *([f"--graphs {a.graphs}"] if a.graphs else []), f"--houses {a.houses}", f"--out {a.out}"]
        err = write_published(a.out, " ".join(command), text)
        if err is not None:
            print(f"error: {err}", file=sys.stderr)
            return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
