"""Segmentation metrics: the paper's (Section III-B) and ones that merging cannot game.

All of them come from one pass: the segments of the prediction, the ground-truth rooms, and
the (segments x rooms) table of overlaps (pixel counts). Every row carries all of them.

**Segments.** A *label map* (class per pixel, our method) has no instance ids: its segments
are the connected regions (``connectivity`` 4 or 8) of one class, as in the paper. An
*instance map* (an id per pixel: SeLRoS, VRF, the geometric segmenters, the sanity rows) says
itself which pixels form one segment: its segments are its ids, whole, like the ground-truth
rooms they are compared with (``instances="connected"`` splits them into connected regions
instead). Ground-truth segments are the room instances, whole.

**Areas.** Segments and rooms smaller than ``min_segment_m2`` (converted to pixels with the
map's resolution, :func:`area_px`) are left out: their pixels still count for pixel accuracy,
class IoU and the union of IoUs, but they are no segment and no room of any average. Every
room, however small, stays a candidate for the paper's best match.

**Ground-truth rooms in pieces.** A room cut into several pieces by furniture is still one
room, and an instance map that gives it one id is one segment: ground truth scored against
itself gives 100 on every metric (tested on the 30 SeLRoS maps). A label map cannot say that
two pieces of one class belong together, so there each piece is its own segment (the paper).

**Metrics** (A a predicted segment, B a room; n segments, m rooms):

* ``iou``, ``precision``, ``recall`` (the paper, the default): each segment A with its best
  room B (largest IoU, ``match="iou"``; or largest overlap, ``match="overlap"``; ties to the
  lower room id): IoU = |A and B| / |A or B|, precision = |A and B| / |A|, recall =
  |A and B| / |B|, each averaged over the segments. Rewards merging: one segment for the
  whole map has precision = IoU = share of its biggest room, recall 1.
* ``matched_iou``, ``matched_precision``, ``matched_recall``: one-to-one Hungarian assignment
  (``scipy.optimize.linear_sum_assignment``) maximising the summed IoU; pairs with no overlap
  are no match. matched_iou = sum of matched IoUs / (n + m - matches) (every unmatched
  segment and room counts 0); matched_precision = sum of |A and B| / |A| over matches / n;
  matched_recall = sum of |A and B| / |B| over matches / m.
* ``room_iou``, ``room_recall``: each room with its best segment (same ``match`` rule),
  averaged over rooms.
* ``pq``, ``sq``, ``rq``: panoptic quality (Kirillov et al. 2019): a segment and a room match
  when their IoU > 0.5 (such matches are unique); TP matches, FP = n - TP, FN = m - TP;
  SQ = mean IoU of the matches (0 without any), RQ = TP / (TP + FP/2 + FN/2), PQ = SQ x RQ.
  ``pq_semantic`` counts a match only when the segment's class is the room's class (label
  maps; NaN for instance maps).
* ``ipa_recall``, ``ipa_precision``: as the ipa_room_segmentation evaluation (Bormann et al.,
  ICRA 2016): recall = share of each room covered by the one segment overlapping it most,
  averaged over rooms; precision = share of each segment inside the one room it overlaps
  most, averaged over segments.
* ``count_error``: n - m (signed; 0 is right).
* ``accuracy``: share of walkable ground-truth pixels whose predicted class is the room's class
  (unlabelled counts as wrong); ``class_iou``: mean over classes (present in the prediction
  or the ground truth) of the pixel IoU of class c; ``iou_<class>`` per class when the class
  names are given. Label maps only (NaN for instance maps).

With no segment every score is 0 (ipa precision and matched precision too); with no room of
at least ``min_segment_m2`` the room-side scores are NaN.

**Metrics of your own** (``extra``): callables ``fn(pred, gt_instances, gt_classes,
resolution) -> {column: value}`` configured as ``metrics.extra: [{_target_: ...}]`` (a class
whose instances are callable, or a function with ``_partial_: true``). Every scoring path
calls them after the built-in metrics (:func:`extra_scores`): ``pred`` is the label map
(class indices, -1 unlabelled; ``gt_classes`` the class index of each room) or the
instance map (segment ids, -1 none; ``gt_classes`` None), both read-only, on the
ground-truth grid of ``resolution`` m/px. Each value becomes a column of the row: a share
(a float in [0, 1], or NaN when undefined) or a count (an int >= 0); a name must be new
(not a column the row already has). Anything else is a ``ValueError`` naming the metric,
the column and the value, so in a sweep that house fails alone with the reason.

Scores are always computed on the ground-truth grid: resample a prediction at another
resolution first with :func:`resample_nearest`.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Annotated

import numpy as np
from scipy.optimize import linear_sum_assignment

from envs.kernel_cache import njit
from envs.maps.ids import dense_ids
from envs.maps.label_png import colour_int
from envs.ranges import NonNegative, OneOf

#: Metric columns of every scored row, in order (label-map-only ones are NaN for instances).
METRIC_COLUMNS = ("iou", "precision", "recall", "matched_iou", "matched_precision", "matched_recall",
                  "room_iou", "room_recall", "pq", "sq", "rq", "pq_semantic", "ipa_recall", "ipa_precision",
                  "count_error", "accuracy", "class_iou", "n_pred_segments", "n_gt_segments")

#: IoU above which a segment and a room are a panoptic match.
PQ_IOU = 0.5

#: Columns a runner row carries besides the metrics (the harness's descriptive and per-house
#: columns): an extra metric may not take these names, nor ``iou_<class>`` or ``t_<stage>``.
ROW_COLUMNS = ("house_id", "dataset", "env", "viewpoints", "renderer", "classifier", "oracle_accuracy",
               "aggregator", "postprocess", "segmenter", "label", "status", "error", "traceback", "score_key",
               "metric_params", "n_views", "n_refused", "view_accuracy", "view_accuracy_seen", "method",
               "resolution", "prediction", "ground_truth")
_RESERVED_PREFIXES = ("iou_", "t_")
_COLUMN_NAME = re.compile(r"[a-z][a-z0-9_]*")


@dataclass(frozen=True)
class MetricParams:
    """Metric parameters, one definition for every scoring command (``conf/metrics``), printed
    beside every table by :func:`describe`.

    Attributes:
        match: "iou" or "overlap": how a segment picks its best room (paper) and a room its
            best segment (room-averaged scores).
        connectivity: 4 or 8: pixel connectivity that splits label maps into segments.
        min_segment_m2: segments and rooms smaller than this (m²) are left out of the
            averages. 0.125 m² = 50 px at 0.05 m/px (the runner's maps), 312.5 px at 0.02 m/px.
        instances: "ids" (an instance map's ids are its segments, whole) or "connected"
            (each id split into its connected regions).
        min_colour_m2: external instance PNGs: a colour on less than this area (m², at that
            image's resolution) is anti-aliasing, not a room; its pixels join the nearest room.
            0.2 m² = 500 px at 0.02 m/px, 80 px at 0.05 m/px.
        not_room_colours: external instance PNGs: colours that are never a room ("#rrggbb");
            their pixels are unassigned (-1). Default black (not walkable) and white.
        extra: metrics of your own, callables ``(pred, gt_instances, gt_classes, resolution)
            -> {column: value}`` (:func:`extra_scores`); ``()`` by default.
    """

    match: Annotated[str, OneOf("iou", "overlap")] = "iou"
    connectivity: Annotated[int, OneOf(4, 8)] = 4
    min_segment_m2: Annotated[float, NonNegative()] = 0.125
    instances: Annotated[str, OneOf("ids", "connected")] = "ids"
    min_colour_m2: Annotated[float, NonNegative()] = 0.2
    not_room_colours: tuple = ("#000000", "#ffffff")
    extra: tuple = ()

    def __post_init__(self) -> None:
        if self.match not in ("iou", "overlap"):
            raise ValueError(f"metrics.match must be 'iou' or 'overlap', got {self.match!r}")
        if self.connectivity not in (4, 8):
            raise ValueError(f"metrics.connectivity must be 4 or 8, got {self.connectivity}")
        if self.instances not in ("ids", "connected"):
            raise ValueError(f"metrics.instances must be 'ids' or 'connected', got {self.instances!r}")
        for k in ("min_segment_m2", "min_colour_m2"):
            v = getattr(self, k)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not v >= 0:
                raise ValueError(f"metrics.{k} must be an area >= 0 in m², got {v!r}")
        colours = self.not_room_colours
        if isinstance(colours, str) or not hasattr(colours, "__iter__"):
            raise ValueError(f"metrics.not_room_colours must be a list of '#rrggbb', got {colours!r}")
        norm = tuple(f"#{colour_int(c):06x}" for c in colours)
        object.__setattr__(self, "not_room_colours", norm)
        object.__setattr__(self, "min_segment_m2", float(self.min_segment_m2))
        object.__setattr__(self, "min_colour_m2", float(self.min_colour_m2))
        extra = () if self.extra is None else self.extra
        if isinstance(extra, str) or not hasattr(extra, "__iter__"):
            raise ValueError(f"metrics.extra must be a list of metric callables ({{_target_: ...}}), got {extra!r}")
        extra = tuple(extra)
        for i, fn in enumerate(extra):
            if not callable(fn):
                raise ValueError(f"metrics.extra[{i}] is {fn!r}, expected a callable (pred, gt_instances, "
                                 "gt_classes, resolution) -> {column: value}: a class with __call__ or a "
                                 "function with _partial_: true")
        object.__setattr__(self, "extra", extra)

    def min_segment_px(self, resolution: float) -> int:
        """The minimum segment/room size in pixels at ``resolution`` m/px (:func:`area_px`)."""
        return area_px(self.min_segment_m2, resolution)

    def min_colour_px(self, resolution: float) -> int:
        """The anti-aliasing colour threshold in pixels at ``resolution`` m/px."""
        return area_px(self.min_colour_m2, resolution)


def area_px(area_m2: float, resolution: float) -> int:
    """Smallest whole pixel count whose area reaches ``area_m2`` at ``resolution`` m/px.

    ``ceil(area / resolution²)``, with a relative tolerance of 1e-9 so that 0.125 m² at
    0.05 m/px is exactly 50 px (not 51 from floating-point rounding).

    Returns: pixels (int >= 0).
    """
    if resolution is None or not resolution > 0:
        raise ValueError(f"resolution must be a positive number of metres per pixel, got {resolution!r} "
                         "(needed to turn areas in m² into pixels)")
    return int(math.ceil(area_m2 / resolution**2 * (1 - 1e-9)))


def describe(params: MetricParams, resolution: float | None = None, colours: bool = False) -> str:
    """One line naming the metric parameters (with pixel counts when ``resolution`` is given;
    with the PNG colour rules when ``colours``)."""
    px = f" ({params.min_segment_px(resolution)} px at {resolution:g} m/px)" if resolution else ""
    text = (f"label maps: {params.connectivity}-connected segments; instance maps: "
            f"{'ids whole' if params.instances == 'ids' else f'{params.connectivity}-connected ids'}; "
            f"segments and rooms < {params.min_segment_m2:g} m²{px} ignored; paper: best {params.match}, "
            f"averaged over segments; PQ: IoU > {PQ_IOU}; matched: Hungarian on IoU")
    if colours:
        cpx = f" ({params.min_colour_px(resolution)} px)" if resolution else ""
        text += (f"; PNG colours < {params.min_colour_m2:g} m²{cpx} anti-aliasing, "
                 f"not rooms: {' '.join(params.not_room_colours)}")
    if params.extra:
        text += f"; extra metrics: {', '.join(callable_name(fn) for fn in params.extra)}"
    return text


def callable_name(fn: Callable) -> str:
    """``module.qualname`` of a metric callable (a function, a partial of one, or an instance)."""
    target = getattr(fn, "func", fn)  # functools.partial
    if not hasattr(target, "__qualname__"):  # an instance: name its class
        target = type(target)
    return f"{target.__module__}.{target.__qualname__}"


def _read_only(a: np.ndarray) -> np.ndarray:
    v = np.asarray(a).view()
    v.flags.writeable = False
    return v


def extra_scores(params: MetricParams, pred: np.ndarray, gt_instances: np.ndarray,
                 gt_classes: Sequence[int] | None, resolution: float, taken: Sequence[str] = ()) -> dict:
    """The columns of the metrics of your own (``params.extra``), checked.

    Args:
        params: metric parameters; ``params.extra`` the callables, called in order.
        pred: (H, W) int label map (class indices, -1 unlabelled) or instance map (segment
            ids, -1 none), on the ground-truth grid. Handed over read-only.
        gt_instances: (H, W) int room ids, -1 not walkable. Read-only.
        gt_classes: class index of each room (label maps), or None (instance maps).
        resolution: metres per pixel of both maps.
        taken: columns the row already has (the built-in metrics).
    Returns: {column: value}; a value is a float in [0, 1] or NaN (a share) or an int >= 0
        (a count).
    Raises:
        ValueError: one line naming the metric, the column and the value, for a result that
            is not such a dict, a name that is not lower_snake_case or is already taken, or
            a value that is neither a share nor a count.
    """
    out: dict = {}
    if not params.extra:
        return out
    taken = set(taken) | set(ROW_COLUMNS) | set(METRIC_COLUMNS)
    pred_ro, gt_ro = _read_only(pred), _read_only(gt_instances)
    classes_ro = None if gt_classes is None else _read_only(np.asarray(gt_classes, dtype=np.int64))
    for fn in params.extra:
        name = callable_name(fn)
        got = fn(pred_ro, gt_ro, classes_ro, resolution)
        if not isinstance(got, Mapping):
            raise ValueError(f"metric {name} returned {type(got).__name__}, expected a dict {{column: value}}")
        for k, v in got.items():
            if not isinstance(k, str) or not _COLUMN_NAME.fullmatch(k):
                raise ValueError(f"metric {name}: column name {k!r} is not lower_snake_case ([a-z][a-z0-9_]*)")
            if k in taken or k in out or k.startswith(_RESERVED_PREFIXES):
                raise ValueError(f"metric {name}: column {k!r} is already a column of the row; choose another name")
            if isinstance(v, bool | np.bool_) or not isinstance(v, int | float | np.integer | np.floating):
                raise ValueError(f"metric {name}: {k}={v!r}, expected a share (float in [0, 1] or NaN) "
                                 "or a count (int >= 0)")
            if isinstance(v, int | np.integer):
                if v < 0:
                    raise ValueError(f"metric {name}: {k}={int(v)}, expected a count (int >= 0)")
                out[k] = int(v)
            else:
                f = float(v)
                if not (math.isnan(f) or 0.0 <= f <= 1.0):
                    raise ValueError(f"metric {name}: {k}={f!r}, expected a share in [0, 1] (or NaN; "
                                     "a count is an int)")
                out[k] = f
    return out


def resample_nearest(labels: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """Nearest-neighbour resampling of a label/instance map to ``shape`` (H, W)."""
    labels = np.asarray(labels)
    if labels.ndim != 2 or labels.size == 0:
        raise ValueError(f"label map must be a non-empty (H, W) array, got shape {labels.shape}")
    if tuple(labels.shape) == tuple(shape):
        return labels.copy()
    h, w = shape
    rows = np.minimum(((np.arange(h) + 0.5) * labels.shape[0] / h).astype(np.int64), labels.shape[0] - 1)
    cols = np.minimum(((np.arange(w) + 0.5) * labels.shape[1] / w).astype(np.int64), labels.shape[1] - 1)
    return labels.take(rows, axis=0).take(cols, axis=1)  # (two gathers: a third of np.ix_'s time)


def segments(labels: np.ndarray, connectivity: int = 4) -> np.ndarray:
    """Connected regions of equal value (a union-find labelling pass, :func:`_region_labels`).

    Args:
        labels: (H, W) int map; values < 0 are background.
        connectivity: 4 or 8.
    Returns: (H, W) int32 segment ids 0..S-1, -1 on background. Ids are ordered by value,
        then by the raster position of each region's first pixel.

    The work arrays are the int32 result and one int32 entry per provisional region, so a large
    map costs about 4 bytes a pixel beyond its labels (a library labelling keeps 64-bit ids and
    a 64-bit forest, 16 bytes a pixel).
    """
    labels = np.asarray(labels)
    if connectivity not in (4, 8):
        raise ValueError(f"connectivity must be 4 or 8, got {connectivity}")
    if labels.ndim != 2:
        raise ValueError(f"segments needs an (H, W) map, got shape {labels.shape}")
    if labels.dtype == bool or labels.dtype.kind not in "iu":
        labels = labels.astype(np.int64)
    lab, values = _region_labels(np.ascontiguousarray(labels), connectivity == 8)
    n = len(values)
    if n == 0:
        return np.full(labels.shape, -1, dtype=np.int32)
    # regions are numbered by their first pixel in raster order; order them by value, stably
    order = np.argsort(values, kind="stable")
    rank = np.empty(n + 1, dtype=np.int32)
    rank[0] = -1
    rank[1 + order] = np.arange(n, dtype=np.int32)
    _apply_rank(lab, rank)
    return lab


@njit(cache=True)
def _region_labels(values, eight):
    """Two-pass union-find labelling of the regions of equal value (values < 0: background).

    Returns:
        ((H, W) int32 region ids 1..n in raster order of each region's first pixel, 0 on
        background; (n,) int64 the value of each region)."""
    h, w = values.shape
    out = np.zeros((h, w), np.int32)
    parent = np.empty(h * w + 1, np.int32)  # provisional ids; pages are touched only as used
    first_value = np.empty(h * w + 1, np.int64)
    n = 0
    for i in range(h):
        for j in range(w):
            v = values[i, j]
            if v < 0:
                continue
            cur = 0
            # neighbours already visited: left, up, and for 8-connectivity up-left and up-right
            for t in range(4):
                if t == 0:
                    a, b = i, j - 1
                elif t == 1:
                    a, b = i - 1, j
                elif not eight:
                    break
                elif t == 2:
                    a, b = i - 1, j - 1
                else:
                    a, b = i - 1, j + 1
                if a < 0 or b < 0 or b >= w or values[a, b] != v:
                    continue
                q = out[a, b]
                while parent[q] != q:
                    q = parent[q]
                if cur == 0:
                    cur = q
                elif q != cur:  # two provisional regions meet: the later joins the earlier
                    if q < cur:
                        parent[cur] = q
                        cur = q
                    else:
                        parent[q] = cur
            if cur == 0:
                n += 1
                parent[n] = n
                first_value[n] = v
                cur = n
            out[i, j] = cur
    # final ids in order of each root's creation (= its first pixel in raster order); every
    # parent is smaller than its child, so parent[p] holds p's final id when p < k is reached
    m = 0
    for k in range(1, n + 1):
        p = parent[k]
        if p == k:
            m += 1
            parent[k] = m
            first_value[m] = first_value[k]
        else:
            parent[k] = parent[p]
    for i in range(h):
        for j in range(w):
            if out[i, j] > 0:
                out[i, j] = parent[out[i, j]]
    return out, first_value[1:m + 1].copy()


@njit(cache=True)
def _apply_rank(lab, rank):
    """In place: ``lab = rank[lab]`` on an (H, W) int32 map."""
    h, w = lab.shape
    for i in range(h):
        for j in range(w):
            lab[i, j] = rank[lab[i, j]]


def _check(pred: np.ndarray, gt_instances: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    pred = np.asarray(pred)
    gt = np.asarray(gt_instances)
    if gt.ndim != 2 or gt.size == 0:
        raise ValueError(f"ground-truth map must be a non-empty (H, W) array, got shape {gt.shape}")
    if pred.shape != gt.shape:
        raise ValueError(f"prediction shape {pred.shape} differs from ground-truth shape {gt.shape}; "
                         "resample it first (benchmark.metrics.resample_nearest)")
    if not (gt >= 0).any():
        raise ValueError("ground-truth map has no room pixel (empty map)")
    return pred, gt


def _mean(x: np.ndarray) -> float:
    return float(np.mean(x)) if len(x) else 0.0


def _segment_scores(seg: np.ndarray, gt: np.ndarray, params: MetricParams, min_px: int,
                    seg_class: np.ndarray | None = None, room_class: np.ndarray | None = None) -> dict[str, float]:
    """All segment metrics from one overlap table.

    Args:
        seg: (H, W) int segment ids 0..S-1, -1 none.
        gt: (H, W) int room ids 0..R-1, -1 not walkable.
        min_px: segments and rooms with fewer pixels are left out.
        seg_class, room_class: (S,), (R,) class of each segment / room (semantic PQ), or None.
    Returns: the segment metrics of :data:`METRIC_COLUMNS` (not accuracy / class IoU).
    """
    n_gt = int(gt.max()) + 1
    gt_size = np.bincount(gt[gt >= 0], minlength=n_gt).astype(np.float64)
    n_seg = int(seg.max()) + 1 if (seg >= 0).any() else 0
    seg_size = np.bincount(seg[seg >= 0], minlength=n_seg).astype(np.float64)
    thr = max(min_px, 1)
    keep = np.nonzero(seg_size >= thr)[0]
    rooms = np.nonzero(gt_size >= thr)[0]
    n, m = len(keep), len(rooms)
    out: dict[str, float] = {"n_pred_segments": int(n), "n_gt_segments": int(m), "count_error": int(n - m)}
    both = (seg >= 0) & (gt >= 0)
    inter_all = np.bincount(seg[both].astype(np.int64) * n_gt + gt[both], minlength=n_seg * n_gt)
    inter_all = inter_all.reshape(n_seg, n_gt).astype(np.float64)[keep]      # (n, all rooms)
    a = seg_size[keep]

    # the paper: each segment with its best room among all rooms, averaged over segments
    if n == 0:
        out.update(iou=0.0, precision=0.0, recall=0.0)
    else:
        union = a[:, None] + gt_size[None, :] - inter_all
        iou_all = np.divide(inter_all, union, out=np.zeros_like(inter_all), where=union > 0)
        best = np.argmax(iou_all if params.match == "iou" else inter_all, axis=1)
        rows = np.arange(n)
        i_best = inter_all[rows, best]
        out["iou"] = float(np.mean(iou_all[rows, best]))
        out["precision"] = float(np.mean(i_best / a))
        out["recall"] = float(np.mean(np.divide(i_best, gt_size[best], out=np.zeros_like(i_best),
                                                where=gt_size[best] > 0)))
    out["ipa_precision"] = _mean(inter_all.max(axis=1) / a) if n and n_gt else 0.0

    if m == 0:  # no room to average over
        for k in ("matched_iou", "matched_precision", "matched_recall", "room_iou", "room_recall", "pq", "sq",
                  "rq", "pq_semantic", "ipa_recall"):
            out[k] = float("nan")
        return out
    inter = inter_all[:, rooms]                                                # (n, m)
    b = gt_size[rooms]
    union = a[:, None] + b[None, :] - inter
    iou = np.divide(inter, union, out=np.zeros_like(inter), where=union > 0)

    # one-to-one matching
    if n:
        r, c = linear_sum_assignment(iou, maximize=True)
        ok = inter[r, c] > 0
        r, c = r[ok], c[ok]
    else:
        r = c = np.zeros(0, dtype=np.int64)
    k = len(r)
    out["matched_iou"] = float(iou[r, c].sum() / (n + m - k))
    out["matched_precision"] = float((inter[r, c] / a[r]).sum() / n) if n else 0.0
    out["matched_recall"] = float((inter[r, c] / b[c]).sum() / m)

    # each room with its best segment
    if n:
        bs = np.argmax(iou if params.match == "iou" else inter, axis=0)
        cols = np.arange(m)
        out["room_iou"] = float(np.mean(iou[bs, cols]))
        out["room_recall"] = float(np.mean(inter[bs, cols] / b))
        out["ipa_recall"] = float(np.mean(inter.max(axis=0) / b))
    else:
        out["room_iou"] = out["room_recall"] = out["ipa_recall"] = 0.0

    # panoptic quality: IoU > 0.5 matches are unique (two would cover more than the whole)
    tp = iou > PQ_IOU
    n_tp = int(tp.sum())
    denom = n_tp + 0.5 * (n - n_tp) + 0.5 * (m - n_tp)
    out["sq"] = float(iou[tp].mean()) if n_tp else 0.0
    out["rq"] = float(n_tp / denom)
    out["pq"] = float(iou[tp].sum() / denom)
    if seg_class is not None and room_class is not None and n:
        same = np.asarray(seg_class)[keep][:, None] == np.asarray(room_class)[rooms][None, :]
        tps = tp & same
        n_s = int(tps.sum())
        out["pq_semantic"] = float(iou[tps].sum() / (n_s + 0.5 * (n - n_s) + 0.5 * (m - n_s)))
    elif seg_class is not None and room_class is not None:
        out["pq_semantic"] = 0.0
    else:
        out["pq_semantic"] = float("nan")
    return out


def score_semantic(pred_labels: np.ndarray, gt_instances: np.ndarray, gt_instance_classes: Sequence[int],
                   params: MetricParams = MetricParams(), classes: Sequence[str] | None = None, *,
                   resolution: float) -> dict[str, float]:
    """Score a label map (class per pixel, -1 unlabelled) against room instances.

    Args:
        pred_labels: (H, W) int class indices, -1 unlabelled.
        gt_instances: (H, W) int room instance ids, -1 not walkable.
        gt_instance_classes: class index of each instance.
        params: segment, area and matching rules.
        classes: class names; adds ``iou_<name>`` per class.
        resolution: metres per pixel of both maps (turns ``min_segment_m2`` into pixels).
    Returns: every column of :data:`METRIC_COLUMNS` (+ ``iou_<name>`` per class, + the
        columns of ``params.extra``); fractions in [0, 1], counts as ints.
    """
    pred, gt = _check(pred_labels, gt_instances)
    inst_cls = np.asarray(gt_instance_classes, dtype=np.int64)
    if gt.max() >= len(inst_cls):
        raise ValueError(f"ground truth has instance {int(gt.max())} but only {len(inst_cls)} instance classes")
    n_cls = len(classes) if classes is not None else int(max(inst_cls.max(), pred.max())) + 1
    if pred.min() < -1 or pred.max() >= n_cls:
        raise ValueError(f"prediction has labels outside [-1, {n_cls}): min {pred.min()}, max {pred.max()}")
    seg = segments(pred, params.connectivity)
    n_seg = int(seg.max()) + 1
    seg_class = np.full(max(n_seg, 0), -1, dtype=np.int64)
    seg_class[seg[seg >= 0]] = pred[seg >= 0]
    out = _segment_scores(seg, gt, params, params.min_segment_px(resolution), seg_class, inst_cls)
    gt_cls = np.where(gt >= 0, inst_cls[np.maximum(gt, 0)], -1)
    walk = gt >= 0
    out["accuracy"] = float(np.mean(pred[walk] == gt_cls[walk]))
    ious = []
    for c in range(n_cls):
        p, g = pred == c, gt_cls == c
        union = np.count_nonzero(p | g)
        v = float(np.count_nonzero(p & g) / union) if union else float("nan")
        if union:
            ious.append(v)
        if classes is not None:
            out[f"iou_{classes[c]}"] = v
    out["class_iou"] = float(np.mean(ious)) if ious else float("nan")
    out.update(extra_scores(params, pred, gt, inst_cls, resolution, taken=out))
    return out


def score_instances(pred_instances: np.ndarray, gt_instances: np.ndarray,
                    params: MetricParams = MetricParams(), *, resolution: float) -> dict[str, float]:
    """Score an instance map (segment id per pixel, -1 none) against room instances.

    Args:
        pred_instances: (H, W) int segment ids, -1 none; with ``params.instances == "ids"``
            each id is one segment (whole), with ``"connected"`` each connected region of one id.
        gt_instances: (H, W) int room instance ids, -1 not walkable.
        params: segment, area and matching rules.
        resolution: metres per pixel of both maps.
    Returns: every column of :data:`METRIC_COLUMNS` (+ the columns of ``params.extra``, called
        with ``gt_classes=None``); accuracy, class IoU and semantic PQ are not defined without
        classes and are NaN.
    """
    pred, gt = _check(pred_instances, gt_instances)
    if params.instances == "connected":
        seg = segments(pred, params.connectivity)
    else:
        seg = np.full(pred.shape, -1, dtype=np.int32)
        fg = pred >= 0
        if fg.any():
            seg[fg] = dense_ids(pred[fg])[0]
    out = _segment_scores(seg, gt, params, params.min_segment_px(resolution))
    out["accuracy"] = float("nan")
    out["class_iou"] = float("nan")
    out.update(extra_scores(params, pred, gt, None, resolution, taken=out))
    return out
