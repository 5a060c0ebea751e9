"""``make perf``: time the aggregators and post-processing against their references.

For each shared ProcTHOR house (first ``--houses``) and each resolution, autotrace poses
with random class probabilities are aggregated by the fast implementation and by its
slow reference (graph KNN: one SciPy csgraph BFS per viewpoint; vision cone: a per-ray
Python loop), on the *same* views, in the same process; the labels must be identical.
The per-ray Python reference is very slow, so it runs on the first ``--cone-ref-views``
views only and the fast version is timed again on exactly those views for the ratio.
Prints per-house medians, the speed-up ratios, and peak traced memory (tracemalloc:
Python and NumPy allocations; numba's internal work arrays are (H*W, K) int32 for graph
KNN and (C, H, W) float32 for the cone, listed as bytes per map pixel).
"""

from __future__ import annotations

import argparse
import os
import time
import tracemalloc
from pathlib import Path

import numpy as np
import pandas as pd


def _timed(fn, *args, repeat: int = 3):
    """(result, best wall time in seconds over ``repeat`` calls)."""
    best = float("inf")
    out = None
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn(*args)
        best = min(best, time.perf_counter() - t)
    return out, best


def _peak(fn, *args) -> int:
    tracemalloc.start()
    fn(*args)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return peak


def run(houses: int, resolutions: list[float], cone_ref_views: int, path: Path) -> pd.DataFrame:
    from benchmark.aggregators.graph_knn import GraphKNN
    from benchmark.aggregators.reference import graph_knn_reference, vision_cone_reference
    from benchmark.aggregators.vision_cone import VisionCone
    from benchmark.postprocess import PostProcess
    from benchmark.viewpoints import Autotrace
    from envs.house import load_houses
    from envs.scene import rasterise_house

    rows = []
    knn, cone, pp = GraphKNN(k=5), VisionCone(), PostProcess()
    for res in resolutions:
        for h in load_houses(path, 0, houses):
            s = rasterise_house(h, resolution=res)
            poses = Autotrace().generate(s)
            proba = np.random.default_rng(0).dirichlet(np.ones(7), len(poses))
            knn(s.grid, poses[:5], proba[:5])  # compile once
            lab, t_knn = _timed(knn, s.grid, poses, proba)
            ref, t_knn_ref = _timed(graph_knn_reference, s.grid, poses, proba, 5, repeat=1)
            cone_lab, t_cone = _timed(cone, s.grid, poses, proba)
            sub = slice(0, cone_ref_views)
            small, t_cone_sub = _timed(cone, s.grid, poses[sub], proba[sub])
            cref, t_cone_ref = _timed(vision_cone_reference, s.grid, poses[sub], proba[sub], repeat=1)
            post, t_pp = _timed(pp, cone_lab, s.grid)
            h_, w_ = s.grid.shape
            rows.append({
                "resolution": res, "house": h.id, "pixels": h_ * w_, "views": len(poses),
                "knn_ms": 1e3 * t_knn, "knn_ref_ms": 1e3 * t_knn_ref, "knn_speedup": t_knn_ref / t_knn,
                "knn_equal": bool(np.array_equal(lab, ref)),
                "cone_ms": 1e3 * t_cone, "cone_speedup": t_cone_ref / t_cone_sub,
                "cone_equal": bool(np.array_equal(small, cref)), "postprocess_ms": 1e3 * t_pp,
                "knn_peak_MB": _peak(knn, s.grid, poses, proba) / 2**20,
                "cone_peak_MB": _peak(cone, s.grid, poses, proba) / 2**20,
                "pp_peak_MB": _peak(pp, cone_lab, s.grid) / 2**20,
            })
            print(f"{res} m/px {h.id}: knn {1e3 * t_knn:.1f} ms (x{t_knn_ref / t_knn:.0f}), "
                  f"cone {1e3 * t_cone:.1f} ms (x{t_cone_ref / t_cone_sub:.0f}), post {1e3 * t_pp:.1f} ms", flush=True)
    return pd.DataFrame(rows)


def main(argv: list[str] | None = None) -> int:
    default = Path(os.environ.get("ROOMSEG_SHARED_DATA", "../shared/data")) / \
        "procthor/procthor-10k-uniform-hard-val.jsonl.gz"
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--houses", type=int, default=5)
    ap.add_argument("--resolutions", type=float, nargs="+", default=[0.05, 0.02])
    ap.add_argument("--cone-ref-views", type=int, default=20)
    ap.add_argument("--data", type=Path, default=default)
    a = ap.parse_args(argv)
    if not a.data.exists():
        print(f"error: shared ProcTHOR houses not found at {a.data}")
        return 2
    df = run(a.houses, a.resolutions, a.cone_ref_views, a.data)
    g = df.groupby("resolution")
    table = pd.DataFrame({
        "houses": g.size(), "median pixels": g["pixels"].median(), "median views": g["views"].median(),
        "graph KNN ms": g["knn_ms"].median(), "csgraph BFS ref ms": g["knn_ref_ms"].median(),
        "KNN speed-up": g["knn_speedup"].median(), "KNN identical": g["knn_equal"].all(),
        "vision cone ms": g["cone_ms"].median(), "cone speed-up": g["cone_speedup"].median(),
        "cone identical": g["cone_equal"].all(), "post-process ms": g["postprocess_ms"].median(),
        "KNN peak MB": g["knn_peak_MB"].median(), "cone peak MB": g["cone_peak_MB"].median(),
        "post peak MB": g["pp_peak_MB"].median(),
    }).reset_index()
    table["resolution"] = table["resolution"].map(lambda r: f"{r:g} m/px")
    print()
    print(table.to_markdown(index=False, floatfmt=".1f"))
    print(f"\nMedians over houses. Speed-ups measured in this run on the same inputs (cone: the first "
          f"{a.cone_ref_views} views). Peak MB: tracemalloc (Python/NumPy allocations).")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
