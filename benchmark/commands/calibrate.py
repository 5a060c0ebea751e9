"""The simulated scanner fitted to the four shared real laser logs (issue 59 item 3).

Each log's FLASER scans at its corrected poses, against the map built from the log's own scans
(:func:`benchmark.conditions.calibration.fit_log`): the share of beams returning nothing, dropout and
grazing dropout, the correlation of dropouts along a scan and over time, the range noise and the
readings shorter or longer than the map, the noise and losses by incidence angle, and the
``ScanSettings`` fields each log gives. With ``--graphs DIR``: the residuals of real scan matching's
odometry edges in the public TORO graphs of Intel and CSAIL after the solve (issue 59 item 5).
With ``--houses N`` (default 5), on the first N shared houses: each SLAM level's odometry edges (the
front end's fused consecutive moves, the edges its back end got) after the level's own solve,
residuals as the real graphs' (the same columns, and where each level falls against Intel and
CSAIL), and its relative pose error against the truth (Kümmerle et al. 2009,
:mod:`benchmark.conditions.relative_error`). ``--figure PATH`` also draws the raw map the project's
mapper builds from the Intel log at its corrected poses beside shared house 0's maps at
``scan_1/3/5`` and ``slam_1/3/5`` (``docs/figures/calibration_maps.png``). ``--out`` writes the
tables to a Markdown file headed by the command (``make docs-numbers``:
``results/published/calibration.md``, included by ``docs/calibration.md``).

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
#: the log whose raw map ``--figure`` draws, and the levels whose maps of shared house 0 it draws beside it
FIGURE_LOG = "Intel"
FIGURE_LEVELS = ("scan_1", "scan_3", "scan_5", "slam_1", "slam_3", "slam_5")


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


def level_rows(n_houses: int) -> tuple[list[dict], list[dict]]:
    """Two rows per SLAM level, from its estimates on the first ``n_houses`` shared houses
    (autotrace views, a node every scan spacing): (the relative pose error over consecutive nodes
    and over :data:`LONG_RELATION_M` of route, translation and rotation apart; the residuals of
    the odometry edges the back end got after its solve, as :func:`graph_residuals` gives them for
    a real graph, with ``closures`` the loop closures accepted, wrong ones included)."""
    from benchmark.commands.maintainer.slam_levels import level_scanner, level_settings  # noqa: PLC0415
    from benchmark.conditions.calibration import chain_edge_errors, residual_summary  # noqa: PLC0415
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
    rows, residuals = [], []
    for level in SLAM_LEVELS:
        s = level_scanner(level)
        slam = OdometrySlam(**level_settings(level))
        short_t, short_r, long_t, long_r, spacing = [], [], [], [], s.spacing
        errs, zs, closures = [], [], 0
        for k, scene in enumerate(scenes):
            est = slam.estimate(scene.grid, Autotrace().generate(scene), str(k), s.spacing)
            truth, guess = to_se2(est.true), to_se2(est.estimate)
            if est.odometry_edges is not None:  # none on a route of one node
                errs.append(chain_edge_errors(guess, est.odometry_edges))
                zs.append(est.odometry_edges)
                closures += len(est.closures) + len(est.wrong)
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
        empty = [np.zeros((0, 3))]
        residuals.append({"level": level, **residual_summary(np.concatenate(errs or empty), np.concatenate(zs or empty)),
                          "closures": closures})
    return rows, residuals


def densest_window(mask: np.ndarray, shape: tuple[int, int]) -> tuple[int, int]:
    """(row, col) of the top-left cell of the ``shape`` window of ``mask`` (H, W bool) holding the
    most True cells (the first such window in row-major order; the whole map when it is smaller)."""
    h, w = min(shape[0], mask.shape[0]), min(shape[1], mask.shape[1])
    sat = np.zeros((mask.shape[0] + 1, mask.shape[1] + 1), np.int64)
    sat[1:, 1:] = np.asarray(mask, bool).cumsum(axis=0).cumsum(axis=1)
    counts = sat[h:, w:] - sat[:-h, w:] - sat[h:, :-w] + sat[:-h, :-w]
    r, c = np.unravel_index(int(np.argmax(counts)), counts.shape)
    return int(r), int(c)


def maps_figure(log_path: Path, out: Path, name: str = FIGURE_LOG) -> None:
    """Draw ``out`` (PNG): the raw map the project's mapper builds from the real log ``log_path``
    (``name`` in the titles) at its corrected poses (:func:`envs.logs.raw_map.raw_map_from_log`, as
    ``map_stats --calibrate``'s raw rows: the simulated scanner's 10 m, 0.05 m cells), cut to what
    it saw and a window of it the size of the house's map (the window holding the most occupied
    cells), beside shared house 0's maps at :data:`FIGURE_LEVELS`
    (:func:`benchmark.commands.map_stats.simulated_maps`)."""
    from benchmark.commands.map_stats import draw, simulated_maps  # noqa: PLC0415
    from benchmark.commands.real_logs import RESOLUTION as RAW_RESOLUTION  # noqa: PLC0415
    from benchmark.paths import procthor_houses  # noqa: PLC0415
    from envs.datasets.house_files import load_houses  # noqa: PLC0415
    from envs.logs.carmen import read_carmen  # noqa: PLC0415
    from envs.logs.raw_map import raw_map_from_log  # noqa: PLC0415
    from envs.maps.scene import rasterise_house  # noqa: PLC0415

    if not log_path.is_file():
        raise FileNotFoundError(f"real log not found: {log_path} (expected the shared logs; set --logs)")
    raw, _ = raw_map_from_log(read_carmen(log_path), RAW_RESOLUTION)
    rows, cols = np.nonzero(raw != -1)
    if not len(rows):
        raise ValueError(f"{log_path}: its raw map holds no known cell: expected scans that see something")
    seen = raw[rows.min():rows.max() + 1, cols.min():cols.max() + 1]
    houses = load_houses(procthor_houses(), 0, 1)
    if not houses:
        raise ValueError(f"{procthor_houses()}: no house: expected the shared houses")
    grid = rasterise_house(houses[0]).grid
    _, first = simulated_maps(1)
    metres = (grid.shape[0] * grid.resolution, grid.shape[1] * grid.resolution)
    shape = (max(round(metres[0] / RAW_RESOLUTION), 1), max(round(metres[1] / RAW_RESOLUTION), 1))
    r, c = densest_window(seen == 100, shape)
    size = f"{seen.shape[1] * RAW_RESOLUTION:.0f} x {seen.shape[0] * RAW_RESOLUTION:.0f} m"
    window = f"{metres[1]:.0f} x {metres[0]:.0f} m"
    panels = {f"{name} raw map ({size})": seen}
    panels.update({f"house 0, {k} ({window})": first[k] for k in FIGURE_LEVELS[:3]})
    panels[f"{name} raw, a {window} window"] = seen[r:r + shape[0], c:c + shape[1]]
    panels.update({f"house 0, {k}": first[k] for k in FIGURE_LEVELS[3:]})
    draw(panels, out)


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
            f"The ScanSettings fields each log gives (the others it cannot tell):\n\n{settings}\n\n"
            f"{ladder_table(fits)}")
    return text


def ladder_table(fits: dict) -> str:
    """The Markdown of the levels' scanner set from the fit (:mod:`benchmark.conditions.scanner_levels`)."""
    from benchmark.conditions.scanner_levels import FAMILIES, FITTED, levels_from_fits  # noqa: PLC0415

    levels = levels_from_fits({name: f for name, (f, _) in fits.items()})
    rows = [{"severity": s, **{f: f"{v[f]:g}" for f in FITTED}} for s, v in levels.items()]
    return ("The levels' scanner from the fit (`calibrate --write-levels` writes it into "
            f"conf/corruption/{{{','.join(FAMILIES)}}}_k.yaml): severity 1 the best log's value, 3 the median of "
            "the four, 5 the poorest, 2 and 4 half way; three significant figures. max_range, closed doors, people "
            "and surface dropout stay set by hand (no log tells them), and so do the odometry alphas (no raw "
            "odometry in the shared logs):\n\n" + pd.DataFrame(rows).to_markdown(index=False, disable_numparse=True))


