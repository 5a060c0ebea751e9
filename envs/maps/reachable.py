"""The reachable area: the free space a robot starting at a known place can drive to.

A furnished map holds free pockets that no robot can reach: the floor enclosed by a ring of
desks and chairs, the gap behind a sofa pushed against a wall, a cupboard's inside. The
geometric segmenters make rooms of them; the view-based methods leave them unlabelled (no
view is taken there). So that every method and the metrics see the same free space, an
environment restricts its scene to the reachable area before any method runs
(:func:`restrict_scene`): ``grid.walkable`` and the ground truth's ``instances`` both lose
the unreachable cells.

**Rule.** The reachable area is the union of the 4-connected components of the walkable
cells (4-connectivity, as the graph KNN aggregator's default and the metrics' segments)
that hold a *seed*: the house's start pose, or the robot's views. A seed that is not on a
walkable cell (a start pose on a rug-covered coffee table, a view pose rounded into a wall)
moves to the nearest walkable cell (Euclidean, in pixels; of two equally near, the one
SciPy's distance transform of the map names) when that cell is at most :data:`SNAP_M` metres
away, and is dropped otherwise. With no seed left, or none given,
the rule is the largest component (ties: the one whose first cell comes first in raster
order).

Settings (``env.reachable``): ``start`` (the seeds the environment knows; with none, the
largest component), ``largest`` (the largest component, seeds ignored), ``all`` (no
restriction: every walkable cell, as before this rule existed).
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Sequence

import numpy as np
from scipy import ndimage

from envs.maps.gridmap import GridMap

#: The values of ``env.reachable``.
RULES = ("start", "largest", "all")
#: A seed off the walkable cells moves to the nearest walkable cell at most this far, metres.
SNAP_M = 1.0
#: Removing more than this share of the walkable cells draws a warning naming the map.
WARN_REMOVED_SHARE = 0.05
_FOUR = ndimage.generate_binary_structure(2, 1)


def check_rule(value, setting: str = "env.reachable") -> str:
    """``value`` if it is one of :data:`RULES`; else one line naming the setting.

    Returns:
        the rule.
    """
    if value not in RULES:
        raise ValueError(f"{setting} is {value!r}; expected one of {list(RULES)}")
    return value


def seed_cells(grid: GridMap, points_xz: np.ndarray | Sequence, snap_m: float = SNAP_M) -> np.ndarray:
    """Seed points in world metres -> walkable cells.

    Args:
        grid: the map.
        points_xz: (N, 2) world (x, z) metres (extra columns, e.g. a yaw, are ignored).
        snap_m: a point off the walkable cells moves to the nearest walkable cell within this
            distance (metres, between cell centres); farther, or off the map, it is dropped.

    Returns:
        (K, 2) int64 (row, col) of walkable cells, K <= N.
    """
    pts = np.asarray(points_xz, dtype=float)
    pts = pts.reshape(1, -1) if pts.ndim == 1 else pts
    if pts.ndim != 2 or (pts.size and pts.shape[1] < 2):
        raise ValueError(f"seed points must be an (N, 2) array of world x, z metres, got shape {pts.shape}")
    walk = np.asarray(grid.walkable, bool)
    if not len(pts) or not walk.any():
        return np.zeros((0, 2), np.int64)
    pts = pts[np.isfinite(pts[:, :2]).all(axis=1)]
    r, c = grid.world_to_cell(pts[:, 0], pts[:, 1])
    r, c = np.asarray(r, np.int64), np.asarray(c, np.int64)
    inside = grid.in_bounds(r, c)
    r, c = r[inside], c[inside]
    on = walk[r, c]
    if on.all():
        return np.stack([r, c], axis=1)
    off_r, off_c = r[~on], c[~on]
    snapped = _snap_in_windows(walk, off_r, off_c, grid.resolution, snap_m)
    if snapped is None:  # two walkable cells equally near a point: the whole map's feature transform decides
        dist, (nr, nc) = ndimage.distance_transform_edt(~walk, return_indices=True)
        near = dist[off_r, off_c] * grid.resolution <= snap_m + 1e-9
        snapped = np.where(near[:, None], np.stack([nr[off_r, off_c], nc[off_r, off_c]], axis=1), -1)
    rr, cc, keep = r.copy(), c.copy(), on.copy()
    rr[~on], cc[~on], keep[~on] = snapped[:, 0], snapped[:, 1], snapped[:, 0] >= 0
    return np.stack([rr[keep], cc[keep]], axis=1).astype(np.int64)


def _snap_in_windows(walk: np.ndarray, rows: np.ndarray, cols: np.ndarray, resolution: float,
                     snap_m: float) -> np.ndarray | None:
    """The nearest walkable cell of each point off the walkable cells, searched in a window of
    the snap distance around it (a nearer cell cannot lie outside it), with the test of the
    whole map's distance transform (distance x resolution <= ``snap_m`` + 1e-9).

    Returns:
        (K, 2) int64 cells, (-1, -1) for a point with none near enough (dropped); None when
        some point has two or more nearest cells (which one the whole map's transform picks
        is its own rule: the caller asks it).
    """
    reach = (snap_m + 1e-9) / resolution
    k = int(np.floor(reach)) + 1 if np.isfinite(reach) else max(walk.shape)
    h, w = walk.shape
    out = np.full((len(rows), 2), -1, np.int64)
    for i, (pr, pc) in enumerate(zip(rows.tolist(), cols.tolist())):
        r0, c0 = max(pr - k, 0), max(pc - k, 0)
        wr, wc = np.nonzero(walk[r0:min(pr + k + 1, h), c0:min(pc + k + 1, w)])
        if not len(wr):
            continue
        d2 = (wr + (r0 - pr)) ** 2 + (wc + (c0 - pc)) ** 2
        j = int(np.argmin(d2))
        if not np.sqrt(float(d2[j])) * resolution <= snap_m + 1e-9:
            continue
        if np.count_nonzero(d2 == d2[j]) > 1:
            return None
        out[i] = (wr[j] + r0, wc[j] + c0)
    return out


def reachable_mask(walkable: np.ndarray, seeds: np.ndarray | None = None) -> np.ndarray:
    """The walkable cells 4-connected to a seed cell; with no seed, the largest component.

    Args:
        walkable: (H, W) bool.
        seeds: (K, 2) int (row, col) cells, or None / empty: the largest 4-connected
            component (ties: the component whose first cell in raster order comes first).
            Seeds on non-walkable cells are ignored.

    Returns:
        (H, W) bool, a subset of ``walkable`` (all False when nothing is walkable).
    """
    walk = np.asarray(walkable, bool)
    lab, n = ndimage.label(walk, _FOUR)
    if n == 0:
        return np.zeros(walk.shape, bool)
    ids = np.zeros(0, np.int64)
    if seeds is not None and len(seeds):
        s = np.asarray(seeds, np.int64).reshape(-1, 2)
        ids = np.unique(lab[s[:, 0], s[:, 1]])
        ids = ids[ids > 0]
    if not len(ids):
        sizes = np.bincount(lab.ravel(), minlength=n + 1)
        sizes[0] = -1
        ids = np.array([int(np.argmax(sizes))])  # argmax: the lowest label (first in raster order) on a tie
    keep = np.zeros(n + 1, bool)
    keep[ids] = True
    return keep[lab]


def restrict_scene(scene, rule: str, points_xz: np.ndarray | Sequence | None = None, snap_m: float = SNAP_M,
                   warn_share: float = WARN_REMOVED_SHARE):
    """The scene with its free space cut to the reachable area (see the module doc).

    Args:
        scene: a :class:`envs.maps.scene.Scene`.
        rule: ``start`` | ``largest`` | ``all``.
        points_xz: the seeds for ``start``: (N, 2+) world (x, z) metres (start pose, views),
            or None.
        snap_m: see :func:`seed_cells`.
        warn_share: removing more than this share of the walkable cells warns
            (``UserWarning`` naming the house, the rule and the share): a map whose free space
            falls apart in large pieces is more likely misread than furnished.

    Returns:
        The same scene (``rule="all"``, or nothing to remove), or a copy
        (``dataclasses.replace``: every other field kept) whose ``grid.walkable`` is the
        reachable area and whose ``instances`` are -1 outside it.
    """
    check_rule(rule, "reachable rule")
    if rule == "all":
        return scene
    walk = np.asarray(scene.grid.walkable, bool)
    seeds = seed_cells(scene.grid, points_xz, snap_m) if rule == "start" and points_xz is not None else None
    reach = reachable_mask(walk, seeds)
    removed = int(walk.sum() - reach.sum())
    if not removed:
        return scene
    share = removed / max(int(walk.sum()), 1)
    if share > warn_share:
        how = "the component(s) of the start pose / views" if seeds is not None and len(seeds) else \
            "the largest component"
        warnings.warn(f"house {scene.house_id!r}: the reachable area ({how}, env.reachable={rule}) leaves out "
                      f"{100 * share:.1f} % of the walkable cells ({removed} px); check the map if this is not "
                      f"furniture", UserWarning, stacklevel=2)
    grid = GridMap(reach, scene.grid.resolution, scene.grid.origin)
    inst = np.where(reach, scene.instances, -1).astype(np.int32)
    return dataclasses.replace(scene, grid=grid, instances=inst)


def start_points(house_data) -> np.ndarray | None:
    """The start pose of a ProcTHOR-schema house: ``metadata.agent.position`` (x, z) metres as
    a (1, 2) array, or None when the house has none (or it is not a pair of finite numbers)."""
    try:
        pos = house_data["metadata"]["agent"]["position"]
        xz = np.array([[float(pos["x"]), float(pos["z"])]])
    except (KeyError, TypeError, ValueError):
        return None
    return xz if np.isfinite(xz).all() else None


__all__ = ["RULES", "SNAP_M", "WARN_REMOVED_SHARE", "check_rule", "reachable_mask", "restrict_scene", "seed_cells",
           "start_points"]
