"""Post-processing of a label map (PAPER.md step 4), each step a plain NumPy function.

Label maps are (H, W) int32: class index 0..C-1, -1 unlabelled (or non-walkable).

1. :func:`rescale` the labels and the walkable mask to ``target_resolution`` m/px (nearest).
2. :func:`apply_background`: background = the non-walkable pixels; they are never labelled.
3. :func:`mode_filter`: up to ``iterations`` passes of a ``window`` x ``window`` majority filter
   over labelled pixels (background and unlabelled pixels neither vote nor change; a pixel
   keeps its label when it ties the majority, other ties go to the lower class index).
4. :func:`remove_small_components`: 4-connected regions of one label smaller than
   ``min_area`` square metres become unlabelled.
5. :func:`fill_unlabelled`: unlabelled walkable pixels take the majority label of their
   labelled 3 x 3 neighbours (ties: lower class index), repeated until nothing changes, so
   every walkable pixel 8-connected (through walkable pixels) to a labelled one ends up labelled.
6. :func:`regularise`: each label's regions are replaced by Douglas-Peucker polygons
   (``dp_tolerance`` metres; ``cv2.findContours`` + ``cv2.approxPolyDP``, holes kept). Order
   and conflicts: labels are drawn by decreasing pixel count (ties: lower class index), so
   where two simplified polygons overlap the *smaller* label wins; the result is cut to the
   walkable mask and the walkable pixels left uncovered are filled again as in step 5.

Back on the input grid (:class:`PostProcess`): the result is resampled (nearest), cut to
the input walkable mask, and filled once more (step 5 on the input grid). Finally
:func:`label_orphan_components` gives every 8-connected walkable component that held a
label in the input but lost all of them (a pocket smaller than ``min_area``, or one the
coarse grid does not resolve) the majority of its input labels. Hence the output never
labels a non-walkable pixel, and leaves a walkable pixel unlabelled only in a walkable
component that had no label in the input.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Annotated

import cv2
import numpy as np

from benchmark.interfaces import PostProcessor
from benchmark.metrics import resample_nearest, segments
from envs.kernel_cache import njit
from envs.maps.gridmap import GridMap
from envs.ranges import Integer, NonNegative, Odd, Positive
from envs.world.classes import PAPER_CLASSES


def check_labels(labels: np.ndarray, walkable: np.ndarray, n_classes: int) -> np.ndarray:
    """Validate a label map against its (H, W) walkable mask; returns it as int32 (the array
    itself when it is one: callers only read it, and a large map keeps no second copy).

    Raises ValueError for different shapes, a map with no walkable pixel, non-integer
    labels, or a label outside [-1, n_classes)."""
    labels = np.asarray(labels)
    walkable = np.asarray(walkable)
    if labels.ndim != 2:
        raise ValueError(f"label map must be 2-D (H, W), got shape {labels.shape}")
    if labels.shape != walkable.shape:
        raise ValueError(f"label map shape {labels.shape} differs from walkable mask shape {walkable.shape}")
    if labels.size == 0 or not walkable.astype(bool).any():
        raise ValueError("post-processing needs a map with walkable pixels (got an all-background map)")
    if not (np.issubdtype(labels.dtype, np.integer) or labels.dtype == bool):
        if not np.all(np.isfinite(labels)) or not np.all(labels == np.round(labels)):
            raise ValueError(f"label map must hold integer class indices, got dtype {labels.dtype} with "
                             "non-integer values")
    if n_classes < 1:
        raise ValueError(f"post-processing needs at least one class, got n_classes={n_classes}")
    bad = (labels < -1) | (labels >= n_classes)
    if bad.any():
        vals = np.unique(labels[bad])[:5].tolist()
        raise ValueError(f"unknown label value(s) {vals}; expected -1 (unlabelled) or a class index "
                         f"0..{n_classes - 1}")
    return labels.astype(np.int32, copy=False)


def rescale(labels: np.ndarray, walkable: np.ndarray, resolution: float,
            target_resolution: float) -> tuple[np.ndarray, np.ndarray]:
    """Nearest resampling of an (H, W) label map and walkable mask from ``resolution`` to
    ``target_resolution`` (both metres per pixel); the new shape is (H, W) scaled by
    resolution / target_resolution, rounded, at least 1 x 1."""
    if resolution <= 0 or target_resolution <= 0:
        raise ValueError(f"resolutions must be positive metres/pixel, got {resolution} -> {target_resolution}")
    h, w = labels.shape
    f = resolution / target_resolution
    shape = (max(int(round(h * f)), 1), max(int(round(w * f)), 1))
    return resample_nearest(labels, shape).astype(np.int32), resample_nearest(walkable, shape).astype(bool)


def apply_background(labels: np.ndarray, walkable: np.ndarray) -> np.ndarray:
    """Step 2: a copy of ``labels`` with every non-walkable (background) pixel set to -1."""
    out = np.array(labels, dtype=np.int32, copy=True)
    out[~np.asarray(walkable, dtype=bool)] = -1
    return out


def _mode_pass(lab: np.ndarray, n_classes: int, window: int) -> np.ndarray:
    """One majority pass: per labelled pixel (``lab`` >= 0) the class with the most pixels in
    its ``window`` x ``window`` neighbourhood (pixels outside the map count as nothing; ties:
    lower index), or its own label when that ties the most; -1 on unlabelled pixels.

    Window counts by running sums (:func:`_mode_kernel`): per column, each class's count over
    the window's rows, updated as the window moves down a row; along a row, their sum over the
    window's columns, updated as it moves right. Work arrays: (W, C) and (C,) counts.

    Returns:
        (H, W) int32 class indices, -1 where ``lab`` < 0."""
    lab = np.ascontiguousarray(lab, dtype=np.int32)
    return _mode_kernel(lab, int(n_classes), int(window) // 2)


@njit(cache=True, nogil=True, inline="always")
def _count_row(lab, a, col, tot, n_classes, d):
    """Add ``d`` (1 or -1) to each column's count of the class of its pixel in row ``a``."""
    for j in range(lab.shape[1]):
        k = lab[a, j]
        if 0 <= k < n_classes:
            col[j, k] += d
            tot[j] += d


