"""The project's own headless driver of ROSE² (run by :mod:`benchmark.segmenters.rose2` with the
interpreter of the isolated environment ``make rose2-env`` creates; it imports no project module).

    <rose2 venv>/bin/python rose2_driver.py --rose2 CHECKOUT --map MAP.npy --params PARAMS.json --out OUT.json

ROSE² (Luperto et al., RA-L 2022; aislabunimi/ROSE2) is a ROS 1 package whose algorithm lives in
plain Python modules: ROSE (``rose_v1_repo``) finds the map's main directions and keeps its
structural pixels, ROSE² (``rose_v2_repo``) builds walls, extended lines, cells and rooms. Its ROS
nodes (``FeatureExtractorROSE.py``, ``FeatureExtractorROSE2.py``) only move messages and log. This
driver does what the two nodes do for one map, with no ROS:

1. the map image as the nodes build it from an ``OccupancyGrid`` (free 255, unknown 200,
   occupied 0; row 0 is the map's bottom row, as ``nav_msgs`` stores it);
2. ROSE: ``FFTStructureExtraction(map, peak_height=0.2, par=50).process_map()``; with two main
   directions or fewer the map is skipped, as the ROS node does ("not enough directions");
   then ``simple_filter_map(filter)``, ``generate_initial_hypothesis_simple()``,
   ``find_walls_flood_filing()``: the clean map;
3. ROSE²: ``Minibatch().start_main(...)`` on the clean and the original map with the main
   directions, without its optional Voronoi refinement (the node's default);
4. the rooms (shapely polygons, pixel coordinates of that image) written as JSON.

Compatibility with today's libraries, handled here and nowhere in ROSE²'s code:

* ``rospy`` is a stand-in module whose log functions write to stderr;
* scikit-learn >= 1.2 made ``DBSCAN``'s arguments keyword-only, and ROSE² passes ``min_samples``
  by position (``util/layout.py``): ``sklearn.cluster.DBSCAN`` is replaced by a subclass that
  takes them by position;
* ROSE² needs shapely < 2 (``cascaded_union``, iteration over multi-geometries) and OpenCV < 5,
  which the isolated environment pins (``make rose2-env``: the versions are in the Makefile).

Output JSON: ``{"status": "ok", "rooms": [{"exterior": [[x, y], ...], "interiors": [...]}, ...],
"n_directions": k}`` or ``{"status": "failed", "error": "..."}`` (the exit status is 0 in both
cases; non-zero only when the driver itself cannot run).
"""

from __future__ import annotations

import argparse
import io
import json
import sys
import time
import traceback
import types
import warnings
from contextlib import redirect_stdout


def _stand_in_rospy() -> types.ModuleType:
    """A ``rospy`` module with the logging functions ROSE² calls."""
    mod = types.ModuleType("rospy")

    def log(*args, **_kwargs):
        print("[rose2]", *args, file=sys.stderr)

    for name in ("loginfo", "logwarn", "logerr", "logdebug", "logfatal"):
        setattr(mod, name, log)
    return mod


def _positional_dbscan() -> None:
    """Let ``DBSCAN(eps, min_samples, ...)`` work with scikit-learn's keyword-only signature."""
    try:
        import sklearn.cluster
    except ImportError:  # a checkout that does not use scikit-learn
        return

    base = sklearn.cluster.DBSCAN

    class DBSCAN(base):  # noqa: D101 - a signature shim only
        def __init__(self, eps=0.5, min_samples=5, **kwargs):
            super().__init__(eps=eps, min_samples=min_samples, **kwargs)

    DBSCAN.__name__ = base.__name__
    sklearn.cluster.DBSCAN = DBSCAN


def segment(checkout: str, image, params: dict) -> dict:
    """ROSE then ROSE² on one map image (uint8, free 255 / unknown 200 / occupied 0, row 0 at
    the bottom). Returns the result dict (see the module doc)."""
    import numpy as np

    sys.path.insert(0, f"{checkout}/src")
    sys.modules.setdefault("rospy", _stand_in_rospy())
    _positional_dbscan()
    from rose_v1_repo.fft_structure_extraction import FFTStructureExtraction
    from rose_v2_repo import minibatch, parameters
    from skimage.util import img_as_ubyte

    grid_map = img_as_ubyte(image)
    rose = FFTStructureExtraction(grid_map, peak_height=params.get("peak_height", 0.2), par=params.get("par", 50))
    rose.process_map()
    n_dir = len(rose.main_directions)
    if n_dir <= 2:
        return {"status": "failed", "error": f"not enough directions ({n_dir} main directions; ROSE needs more than 2)",
                "n_directions": n_dir}
    rose.simple_filter_map(params.get("filter", 0.18))
    rose.generate_initial_hypothesis_simple()
    try:
        rose.find_walls_flood_filing()
    except ValueError as e:
        return {"status": "failed", "error": f"can't find walls ({e})", "n_directions": n_dir}
    clean = rose.analysed_map.astype(np.uint8)
    p = parameters.ParameterObj()
    for key in ("spatialClusteringLineSegmentsThreshold", "th1", "distance_extended_segment", "threshold_edges"):
        if key in params:
            setattr(p, key, params[key])
    p.comp = list(rose.main_directions)
    rose2 = minibatch.Minibatch()
    rose2.start_main(parameters, p, clean, image.astype(np.uint8), None, False)
    rooms = []
    for poly in rose2.rooms_th1 or []:
        if poly.is_empty:
            continue
        rooms.append({"exterior": [list(map(float, c)) for c in poly.exterior.coords],
                      "interiors": [[list(map(float, c)) for c in ring.coords] for ring in poly.interiors]})
    if not rooms:
        return {"status": "failed", "error": "no room found", "n_directions": n_dir}
    return {"status": "ok", "rooms": rooms, "n_directions": n_dir}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rose2", required=True, help="the ROSE2 checkout (its src/ holds rose_v1_repo, rose_v2_repo)")
    ap.add_argument("--map", required=True, help="the map image as .npy (uint8: 255 free, 200 unknown, 0 occupied)")
    ap.add_argument("--params", default=None, help="JSON of ROSE / ROSE2 parameters (pixels)")
    ap.add_argument("--out", required=True, help="the result JSON")
    a = ap.parse_args(argv)
    import numpy as np

    params = json.loads(open(a.params, encoding="utf-8").read()) if a.params else {}
    t = time.perf_counter()
    warnings.filterwarnings("ignore")
    try:
        with redirect_stdout(io.StringIO()):  # ROSE² prints progress; the result goes to the JSON
            out = segment(a.rose2, np.load(a.map, allow_pickle=False), params)
    except Exception as e:  # noqa: BLE001 - ROSE²'s own failure on this map, reported as a result
        tb = traceback.extract_tb(e.__traceback__)
        where = f" at {tb[-1].filename.rsplit('/', 2)[-1]}:{tb[-1].lineno}" if tb else ""
        out = {"status": "failed", "error": f"{type(e).__name__}: {' '.join(str(e).split())[:300]}{where}"}
    out["seconds"] = round(time.perf_counter() - t, 3)
    with open(a.out, "w", encoding="utf-8") as f:
        json.dump(out, f)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
