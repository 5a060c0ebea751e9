"""A metric of your own: boundary F1, how well the borders between segments fall on the
borders between rooms, within a tolerance in metres (the boundary F-measure of Csurka et
al., BMVC 2013, on room maps).

A boundary pixel is a walkable pixel with a 4-neighbour that is walkable and belongs to
another segment (prediction) or another room (ground truth); unlabelled pixels are a
segment of their own. Precision is the share of predicted boundary pixels within
``tolerance_m`` of a ground-truth boundary pixel, recall the share of ground-truth boundary
pixels within ``tolerance_m`` of a predicted one, F1 their harmonic mean. A map with no
boundary (one segment) against a house with several rooms scores F1 0; one room predicted
as one room scores 1.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage


def boundary_pixels(ids: np.ndarray, walkable: np.ndarray) -> np.ndarray:
    """(H, W) bool: walkable pixels with a walkable 4-neighbour of another id."""
    out = np.zeros(ids.shape, dtype=bool)
    for axis in (0, 1):
        a = [slice(None), slice(None)]
        b = [slice(None), slice(None)]
        a[axis], b[axis] = slice(None, -1), slice(1, None)
        edge = walkable[tuple(a)] & walkable[tuple(b)] & (ids[tuple(a)] != ids[tuple(b)])
        out[tuple(a)] |= edge
        out[tuple(b)] |= edge
    return out


class BoundaryF1:
    """Boundary precision, recall and F1 within a tolerance.

    Args:
        tolerance_m: a boundary pixel within this distance (metres) of a boundary pixel of
            the other map counts as found.
    """

    def __init__(self, tolerance_m: float = 0.2):
        if isinstance(tolerance_m, bool) or not isinstance(tolerance_m, int | float) or not tolerance_m >= 0:
            raise ValueError(f"metrics.extra BoundaryF1 tolerance_m={tolerance_m!r}: expected a distance >= 0 in metres")
        self.tolerance_m = float(tolerance_m)

    def __call__(self, pred, gt_instances, gt_classes, resolution) -> dict:
        """Scores of ``pred`` (label or instance map) against the rooms ``gt_instances``
        ((H, W) ids, -1 not walkable) at ``resolution`` m/px.

        Returns: boundary_precision, boundary_recall (shares; NaN when that side has no
        boundary), boundary_f1 (share) and boundary_px (count of predicted boundary pixels).
        """
        walkable = gt_instances >= 0
        pred_b = boundary_pixels(np.where(walkable, pred, -2), walkable)
        gt_b = boundary_pixels(gt_instances, walkable)
        tol_px = self.tolerance_m / resolution
        precision = recall = float("nan")
        if pred_b.any():
            near_gt = ndimage.distance_transform_edt(~gt_b) <= tol_px if gt_b.any() else np.zeros_like(gt_b)
            precision = float(near_gt[pred_b].mean())
        if gt_b.any():
            near_pred = ndimage.distance_transform_edt(~pred_b) <= tol_px if pred_b.any() else np.zeros_like(pred_b)
            recall = float(near_pred[gt_b].mean())
        if not pred_b.any() and not gt_b.any():
            f1 = 1.0  # one segment for one room
        elif not pred_b.any() or not gt_b.any() or precision + recall == 0:
            f1 = 0.0
        else:
            f1 = 2 * precision * recall / (precision + recall)
        return {"boundary_precision": precision, "boundary_recall": recall, "boundary_f1": f1,
                "boundary_px": int(pred_b.sum())}