@njit(cache=True, nogil=True, inline="always")
def _count_column(cnt, col, tot, b, d):
    """Add ``d`` times column ``b``'s counts to the window's (a column without any adds nothing)."""
    if tot[b]:
        for k in range(cnt.shape[0]):
            cnt[k] += d * col[b, k]


@njit(cache=True, nogil=True)
def _mode_kernel(lab, n_classes, r):
    h, w = lab.shape
    col = np.zeros((w, n_classes), np.int32)  # per column: each class's pixels in rows i - r .. i + r
    tot = np.zeros(w, np.int32)  # per column: all of them
    cnt = np.zeros(n_classes, np.int32)  # the window's counts
    best = np.zeros((h, w), np.int32)
    for a in range(min(r, h - 1) + 1):
        _count_row(lab, a, col, tot, n_classes, 1)
    for i in range(h):
        if i > 0:
            if i + r < h:
                _count_row(lab, i + r, col, tot, n_classes, 1)
            if i - r - 1 >= 0:
                _count_row(lab, i - r - 1, col, tot, n_classes, -1)
        cnt[:] = 0
        for b in range(min(r, w - 1) + 1):
            _count_column(cnt, col, tot, b, 1)
        for j in range(w):
            if j > 0:
                if j + r < w:
                    _count_column(cnt, col, tot, j + r, 1)
                if j - r - 1 >= 0:
                    _count_column(cnt, col, tot, j - r - 1, -1)
            own = lab[i, j]
            if own < 0:  # unlabelled: not voted on
                best[i, j] = -1
                continue
            top = cnt[0]
            arg = 0
            for k in range(1, n_classes):
                if cnt[k] > top:  # strictly: a tie keeps the lower class
                    top = cnt[k]
                    arg = k
            mine = cnt[own] if own < n_classes else 0  # (a label >= n_classes counts nothing)
            best[i, j] = own if mine >= top else arg  # its own class when that ties the most
    return best


