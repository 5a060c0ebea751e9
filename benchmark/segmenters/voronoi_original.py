"""The Voronoi segmentation's ``original`` rule (``segmenter.rule=original``): ipa_room_segmentation's
Voronoi graph, critical-point rule and merging passes (Bormann et al., ICRA 2016;
``voronoi_segmentation.cpp``, ``abstract_voronoi_segmentation.cpp`` and ``room_class.cpp`` of
ipa320/ipa_coverage_planning), re-implemented as plain functions over arrays.

The steps, as the authors take them (:meth:`benchmark.segmenters.voronoi.Voronoi.original_rooms`
runs them on the map resampled to the authors' 0.05 m/px):

0. **Graph** (:func:`voronoi_graph`): the Voronoi diagram of the free space's border pixels,
   away from the walls, pruned of every branch that ends in a tip back to the junction it leaves
   from (:func:`benchmark.segmenters.voronoi.prune_spurs` with no exception).
1. **Critical points** (:func:`critical_points`): the graph is walked in raster order; from each
   graph pixel not yet taken, a breadth-first search over the graph takes pixels until it has
   counted more than ``reach / clearance`` of them (the authors' ``voronoi_neighborhood_index``,
   280 pixels² at 0.05 m/px: 0.7 m², so a neighbourhood of 0.7 m² / clearance metres of graph) or
   has made ``max_search`` metres of steps; the pixel of lowest clearance among those taken is a
   critical point. Every stretch of the graph gives one, in wide rooms too (no widest door).
2. **Critical lines** (:func:`critical_lines`): from the point to the nearest pixel on the free
   space's border, and to the nearest border pixel farther than that one and more than the
   point's clearance away from it; the angle between the two is the line's angle.
3. **Thinning** (:func:`keep_lines`): of two critical points closer than ``min_critical_distance``
   times the first's clearance, the one whose line turns less (smaller angle) is dropped; on equal
   angles the longer line is.
4. **Cells** (:func:`cells`): the lines are drawn 2 pixels wide; each 8-connected part of the cut
   free space whose contour encloses at least ``min_segment_area`` is a cell; the rest of the free
   space (the lines, smaller parts) takes the label of its neighbours ring by ring.
5. **Merging** (:func:`merge_cells`): five passes over the cells, smallest first, each restarting
   after a merge, on the cells' area, their share of wall on their perimeter and their shared
   borders (the pixels just outside a cell, counted by what lies there); see that function.

Differences kept: the pruning removes tips until none is left, where the authors stop after 100
raster sweeps (a spur longer than about 100 pixels keeps its rest); their passes sort cells of
equal area in no fixed order, where these keep the order before; free space that no cell reaches
counts as the smallest label in ties of shared borders (theirs as the largest) and becomes a room
of its own instead of staying unlabelled.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from benchmark.segmenters.ipa import PAD_PX

#: the label of obstacles (walls) in the merging passes' statistics.
WALL = 0
#: the label of free pixels no cell reached (counted as a neighbour, never a room).
UNASSIGNED = -1
#: pass b merges cells below this area, square metres (hard-coded by the authors).
SMALL_CELL_AREA = 2.0
#: the width of the critical lines, pixels (the authors' ``cv::line`` thickness).
LINE_PX = 2
#: the 8 neighbours in the authors' scan order (row -1..1, then column -1..1).
NEIGHBOURS = [(dr, dc) for dr in (-1, 0, 1) for dc in (-1, 0, 1) if (dr, dc) != (0, 0)]


def rounded_clearance(walkable: np.ndarray) -> np.ndarray:
    """(H, W) int distance of each free pixel to the nearest obstacle, pixels, as the authors
    take it: OpenCV's 5 x 5 mask approximation of the Euclidean distance, rounded to whole
    pixels (at most 255); the map's edge is an obstacle."""
    pad = np.pad(np.asarray(walkable, bool), 1).view(np.uint8)
    d = cv2.distanceTransform(pad, cv2.DIST_L2, 5)[1:-1, 1:-1]
    return np.minimum(np.rint(d), 255).astype(np.int64)


