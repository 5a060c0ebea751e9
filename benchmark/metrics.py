"""Segmentation metrics (paper, Section III-B), for label maps and instance maps.

* **Segments.** Predicted segments are the connected regions (``connectivity`` 4 or 8)
  of one label (label maps) or one instance id (instance maps); predicted segments smaller
  than ``min_segment_px`` pixels are dropped from the segment averages (their pixels still
  count for pixel accuracy). Ground-truth segments are the room instances, whole.
* **Matching.** Each predicted segment A is matched to the ground-truth segment B with the
  largest IoU (``match="iou"``, default) or the largest overlap ``|A and B|``
  (``match="overlap"``); ties go to the lower instance id.
* **IoU** = |A and B| / |A or B|, **precision** = |A and B| / |A|, **recall** =
  |A and B| / |B|, each averaged over the predicted segments. A prediction with no segment
  scores 0 on all three.
* **Pixel accuracy** = share of walkable ground-truth pixels whose predicted class is the
  room's class (unlabelled counts as wrong). Not defined for instance maps (NaN).
* **Per-class IoU** (``iou_<class>``) = pixel IoU of predicted class c against ground-truth
  class c over the map; NaN for a class absent from both.

Scores are always computed on the ground-truth grid: resample a prediction at another
resolution first with :func:`resample_nearest`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np


@dataclass(frozen=True)
class MetricParams:
    """Metric parameters (printed beside every table by :func:`describe`).

    Attributes:
        match: "iou" or "overlap": how a predicted segment picks its ground-truth segment.
        connectivity: 4 or 8: pixel connectivity that splits labels into segments.
        min_segment_px: predicted segments with fewer pixels are left out of the averages.
    """

    match: str = "iou"
    connectivity: int = 4
    min_segment_px: int = 50

    def __post_init__(self) -> None:
        if self.match not in ("iou", "overlap"):
            raise ValueError(f"MetricParams.match must be 'iou' or 'overlap', got {self.match!r}")
        if self.connectivity not in (4, 8):
            raise ValueError(f"MetricParams.connectivity must be 4 or 8, got {self.connectivity}")
        if self.min_segment_px < 0:
            raise ValueError(f"MetricParams.min_segment_px must be >= 0, got {self.min_segment_px}")


def describe(params: MetricParams) -> str:
    """One line naming the metric parameters."""
    return (f"segments: {params.connectivity}-connected, predicted segments < {params.min_segment_px} px "
            f"ignored; match: best {params.match}")


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
    return labels[np.ix_(rows, cols)]


def segments(labels: np.ndarray, connectivity: int = 4) -> np.ndarray:
    """(H, W) int32 segment ids 0..S-1: connected regions of each value >= 0; -1 elsewhere."""
    labels = np.asarray(labels)
    out = np.full(labels.shape, -1, dtype=np.int32)
    nxt = 0
    for v in np.unique(labels[labels >= 0]):
        n, comp = cv2.connectedComponents((labels == v).astype(np.uint8), connectivity=connectivity,
                                          ltype=cv2.CV_32S)
        m = comp > 0
        out[m] = comp[m] - 1 + nxt
        nxt += n - 1
    return out


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


def _segment_scores(seg: np.ndarray, gt: np.ndarray, params: MetricParams) -> dict[str, float]:
    n_gt = int(gt.max()) + 1
    gt_size = np.bincount(gt[gt >= 0], minlength=n_gt).astype(np.float64)
    n_seg = int(seg.max()) + 1 if (seg >= 0).any() else 0
    seg_size = np.bincount(seg[seg >= 0], minlength=n_seg).astype(np.float64)
    keep = np.nonzero(seg_size >= max(params.min_segment_px, 1))[0]
    out = {"n_pred_segments": int(len(keep)), "n_gt_segments": int((gt_size > 0).sum())}
    if len(keep) == 0:
        out.update(iou=0.0, precision=0.0, recall=0.0)
        return out
    both = (seg >= 0) & (gt >= 0)
    inter = np.bincount(seg[both].astype(np.int64) * n_gt + gt[both], minlength=n_seg * n_gt)
    inter = inter.reshape(n_seg, n_gt).astype(np.float64)[keep]
    union = seg_size[keep, None] + gt_size[None, :] - inter
    iou = np.divide(inter, union, out=np.zeros_like(inter), where=union > 0)
    best = np.argmax(iou if params.match == "iou" else inter, axis=1)
    rows = np.arange(len(keep))
    i_best = inter[rows, best]
    out["iou"] = float(np.mean(iou[rows, best]))
    out["precision"] = float(np.mean(i_best / seg_size[keep]))
    out["recall"] = float(np.mean(np.divide(i_best, gt_size[best], out=np.zeros_like(i_best),
                                            where=gt_size[best] > 0)))
    return out


def score_semantic(pred_labels: np.ndarray, gt_instances: np.ndarray, gt_instance_classes: Sequence[int],
                   params: MetricParams = MetricParams(), classes: Sequence[str] | None = None) -> dict[str, float]:
    """Score a label map (class per pixel, -1 unlabelled) against room instances.

    Args:
        pred_labels: (H, W) int class indices, -1 unlabelled.
        gt_instances: (H, W) int room instance ids, -1 not walkable.
        gt_instance_classes: class index of each instance.
        params: segment and matching rules.
        classes: class names; adds ``iou_<name>`` per class.
    Returns: iou, precision, recall, accuracy, n_pred_segments, n_gt_segments (+ per class).
    """
    pred, gt = _check(pred_labels, gt_instances)
    inst_cls = np.asarray(gt_instance_classes, dtype=np.int64)
    if gt.max() >= len(inst_cls):
        raise ValueError(f"ground truth has instance {int(gt.max())} but only {len(inst_cls)} instance classes")
    n_cls = len(classes) if classes is not None else int(max(inst_cls.max(), pred.max())) + 1
    if pred.min() < -1 or pred.max() >= n_cls:
        raise ValueError(f"prediction has labels outside [-1, {n_cls}): min {pred.min()}, max {pred.max()}")
    out = _segment_scores(segments(pred, params.connectivity), gt, params)
    gt_cls = np.where(gt >= 0, inst_cls[np.maximum(gt, 0)], -1)
    walk = gt >= 0
    out["accuracy"] = float(np.mean(pred[walk] == gt_cls[walk]))
    if classes is not None:
        for c, name in enumerate(classes):
            p, g = pred == c, gt_cls == c
            union = np.count_nonzero(p | g)
            out[f"iou_{name}"] = float(np.count_nonzero(p & g) / union) if union else float("nan")
    return out


def score_instances(pred_instances: np.ndarray, gt_instances: np.ndarray,
                    params: MetricParams = MetricParams()) -> dict[str, float]:
    """Score an instance map (segment id per pixel, -1 none) against room instances;
    accuracy is not defined without classes and is NaN."""
    pred, gt = _check(pred_instances, gt_instances)
    out = _segment_scores(segments(pred, params.connectivity), gt, params)
    out["accuracy"] = float("nan")
    return out
