"""What an occupancy map looks like, in numbers: for comparing simulated robot maps with real ones.

Every statistic takes a trinary occupancy raster (H, W) int8 (-1 unknown, 0 free, 100 occupied,
as ``nav_msgs/OccupancyGrid``) and its resolution (metres per cell):

* ``wall_thickness_m``: the mean thickness of occupied structure: at each cell of the occupied
  cells' skeleton (scikit-image), twice its Euclidean distance to the nearest non-occupied cell,
  less one cell (a 1-cell wall is 1 cell thick, a 3-cell wall 3), times the resolution.
* ``speckle_per_m2``: specks in free space per m^2 of free space: 8-connected components of
  non-free cells (occupied or unknown) of at most ``speckle_max_m2`` (default 0.01 m^2, 4 cells at
  0.05 m) whose every 8-neighbour outside the component is free.
* ``clutter_per_m2``, ``clutter_median_m2``: occupied 8-connected components whose bounding box
  diagonal is below ``clutter_max_m`` (default 1 m: furniture, legs, people; walls are longer),
  counted per m^2 of free space, and their median area in m^2 (0 when there is none).
* ``unknown_inside``: the share of unknown cells inside the building outline; the outline is the
  known (free or occupied) cells closed by a disk of ``outline_close_m`` (default 0.5 m) with holes
  filled (SciPy).
* ``wall_straight``: the share of skeleton cells of the occupied structure within 1 cell of a
  straight segment at least ``line_min_m`` long (default 1 m) found by OpenCV's probabilistic Hough
  transform (1 px, 1 degree, gaps up to 2 cells bridged).

:func:`occupancy_from_grey` turns an image into the trinary raster by two grey thresholds.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import ndimage

from envs.maps.distance import distance_px

FREE, UNKNOWN, OCCUPIED = 0, -1, 100
EIGHT = np.ones((3, 3), bool)


def occupancy_from_grey(grey: np.ndarray, free_min: int, occupied_max: int) -> np.ndarray:
    """(H, W) grey levels -> trinary occupancy: ``>= free_min`` free, ``<= occupied_max`` occupied,
    unknown between. ROS trinary PNGs (254 / 205 / 0) read with ``free_min=250, occupied_max=50``."""
    g = np.asarray(grey)
    if g.ndim == 3:
        g = g[..., :3].mean(axis=2)
    if not occupied_max < free_min:
        raise ValueError(f"grey thresholds occupied_max={occupied_max} free_min={free_min}: expected "
                         f"occupied_max < free_min")
    occ = np.full(g.shape, UNKNOWN, np.int8)
    occ[g >= free_min] = FREE
    occ[g <= occupied_max] = OCCUPIED
    return occ


def _skeleton(mask: np.ndarray) -> np.ndarray:
    from skimage.morphology import skeletonize

    return skeletonize(mask) if mask.any() else np.zeros_like(mask)


def wall_thickness(occ: np.ndarray, resolution: float) -> float:
    """Mean thickness of occupied structure, metres (module docstring); NaN without any."""
    wall = np.asarray(occ) == OCCUPIED
    if not wall.any():
        return math.nan
    dist = distance_px(np.pad(wall, 1))[1:-1, 1:-1]
    skel = _skeleton(wall)
    return float(np.mean(2.0 * dist[skel] - 1.0) * resolution)


def speckle_per_m2(occ: np.ndarray, resolution: float, speckle_max_m2: float = 0.01) -> float:
    """Specks (small non-free components surrounded by free cells) per m^2 of free space."""
    occ = np.asarray(occ)
    free = occ == FREE
    if not free.any():
        return math.nan
    labels, n = ndimage.label(~free, structure=EIGHT)
    if n == 0:
        return 0.0
    area = np.bincount(labels.ravel(), minlength=n + 1)
    # every 8-neighbour of a component outside it is free (8-connected components cannot touch),
    # unless it reaches the map's edge
    edge = np.zeros(n + 1, bool)
    edge[np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]])] = True
    small = area <= speckle_max_m2 / resolution ** 2 + 1e-9
    ok = small & ~edge
    ok[0] = False
    return float(ok.sum() / (free.sum() * resolution ** 2))


def clutter(occ: np.ndarray, resolution: float, clutter_max_m: float = 1.0) -> tuple[float, float]:
    """(blobs per m^2 of free space, their median area m^2): occupied components shorter than
    ``clutter_max_m`` (bounding-box diagonal between cell centres, metres)."""
    occ = np.asarray(occ)
    free_m2 = float((occ == FREE).sum()) * resolution ** 2
    labels, n = ndimage.label(occ == OCCUPIED, structure=EIGHT)
    if n == 0 or free_m2 == 0:
        return (0.0 if free_m2 else math.nan), 0.0
    areas = np.bincount(labels.ravel(), minlength=n + 1)[1:] * resolution ** 2
    sizes = []
    for k, sl in enumerate(ndimage.find_objects(labels)):
        diag = math.hypot(sl[0].stop - sl[0].start - 1, sl[1].stop - sl[1].start - 1) * resolution
        if diag < clutter_max_m:
            sizes.append(areas[k])
    return len(sizes) / free_m2, float(np.median(sizes)) if sizes else 0.0


def unknown_inside(occ: np.ndarray, resolution: float, outline_close_m: float = 0.5) -> float:
    """Share of unknown cells inside the building outline (module docstring)."""
    occ = np.asarray(occ)
    known = occ != UNKNOWN
    if not known.any():
        return math.nan
    r = max(1, int(round(outline_close_m / resolution)))
    yy, xx = np.mgrid[-r:r + 1, -r:r + 1]
    disk = xx ** 2 + yy ** 2 <= r * r
    closed = ndimage.binary_closing(np.pad(known, r), disk)[r:-r, r:-r]
    outline = ndimage.binary_fill_holes(closed)
    return float((outline & ~known).sum() / outline.sum())


def wall_straightness(occ: np.ndarray, resolution: float, line_min_m: float = 1.0) -> float:
    """Share of the occupied skeleton within 1 cell of a straight segment >= ``line_min_m``."""
    import cv2

    skel = _skeleton(np.asarray(occ) == OCCUPIED)
    if not skel.any():
        return math.nan
    length = max(2, int(round(line_min_m / resolution)))
    lines = cv2.HoughLinesP(skel.astype(np.uint8) * 255, 1, np.pi / 180, threshold=max(2, length // 2),
                            minLineLength=length, maxLineGap=2)
    drawn = np.zeros(skel.shape, np.uint8)
    for x0, y0, x1, y1 in ([] if lines is None else np.asarray(lines).reshape(-1, 4)):
        cv2.line(drawn, (int(x0), int(y0)), (int(x1), int(y1)), 1, thickness=3)
    return float((skel & (drawn > 0)).sum() / skel.sum())


def map_stats(occ: np.ndarray, resolution: float) -> dict[str, float]:
    """Every statistic of the module docstring, with the map's free area (m^2)."""
    occ = np.asarray(occ)
    if occ.ndim != 2 or not np.isin(occ, (FREE, UNKNOWN, OCCUPIED)).all():
        raise ValueError(f"occupancy must be (H, W) of -1 / 0 / 100, got shape {occ.shape} "
                         f"values {np.unique(occ)[:6].tolist()}")
    if not (math.isfinite(resolution) and resolution > 0):
        raise ValueError(f"resolution = {resolution!r}: expected metres per cell > 0")
    n_clutter, clutter_m2 = clutter(occ, resolution)
    return {"free_m2": float((occ == FREE).sum() * resolution ** 2),
            "wall_thickness_m": wall_thickness(occ, resolution),
            "speckle_per_m2": speckle_per_m2(occ, resolution),
            "clutter_per_m2": n_clutter, "clutter_median_m2": clutter_m2,
            "unknown_inside": unknown_inside(occ, resolution),
            "wall_straight": wall_straightness(occ, resolution)}


__all__ = ["map_stats", "occupancy_from_grey", "wall_thickness", "speckle_per_m2", "clutter", "unknown_inside",
           "wall_straightness"]
