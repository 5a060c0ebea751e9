"""Score the SeLRoS release's SeLRoS and VRF outputs against its ground truth.

``python -m benchmark.commands.selros [--data ../shared/data/selros] [--min-segment-px 50] [--geometric]``
prints the per-method means (IoU, precision, recall) over the 30 environments and the
metric parameters; ``--out DIR`` also writes the per-map ``metrics.csv``.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from benchmark.baselines.external import score_directory
from benchmark.metrics import MetricParams, describe
from benchmark.paths import selros_dir

#: (method, folder, file pattern) of the outputs in the SeLRoS release.
SELROS_METHODS = (("SeLRoS", "selros", "{id}_output.png"), ("VRF", "vrf", "{id}_segmented.png"))
SELROS_RESOLUTION = 0.02  # metres per pixel


def default_selros_dir() -> Path:
    """The SeLRoS release under the shared-data root (:func:`benchmark.paths.selros_dir`)."""
    return selros_dir()


def selros_rows(data: Path, params: MetricParams) -> pd.DataFrame:
    """Per-map rows of every method in the SeLRoS release."""
    frames = [score_directory(data / "ground_truth", "{id}_ground_truth.png", data / folder, pattern, method,
                              params, dataset="selros", resolution=SELROS_RESOLUTION)
              for method, folder, pattern in SELROS_METHODS]
    return pd.concat(frames, ignore_index=True)


def geometric_rows(data: Path, params: MetricParams) -> pd.DataFrame:
    """Per-map rows of the geometric baselines run on each ground-truth map's walkable mask."""
    from benchmark.metrics import score_instances
    from benchmark.segmenters.distance import DistanceTransform
    from benchmark.segmenters.morphological import Morphological
    from benchmark.segmenters.voronoi import Voronoi
    from envs.maps.gridmap import GridMap
    from envs.maps.label_png import read_instance_png

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