def write_levels(fits: dict, conf_dir: Path) -> list[Path]:
    """Set the fitted scanner fields of every ``<family>_<k>.yaml`` of ``conf_dir`` (the corruption
    group) from the fit; the files changed."""
    from benchmark.conditions.scanner_levels import FAMILIES, levels_from_fits, set_fitted  # noqa: PLC0415
    from envs.atomic import atomic_write_text  # noqa: PLC0415

    levels = levels_from_fits({name: f for name, (f, _) in fits.items()})
    changed = []
    for family in FAMILIES:
        for s, values in levels.items():
            path = conf_dir / f"{family}_{s}.yaml"
            if not path.is_file():
                raise FileNotFoundError(f"level file not found: {path} (expected conf/corruption/{family}_{s}.yaml)")
            old = path.read_text(encoding="utf-8")
            new = set_fitted(old, values)
            if new != old:
                atomic_write_text(path, new)
                changed.append(path)
    return changed


def _residual_row(first: str, r: dict) -> dict:
    """One row of the odometry residual tables (a real graph's or a level's: the same columns)."""
    return {first: r[first], "odometry edges": r["edges"], "closures": r["closures"],
            "mean move (m)": f"{r['move_m']:.3f}", "mean turn (deg)": f"{r['turn_deg']:.2f}",
            "trans residual (m)": f"{r['trans_mean_m']:.4f} ± {r['trans_std_m']:.4f}",
            "median (m)": f"{r['trans_median_m']:.4f}",
            "rot residual (deg)": f"{r['rot_mean_deg']:.3f} ± {r['rot_std_deg']:.3f}",
            "median (deg)": f"{r['rot_median_deg']:.3f}"}


