"""Ids renumbered 0..K-1 in the order of their values: what ``np.unique(values,
return_inverse=True)`` gives, by counting instead of sorting where the values are small."""

from __future__ import annotations

import numpy as np


def dense_ids(values: np.ndarray) -> tuple[np.ndarray, int]:
    """Each value's rank among the distinct values present, and their count.

    Non-negative values below ``2 * size + 1024`` (a segmentation's ids, squares of a grid) are
    ranked by counting (a cumulative sum over which values occur: linear time); any others by
    ``np.unique``. Both give the same ranks.

    Args:
        values: (N,) integers.

    Returns:
        ((N,) int64 ranks 0..K-1, K).
    """
    v = np.asarray(values).ravel()
    if v.size == 0:
        return np.zeros(0, np.int64), 0
    if not np.issubdtype(v.dtype, np.integer):
        raise ValueError(f"dense_ids needs integer values, got dtype {v.dtype}")
    if int(v.min()) >= 0 and int(v.max()) < 2 * v.size + 1024:
        present = np.bincount(v) > 0
        return (np.cumsum(present) - 1)[v], int(present.sum())
    ids, inverse = np.unique(v, return_inverse=True)
    return inverse.ravel().astype(np.int64, copy=False), len(ids)


__all__ = ["dense_ids"]
