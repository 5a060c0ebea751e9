"""Post-processing of a label map (PAPER.md step 4), each step a plain function.

1. :func:`rescale` the labels and the walkable mask to ``target_resolution`` (nearest).
2. Background = the non-walkable pixels (never labelled).
3. :func:`mode_filter`: ``iterations`` passes of a ``window`` x ``window`` majority filter
   over labelled pixels (background and unlabelled do not vote; ties: lower class index).
4. :func:`remove_small_components`: connected regions of one label smaller than
   ``min_area`` square metres become unlabelled.
5. :func:`fill_unlabelled`: unlabelled walkable pixels take the majority label of their
   labelled 3 x 3 neighbours, repeated until nothing changes (so every walkable pixel
   connected to a labelled one ends up labelled).
6. :func:`regularise`: each label's regions are replaced by Douglas-Peucker polygons
   (``dp_tolerance`` metres; OpenCV contours + approxPolyDP, holes kept); larger regions are
   drawn first so smaller ones stay on top; the result is cut to the walkable mask and the
   pixels this empties are filled again as in step 5.

The result is resampled (nearest) back to the input grid, cut to its walkable mask, and
unlabelled walkable pixels are filled once more (step 5 on the input grid).
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np

from benchmark.metrics import resample_nearest
from envs.classes import PAPER_CLASSES
from envs.gridmap import GridMap


def check_labels(labels: np.ndarray, walkable: np.ndarray, n_classes: int) -> np.ndarray:
    """Validate a label map against its walkable mask and class count."""
    labels = np.asarray(labels)
    walkable = np.asarray(walkable, dtype=bool)
    if labels.shape != walkable.shape:
        raise ValueError(f"label map shape {labels.shape} differs from walkable mask shape {walkable.shape}")
    if labels.size == 0 or not walkable.any():
        raise ValueError("post-processing needs a map with walkable pixels (got an all-background map)")
    if labels.min() < -1 or labels.max() >= n_classes:
        bad = np.unique(labels[(labels < -1) | (labels >= n_classes)])
        raise ValueError(f"unknown label value(s) {bad[:5].tolist()}; expected -1 or 0..{n_classes - 1}")
    return labels.astype(np.int32)


def rescale(labels: np.ndarray, walkable: np.ndarray, resolution: float, target_resolution: float):
    """Nearest resampling of labels and mask from ``resolution`` to ``target_resolution`` (m/px)."""
    h, w = labels.shape
    f = resolution / target_resolution
    shape = (max(int(round(h * f)), 1), max(int(round(w * f)), 1))
    return resample_nearest(labels, shape), resample_nearest(walkable, shape).astype(bool)


def _class_counts(labels: np.ndarray, n_classes: int, window: int) -> np.ndarray:
    return np.stack([cv2.boxFilter((labels == k).astype(np.float32), -1, (window, window), normalize=False,
                                   borderType=cv2.BORDER_CONSTANT) for k in range(n_classes)])


def mode_filter(labels: np.ndarray, walkable: np.ndarray, n_classes: int, window: int = 5,
                iterations: int = 2) -> np.ndarray:
    """Iterated sliding-window majority over labelled pixels; labelled pixels only change."""
    if window < 1 or window % 2 == 0:
        raise ValueError(f"mode window must be an odd number of pixels, got {window}")
    lab = labels.copy()
    for _ in range(iterations):
        counts = _class_counts(lab, n_classes, window)
        best = np.argmax(counts, axis=0).astype(np.int32)
        m = (lab >= 0) & walkable
        lab[m] = best[m]
    return lab


def remove_small_components(labels: np.ndarray, min_area_px: float, connectivity: int = 4) -> np.ndarray:
    """Regions of one label with fewer than ``min_area_px`` pixels become -1."""
    lab = labels.copy()
    for k in np.unique(lab[lab >= 0]):
        n, comp, stats, _ = cv2.connectedComponentsWithStats((lab == k).astype(np.uint8), connectivity=connectivity)
        small = np.nonzero(stats[1:, cv2.CC_STAT_AREA] < min_area_px)[0] + 1
        if len(small):
            lab[np.isin(comp, small)] = -1
    return lab


def fill_unlabelled(labels: np.ndarray, walkable: np.ndarray, n_classes: int) -> np.ndarray:
    """Unlabelled walkable pixels take the majority of their labelled 3 x 3 neighbours
    (ties: lower class index), repeated until nothing changes."""
    lab = labels.copy()
    while True:
        todo = walkable & (lab < 0)
        if not todo.any():
            return lab
        rr, cc = np.nonzero(todo)
        r0, r1 = max(rr.min() - 1, 0), rr.max() + 2
        c0, c1 = max(cc.min() - 1, 0), cc.max() + 2
        sub = lab[r0:r1, c0:c1]
        counts = _class_counts(sub, n_classes, 3)
        best = np.argmax(counts, axis=0).astype(np.int32)
        upd = todo[r0:r1, c0:c1] & (counts.max(axis=0) > 0)
        if not upd.any():
            return lab
        sub[upd] = best[upd]


def regularise(labels: np.ndarray, walkable: np.ndarray, n_classes: int, tolerance_px: float) -> np.ndarray:
    """Replace each label's regions by Douglas-Peucker polygons (larger regions drawn first),
    cut to the walkable mask, and refill emptied walkable pixels."""
    regions = []
    for k in np.unique(labels[labels >= 0]):
        mask = (labels == k).astype(np.uint8)
        contours, hier = cv2.findContours(mask, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_NONE)
        if hier is None:
            continue
        poly = np.zeros_like(mask)
        for i, cnt in enumerate(contours):
            approx = cv2.approxPolyDP(cnt, tolerance_px, True) if tolerance_px > 0 else cnt
            if hier[0, i, 3] < 0:  # outer boundary
                cv2.drawContours(poly, [approx], -1, 1, thickness=cv2.FILLED)
        for i, cnt in enumerate(contours):
            approx = cv2.approxPolyDP(cnt, tolerance_px, True) if tolerance_px > 0 else cnt
            if hier[0, i, 3] >= 0:  # hole: clear its inside, keep its boundary pixels
                cv2.drawContours(poly, [approx], -1, 0, thickness=cv2.FILLED)
                cv2.drawContours(poly, [approx], -1, 1, thickness=1)
        regions.append((int(mask.sum()), int(k), poly.astype(bool)))
    out = np.full(labels.shape, -1, np.int32)
    for _, k, poly in sorted(regions, key=lambda t: (-t[0], t[1])):
        out[poly] = k
    out[~walkable] = -1
    return fill_unlabelled(out, walkable, n_classes)


class PostProcess:
    """The six-step post-processing; called ``pp(labels, grid) -> labels`` on grid's shape.

    Args:
        target_resolution: metres per pixel at which the clean-up runs.
        window, iterations: mode filter window (pixels, odd) and passes.
        min_area: smallest kept region, square metres.
        dp_tolerance: Douglas-Peucker tolerance, metres (0 disables regularisation).
        classes: the ordered class names (their count bounds the label values).
    """

    def __init__(self, target_resolution: float = 0.1, window: int = 5, iterations: int = 2, min_area: float = 0.5,
                 dp_tolerance: float = 0.1, classes: Sequence[str] = PAPER_CLASSES):
        if target_resolution <= 0 or min_area < 0 or dp_tolerance < 0 or iterations < 0:
            raise ValueError("PostProcess needs target_resolution > 0 and min_area, dp_tolerance, iterations >= 0")
        if window < 1 or window % 2 == 0:
            raise ValueError(f"mode window must be an odd number of pixels, got {window}")
        self.target_resolution, self.window, self.iterations = target_resolution, window, iterations
        self.min_area, self.dp_tolerance, self.n_classes = min_area, dp_tolerance, len(classes)

    def __call__(self, labels: np.ndarray, grid: GridMap) -> np.ndarray:
        n = self.n_classes
        labels = check_labels(labels, grid.walkable, n)
        lab, walk = rescale(labels, grid.walkable, grid.resolution, self.target_resolution)
        lab[~walk] = -1
        lab = mode_filter(lab, walk, n, self.window, self.iterations)
        lab = remove_small_components(lab, self.min_area / self.target_resolution ** 2)
        lab = fill_unlabelled(lab, walk, n)
        if self.dp_tolerance > 0:
            lab = regularise(lab, walk, n, self.dp_tolerance / self.target_resolution)
        out = resample_nearest(lab, grid.shape)
        out[~grid.walkable] = -1
        return fill_unlabelled(out, grid.walkable, n)


class NoPostProcess:
    """The raw output: labels unchanged except that non-walkable pixels are set to -1."""

    def __init__(self, classes: Sequence[str] = PAPER_CLASSES):
        self.n_classes = len(classes)

    def __call__(self, labels: np.ndarray, grid: GridMap) -> np.ndarray:
        out = check_labels(labels, grid.walkable, self.n_classes).copy()
        out[~grid.walkable] = -1
        return out
