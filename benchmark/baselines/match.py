"""Match maps to the houses they were made from by comparing walkable masks.

Both masks are brought to ``resolution`` (default 0.1 m/px; a coarse cell is walkable
when at least half of it is), and for each of the 8 rotations/flips of the house mask the
best translation is found by FFT cross-correlation; the score is the IoU of the two masks
at that placement. Reports, per map, the best house, its IoU, the runner-up's IoU and the
transform; ``matched`` says whether the best is a credible match (IoU at least ``min_iou``
and ahead of the runner-up by ``min_margin``). :func:`carry_to_map` then puts anything
drawn on the house's grid (our method's label map) onto the map, so that every method is
scored on the same map.
"""

from __future__ import annotations

import numpy as np
from scipy.signal import fftconvolve

from envs.maps.scene import rasterise_house
from envs.world.house import House


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
        bb = transform_mask(b, t).astype(np.float32)
        nb = bb.sum()
        inter = fftconvolve(a, bb[::-1, ::-1], mode="full")
        iou = inter / np.maximum(na + nb - inter, 1e-9)
        i = np.unravel_index(np.argmax(iou), iou.shape)
        if iou[i] > best[0]:
            best = (float(iou[i]), t, (int(i[0] - bb.shape[0] + 1), int(i[1] - bb.shape[1] + 1)))
    return best


def transform_mask(b: np.ndarray, t: int) -> np.ndarray:
    """Transform ``t`` of :func:`best_overlap` applied to a map: flip left-right first when
    ``t >= 4``, then ``t % 4`` quarter turns (numpy's ``rot90``, counter-clockwise)."""
    if not 0 <= t < 8:
        raise ValueError(f"transform index must be 0-7, got {t}")
    return np.rot90(np.fliplr(b) if t >= 4 else b, t % 4)


def carry_to_map(labels: np.ndarray, t: int, shift: tuple[int, int], map_shape: tuple[int, int],
                 factor: int) -> np.ndarray:
    """Put a label/instance map of the house grid onto a matched map.

    Args:
        labels: (h, w) int map on the house grid at the match resolution (``resolution`` of
            :func:`match_maps`; resample another grid first with benchmark.metrics.resample_nearest).
        t, shift: the match's transform index and (d_row, d_col) shift, in coarse pixels.
        map_shape: (H, W) of the full-resolution map.
        factor: match resolution / map resolution (e.g. 0.1 / 0.02 = 5).
    Returns: (H, W) int32 on the map grid, -1 where the house grid does not reach.
    """
    if factor < 1:
        raise ValueError(f"factor must be a positive integer, got {factor}")
    lab = transform_mask(np.asarray(labels), t)
    ch, cw = -(-map_shape[0] // factor), -(-map_shape[1] // factor)
    coarse = np.full((ch, cw), -1, np.int32)
    dr, dc = shift
    r0, c0 = max(dr, 0), max(dc, 0)
    r1, c1 = min(dr + lab.shape[0], ch), min(dc + lab.shape[1], cw)
    if r1 > r0 and c1 > c0:
        coarse[r0:r1, c0:c1] = lab[r0 - dr:r1 - dr, c0 - dc:c1 - dc]
    return np.kron(coarse, np.ones((factor, factor), np.int32))[: map_shape[0], : map_shape[1]]


def match_maps(maps: dict[str, np.ndarray], map_resolution: float, houses: list[House],
               resolution: float = 0.1, min_iou: float = 0.8, min_margin: float = 0.05) -> list[dict]:
    """For each named walkable mask (metres/pixel ``map_resolution``), the best-overlapping house.

    Masks are compared at ``resolution`` metres/pixel (a multiple of ``map_resolution``).
    Rows: map, best_house, iou, transform (0-7), shift (d_row, d_col in coarse pixels),
    second_iou (the runner-up house), matched (iou >= min_iou and ahead by min_margin).
    """
    if not houses:
        raise ValueError("match_maps needs at least one house")
    factor = int(round(resolution / map_resolution))
    if factor < 1 or not np.isclose(factor * map_resolution, resolution):
        raise ValueError(f"comparison resolution {resolution} m/px must be a whole multiple of the maps' "
                         f"{map_resolution} m/px")
    targets = {k: downsample_mask(m, factor) for k, m in maps.items()}
    masks = {h.id: rasterise_house(h, resolution=resolution).grid.walkable for h in houses}
    rows = []
    for name, a in targets.items():
        scores = sorted(((best_overlap(a, b), hid) for hid, b in masks.items()), key=lambda t: -t[0][0])
        (iou, t, shift), hid = scores[0]
        second = scores[1][0][0] if len(scores) > 1 else 0.0
        rows.append({"map": name, "best_house": hid, "iou": iou, "transform": t, "shift": shift,
                     "second_iou": second if len(scores) > 1 else float("nan"),
                     "matched": bool(iou >= min_iou and iou - second >= min_margin)})
    return rows
