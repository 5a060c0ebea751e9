"""The path a robot drives through its views, and shortest paths on the grid.

:func:`route` joins consecutive views (in capture order): by the straight segment between
their cells when every cell of its digital line (:func:`envs.maps.rays.trace_ray`) is
walkable, else by the shortest **8-connected** walkable path (:func:`shortest_path`: steps
cost 1 and sqrt(2) cells, a diagonal step only where both cells beside it are walkable: no
corner cutting; paths are not smoothed, so a path is up to 8 % longer than the taut string).
A view the previous one cannot reach (another walkable component, or a view off the
walkable cells) is joined by a *jump*: nothing is driven or scanned in between, and its
straight-line distance is counted as travelled (a lower bound of the real detour).

:func:`trajectory` samples the route every ``spacing`` metres of driven path (yaw = the
direction of travel) and includes every view pose (with its own yaw): the scan poses of
:func:`envs.maps.scan.scan_map`. :func:`view_distances` is the distance travelled up to
each view (what pose drift grows with).
"""

from __future__ import annotations

import heapq
import math
from dataclasses import dataclass

import numpy as np

from envs.digest import arrays_key
from envs.kernel_cache import njit
from envs.maps.gridmap import GridMap
from envs.maps.rays import trace_ray
from envs.memo import ByteLRU

SQRT2 = math.sqrt(2.0)
#: 8-neighbour offsets (d_row, d_col) and step costs (cells), in the order paths are relaxed.
STEPS = np.array([[-1, 0], [1, 0], [0, -1], [0, 1], [-1, -1], [-1, 1], [1, -1], [1, 1]], np.int64)
STEP_COST = np.array([1.0, 1.0, 1.0, 1.0, SQRT2, SQRT2, SQRT2, SQRT2])


@njit(cache=True, nogil=True)
def _dijkstra(passable, start, targets, dist, pred, steps, cost):
    """8-connected Dijkstra over ``passable`` (H, W) from flat cell ``start``; stops at the
    first ``targets`` cell popped (heap order: distance, then flat index). Returns it or -1."""
    h, w = passable.shape
    heap = [(0.0, start)]
    dist[start] = 0.0
    while len(heap) > 0:
        d, v = heapq.heappop(heap)
        if d > dist[v]:
            continue
        if targets[v]:
            return v
        r = v // w
        c = v % w
        for k in range(8):
            rr = r + steps[k, 0]
            cc = c + steps[k, 1]
            if rr < 0 or rr >= h or cc < 0 or cc >= w or not passable[rr, cc]:
                continue
            if k >= 4 and not (passable[rr, c] and passable[r, cc]):
                continue
            u = rr * w + cc
            nd = d + cost[k]
            if nd < dist[u]:
                dist[u] = nd
                pred[u] = v
                heapq.heappush(heap, (nd, u))
    return -1


