"""Score the SeLRoS release's SeLRoS and VRF outputs against its ground truth.

``python -m benchmark.selros_table [--data ../shared/data/selros] [--min-segment-px 50] [--geometric]``
prints the per-method means (IoU, precision, recall) over the 30 environments and the
metric parameters; ``--out DIR`` also writes the per-map ``metrics.csv``.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import pandas as pd

from benchmark.baselines.external import report, score_directory
from benchmark.metrics import MetricParams, describe

#: (method, folder, file pattern) of the outputs in the SeLRoS release.
SELROS_METHODS = (("SeLRoS", "selros", "{id}_output.png"), ("VRF", "vrf", "{id}_segmented.png"))
SELROS_RESOLUTION = 0.02  # metres per pixel


def default_selros_dir() -> Path:
    return Path(os.environ.get("ROOMSEG_SHARED_DATA", "../shared/data")) / "selros"


def selros_rows(data: Path, params: MetricParams) -> pd.DataFrame:
    """Per-map rows of every method in the SeLRoS release."""
    frames = [score_directory(data / "ground_truth", "{id}_ground_truth.png", data / folder, pattern, method,
                              params, dataset="selros", resolution=SELROS_RESOLUTION)
              for method, folder, pattern in SELROS_METHODS]
    return pd.concat(frames, ignore_index=True)


def geometric_rows(data: Path, params: MetricParams) -> pd.DataFrame:
    """Per-map rows of the geometric baselines run on each ground-truth map's walkable mask."""
    from benchmark.baselines.geometric import DistanceTransform, Morphological, Voronoi
    from benchmark.metrics import score_instances
    from envs.gridmap import GridMap
    from envs.mapio import read_instance_png

    rows = []
    for gpath in sorted((data / "ground_truth").glob("*_ground_truth.png")):
        mid = gpath.name.split("_")[0]
        gt = read_instance_png(gpath)
        grid = GridMap(gt >= 0, SELROS_RESOLUTION, (0.0, 0.0))
        for name, seg in (("morphological", Morphological()), ("distance", DistanceTransform()),
                          ("voronoi", Voronoi())):
            row = {"house_id": mid, "dataset": "selros", "method": name, "resolution": SELROS_RESOLUTION,
                   "metric_params": describe(params), "status": "ok", "error": ""}
            try:
                row.update(score_instances(seg(grid), gt, params))
            except Exception as e:  # one map fails alone
                row.update(status="failed", error=f"{type(e).__name__}: {e}")
            rows.append(row)
    return pd.DataFrame(rows)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="SeLRoS / VRF outputs vs the SeLRoS ground truth")
    ap.add_argument("--data", type=Path, default=default_selros_dir())
    ap.add_argument("--min-segment-px", type=int, default=MetricParams().min_segment_px)
    ap.add_argument("--connectivity", type=int, default=MetricParams().connectivity)
    ap.add_argument("--match", default=MetricParams().match)
    ap.add_argument("--out", type=Path, default=None, help="folder for metrics.csv")
    ap.add_argument("--geometric", action="store_true", help="add the geometric baselines on the same maps")
    a = ap.parse_args(argv)
    params = MetricParams(match=a.match, connectivity=a.connectivity, min_segment_px=a.min_segment_px)
    df = selros_rows(a.data, params)
    if a.geometric:
        df = pd.concat([df, geometric_rows(a.data, params)], ignore_index=True)
    report(df, params, a.out, f"; maps at {SELROS_RESOLUTION} m/px.")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
