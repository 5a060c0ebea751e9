"""Match maps to the houses they were made from by comparing walkable masks.

Both masks are brought to ``resolution`` (default 0.1 m/px; a coarse cell is walkable
when at least half of it is), and for each of the 8 rotations/flips of the house mask the
best translation is found by FFT cross-correlation; the score is the IoU of the two masks
at that placement. Reports, per map, the best house, its IoU and the transform.
"""

from __future__ import annotations

import numpy as np
from scipy.signal import fftconvolve

from envs.house import House
from envs.scene import rasterise_house


def downsample_mask(mask: np.ndarray, factor: int) -> np.ndarray:
    """Block-average a bool mask by an integer ``factor``; a block is True when >= half walkable."""
    if factor <= 1:
        return mask.astype(bool)
    h, w = (mask.shape[0] // factor) * factor, (mask.shape[1] // factor) * factor
    m = mask[:h, :w].reshape(h // factor, factor, w // factor, factor).mean(axis=(1, 3))
    return m >= 0.5


def best_overlap(a: np.ndarray, b: np.ndarray) -> tuple[float, int, tuple[int, int]]:
    """Largest IoU of mask ``b`` (under 8 rotations/flips and any translation) with ``a``.

    Returns (iou, transform index 0-7: k quarter turns, +4 if flipped first, (d_row, d_col))."""
    a = a.astype(np.float32)
    na = a.sum()
    best = (0.0, 0, (0, 0))
    for t in range(8):
        bb = np.rot90(np.fliplr(b) if t >= 4 else b, t % 4).astype(np.float32)
        nb = bb.sum()
        inter = fftconvolve(a, bb[::-1, ::-1], mode="full")
        iou = inter / np.maximum(na + nb - inter, 1e-9)
        i = np.unravel_index(np.argmax(iou), iou.shape)
        if iou[i] > best[0]:
            best = (float(iou[i]), t, (int(i[0] - bb.shape[0] + 1), int(i[1] - bb.shape[1] + 1)))
    return best


def match_maps(maps: dict[str, np.ndarray], map_resolution: float, houses: list[House],
               resolution: float = 0.1) -> list[dict]:
    """For each named walkable mask, the best-overlapping house (rows: map, house, iou, transform)."""
    factor = int(round(resolution / map_resolution))
    targets = {k: downsample_mask(m, factor) for k, m in maps.items()}
    masks = {h.id: rasterise_house(h, resolution=resolution).grid.walkable for h in houses}
    rows = []
    for name, a in targets.items():
        scores = sorted(((best_overlap(a, b), hid) for hid, b in masks.items()), key=lambda t: -t[0][0])
        (iou, t, shift), hid = scores[0]
        rows.append({"map": name, "best_house": hid, "iou": iou, "transform": t, "shift": shift,
                     "second_iou": scores[1][0][0] if len(scores) > 1 else float("nan")})
    return rows