def mode_filter(labels: np.ndarray, walkable: np.ndarray, n_classes: int, window: int = 5,
                iterations: int = 2) -> np.ndarray:
    """Step 3: up to ``iterations`` passes of a ``window`` x ``window`` (pixels, odd) majority
    filter. Only labelled walkable pixels vote and change; a pixel keeps its label when that
    ties the majority; stops early when a pass changes nothing."""
    if window < 1 or window % 2 == 0:
        raise ValueError(f"mode window must be an odd number of pixels, got {window}")
    if iterations < 0:
        raise ValueError(f"mode filter iterations must be >= 0, got {iterations}")
    lab = apply_background(labels, walkable)
    for _ in range(iterations):
        new = _mode_pass(lab, n_classes, window)  # (-1 where lab is: the labelled pixels stay labelled)
        if np.array_equal(new, lab):
            break
        lab = new
    return lab


def remove_small_components(labels: np.ndarray, min_area_px: float, connectivity: int = 4) -> np.ndarray:
    """Step 4: 4- (or 8-) connected regions of one label with fewer than ``min_area_px``
    pixels become -1.

    The regions of every label at once (:func:`benchmark.metrics.segments`, one labelling of
    the regions of equal value) and their sizes by counting."""
    if connectivity not in (4, 8):
        raise ValueError(f"connectivity must be 4 or 8, got {connectivity}")
    lab = np.array(labels, dtype=np.int32, copy=True)
    ids = segments(lab, connectivity)  # -1 on unlabelled pixels, regions 0..S-1
    small = np.append(np.bincount(ids[ids >= 0]) < min_area_px, False)  # (ids -1 -> the last: kept)
    lab[small[ids]] = -1
    return lab


def fill_unlabelled(labels: np.ndarray, walkable: np.ndarray, n_classes: int) -> np.ndarray:
    """Step 5: unlabelled walkable pixels take the majority of their labelled 3 x 3 neighbours
    (ties: lower class index), all at once per pass, repeated until nothing changes. Pixels
    not 8-connected through walkable pixels to any labelled one stay -1.

    Each pass visits only its front (the unlabelled walkable pixels next to a labelled one),
    in a numba loop: time O(H x W) over all passes.

    Returns:
        (H, W) int32 labels, -1 on background and on unreachable walkable pixels.
    """
    lab = apply_background(labels, walkable)
    walkable = np.ascontiguousarray(walkable, dtype=bool)
    if (lab >= n_classes).any():
        raise ValueError(f"labels must be < n_classes = {n_classes}, got {int(lab.max())}")
    _fill_fronts(lab, walkable, int(n_classes))
    return lab


@njit(cache=True)
def _fill_fronts(lab, walkable, n_classes):
    """In place: the passes of :func:`fill_unlabelled`, each over its front only (1 byte a
    pixel for the queued marks, 4 per queued pixel for its row and column: a large map's front
    costs no 64-bit arrays)."""
    h, w = lab.shape
    queued = np.zeros((h, w), np.bool_)  # put on a front already
    fr = np.empty(h * w, np.int32)
    fc = np.empty(h * w, np.int32)
    n = 0
    for i in range(h):
        for j in range(w):
            if walkable[i, j] and lab[i, j] < 0:
                for a in range(max(i - 1, 0), min(i + 2, h)):
                    for b in range(max(j - 1, 0), min(j + 2, w)):
                        if lab[a, b] >= 0 and not queued[i, j]:
                            queued[i, j] = True
                            fr[n] = i
                            fc[n] = j
                            n += 1
    counts = np.zeros(n_classes, np.int64)
    new = np.empty(h * w, np.int32)
    while n > 0:
        for t in range(n):  # every front pixel votes on the labels at the start of the pass
            i, j = fr[t], fc[t]
            counts[:] = 0
            for a in range(max(i - 1, 0), min(i + 2, h)):
                for b in range(max(j - 1, 0), min(j + 2, w)):
                    if lab[a, b] >= 0:
                        counts[lab[a, b]] += 1
            best = 0
            for k in range(1, n_classes):
                if counts[k] > counts[best]:
                    best = k
            new[t] = best
        for t in range(n):
            lab[fr[t], fc[t]] = new[t]
        m = 0  # the next front: unlabelled walkable neighbours of this pass's pixels
        for t in range(n):
            i, j = fr[t], fc[t]
            for a in range(max(i - 1, 0), min(i + 2, h)):
                for b in range(max(j - 1, 0), min(j + 2, w)):
                    if walkable[a, b] and lab[a, b] < 0 and not queued[a, b]:
                        queued[a, b] = True
                        fr[n + m] = a
                        fc[n + m] = b
                        m += 1
        fr[:m] = fr[n:n + m]
        fc[:m] = fc[n:n + m]
        n = m