def resample(walkable: np.ndarray, resolution: float, target: float) -> np.ndarray:
    """The walkable mask at ``target`` metres per pixel (nearest cell centre, as
    :func:`benchmark.segmenters.ipa.ipa_image` samples the maps it gives the authors' build).

    Args:
        walkable: (H, W) bool at ``resolution`` metres per pixel.

    Returns:
        (h, w) bool, h = round(H * resolution / target) (at least 1), likewise w.
    """
    h, w = walkable.shape
    scale = resolution / target
    rows = np.minimum(((np.arange(max(1, int(round(h * scale)))) + 0.5) / scale).astype(np.int64), h - 1)
    cols = np.minimum(((np.arange(max(1, int(round(w * scale)))) + 0.5) / scale).astype(np.int64), w - 1)
    return np.asarray(walkable, bool)[rows][:, cols]


def sample_back(lab: np.ndarray, shape: tuple[int, int], resolution: float, target: float) -> np.ndarray:
    """Labels made on :func:`resample`'s mask back onto the (H, W) ``shape`` at ``resolution``
    (nearest pixel); returns (H, W) of ``lab``'s dtype."""
    scale = resolution / target
    rr = np.minimum(((np.arange(shape[0]) + 0.5) * scale).astype(np.int64), lab.shape[0] - 1)
    cc = np.minimum(((np.arange(shape[1]) + 0.5) * scale).astype(np.int64), lab.shape[1] - 1)
    return lab[rr][:, cc]


def voronoi_graph(walkable: np.ndarray) -> np.ndarray:
    """The authors' generalised Voronoi graph of the free space, unpruned: the Voronoi diagram of
    every border pixel of the free space (OpenCV's Delaunay subdivision), each edge of it drawn
    (1 pixel, 8-connected) where both its ends lie in the free space opened by a 3 x 3 square and
    then eroded twice by it (so no edge runs along a wall).

    Args:
        walkable: (H, W) bool.

    Returns:
        (H, W) bool, the graph's pixels (free pixels only).
    """
    walk = np.asarray(walkable, bool)
    pad = PAD_PX  # the frame the authors' build gets its maps in: their diagram depends on it (ties on the grid)
    free = np.ascontiguousarray(np.pad(walk, pad), dtype=np.uint8) * 255
    square = np.ones((3, 3), np.uint8)
    opened = cv2.dilate(cv2.erode(free, square), square)
    inner = cv2.erode(opened, square, iterations=2) > 0
    contours, _ = cv2.findContours(free.copy(), cv2.RETR_CCOMP, cv2.CHAIN_APPROX_NONE)
    h, w = free.shape
    out = np.zeros((h, w), np.uint8)
    if contours:
        sub = cv2.Subdiv2D((0, 0, w, h))
        sub.insert([(float(x), float(y)) for c in contours for x, y in c.reshape(-1, 2)])
        facets, _ = sub.getVoronoiFacetList([])
        for f in facets:
            pts = np.asarray(f, float)
            for a, b in zip(np.roll(pts, 1, axis=0), pts):
                ia, ib = a.astype(np.int64), b.astype(np.int64)  # truncated, as the authors test them
                if ((ia >= 0).all() and (ib >= 0).all() and ia[0] < w and ib[0] < w and ia[1] < h and ib[1] < h
                        and inner[ia[1], ia[0]] and inner[ib[1], ib[0]]):
                    cv2.line(out, tuple(int(v) for v in np.rint(a)), tuple(int(v) for v in np.rint(b)), 1, 1)
    return (out > 0)[pad:-pad, pad:-pad] & walk


