"""``python -m benchmark.commands.real_logs``: real pose graphs through the project's solve, and raw
maps from real laser logs.

    python -m benchmark.commands.real_logs graphs [--dir DIR] [--out results/published/real_graphs.md]
    python -m benchmark.commands.real_logs maps [--dir DIR] [--out-dir DIR]

``graphs`` reads every ``*.graph`` (TORO) and ``*.g2o`` file of ``--dir`` (default
``<data root>/real_graphs``, ``python -m benchmark.commands.data fetch real_graphs``) with
:mod:`envs.logs.g2o` and solves it with the project's back end
(:func:`benchmark.conditions.pose_graph.solve`, GTSAM Levenberg-Marquardt, no robust kernel: every
edge Gaussian) from the file's own initial guess. Per graph: vertices, edges, the largest
condition number of an edge's information matrix, chi2 at the initial guess and at the answer
(GTSAM's cost: the sum of squared whitened ``Log(Z^-1 X_i^-1 X_j)``, twice GTSAM's error), the
same answer's g2o chi2 (the sum of ``e' I e`` with g2o's EdgeSE2 error ``t2v(Z^-1 X_i^-1 X_j)``),
iterations and convergence, and the independent check: the file (a TORO file written out in g2o
order first) read by ``gtsam.readG2o`` and solved by GTSAM's LevenbergMarquardtOptimizer with a
tighter stop than the back end's (:data:`CHECK_TOLERANCE`), node 0 held by a prior; its chi2 is the same cost, so the two agree when both
reach the optimum. A solve that raises (GTSAM refuses an ill-posed linear system) is reported
with GTSAM's first line, not as a number. For the graphs SE-Sync publishes (:data:`SESYNC_OPTIMA`:
CSAIL and M3500, "manhattan" there) the table also gives SE-Sync's chordal cost
(:func:`sesync_cost`) at our answer beside SE-Sync's certified global minimum f* of that cost: the
cost at any states is at least f*, and close to it when our solve reaches the same basin. To tell
the basin from the weighting, the table also gives that cost after the project's solve of the graph
reweighted as SE-Sync weighs it (:func:`sesync_weighted`), started from our answer: it reaches f*
when our answer lies in f*'s basin.

``maps`` builds the raw occupancy map of each ``*.log`` / ``*.log.gz`` CARMEN log of ``--dir``
(default ``<data root>/real_logs``, ``data fetch real_logs``) with :mod:`envs.logs.raw_map` (the
scan mapper's update rule, the simulated scanner's ``max_range`` 10 m, 0.05 m cells; FLASER scans
at their logged laser poses) and prints their map statistics (:mod:`envs.maps.map_stats`);
``--out-dir`` also writes each as a ROS ``map_server`` map (``<log>_raw.yaml`` + ``.pgm``).

Exit 0 when done, 2 on bad input (one line naming the file and line).
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
from pathlib import Path

import numpy as np

from benchmark.commands.errors import cli_errors, one_line
from benchmark.paths import data_dir

RESOLUTION = 0.05
#: the independent check's LM: at most this many iterations, stopping when the cost falls by less
#: than this share (and this much) per iteration (tighter than the back end's 1e-6)
CHECK_MAX_ITERATIONS = 2000
CHECK_TOLERANCE = 1e-10
#: file name -> (SE-Sync's name of the graph, the certified global minimum f* of :func:`sesync_cost`):
#: Rosen, Carlone, Bandeira, Leonard, "SE-Sync: A certifiably correct algorithm for synchronization
#: over the special Euclidean group", IJRR 38(2-3), 2019, Table 1 (SE-Sync's objective value);
#: the paper and the data (data/CSAIL.g2o, data/manhattan.g2o) in github.com/david-m-rosen/SE-Sync
#: at commit 9b631b6b82d8aa7d32ab846412ae1c070412b7b6, under references/
SESYNC_OPTIMA = {"CSAIL_P_toro.graph": ("csail", 3.170e1), "M3500_P_toro.graph": ("manhattan", 6.432e3)}
SESYNC_SOURCE = ("Rosen et al., SE-Sync: a certifiably correct algorithm for synchronization over the special "
                 "Euclidean group, IJRR 38(2-3), 2019, Table 1 (SE-Sync's objective value, 4 digits); the paper in "
                 "github.com/david-m-rosen/SE-Sync references/ at commit 9b631b6b82d8aa7d32ab846412ae1c070412b7b6, "
                 "whose data/CSAIL.g2o and data/manhattan.g2o hold the graphs of CSAIL_P_toro.graph and "
                 "M3500_P_toro.graph")


def sesync_cost(g, states: np.ndarray) -> float:
    """SE-Sync's cost (Rosen et al. 2019, Problem 1, eq. 12) of the graph ``g``
    (:class:`envs.logs.g2o.PoseGraphFile`) at ``states`` (N, 3) x, y, theta: the sum over edges of
    ``kappa ||R_j - R_i R~_ij||_F^2 + tau ||t_j - t_i - R_i t~_ij||^2`` with R~_ij, t~_ij the
    measurement, kappa the information's I33 and tau = 2 / tr(Sigma_t), Sigma_t the inverse of the
    information's xy block (as SE-Sync reads a g2o edge, C++/SE-Sync/src/SESync_utils.cpp). In 2D
    ``||R(a) - R(b)||_F^2 = 4 (1 - cos(a - b))``."""
    s = np.asarray(states, np.float64).reshape(-1, 3)
    xi, xj, z = s[g.i], s[g.j], np.asarray(g.z, np.float64)
    kappa = g.information[:, 2, 2]
    tau = 2.0 / np.trace(np.linalg.inv(g.information[:, :2, :2]), axis1=1, axis2=2)
    rot = 4.0 * (1.0 - np.cos(xj[:, 2] - xi[:, 2] - z[:, 2]))
    c, sn = np.cos(xi[:, 2]), np.sin(xi[:, 2])
    rt = np.column_stack([c * z[:, 0] - sn * z[:, 1], sn * z[:, 0] + c * z[:, 1]])  # R_i t~_ij
    d = xj[:, :2] - xi[:, :2] - rt
    return float(np.sum(kappa * rot + tau * np.einsum("ei,ei->e", d, d)))


def sesync_weighted(g):
    """A copy of ``g`` whose every edge carries SE-Sync's weights as a g2o information matrix:
    ``diag(tau, tau, 2 kappa)`` (:func:`sesync_cost`). Its chi2 is SE-Sync's cost to second order
    in each edge's angle error (``4 kappa (1 - cos d) = 2 kappa d^2 + O(d^4)``), the translation
    taken through SE(2)'s logarithm by the project's solve rather than as SE-Sync's plain
    difference: no SE-Sync solver, a descent towards its optimum from given states."""
    import dataclasses

    kappa = g.information[:, 2, 2]
    tau = 2.0 / np.trace(np.linalg.inv(g.information[:, :2, :2]), axis1=1, axis2=2)
    info = np.zeros_like(g.information)
    info[:, 0, 0] = info[:, 1, 1] = tau
    info[:, 2, 2] = 2.0 * kappa
    return dataclasses.replace(g, information=info)


def graph_files(folder: Path) -> list[Path]:
    """The TORO (``*.graph``) and g2o (``*.g2o``) files of ``folder``, sorted by name."""
    if not folder.is_dir():
        raise FileNotFoundError(f"pose-graph folder not found: {folder} (python -m benchmark.commands.data fetch "
                                f"real_graphs, or --dir)")
    files = sorted(p for p in folder.iterdir() if p.suffix in (".graph", ".g2o") and p.is_file())
    if not files:
        raise FileNotFoundError(f"{folder}: no *.graph or *.g2o file: expected TORO or g2o pose graphs")
    return files


def write_g2o(g, path: Path) -> None:
    """``g`` (:class:`envs.logs.g2o.PoseGraphFile`) as a g2o text file (VERTEX_SE2 / EDGE_SE2,
    information row by row), vertices numbered 0..N-1 as the rows of ``g.ids``."""
    lines = [f"VERTEX_SE2 {k} {x!r} {y!r} {t!r}" for k, (x, y, t) in enumerate(g.initial.tolist())]
    for a, b, z, m in zip(g.i.tolist(), g.j.tolist(), g.z.tolist(), g.information):
        up = " ".join(repr(float(m[r, c])) for r, c in ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)))
        lines.append(f"EDGE_SE2 {a} {b} {z[0]!r} {z[1]!r} {z[2]!r} {up}")
    path.write_text("\n".join(lines) + "\n")


def gtsam_check(path: Path, g) -> tuple[float | None, str]:
    """(chi2, note) of the independent check: ``gtsam.readG2o`` + GTSAM's LM with default
    parameters; chi2 None and GTSAM's first line as the note when it raises."""
    import gtsam

    with tempfile.TemporaryDirectory() as tmp:
        src = path
        if g.format != "g2o":
            src = Path(tmp) / "graph.g2o"
            write_g2o(g, src)
        try:
            fg, values = gtsam.readG2o(str(src), False)
            fg.add(gtsam.PriorFactorPose2(0, values.atPose2(0), gtsam.noiseModel.Constrained.All(3)))
            params = gtsam.LevenbergMarquardtParams()
            params.setMaxIterations(CHECK_MAX_ITERATIONS)
            params.setRelativeErrorTol(CHECK_TOLERANCE)
            params.setAbsoluteErrorTol(CHECK_TOLERANCE)
            result = gtsam.LevenbergMarquardtOptimizer(fg, values, params).optimize()
            fg.remove(fg.size() - 1)
            return 2.0 * fg.error(result), ""
        except RuntimeError as e:
            return None, str(e).strip().splitlines()[0]


