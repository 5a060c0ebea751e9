"""The SeLRoS release (30 ProcTHOR environments; see the shared data's README) and the geometric
baselines on maps given as files.

The SeLRoS and VRF outputs are scored by :class:`benchmark.baselines.external.ExternalMethod`
from the presets ``conf/scoring/external/selros.yaml`` and ``vrf.yaml``. The geometric segmenters
need an occupancy map: they take it from files (:func:`geometric_rows`), never from the
ground truth's rooms. For the SeLRoS release the map is the free space the other methods were
given: the non-black pixels of the VRF outputs. They equal the SeLRoS outputs' on all 30 maps
and the ground truth's on 29 (on map 25 the ground truth has 74 more pixels; checked by
``tests/test_selros.py``). The ground truth draws no border lines between rooms (rooms of
different colours touch at their doorways), so neither map carries room borders.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
from PIL import Image

from benchmark.metrics import MetricParams, describe, score_instances
from benchmark.paths import selros_dir

#: The release's folders and file name rules (ground truth, occupancy maps = VRF outputs).
GT_FOLDER, GT_PATTERN = "ground_truth", "{id}_ground_truth.png"
OCCUPANCY_FOLDER, OCCUPANCY_PATTERN = "vrf", "{id}_segmented.png"


def default_selros_dir() -> Path:
    """The SeLRoS release under the shared-data root (:func:`benchmark.paths.selros_dir`)."""
    return selros_dir()


def read_free_space(path: str | Path) -> np.ndarray:
    """An occupancy image -> (H, W) bool free space: every pixel that is not black (0, 0, 0)
    (instance-coloured maps; a plain occupancy PNG with white free space reads the same)."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"occupancy map not found: {path}")
    return np.asarray(Image.open(path).convert("RGB")).any(axis=-1)


def geometric_rows(gt_paths: dict[str, Path], occupancy_paths: dict[str, Path], params: MetricParams,
                   resolution: float, dataset: str = "selros", segmenters: dict | None = None,
                   keep=None) -> pd.DataFrame:
    """Per-map rows of the geometric segmenters, each run on the map's occupancy image.

    Args:
        gt_paths: map id -> instance-coloured ground truth.
        occupancy_paths: map id -> occupancy image (non-black = free); a missing one fails
            that map's rows, naming the file.
        params: metric and colour rules.
        resolution: metres per pixel of both images.
        dataset: value of the ``dataset`` column.
        segmenters: name -> segmenter (default: morphological, distance, voronoi; ROSE² is added by
            the command when a checkout is given).
        keep: a :class:`benchmark.baselines.external.MapSample` keeping the maps of a few ids.
    Returns: DataFrame, one row per (map, segmenter), columns as external scoring.
    """
    from benchmark.baselines.external import read_gt
    from benchmark.segmenters.distance import DistanceTransform
    from benchmark.segmenters.morphological import Morphological
    from benchmark.segmenters.voronoi import Voronoi
    from envs.maps.gridmap import GridMap

    if segmenters is None:
        segmenters = {"morphological": Morphological(), "distance": DistanceTransform(), "voronoi": Voronoi()}
    rows = []
    for mid, gpath in gt_paths.items():
        try:
            gt, _ = read_gt(gpath, "instance", params, resolution)
            occ = occupancy_paths.get(mid)
            if occ is None:
                raise FileNotFoundError(f"no occupancy map for {mid!r}")
            free = read_free_space(occ)
            if free.shape != gt.shape:
                raise ValueError(f"occupancy map {occ} has shape {free.shape}, ground truth {gt.shape}")
            grid = GridMap(free, resolution, (0.0, 0.0))
            err = None
        except Exception as e:  # one map fails alone
            err = f"{type(e).__name__}: {e}"
        for name, seg in segmenters.items():
            row = {"house_id": mid, "dataset": dataset, "method": name, "resolution": resolution,
                   "metric_params": describe(params, resolution, colours=True), "status": "ok", "error": ""}
            try:
                if err:
                    raise RuntimeError(err)
                inst = seg(grid)
                row.update(score_instances(inst, gt, params, resolution=resolution))
                if keep is not None:
                    keep.add(name, mid, inst, gt)
                row.update(getattr(seg, "last_info", None) or {})  # e.g. ROSE²'s seconds (t_rose2)
            except Exception as e:  # one map fails alone
                row.update(status="failed", error=err or f"{type(e).__name__}: {e}")
            rows.append(row)
    return pd.DataFrame(rows)