def shortest_path(passable: np.ndarray, start: tuple[int, int], targets: np.ndarray) -> tuple[np.ndarray, float]:
    """Shortest 8-connected path over ``passable`` cells from ``start`` to the nearest cell of
    ``targets`` (ties: the lower row-major index).

    Args:
        passable: (H, W) bool cells the path may use.
        start: (row, col) of a passable cell.
        targets: (H, W) bool cells to reach.

    Returns:
        ((L, 2) int64 (row, col) cells from start to the target, both included; length in
        cells (1 per straight, sqrt(2) per diagonal step)), or ((0, 2), inf) when no target
        is reachable.
    """
    passable = np.ascontiguousarray(passable, np.bool_)
    h, w = passable.shape
    r, c = int(start[0]), int(start[1])
    if not (0 <= r < h and 0 <= c < w and passable[r, c]):
        return np.zeros((0, 2), np.int64), math.inf
    dist = np.full(h * w, np.inf)
    pred = np.full(h * w, -1, np.int64)
    end = _dijkstra(passable, r * w + c, np.ascontiguousarray(targets, np.bool_).ravel(), dist, pred, STEPS, STEP_COST)
    if end < 0:
        return np.zeros((0, 2), np.int64), math.inf
    cells = [end]
    while cells[-1] != r * w + c:
        cells.append(int(pred[cells[-1]]))
    flat = np.array(cells[::-1], np.int64)
    return np.column_stack([flat // w, flat % w]), float(dist[end])


def straight_clear(walkable: np.ndarray, a: tuple[int, int], b: tuple[int, int]) -> bool:
    """True when every cell of the digital line from cell ``a`` to cell ``b`` is walkable."""
    n = max(abs(b[0] - a[0]), abs(b[1] - a[1])) + 1
    buf_r, buf_c = np.empty(n, np.int32), np.empty(n, np.int32)
    got, hr, _ = trace_ray(np.ascontiguousarray(~np.asarray(walkable, bool)), int(a[0]), int(a[1]),
                           int(b[0]), int(b[1]), buf_r, buf_c)
    return hr < 0 and got == n


@dataclass
class Route:
    """The polyline a robot drives through its views.

    Attributes:
        points: (K, 2) world (x, z) metres: the views' positions and the path cells' centres.
        view_index: (N,) index into ``points`` of each view.
        driven: (K,) bool, True where the segment from point k-1 to point k is driven
            (False for k = 0 and for jumps).
        travelled: (K,) metres travelled up to each point (jumps count their straight distance).
    """

    points: np.ndarray
    view_index: np.ndarray
    driven: np.ndarray
    travelled: np.ndarray

    @property
    def length(self) -> float:
        """Metres travelled up to the last view."""
        return float(self.travelled[-1]) if len(self.travelled) else 0.0


#: bytes of routes :func:`route` keeps per process (least recently used dropped first): the
#: jobs of a sweep ask for the same house's route again (every method and severity of a pose
#: error or a scan map drives the same views), and a route of a shared ProcTHOR house holds
#: tens of kilobytes
ROUTE_MEMO_BYTES = 32 * 2**20
_ROUTES = ByteLRU()


def _route_key(walkable: np.ndarray, grid: GridMap, poses: np.ndarray) -> bytes:
    """A digest of everything :func:`route` reads: the walkable cells, the grid's cells, size
    and placement, and the poses."""
    return arrays_key((walkable, np.asarray(grid.walkable, bool), poses),
                      (float(grid.resolution), tuple(float(o) for o in grid.origin)))


def route(walkable: np.ndarray, grid: GridMap, poses: np.ndarray) -> Route:
    """Join (N, 3) view poses (x, z metres, yaw degrees) in capture order (module docstring).

    Kept per process by a digest of its inputs (:data:`ROUTE_MEMO_BYTES`); the arrays of a
    route are read-only.

    Returns:
        :class:`Route`.
    """
    poses = np.asarray(poses, np.float64).reshape(-1, 3)
    walkable = np.asarray(walkable, bool)
    key = _route_key(walkable, grid, poses)
    out = _ROUTES.get(key)
    if out is None:
        out = _route(walkable, grid, poses)
        for a in (out.points, out.view_index, out.driven, out.travelled):
            a.setflags(write=False)
        _ROUTES.put(key, out, _route_bytes(out), ROUTE_MEMO_BYTES)
    return out


def _route_bytes(r: Route) -> int:
    return r.points.nbytes + r.view_index.nbytes + r.driven.nbytes + r.travelled.nbytes


def _route(walkable: np.ndarray, grid: GridMap, poses: np.ndarray) -> Route:
    """:func:`route`, computed."""
    rows, cols = grid.world_to_cell(poses[:, 0], poses[:, 1])
    ok = grid.is_walkable(rows, cols)
    pts: list[np.ndarray] = []
    driven: list[bool] = []
    view_index = np.zeros(len(poses), np.int64)
    for i in range(len(poses)):
        if i > 0:
            a, b = (int(rows[i - 1]), int(cols[i - 1])), (int(rows[i]), int(cols[i]))
            if ok[i - 1] and ok[i] and a != b and not straight_clear(walkable, a, b):
                target = np.zeros(walkable.shape, bool)
                target[b] = True
                path, _ = shortest_path(walkable, a, target)
                if len(path) == 0:
                    driven_here = False
                else:
                    x, z = grid.pixel_to_world(path[1:-1, 0], path[1:-1, 1])
                    pts.extend(np.column_stack([x, z]))
                    driven.extend([True] * (len(path) - 2))
                    driven_here = True
            else:
                driven_here = bool(ok[i - 1] and ok[i])
            driven.append(driven_here)
        else:
            driven.append(False)
        view_index[i] = len(pts)
        pts.append(poses[i, :2])
    points = np.array(pts, np.float64).reshape(-1, 2)
    steps = np.hypot(*np.diff(points, axis=0).T) if len(points) > 1 else np.zeros(0)
    travelled = np.concatenate([[0.0], np.cumsum(steps)]) if len(points) else np.zeros(0)
    return Route(points, view_index, np.array(driven, bool), travelled)


def view_distances(walkable: np.ndarray, grid: GridMap, poses: np.ndarray) -> np.ndarray:
    """(N,) metres travelled along :func:`route` up to each view (0 for the first)."""
    r = route(walkable, grid, poses)
    return r.travelled[r.view_index]


def segment_yaw(dx, dz) -> np.ndarray:
    """Simulator yaw (degrees, [0, 360)) of a world displacement (dx, dz): 0 faces +z, 90 faces +x."""
    return np.mod(np.rad2deg(np.arctan2(dx, dz)), 360.0)


def trajectory_with_views(walkable: np.ndarray, grid: GridMap, poses: np.ndarray,
                          spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """:func:`trajectory` and (N,) the index of each view among its scan poses.

    Args:
        walkable: (H, W) bool cells the robot may drive on.
        grid: the map's geometry.
        poses: (N, 3) views (x, z metres, yaw degrees) in capture order.
        spacing: metres of route between samples.

    Returns:
        (M, 3) poses in travel order: a sample at every multiple of ``spacing`` along the route
        that falls on a driven segment (yaw = that segment's direction of travel), and every
        view pose (its own yaw); at equal distance the sample comes first.
    """
    if not (math.isfinite(spacing) and spacing > 0):
        raise ValueError(f"trajectory spacing = {spacing!r}: expected metres > 0")
    poses = np.asarray(poses, np.float64).reshape(-1, 3)
    if len(poses) == 0:
        return np.zeros((0, 3)), np.zeros(0, np.int64)
    r = route(walkable, grid, poses)
    seg_len = np.diff(r.travelled)
    moving = r.driven[1:] & (seg_len > 0)
    s = np.arange(0.0, r.length + 1e-9, spacing)
    # the segment each sample lies on: the last moving segment starting at or before it
    seg = np.searchsorted(r.travelled[1:], s, side="right")
    seg = np.clip(seg, 0, max(len(seg_len) - 1, 0))
    keep = moving[seg] if len(seg_len) else np.zeros(len(s), bool)
    s, seg = s[keep], seg[keep]
    t = (s - r.travelled[seg]) / np.where(seg_len[seg] > 0, seg_len[seg], 1.0)
    p0, p1 = r.points[seg], r.points[seg + 1]
    xy = p0 + t[:, None] * (p1 - p0)
    yaw = segment_yaw(p1[:, 0] - p0[:, 0], p1[:, 1] - p0[:, 1])
    samples = np.column_stack([xy, yaw])
    dist = np.concatenate([s, r.travelled[r.view_index]])
    kind = np.concatenate([np.zeros(len(s), np.int64), np.ones(len(poses), np.int64)])
    order = np.lexsort((kind, dist))
    return np.vstack([samples, poses])[order], _positions(order, len(s))


def _positions(order: np.ndarray, n_samples: int) -> np.ndarray:
    """Where each view (rows ``n_samples..`` before sorting) lands in the sorted scan poses."""
    where = np.empty(len(order), np.int64)
    where[order] = np.arange(len(order))
    return where[n_samples:]


def trajectory(walkable: np.ndarray, grid: GridMap, poses: np.ndarray, spacing: float) -> np.ndarray:
    """The robot's scan poses: its route through the views sampled every ``spacing`` metres.

    Args:
        walkable: (H, W) bool cells the robot may drive on.
        grid: the map's geometry.
        poses: (N, 3) views (x, z metres, yaw degrees) in capture order.
        spacing: metres of route between samples.

    Returns:
        (M, 3) poses in travel order: a sample at every multiple of ``spacing`` along the route
        that falls on a driven segment (yaw = that segment's direction of travel), and every
        view pose (its own yaw); at equal distance the sample comes first.
    """
    return trajectory_with_views(walkable, grid, poses, spacing)[0]


__all__ = ["Route", "route", "view_distances", "trajectory", "trajectory_with_views", "shortest_path", "straight_clear", "segment_yaw",
           "STEPS", "STEP_COST"]