def _label_polygon(mask: np.ndarray, tolerance_px: float) -> np.ndarray:
    """(H, W) bool: ``mask`` redrawn from its Douglas-Peucker simplified contours (holes kept;
    a hole's boundary pixels stay in the region)."""
    contours, hier = cv2.findContours(mask.astype(np.uint8), cv2.RETR_CCOMP, cv2.CHAIN_APPROX_NONE)
    poly = np.zeros(mask.shape, np.uint8)
    if hier is None:
        return poly.astype(bool)
    approx = [cv2.approxPolyDP(c, tolerance_px, True) if tolerance_px > 0 else c for c in contours]
    outer = [a for a, h in zip(approx, hier[0]) if h[3] < 0]
    holes = [a for a, h in zip(approx, hier[0]) if h[3] >= 0]
    cv2.drawContours(poly, outer, -1, 1, thickness=cv2.FILLED)
    if holes:
        cv2.drawContours(poly, holes, -1, 0, thickness=cv2.FILLED)
        cv2.drawContours(poly, holes, -1, 1, thickness=1)
    return poly.astype(bool)


def regularise(labels: np.ndarray, walkable: np.ndarray, n_classes: int, tolerance_px: float) -> np.ndarray:
    """Step 6: each label's regions become Douglas-Peucker polygons (``tolerance_px`` pixels),
    drawn by decreasing pixel count (ties: lower class index) so a smaller label wins where
    polygons overlap; then cut to the walkable mask and walkable pixels left uncovered are
    refilled by :func:`fill_unlabelled`."""
    if tolerance_px < 0:
        raise ValueError(f"Douglas-Peucker tolerance must be >= 0 pixels, got {tolerance_px}")
    present = np.unique(labels[labels >= 0])
    sizes = [(-int((labels == k).sum()), int(k)) for k in present]
    out = np.full(labels.shape, -1, np.int32)
    for _, k in sorted(sizes):
        out[_label_polygon(labels == k, tolerance_px)] = k
    return fill_unlabelled(out, walkable, n_classes)


def label_orphan_components(labels: np.ndarray, reference: np.ndarray, walkable: np.ndarray,
                            n_classes: int) -> np.ndarray:
    """Every 8-connected walkable component with no label in ``labels`` but some label in
    ``reference`` (the input map) takes the majority of its ``reference`` labels (ties: lower
    class index). Other pixels are unchanged."""
    walkable = np.asarray(walkable, dtype=bool)
    lab = apply_background(labels, walkable)
    n, comp = cv2.connectedComponents(np.ascontiguousarray(walkable).view(np.uint8), connectivity=8,
                                      ltype=cv2.CV_32S)
    if n <= 1:
        return lab
    reference = np.ascontiguousarray(reference, dtype=np.int32)
    if reference.shape != comp.shape or (reference.size and int(reference.max()) >= n_classes):
        raise ValueError(f"reference labels of shape {reference.shape} with values up to {int(reference.max())}; "
                         f"expected the map's shape {comp.shape} and values below n_classes = {n_classes}")
    has_out, votes = _component_votes(comp, lab, reference, np.ascontiguousarray(walkable), n, int(n_classes))
    orphan = ~has_out & (votes.sum(axis=1) > 0)
    orphan[0] = False  # component 0 is the background
    if orphan.any():
        fill = np.where(orphan, np.argmax(votes, axis=1), -1).astype(np.int32)
        m = orphan[comp] & walkable
        lab[m] = fill[comp[m]]
    return lab