def critical_points(graph: np.ndarray, clearance: np.ndarray, reach_px2: float, max_steps: int) -> np.ndarray:
    """The authors' critical points: one per stretch of the graph (step 1 of the module doc).

    Args:
        graph: (H, W) bool, the pruned graph (skeleton).
        clearance: (H, W) int, :func:`rounded_clearance`.
        reach_px2: the neighbourhood, pixels² (``reach`` / resolution²): a search from a pixel of
            clearance d stops once it has counted more than ``reach_px2 // d`` graph pixels.
        max_steps: the most breadth-first steps of one search.

    Returns:
        (M, 2) int (row, col) of the critical points, in the order their searches started.
    """
    left = np.asarray(graph, bool).copy()
    h, w = left.shape
    out = []
    for r0, c0 in zip(*np.nonzero(left)):
        if not left[r0, c0]:
            continue
        eps = int(reach_px2) // max(int(clearance[r0, c0]), 1)
        taken, front, count, steps = [(r0, c0)], [(r0, c0)], 0, 0
        while True:
            steps += 1
            found = []
            for r, c in front:
                for dr, dc in NEIGHBOURS:
                    rr, cc = r + dr, c + dc
                    if 0 <= rr < h and 0 <= cc < w and left[rr, cc] and (rr, cc) != (r0, c0):
                        count += 1  # counted once per pixel of the front it touches, as the authors count
                        found.append((rr, cc))
            front = list(dict.fromkeys(found))
            for p in front:
                left[p] = False
            if found:
                left[r0, c0] = False
            taken += front
            if not (count <= eps and steps < max_steps) or not front:
                break
        # the lowest clearance; on a tie the first in raster order (the search's set order)
        r, c = min(taken, key=lambda p: (clearance[p], p))
        out.append((r, c))
    return np.array(out, dtype=np.int64).reshape(-1, 2)


def border_pixels(walkable: np.ndarray) -> np.ndarray:
    """(K, 2) int (row, col) of the free space's border pixels in OpenCV's contour order (every
    contour, outer and holes, all its points), the candidates for the critical lines' ends."""
    pad = np.pad(np.asarray(walkable, bool), 1).astype(np.uint8)
    contours, _ = cv2.findContours(pad, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_NONE)
    if not contours:
        return np.zeros((0, 2), np.int64)
    xy = np.concatenate([c.reshape(-1, 2) for c in contours]).astype(np.int64)
    return xy[:, ::-1] - 1