def solve_graph(path: Path) -> dict:
    """One row of the ``graphs`` table for the pose graph at ``path`` (module docstring)."""
    from benchmark.conditions.pose_graph import graph_of_file, solve
    from envs.logs.g2o import read_pose_graph

    g = read_pose_graph(path)
    graph = graph_of_file(g)
    cond = float(np.max(np.linalg.cond(g.information)))
    chi2_initial = solve(graph, g.initial, kernel="none", max_iterations=0)[1]["chi2"]  # the cost, no step
    row = {"graph": path.name, "format": g.format, "vertices": g.n, "edges": len(g.i), "max_info_cond": cond,
           "chi2_initial": chi2_initial, "sesync_cost": None, "sesync_reweighted": None,
           "sesync_optimum": SESYNC_OPTIMA.get(path.name, (None, None))[1]}
    try:
        states, info = solve(graph, g.initial, kernel="none")
        row.update(chi2=info["chi2"], g2o_chi2=g.chi2(states), iterations=info["iterations"],
                   converged=info["converged"], note="")
        if path.name in SESYNC_OPTIMA:
            row["sesync_cost"] = sesync_cost(g, states)
            reweighted, _ = solve(graph_of_file(sesync_weighted(g)), states, kernel="none")
            row["sesync_reweighted"] = sesync_cost(g, reweighted)
        if info["iterations"] == 0 and chi2_initial > 0:  # the back end counts that as converged
            row["converged"] = False
            row["note"] = ("no step taken: every damped step failed (near-singular information matrices make the "
                           "linear system ill-posed for GTSAM's Cholesky)")
    except RuntimeError as e:
        row.update(chi2=None, g2o_chi2=None, iterations=None, converged=False,
                   note=str(e).strip().splitlines()[0])
    check, why = gtsam_check(path, g)
    row["gtsam_readG2o_lm_chi2"] = check
    if why:
        row["note"] = "; ".join(x for x in (row["note"], f"check: {why}") if x)
    return row