@njit(cache=True)
def _component_votes(comp, lab, reference, walkable, n, n_classes):
    """Per component of ``comp`` (n ids): does ``lab`` label any of its pixels ((n,) bool), and
    the (n, n_classes) int64 count of each ``reference`` label on its walkable pixels; one
    pass over the map, no map-sized temporaries."""
    has_out = np.zeros(n, np.bool_)
    votes = np.zeros((n, n_classes), np.int64)
    h, w = comp.shape
    for i in range(h):
        for j in range(w):
            k = comp[i, j]
            if lab[i, j] >= 0:
                has_out[k] = True
            if walkable[i, j] and reference[i, j] >= 0:
                votes[k, reference[i, j]] += 1
    return has_out, votes


class PostProcess(PostProcessor):
    """The six-step post-processing; ``pp(labels, grid) -> labels`` on grid's shape.

    Args:
        target_resolution: metres per pixel at which the clean-up runs.
        window: mode filter window, pixels (odd).
        iterations: mode filter passes (at most; stops when a pass changes nothing).
        min_area: smallest kept region of one label, square metres.
        dp_tolerance: Douglas-Peucker tolerance, metres (0 disables regularisation).
        classes: the ordered class names (their count bounds the label values).
    """

    def __init__(self, target_resolution: Annotated[float, Positive()] = 0.1,
                 window: Annotated[int, Odd()] = 5, iterations: Annotated[int, Integer(0)] = 2,
                 min_area: Annotated[float, NonNegative()] = 0.5,
                 dp_tolerance: Annotated[float, NonNegative()] = 0.1, classes: Sequence[str] = PAPER_CLASSES):
        if not target_resolution > 0:
            raise ValueError(f"target_resolution must be > 0 metres/pixel, got {target_resolution}")
        if min_area < 0 or dp_tolerance < 0 or iterations < 0:
            raise ValueError(f"min_area (m^2), dp_tolerance (m) and iterations must be >= 0, got "
                             f"{min_area}, {dp_tolerance}, {iterations}")
        if window < 1 or window % 2 == 0:
            raise ValueError(f"mode window must be an odd number of pixels, got {window}")
        if len(classes) < 1:
            raise ValueError("PostProcess needs a non-empty class list")
        self.target_resolution, self.window, self.iterations = float(target_resolution), int(window), int(iterations)
        self.min_area, self.dp_tolerance, self.n_classes = float(min_area), float(dp_tolerance), len(classes)

    def __call__(self, labels: np.ndarray, grid: GridMap) -> np.ndarray:
        n = self.n_classes
        labels = check_labels(labels, grid.walkable, n)
        lab, walk = rescale(labels, grid.walkable, grid.resolution, self.target_resolution)
        lab = apply_background(lab, walk)
        lab = mode_filter(lab, walk, n, self.window, self.iterations)
        lab = remove_small_components(lab, self.min_area / self.target_resolution ** 2)
        lab = fill_unlabelled(lab, walk, n)
        if self.dp_tolerance > 0:
            lab = regularise(lab, walk, n, self.dp_tolerance / self.target_resolution)
        out = apply_background(resample_nearest(lab, grid.shape), grid.walkable)
        out = fill_unlabelled(out, grid.walkable, n)
        return label_orphan_components(out, labels, grid.walkable, n)


class NoPostProcess(PostProcessor):
    """The raw output (``postprocess=none``): the labels validated as in :class:`PostProcess`
    and returned unchanged except that non-walkable pixels are set to -1."""

    def __init__(self, classes: Sequence[str] = PAPER_CLASSES):
        self.n_classes = len(classes)

    def __call__(self, labels: np.ndarray, grid: GridMap) -> np.ndarray:
        return apply_background(check_labels(labels, grid.walkable, self.n_classes), grid.walkable)


def noisy_ground_truth(semantic: np.ndarray, walkable: np.ndarray, n_classes: int, noise: float,
                       seed: int) -> np.ndarray:
    """The ground-truth label map with a fraction ``noise`` of walkable pixels set to a random
    value in -1..C-1 (salt-and-pepper), for timing and tests."""
    rng = np.random.default_rng(seed)
    lab = apply_background(semantic, walkable)
    flip = np.asarray(walkable, bool) & (rng.random(lab.shape) < noise)
    lab[flip] = rng.integers(-1, n_classes, int(flip.sum()))
    return lab