def critical_lines(points: np.ndarray, clearance: np.ndarray, border: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Each critical point's two basis points (step 2 of the module doc).

    Args:
        points: (M, 2) int (row, col), :func:`critical_points`.
        clearance: (H, W) int, :func:`rounded_clearance`.
        border: (K, 2) int, :func:`border_pixels`.

    Returns:
        (ok, first, second, angle, length): (M,) bool whether a second basis point exists,
        (M, 2) int the nearest border pixel, (M, 2) int the second, (M,) float the angle between
        the two, degrees, (M,) float the line's length (the two distances), pixels.
    """
    m = len(points)
    ok = np.zeros(m, bool)
    first, second = np.zeros((m, 2), np.int64), np.zeros((m, 2), np.int64)
    angle, length = np.zeros(m), np.zeros(m)
    b = border.astype(float)
    for i, p in enumerate(points):
        v = b - p
        d = np.hypot(v[:, 0], v[:, 1])
        j = int(np.argmin(d))  # the first of the nearest, in contour order
        apart = np.hypot(*(b - b[j]).T)
        cand = (d > d[j]) & (apart > clearance[tuple(p)])
        if not cand.any():
            continue
        k = int(np.nonzero(cand)[0][np.argmin(d[cand])])
        cos = float(v[j] @ v[k]) / (d[j] * d[k])
        ok[i], first[i], second[i] = True, border[j], border[k]
        angle[i], length[i] = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))), d[j] + d[k]
    return ok, first, second, angle, length


def keep_lines(points: np.ndarray, clearance_at: np.ndarray, angle: np.ndarray, length: np.ndarray,
               factor: float) -> np.ndarray:
    """Which critical lines are drawn (step 3 of the module doc): a point is dropped when another
    lies closer than ``factor`` times its clearance and turns more (a larger angle), or turns as
    much with a shorter line (longer than 3 pixels, or earlier in order).

    Args:
        points: (M, 2) int (row, col); clearance_at: (M,) int their clearance, pixels;
        angle: (M,) degrees; length: (M,) pixels; factor: the authors'
            ``min_critical_point_distance_factor``.

    Returns:
        (M,) bool.
    """
    m = len(points)
    if m == 0:
        return np.zeros(0, bool)
    p = points.astype(float)
    close = np.hypot(p[:, None, 0] - p[None, :, 0], p[:, None, 1] - p[None, :, 1]) < clearance_at[:, None] * factor
    np.fill_diagonal(close, False)
    turns_more = angle[None, :] > angle[:, None]
    idx = np.arange(m)
    shorter = ((angle[None, :] == angle[:, None]) & (length[:, None] > length[None, :])
               & ((length[None, :] > 3) | (idx[:, None] > idx[None, :])))
    return ~(close & (turns_more | shorter)).any(axis=1)


def colour_ids(n: int) -> list[int]:
    """The ids the authors' cells get, in order: each cell draws a colour ``rand() % 52224 + 13056``
    until it draws one no cell has. Their ``rand()`` is never seeded, so these are the first draws
    of glibc's generator under its default seed 1 (its additive feedback generator: 34 words from
    the seed by 16807 x mod 2^31 - 1, then each word the sum of those 31 and 3 before, mod 2^32,
    the first 310 thrown away, each draw a word halved). The ids matter where borders tie: the
    merging passes take, of equal shared borders, the cell with the larger id.

    Args:
        n: how many cells.

    Returns:
        n distinct ids in [13056, 65279].
    """
    r = [1]
    for _ in range(30):
        hi, lo = divmod(r[-1], 127773)
        r.append((16807 * lo - 2836 * hi) % 2147483647)
    r += r[:3]
    out: list[int] = []
    seen: set[int] = set()
    k = len(r)
    while len(out) < n:
        r.append((r[k - 31] + r[k - 3]) & 0xFFFFFFFF)
        if k >= 344:
            v = (r[k] >> 1) % 52224 + 13056
            if v not in seen:
                seen.add(v)
                out.append(v)
        k += 1
    return out


def cells(walkable: np.ndarray, lines: list[tuple[tuple[int, int], tuple[int, int]]], resolution: float,
          min_segment_area: float) -> np.ndarray:
    """The free space cut by the critical lines, as cells (step 4 of the module doc).

    Args:
        walkable: (H, W) bool.
        lines: ((row, col), (row, col)) segments to draw, :data:`LINE_PX` wide.
        resolution: metres per pixel.
        min_segment_area: square metres: smaller parts (by the area their outer contour
            encloses, as OpenCV's ``contourArea``) are no cell of their own.

    Returns:
        (H, W) int64: the cells' ids (:func:`colour_ids`, in contour order) on the free space they
        reach, :data:`UNASSIGNED` on free pixels none reaches, :data:`WALL` on obstacles.
    """
    walk = np.asarray(walkable, bool)
    cut = np.ascontiguousarray(np.pad(walk, 1), dtype=np.uint8) * 255
    for a, b in lines:
        cv2.line(cut, (int(a[1]) + 1, int(a[0]) + 1), (int(b[1]) + 1, int(b[0]) + 1), 0, LINE_PX)
    parts, part = cv2.connectedComponents((cut > 0).view(np.uint8), connectivity=8)
    contours, hierarchy = cv2.findContours(cut, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_SIMPLE)
    found = []  # each cell's part, in contour order
    for c, hier in zip(contours, hierarchy[0] if hierarchy is not None else []):
        if hier[3] != -1 or cv2.contourArea(c) * resolution ** 2 < min_segment_area:
            continue  # a hole's contour, or too small
        x, y = c[0, 0]
        found.append(part[y, x])
    number = np.zeros(parts, np.int64)  # each part's cell id, 0: none
    number[found] = colour_ids(len(found))
    lab = number[part[1:-1, 1:-1]]
    lab[walk & (lab == 0)] = UNASSIGNED
    return wavefront(lab, walk)


def wavefront(lab: np.ndarray, walkable: np.ndarray) -> np.ndarray:
    """Free pixels with no cell (:data:`UNASSIGNED`) take a neighbouring cell's label, ring by
    ring: each ring, the first labelled of the 8 neighbours in the authors' scan order (as they
    were before the ring). Returns a new (H, W) int64 array."""
    lab = np.pad(lab, 1, constant_values=WALL)
    walk = np.pad(np.asarray(walkable, bool), 1)
    h, w = lab.shape
    while True:
        todo = walk & (lab == UNASSIGNED)
        new = lab.copy()
        free = todo.copy()
        for dr, dc in NEIGHBOURS:
            nb = np.zeros_like(lab)
            nb[max(-dr, 0):h - max(dr, 0), max(-dc, 0):w - max(dc, 0)] = \
                lab[max(dr, 0):h + min(dr, 0), max(dc, 0):w + min(dc, 0)]
            take = free & (nb > 0)
            new[take] = nb[take]
            free &= ~take
        if (new == lab).all():
            return lab[1:-1, 1:-1]
        lab = new


@dataclass
class _Cell:
    """One cell in the merging passes: its area (square metres), the ids of its neighbouring
    cells, and ``border``: the pixels just outside it counted by their label (:data:`WALL`,
    :data:`UNASSIGNED` or a cell's id); their sum is its perimeter."""

    area: float
    neighbours: set[int] = field(default_factory=set)
    border: dict[int, int] = field(default_factory=dict)

    def perimeter(self) -> int:
        return sum(self.border.values())

    def share(self, label: int) -> float:
        p = self.perimeter()
        return self.border.get(label, 0) / p if p else 0.0

    def by_border(self) -> list[tuple[int, int]]:
        """(border length, label), longest first, one label per length (the largest: the
        authors key a map by length, so labels of equal length overwrite each other)."""
        inv = {}
        for k in sorted(self.border):
            inv[self.border[k]] = k
        return sorted(inv.items(), reverse=True)

    def largest_border(self) -> int:
        """The label sharing the longest border, the wall skipped when anything else borders."""
        inv = self.by_border()
        if not inv:
            return WALL
        return inv[1][1] if inv[0][1] == WALL and len(inv) > 1 else inv[0][1]

    def share_of_largest(self, n: int) -> float:
        """The share of the perimeter of the longest borders down to the ``n``-th cell's (the
        wall counted where it comes before)."""
        p, value, counted = self.perimeter(), 0, 0
        for length, label in self.by_border():
            if counted >= n:
                break
            value += length
            counted += label != WALL
        return value / p if p else 0.0


def cell_statistics(lab: np.ndarray, resolution: float) -> dict[int, _Cell]:
    """Each cell's area, neighbours and border counts from the label map (:func:`cells`): the
    border of a cell is every pixel in the 8-neighbourhood of its pixels that is not its own,
    counted once by that pixel's label (obstacles and the map's edge: :data:`WALL`)."""
    pad = np.pad(lab, 1, constant_values=WALL)
    h, w = pad.shape
    flat = pad.ravel()
    ids = np.unique(flat[flat > 0])
    out = {int(i): _Cell(area=0.0) for i in ids}
    area = np.bincount(flat[flat > 0])
    for i in out:
        out[i].area = float(area[i]) * resolution ** 2
    inside = np.nonzero(flat > 0)[0]
    owners, pixels = [], []
    for dr, dc in NEIGHBOURS:
        q = inside + dr * w + dc
        diff = flat[q] != flat[inside]
        owners.append(flat[inside[diff]])
        pixels.append(q[diff])
    if not owners or not np.concatenate(owners).size:
        return out
    pairs = np.unique(np.stack([np.concatenate(owners), np.concatenate(pixels)], axis=1), axis=0)
    keys, counts = np.unique(np.stack([pairs[:, 0], flat[pairs[:, 1]]], axis=1), axis=0, return_counts=True)
    for (i, label), cnt in zip(keys.tolist(), counts.tolist()):
        out[i].border[label] = cnt
        if label != WALL:
            out[i].neighbours.add(label)
    return out


def _merge(rooms: dict[int, _Cell], target: int, gone: int, parent: dict[int, int]) -> None:
    """Cell ``gone`` into cell ``target``, the bookkeeping as the authors keep it (borders are
    added, not measured again)."""
    t, g = rooms[target], rooms.pop(gone)
    t.area += g.area
    t.neighbours = (t.neighbours | g.neighbours) - {target, gone}
    for k, v in g.border.items():
        if k != target:
            t.border[k] = t.border.get(k, 0) + v
    t.border.pop(gone, None)
    parent[gone] = target
    for cell in rooms.values():
        if gone in cell.neighbours:
            cell.neighbours.discard(gone)
            cell.neighbours.add(target)
        if gone in cell.border:
            cell.border[target] = cell.border.get(target, 0) + cell.border.pop(gone)


def _pass(rooms: dict[int, _Cell], parent: dict[int, int], partner) -> None:  # noqa: ANN001
    """One merging pass: cells smallest first; the first for which ``partner(id, cell)`` names
    a cell merges into it, and the pass starts again from the smallest."""
    while True:
        for i in sorted(rooms, key=lambda r: rooms[r].area):
            j = partner(i, rooms[i])
            if j is not None:
                _merge(rooms, j, i, parent)
                break
        else:
            return


def merge_cells(lab: np.ndarray, resolution: float, max_merge_area: float) -> np.ndarray:
    """The authors' five merging passes over the cells (step 5 of the module doc). With ``share``
    a cell's border with something over its perimeter and ``partner`` the cell sharing its longest
    border, a cell merges into ``partner`` when:

    a. it has one neighbouring cell, is under ``max_merge_area`` and has at most 75 % wall;
    b. it is under 2 m², its partner's share is over 0.2 and the partner has at most 80 % wall;
    c. it has one neighbouring cell (or its partner and the wall make over 98 % of its
       perimeter), over 50 % wall and the partner's share over 0.15, unless the partner has
       more than two neighbours and its two longest borders (and the wall before them) make
       under 95 % of its perimeter;
    d. (any neighbour, longest border first) the neighbour's share is over 0.2, or over 0.1 with
       the wall's share between 1 - 2 x share - 0.05 and 1 - share, and the cell is over 10 % of
       the neighbour's perimeter;
    e. its partner's share is over 0.4.

    Args:
        lab: (H, W) int, :func:`cells`.
        resolution: metres per pixel.
        max_merge_area: square metres (the authors' ``max_area_for_merging``).

    Returns:
        (H, W) int64: the label map with every merged cell's pixels under the cell it joined.
    """
    rooms = cell_statistics(lab, resolution)
    parent: dict[int, int] = {}

    def a(i: int, c: _Cell) -> int | None:
        if len(c.neighbours) == 1 and c.area < max_merge_area and c.share(WALL) <= 0.75:
            j = c.largest_border()
            return j if j in rooms else None
        return None

    def b(i: int, c: _Cell) -> int | None:
        j = c.largest_border()
        if c.area < SMALL_CELL_AREA and c.share(j) > 0.2 and j in rooms and rooms[j].share(WALL) <= 0.8:
            return j
        return None

    def c_(i: int, c: _Cell) -> int | None:
        j = c.largest_border()
        if ((len(c.neighbours) == 1 or c.share_of_largest(1) > 0.98) and c.share(WALL) > 0.5 and c.share(j) > 0.15
                and j in rooms and not (len(rooms[j].neighbours) > 2 and rooms[j].share_of_largest(2) < 0.95)):
            return j
        return None

    def d(i: int, c: _Cell) -> int | None:
        wall = c.share(WALL)
        for _, j in c.by_border():
            if j == WALL:
                continue
            s = c.share(j)
            if (s > 0.2 or (s > 0.1 and 1 - 2 * s - 0.05 < wall < 1 - s)) and j in rooms and rooms[j].share(i) > 0.1:
                return j
        return None

    def e(i: int, c: _Cell) -> int | None:
        j = c.largest_border()
        return j if c.share(j) > 0.4 and j in rooms else None

    for rule in (a, b, c_, d, e):
        _pass(rooms, parent, rule)
    # every merged cell under the cell it ended in
    top = np.arange(int(lab.max()) + 1 if lab.size else 1)
    for g in parent:
        r = g
        while r in parent:
            r = parent[r]
        top[g] = r
    out = lab.copy()
    m = lab > 0
    out[m] = top[lab[m]]
    return out


__all__ = ["colour_ids", "resample", "sample_back", "voronoi_graph", "critical_points", "critical_lines", "keep_lines", "cells", "wavefront", "merge_cells",
           "cell_statistics", "rounded_clearance", "border_pixels"]