def graphs_table(rows: list[dict]) -> str:
    """The Markdown table of :func:`solve_graph` rows and the lines under it."""
    head = ("| graph | format | vertices | edges | max cond(I) | chi2 initial | chi2 (ours) | g2o chi2 (ours) | "
            "iterations | converged | chi2 readG2o + LM | SE-Sync cost (ours) | SE-Sync cost, reweighted solve | "
            "SE-Sync f* (a) | note |")
    out = [head, "|:--|:--|--:|--:|--:|--:|--:|--:|--:|:--|--:|--:|--:|--:|:--|"]

    def num(v, fmt):
        return "–" if v is None or (isinstance(v, float) and not math.isfinite(v)) else format(v, fmt)

    for r in rows:
        out.append(f"| {r['graph']} | {r['format']} | {r['vertices']} | {r['edges']} | {num(r['max_info_cond'], '.2e')} "
                   f"| {num(r['chi2_initial'], '.6g')} | {num(r['chi2'], '.6g')} | {num(r['g2o_chi2'], '.6g')} | "
                   f"{num(r['iterations'], 'd')} | {'yes' if r['converged'] else 'no'} | "
                   f"{num(r['gtsam_readG2o_lm_chi2'], '.6g')} | {num(r['sesync_cost'], '.6g')} | "
                   f"{num(r['sesync_reweighted'], '.6g')} | "
                   f"{num(r['sesync_optimum'], '.3e')} | {r['note'] or ''} |")
    out += ["", "chi2: the sum of squared whitened residuals Log(Z^-1 X_i^-1 X_j) over every edge (GTSAM's "
            "BetweenFactorPose2 cost, twice its error), from the file's own initial guess; ours: "
            "benchmark.conditions.pose_graph.solve (LM to a relative decrease of 1e-6, kernel none); g2o chi2: the "
            "same answer under g2o's EdgeSE2 error t2v(Z^-1 X_i^-1 X_j); readG2o + LM: the file read by "
            "gtsam.readG2o (a TORO file written out in g2o order first: readG2o reads every file in g2o order) and "
            f"GTSAM's LevenbergMarquardtOptimizer (up to {CHECK_MAX_ITERATIONS} iterations, relative and absolute tolerance {CHECK_TOLERANCE:g}), node 0 held by a prior. max cond(I): the "
            "largest condition number of an edge's information matrix. A TORO file's information is read into the "
            "frame of the error above (envs.logs.g2o: rotated by the measured angle, as in the graphs' own g2o "
            "versions). SE-Sync cost (ours): SE-Sync's objective (Rosen et al. 2019, eq. 12: the sum of kappa "
            "||R_j - R_i R~_ij||_F^2 + tau ||t_j - t_i - R_i t~_ij||^2, kappa = I33, tau = 2 / tr(Sigma_t)) at our "
            "answer, for the graphs SE-Sync publishes; no poses score below f*, its certified global minimum. "
            "Reweighted solve: the same cost after our solve of the graph with SE-Sync's weights (information "
            "diag(tau, tau, 2 kappa)) from our answer: f* when our answer lies in f*'s basin.",
            "", f"(a) {SESYNC_SOURCE}."]
    return "\n".join(out)