def _place(value: float, refs: dict[str, float]) -> str:
    """Where ``value`` falls among the named ``refs``: below the least, above the largest, or
    between two neighbours."""
    order = sorted(refs.items(), key=lambda kv: kv[1])
    if value < order[0][1]:
        return f"below {order[0][0]}"
    for (a, va), (b, vb) in zip(order, order[1:]):
        if va <= value <= vb:
            return f"between {a} and {b}"
    return f"above {order[-1][0]}"


def placement(graphs: list[dict], residuals: list[dict]) -> str:
    """One line per level: where its mean translational and rotational odometry residual falls
    against the real graphs' (:func:`_place`)."""
    trans = {r["graph"]: r["trans_mean_m"] for r in graphs}
    rot = {r["graph"]: r["rot_mean_deg"] for r in graphs}
    return "\n".join(f"- `{r['level']}`: translation {_place(r['trans_mean_m'], trans)}, rotation "
                     f"{_place(r['rot_mean_deg'], rot)}" for r in residuals)


def front_end_tables(graphs: list[dict], levels: list[dict], residuals: list[dict] | None = None) -> str:
    """The Markdown of the front end's section: real graphs' odometry residuals, the levels' odometry
    residuals (the same columns) and where they fall against the graphs', the levels' relative error."""
    parts = []
    if graphs:
        g = pd.DataFrame([_residual_row("graph", r) for r in graphs])
        parts.append("Real scan matching: the odometry edges (consecutive vertices) of the public TORO graphs "
                     "after a least-squares solve, residual mean ± standard deviation (closures: the graph's "
                     "other edges):\n\n" + g.to_markdown(index=False, disable_numparse=True))
    if residuals:
        parts.append("The SLAM levels, the same quantity: the odometry edges the back end got (the front end's "
                     "fused moves between consecutive nodes) after the level's own solve (its robust kernel on "
                     "the closures), residual mean ± standard deviation over the edges of every house (closures: "
                     "the loop closures accepted, wrong ones included). A residual is what the closures pull "
                     "against the chain: a route with no closure leaves none:\n\n"
                     + pd.DataFrame([_residual_row("level", r) for r in residuals]).to_markdown(
                         index=False, disable_numparse=True))
        if graphs:
            parts.append("Where each level's mean residual falls against the real graphs':\n\n"
                         + placement(graphs, residuals))
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
    ap.add_argument("--houses", type=int, default=5, help="shared houses for the SLAM levels' odometry residuals "
                    "and relative error (0: leave the levels out)")
    ap.add_argument("--write-levels", action="store_true",
                    help="set the scanner fields of conf/corruption's scan_k, slam_k and realistic_k from the fit")
    ap.add_argument("--figure", type=Path, default=None,
                    help=f"also draw this PNG: the raw map of the {FIGURE_LOG} log (the project's mapper at its "
                         f"corrected poses) beside shared house 0's maps at {', '.join(FIGURE_LEVELS)}")
    ap.add_argument("--out", type=Path, default=None,
                    help="also write the tables to this Markdown file, headed by the command that made it "
                         "(make docs-numbers: results/published/calibration.md, which docs/calibration.md includes)")
    a = ap.parse_args(argv)
    try:
        if a.houses < 0:
            raise ValueError(f"--houses {a.houses}: expected 0 or more houses")
        fits = fit_logs(a.logs or data_dir() / "real_logs")
        text = tables(fits)
        if a.write_levels:
            from benchmark.paths import CONF_DIR  # noqa: PLC0415

            for path in write_levels(fits, Path(CONF_DIR) / "corruption"):
                print(f"calibrate: wrote {path}", file=sys.stderr)
        graphs = a.graphs or (data_dir() / "real_graphs" if (data_dir() / "real_graphs").is_dir() else None)
        if graphs is None:
            print("calibrate: the real pose graphs are absent (roomseg data fetch real_graphs): "
                  "no section on real scan matching", file=sys.stderr)
        errors, residuals = level_rows(a.houses) if a.houses else ([], [])
        front = front_end_tables(graph_residuals(graphs) if graphs else [], errors, residuals)
        if front:
            text += "\n\n" + front
        if a.figure is not None:
            maps_figure((a.logs or data_dir() / "real_logs") / LOGS[FIGURE_LOG], a.figure)
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