def maps_rows(folder: Path, out_dir: Path | None) -> list[dict]:
    """Per CARMEN log of ``folder``: its raw map's statistics (and its ROS map in ``out_dir``)."""
    from envs.logs.carmen import read_carmen
    from envs.logs.raw_map import raw_map_from_log
    from envs.maps.map_stats import map_stats

    if not folder.is_dir():
        raise FileNotFoundError(f"log folder not found: {folder} (python -m benchmark.commands.data fetch real_logs, "
                                f"or --dir)")
    logs = sorted(p for p in folder.iterdir() if p.name.endswith((".log", ".log.gz")))
    if not logs:
        raise FileNotFoundError(f"{folder}: no *.log or *.log.gz file: expected CARMEN logs")
    rows = []
    for p in logs:
        occ, origin = raw_map_from_log(read_carmen(p), RESOLUTION)
        name = p.name.split(".log")[0]
        rows.append({"map": f"{name} (raw)", **map_stats(occ, RESOLUTION)})
        if out_dir is not None:
            from envs.maps.ros import write_ros_map

            img = np.full(occ.shape, 205, np.uint8)
            img[occ == 0] = 254
            img[occ == 100] = 0
            bottom = origin[1] - occ.shape[0] * RESOLUTION
            write_ros_map(out_dir / f"{name}_raw.yaml", img, RESOLUTION, (origin[0], bottom, 0.0))
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="what", required=True)
    g = sub.add_parser("graphs", help="solve the real pose graphs, chi2 beside GTSAM's own reader and LM")
    g.add_argument("--dir", type=Path, default=None, help="folder of *.graph / *.g2o files (<data root>/real_graphs)")
    g.add_argument("--out", type=Path, default=None, help="also write the table here (results/published/real_graphs.md)")
    m = sub.add_parser("maps", help="raw maps of the real CARMEN logs and their map statistics")
    m.add_argument("--dir", type=Path, default=None, help="folder of CARMEN logs (<data root>/real_logs)")
    m.add_argument("--out-dir", type=Path, default=None, help="also write each raw map as a ROS map here")
    a = ap.parse_args(argv)
    try:
        if a.what == "graphs":
            rows = [solve_graph(p) for p in graph_files(a.dir or data_dir() / "real_graphs")]
            text = graphs_table(rows)
        else:
            import pandas as pd

            if a.out_dir is not None:
                a.out_dir.mkdir(parents=True, exist_ok=True)
            text = pd.DataFrame(maps_rows(a.dir or data_dir() / "real_logs", a.out_dir)).to_markdown(
                index=False, floatfmt=".3f")
    except cli_errors() as e:
        print(f"error: {one_line(e)}", file=sys.stderr)
        return 2
    print(text)
    if a.what == "graphs" and a.out is not None:
        from benchmark.reports.published import write_published

        command = "python -m benchmark.commands.real_logs graphs" + (f" --dir {a.dir}" if a.dir else "")
        err = write_published(a.out, f"{command} --out {a.out}", text)
        if err is not None:
            print(f"error: {err}", file=sys.stderr)
            return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
