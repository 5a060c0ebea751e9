"""Exploration that stops: viewpoints a robot captures while exploring on a path-length budget.

Both strategies start at ``scene.start`` (the house's agent pose), snapped to the nearest
walkable cell when it is not on one; a scene without a start pose starts on the walkable cell
nearest the centroid of the walkable cells (ties: lower row, then column), facing yaw 0. The
robot moves cell to cell (8-connected steps of 1 or sqrt(2) cells); ``budget`` metres is the
most it drives. Views are captured at the start and then every ``spacing`` metres driven,
``n_headings`` headings spread over ``heading_spread`` degrees around the direction of
motion (the direction from the path cell 0.25 m behind to the one 0.25 m ahead on the current
leg; the start's own yaw at the start). A view is a pose at the centre of the robot's cell.

* :class:`Frontier`: nearest-frontier exploration (Yamauchi 1997). The robot builds its own
  scan map as it goes (:class:`envs.maps.scan.ScanMapper`, the same code as the scan-map
  condition, one scan at the start, then every ``scan_spacing`` metres and at the end of every
  leg). For planning, a cell is *known free* when its log-odds is below 0 (seen free more than
  hit) and it is truly walkable (``scene.grid.walkable``), and *unobserved* when no beam has
  reached it (log-odds 0). Frontier cells are known-free cells with an unobserved 4-neighbour;
  8-connected clusters of fewer than ``min_frontier`` metres (cells x resolution) are ignored,
  and so is a frontier cell the robot reached that stayed a frontier after the arrival scan.
  The robot drives the shortest 8-connected path over known-free cells
  (:func:`envs.maps.trajectory.shortest_path`) to the nearest frontier cell, replanning after
  any scan that turns its target into a non-frontier; it stops when the budget is spent or no
  frontier is reachable.
* :class:`RandomWalk`: straight runs: a heading drawn uniformly in [0, 360) degrees and a run
  length uniformly in [``min_run``, ``max_run``] metres; the robot drives the digital line of
  that run (:func:`envs.maps.rays.trace_ray` over the non-walkable cells) and stops
  before the first non-walkable cell. A run that cannot move at all is drawn again; 1000 such
  runs in a row end the walk.

Both are deterministic for (``seed``, house id) (:func:`benchmark.classifiers.noise.text_key`).
What they leave out: the robot's size (it drives on the walkable cells, which carry the map's
clearance), its dynamics (turning costs nothing), localisation error while exploring (pose
error is a separate stage), and smoothing of grid paths.
"""

from __future__ import annotations

import heapq
import math
from dataclasses import dataclass
from typing import Annotated

import numpy as np

from benchmark.classifiers.noise import text_key
from envs.digest import arrays_key
from envs.kernel_cache import njit
from envs.maps.gridmap import GridMap, pixel_direction_to_yaw
from envs.maps.rays import ray_end, trace_ray
from envs.maps.scan import (
    SCAN_HEIGHT,
    ReferenceScanMapper,
    ScanMap,
    ScanMapper,
    ScanSettings,
    scan_obstacles,
)
from envs.maps.scene import Scene
from envs.maps.trajectory import shortest_path
from envs.maps.union_find import find_root
from envs.memo import ByteLRU
from envs.ranges import DROPOUT, HEADING_SPREAD, Integer, Metres, NonNegative, Positive

#: metres behind and ahead on the path that set the direction of motion of a view.
MOTION_BASE = 0.25
#: the Frontier argument behind each scanner setting (for its error messages).
SCAN_ARGUMENTS = {"height": "viewpoints.scan_height", "max_range": "viewpoints.sensor_range",
                  "angular_step": "viewpoints.angular_step", "range_noise": "viewpoints.range_noise",
                  "dropout": "viewpoints.dropout", "spacing": "viewpoints.scan_spacing", "seed": "viewpoints.seed"}
#: consecutive runs that cannot move before a random walk gives up.
MAX_STUCK_RUNS = 1000


def heading_offsets(n_headings: int, heading_spread: float) -> np.ndarray:
    """(n,) degrees relative to a central heading: ``n`` evenly over ``heading_spread``
    (a full circle is not closed twice: 4 over 360 gives 0, 90, 180, 270 around -180)."""
    if n_headings == 1:
        return np.zeros(1)
    full = abs(heading_spread) >= 360
    return np.linspace(-heading_spread / 2, heading_spread / 2, n_headings, endpoint=not full)


def start_cell(grid: GridMap, start: tuple[float, float, float] | None) -> tuple[int, int, float]:
    """(row, col, yaw degrees) the robot starts from (module docstring)."""
    walk = grid.walkable
    if not walk.any():
        raise ValueError("the map has no walkable cell to start exploring from")
    if start is not None:
        r, c = (int(v) for v in grid.world_to_cell(start[0], start[1]))
        yaw = float(start[2])
        target_r, target_c = float(r), float(c)
        if grid.is_walkable(r, c):
            return r, c, yaw
    else:
        rr, cc = np.nonzero(walk)
        target_r, target_c, yaw = rr.mean(), cc.mean(), 0.0
    rr, cc = np.nonzero(walk)
    d2 = (rr - target_r) ** 2 + (cc - target_c) ** 2
    k = int(np.argmin(d2))  # np.nonzero is row-major: ties go to the lower row, then column
    return int(rr[k]), int(cc[k]), yaw


@dataclass
class Exploration:
    """What an exploration did.

    Attributes:
        poses: (N, 3) views (x, z metres, yaw degrees) in capture order.
        travelled: (N,) metres driven before each view.
        path: (K, 2) world (x, z) of the cells driven through, start included.
        length: metres driven.
        scan_map: the map the robot built (frontier), or None (random walk).
        stop: why it stopped: ``budget``, ``explored`` (no reachable frontier) or ``stuck``.
        explorer: the :class:`Frontier` that explored (None elsewhere): its budget check
            (:func:`no_view_on_own_map`) explores again with larger budgets.
    """

    poses: np.ndarray
    travelled: np.ndarray
    path: np.ndarray
    length: float
    scan_map: ScanMap | None
    stop: str
    explorer: Frontier | None = None


class _Drive:
    """The robot's odometer, path and cameras; scans through ``mapper`` when given."""

    def __init__(self, grid: GridMap, r: int, c: int, yaw: float, budget: float, spacing: float,
                 offsets: np.ndarray, mapper: ScanMapper | None = None, scan_spacing: float = math.inf):
        self.grid, self.budget, self.spacing, self.offsets = grid, budget, spacing, offsets
        self.mapper, self.scan_spacing = mapper, scan_spacing
        self.cells = [(r, c)]
        self.odo = 0.0
        self.views: list[tuple[float, float, float]] = []
        self.view_odo: list[float] = []
        self.base = max(1, int(round(MOTION_BASE / grid.resolution)))
        self._capture(r, c, yaw)
        self.next_view = spacing
        self.next_scan = scan_spacing
        self.scanned_here = False
        if mapper is not None:
            self._scan(r, c)

    def _capture(self, r: int, c: int, yaw: float) -> None:
        x, z = self.grid.pixel_to_world(r, c)
        for off in self.offsets:
            self.views.append((float(x), float(z), float(np.mod(yaw + off, 360.0))))
            self.view_odo.append(self.odo)

    def _scan(self, r: int, c: int) -> None:
        x, z = self.grid.pixel_to_world(r, c)
        self.mapper.add(np.array([[float(x), float(z), 0.0]]))
        self.scanned_here = True

    def leg(self, cells: np.ndarray, interrupt=None) -> str:
        """Drive ``cells`` ((L, 2) row, col; ``cells[0]`` is where the robot is).

        Returns:
            ``budget`` (stopped by the budget), ``interrupted`` (``interrupt()`` was true after
            a scan) or ``arrived``.
        """
        n = len(cells)
        for i in range(1, n):
            step = math.hypot(cells[i, 0] - cells[i - 1, 0], cells[i, 1] - cells[i - 1, 1]) * self.grid.resolution
            if self.odo + step > self.budget + 1e-9:
                return "budget"
            self.odo += step
            r, c = int(cells[i, 0]), int(cells[i, 1])
            self.cells.append((r, c))
            self.scanned_here = False
            if self.odo >= self.next_view - 1e-9:
                a, b = cells[max(i - self.base, 0)], cells[min(i + self.base, n - 1)]
                self._capture(r, c, float(pixel_direction_to_yaw(b[0] - a[0], b[1] - a[1])))
                while self.next_view <= self.odo + 1e-9:
                    self.next_view += self.spacing
            if self.mapper is not None and self.odo >= self.next_scan - 1e-9:
                self._scan(r, c)
                while self.next_scan <= self.odo + 1e-9:
                    self.next_scan += self.scan_spacing
                if interrupt is not None and i < n - 1 and interrupt():
                    return "interrupted"
        if self.mapper is not None and not self.scanned_here:
            self._scan(*self.cells[-1])
        return "arrived"

    def result(self, stop: str) -> Exploration:
        cells = np.array(self.cells, np.int64)
        x, z = self.grid.pixel_to_world(cells[:, 0], cells[:, 1])
        return Exploration(np.array(self.views, np.float64).reshape(-1, 3), np.array(self.view_odo),
                           np.column_stack([x, z]), self.odo,
                           self.mapper.result() if self.mapper is not None else None, stop)


def _check_common(budget, spacing, n_headings, heading_spread, unlimited: bool = False) -> None:
    """Refuse a bad common setting (one line); ``unlimited``: a budget of .inf is allowed."""
    for key, v, ok, want in (
        ("budget", budget, lambda v: v > 0 and (unlimited or math.isfinite(v)),
         "metres > 0 (.inf: until no reachable frontier)" if unlimited else "metres > 0"),
        ("spacing", spacing, lambda v: v > 0 and math.isfinite(v), "metres > 0"),
        ("heading_spread", heading_spread, lambda v: 0 <= v <= 360, "degrees in [0, 360]"),
    ):
        if isinstance(v, bool) or not isinstance(v, int | float) or math.isnan(v) or not ok(v):
            raise ValueError(f"viewpoints.{key} = {v!r}: expected {want}")
    if isinstance(n_headings, bool) or not isinstance(n_headings, int) or n_headings < 1:
        raise ValueError(f"viewpoints.n_headings = {n_headings!r}: expected an integer >= 1")


def frontier_cells(known_free: np.ndarray, unobserved: np.ndarray, min_cells: int) -> np.ndarray:
    """(H, W) bool known-free cells with an unobserved 4-neighbour, in 8-connected clusters of
    at least ``min_cells`` cells (one compiled pass: the clusters by union-find over the frontier
    cells only)."""
    known_free = np.ascontiguousarray(known_free, np.bool_)
    unobserved = np.ascontiguousarray(unobserved, np.bool_)
    if known_free.shape != unobserved.shape or known_free.ndim != 2:
        raise ValueError(f"frontier_cells: known_free {known_free.shape} and unobserved {unobserved.shape} "
                         f"must be the same (H, W)")
    out = np.zeros(known_free.shape, np.bool_)
    _frontier_kernel(known_free, unobserved, int(max(min_cells, 0)), out,
                     np.empty(known_free.size, np.int32), np.empty(known_free.size, np.int32))
    return out


@njit(cache=True, nogil=True)
def _frontier_kernel(known, unobs, min_cells, out, parent, size):
    """:func:`frontier_cells` into ``out``; ``parent`` and ``size`` are (H W,) scratch."""
    h, w = known.shape
    n = 0
    for r in range(h):
        for c in range(w):
            if not known[r, c]:
                continue
            if ((r > 0 and unobs[r - 1, c]) or (r < h - 1 and unobs[r + 1, c]) or (c > 0 and unobs[r, c - 1])
                    or (c < w - 1 and unobs[r, c + 1])):
                out[r, c] = True
                n += 1
    if n == 0 or min_cells <= 1:
        return
    # 8-connected clusters: each frontier cell joins those before it in raster order
    for r in range(h):
        for c in range(w):
            if not out[r, c]:
                continue
            p = r * w + c
            parent[p] = p
            size[p] = 1
            for dr, dc in ((0, -1), (-1, -1), (-1, 0), (-1, 1)):
                rr = r + dr
                cc = c + dc
                if rr < 0 or cc < 0 or cc >= w or not out[rr, cc]:
                    continue
                a = find_root(parent, p)
                b = find_root(parent, rr * w + cc)
                if a != b:
                    if size[a] < size[b]:
                        a, b = b, a
                    parent[b] = a
                    size[a] += size[b]
    for r in range(h):
        for c in range(w):
            if out[r, c] and size[find_root(parent, r * w + c)] < min_cells:
                out[r, c] = False


class Frontier:
    """Nearest-frontier exploration viewpoints (module docstring).

    Args:
        budget: most metres driven (.inf: until no reachable frontier is left).
        spacing: metres driven between captures.
        n_headings: views per capture.
        heading_spread: degrees the headings span around the direction of motion.
        sensor_range: the scanner's maximum range, metres.
        scan_height: the scan plane's height, metres.
        angular_step: degrees between beams.
        scan_spacing: metres driven between scans.
        range_noise: the scanner's range sigma, metres.
        dropout: share of beams returning nothing.
        min_frontier: frontier clusters shorter than this (metres: cells x resolution) are ignored.
        seed: with the house id, seeds the scan noise.
    """

    def __init__(self, budget: Annotated[float, Metres(inf_ok=True)] = 40.0,
                 spacing: Annotated[float, Positive()] = 1.0, n_headings: Annotated[int, Integer(1)] = 3,
                 heading_spread: Annotated[float, HEADING_SPREAD] = 180.0,
                 sensor_range: Annotated[float, Metres(inf_ok=True)] = 10.0,
                 scan_height: Annotated[float, SCAN_HEIGHT] = 0.25, angular_step: float = 1.0,
                 scan_spacing: Annotated[float, Positive()] = 0.5,
                 range_noise: Annotated[float, NonNegative()] = 0.0, dropout: Annotated[float, DROPOUT] = 0.0,
                 min_frontier: float = 0.3, seed: int = 0):
        _check_common(budget, spacing, n_headings, heading_spread, unlimited=True)
        if isinstance(min_frontier, bool) or not isinstance(min_frontier, int | float) or not min_frontier >= 0:
            raise ValueError(f"viewpoints.min_frontier = {min_frontier!r}: expected metres >= 0")
        self.scan = ScanSettings(height=scan_height, max_range=sensor_range, angular_step=angular_step,
                                 range_noise=range_noise, dropout=dropout, spacing=scan_spacing,
                                 seed=seed).check(SCAN_ARGUMENTS)
        self.budget, self.spacing, self.n_headings = float(budget), float(spacing), int(n_headings)
        self.heading_spread, self.min_frontier, self.seed = float(heading_spread), float(min_frontier), int(seed)
        self.last: Exploration | None = None

    def settings_for(self, scene: Scene) -> ScanSettings:
        """The scanner of this house: the noise seed from (seed, house id)."""
        return self.scan.replace(seed=text_key(self.seed, scene.house_id))

    def min_cells(self, grid: GridMap) -> int:
        return max(1, int(math.ceil(self.min_frontier / grid.resolution - 1e-9)))

    def explore(self, scene: Scene) -> Exploration:
        """Explore ``scene`` (fast path). Returns :class:`Exploration`."""
        return self._explore(scene, scan_obstacles(scene, self.scan.height))

    def _explore(self, scene: Scene, obstacles: np.ndarray) -> Exploration:
        """:meth:`explore` with the scan plane's obstacles (``scan_obstacles(scene,
        self.scan.height)``) already made."""
        grid = scene.grid
        walk = np.asarray(grid.walkable, bool)
        settings = self.settings_for(scene)
        mapper = ScanMapper(obstacles, grid, settings)
        r, c, yaw = start_cell(grid, scene.start)
        drive = _Drive(grid, r, c, yaw, self.budget, self.spacing,
                       heading_offsets(self.n_headings, self.heading_spread), mapper, settings.spacing)
        min_cells = self.min_cells(grid)
        done = np.zeros(grid.shape, bool)
        lo = mapper.log_odds
        stop = "explored"
        while True:
            known = (lo < 0) & walk
            front = frontier_cells(known & ~done, lo == 0, min_cells)
            here = drive.cells[-1]
            known[here] = True  # the robot's own cell, even if a noisy hit landed on it
            path, _ = shortest_path(known, here, front)
            if len(path) == 0:
                break
            tr, tc = (int(v) for v in path[-1])

            def target_gone(tr=tr, tc=tc) -> bool:
                return not _is_frontier(lo, walk, tr, tc)

            how = drive.leg(path, target_gone)
            if how == "budget":
                stop = "budget"
                break
            if how == "arrived" and _is_frontier(lo, walk, tr, tc):
                done[tr, tc] = True
        self.last = drive.result(stop)
        self.last.explorer = self
        return self.last

    def generate(self, scene: Scene) -> np.ndarray:
        """(N, 3) view poses (x, z metres, yaw degrees); :attr:`last` keeps the whole exploration."""
        return self.explore(scene).poses

    def smallest_budget(self, scene: Scene, up_to: float | None = None) -> float | None:
        """The smallest budget, in steps of ``scan_spacing`` above this explorer's, with which
        the map the robot builds of ``scene`` holds one of its views (:func:`views_on_own_map`:
        ``mapping=explored`` can then work); None when none up to ``up_to`` metres (default
        :data:`SMALLEST_BUDGET_SEARCH_M`) does, or when the robot explores everything it can
        reach first (a larger budget then adds nothing)."""
        import copy

        up_to = SMALLEST_BUDGET_SEARCH_M if up_to is None else float(up_to)
        step = self.scan.spacing
        if not math.isfinite(self.budget):
            return None
        obstacles = scan_obstacles(scene, self.scan.height)
        budget = (math.floor(self.budget / step + 1e-9) + 1) * step
        while budget <= up_to + 1e-9:
            trial = copy.copy(self)
            trial.budget = budget
            found = trial._explore(scene, obstacles)
            if views_on_own_map(found, scene.grid):
                return round(budget, 6)
            if found.stop != "budget":
                return None
            budget += step
        return None


#: the largest budget (metres) :meth:`Frontier.smallest_budget` tries.
SMALLEST_BUDGET_SEARCH_M = 20.0


def views_on_own_map(exploration: Exploration, grid: GridMap) -> bool:
    """Whether a view of ``exploration`` stands on a free cell of the map the robot built (its
    ``scan_map``): under ``mapping=explored`` the aggregators keep the views on that map's cells
    and drop the others; True without a map of its own."""
    scan = exploration.scan_map
    if scan is None:
        return True
    own = GridMap(np.asarray(scan.free, bool), grid.resolution, grid.origin)
    poses = np.asarray(exploration.poses, np.float64).reshape(-1, 3)
    r, c = own.world_to_cell(poses[:, 0], poses[:, 1])
    return bool(np.any(own.is_walkable(r, c)))


def no_view_on_own_map(exploration: Exploration, scene: Scene) -> str | None:
    """The budget check of ``mapping=explored``: None when a view of ``exploration`` lies on the
    map the robot built, else one line saying so and the smallest budget with which one does
    for this house (:meth:`Frontier.smallest_budget`). A cell is free on that map only once
    several scans have crossed it, so a short drive leaves every view, the start pose's too,
    off the map."""
    if views_on_own_map(exploration, scene.grid):
        return None
    explorer = exploration.explorer
    line = (f"house {scene.house_id!r}: none of the {len(exploration.poses)} views lies on the map the exploring "
            f"robot built in {exploration.length:.2f} m (a cell is free on it once several scans crossed it)")
    if explorer is None:
        return line + "; expected a larger viewpoints.budget"
    best = explorer.smallest_budget(scene)
    if best is None:
        return (line + f"; no viewpoints.budget up to {SMALLEST_BUDGET_SEARCH_M:g} m puts one there "
                f"(viewpoints.budget={explorer.budget:g})")
    return line + f"; viewpoints.budget={explorer.budget:g}: expected at least {best:g} m for this house"


#: metres driven between the poses of a mapping route (:func:`exploration_route`).
ROUTE_SPACING = 1.0


#: bytes of mapping routes :func:`exploration_route` keeps per process: every severity of a scan
#: map (and every method of each) drives the same route through a house (a few kilobytes each)
ROUTE_MEMO_BYTES = 8 * 2**20
_ROUTES = ByteLRU()


def _route_key(scene: Scene, obstacles: np.ndarray) -> bytes:
    """A digest of everything the explorer reads from ``scene``: its walkable cells, what its
    laser hits, the grid's size and placement, the start pose and the house id (its noise seed)."""
    grid = scene.grid
    return arrays_key((np.asarray(grid.walkable, bool), np.asarray(obstacles, bool)),
                      (float(grid.resolution), tuple(float(o) for o in grid.origin), scene.start, str(scene.house_id)))


def exploration_route(scene: Scene) -> np.ndarray:
    """(M, 3) poses (x, z metres, yaw degrees) along the route of a frontier exploration with no
    budget (default explorer: 10 m laser, scans every 0.5 m), one every :data:`ROUTE_SPACING`
    metres driven, facing the direction of motion: where a mapping robot drives
    (``mapping.route: explore``). Deterministic per house: kept per process by a digest of what
    the explorer reads (:data:`ROUTE_MEMO_BYTES`), read-only."""
    explorer = Frontier(budget=math.inf, spacing=ROUTE_SPACING, n_headings=1, heading_spread=0.0)
    obstacles = scan_obstacles(scene, explorer.scan.height)
    key = _route_key(scene, obstacles)
    poses = _ROUTES.get(key)
    if poses is None:  # (the obstacles of the key are the explorer's: made once)
        poses = np.array(explorer._explore(scene, obstacles).poses, dtype=np.float64)
        poses.setflags(write=False)
        _ROUTES.put(key, poses, poses.nbytes + 256, ROUTE_MEMO_BYTES)
    return poses


def _is_frontier(lo: np.ndarray, walk: np.ndarray, r: int, c: int) -> bool:
    """A known-free cell with an unobserved 4-neighbour (cluster size not considered)."""
    if not (lo[r, c] < 0 and walk[r, c]):
        return False
    h, w = lo.shape
    return any(0 <= rr < h and 0 <= cc < w and lo[rr, cc] == 0
               for rr, cc in ((r - 1, c), (r + 1, c), (r, c - 1), (r, c + 1)))


class RandomWalk:
    """Random-walk viewpoints on the walkable cells (module docstring).

    Args:
        budget: most metres driven.
        spacing: metres driven between captures.
        n_headings: views per capture.
        heading_spread: degrees the headings span around the direction of motion.
        min_run: shortest run, metres.
        max_run: longest run, metres.
        seed: with the house id, seeds the walk.
    """

    def __init__(self, budget: Annotated[float, Positive()] = 40.0,
                 spacing: Annotated[float, Positive()] = 1.0, n_headings: Annotated[int, Integer(1)] = 3,
                 heading_spread: Annotated[float, HEADING_SPREAD] = 180.0,
                 min_run: Annotated[float, Positive()] = 0.5, max_run: Annotated[float, Positive()] = 3.0,
                 seed: int = 0):
        _check_common(budget, spacing, n_headings, heading_spread)
        for key, v in (("min_run", min_run), ("max_run", max_run)):
            if isinstance(v, bool) or not isinstance(v, int | float) or not (math.isfinite(v) and v > 0):
                raise ValueError(f"viewpoints.{key} = {v!r}: expected metres > 0")
        if max_run < min_run:
            raise ValueError(f"viewpoints.max_run = {max_run!r}: expected >= min_run = {min_run!r}")
        self.budget, self.spacing, self.n_headings = float(budget), float(spacing), int(n_headings)
        self.heading_spread, self.min_run, self.max_run, self.seed = float(heading_spread), float(min_run), \
            float(max_run), int(seed)
        self.last: Exploration | None = None

    def explore(self, scene: Scene) -> Exploration:
        grid = scene.grid
        rng = np.random.default_rng([self.seed, text_key("random_walk", scene.house_id)])
        blocked = np.ascontiguousarray(~np.asarray(grid.walkable, bool))
        r, c, yaw = start_cell(grid, scene.start)
        drive = _Drive(grid, r, c, yaw, self.budget, self.spacing, heading_offsets(self.n_headings, self.heading_spread))
        cap = int(math.ceil(self.max_run / grid.resolution)) + 3
        buf_r, buf_c = np.empty(cap, np.int32), np.empty(cap, np.int32)
        stuck, stop = 0, "stuck"
        while stuck < MAX_STUCK_RUNS:
            theta = math.radians(rng.uniform(0.0, 360.0))
            run = rng.uniform(self.min_run, self.max_run) / grid.resolution
            r0, c0 = drive.cells[-1]
            r1, c1 = ray_end(r0, c0, theta, run)
            n, _, _ = trace_ray(blocked, r0, c0, r1, c1, buf_r, buf_c)
            if n < 2:
                stuck += 1
                continue
            stuck = 0
            if drive.leg(np.column_stack([buf_r[:n], buf_c[:n]]).astype(np.int64)) == "budget":
                stop = "budget"
                break
        self.last = drive.result(stop)
        return self.last

    def generate(self, scene: Scene) -> np.ndarray:
        """(N, 3) view poses; :attr:`last` keeps the whole walk."""
        return self.explore(scene).poses


# --------------------------------------------------------------------------- slow reference


def explore_frontier_reference(scene: Scene, frontier: Frontier) -> Exploration:
    """Slow, obviously correct :meth:`Frontier.explore`: plain Python sets, dicts and loops,
    the reference scan mapper (:class:`envs.maps.scan.ReferenceScanMapper`), a heapq Dijkstra,
    a breadth-first cluster labelling; it shares no code with the fast path beyond the
    obstacles, the start rule and the settings. Gives the same exploration."""
    grid = scene.grid
    res = grid.resolution
    h, w = grid.shape
    walk = grid.walkable.tolist()
    settings = frontier.settings_for(scene)
    mapper = ReferenceScanMapper(scan_obstacles(scene, settings.height), grid, settings)
    min_cells = frontier.min_cells(grid)
    r, c, yaw = start_cell(grid, scene.start)
    n = frontier.n_headings
    if n == 1:
        offsets = [0.0]
    else:
        spread = frontier.heading_spread
        step = spread / n if spread >= 360 else spread / (n - 1)
        offsets = [-spread / 2 + k * step for k in range(n)]
        if spread < 360:
            offsets[-1] = spread / 2
    base = max(1, round(MOTION_BASE / res))
    views, view_odo, cells = [], [], [(r, c)]
    odo = 0.0

    def world(rr, cc):
        return grid.origin[0] + (cc + 0.5) * res, grid.origin[1] - (rr + 0.5) * res

    def capture(rr, cc, heading):
        x, z = world(rr, cc)
        for off in offsets:
            views.append((x, z, (heading + off) % 360.0))
            view_odo.append(odo)

    def scan(rr, cc):
        x, z = world(rr, cc)
        mapper.add([[x, z, 0.0]])

    def lo(rr, cc):
        return mapper.cells.get((rr, cc), 0.0)

    def known(rr, cc):
        return 0 <= rr < h and 0 <= cc < w and walk[rr][cc] and lo(rr, cc) < 0

    def frontier_cell(rr, cc):
        return known(rr, cc) and any(0 <= a < h and 0 <= b < w and lo(a, b) == 0
                                     for a, b in ((rr - 1, cc), (rr + 1, cc), (rr, cc - 1), (rr, cc + 1)))

    capture(r, c, yaw)
    scan(r, c)
    scanned = True  # a scan was taken at the robot's cell and it has not moved since
    next_view, next_scan = frontier.spacing, settings.spacing
    done: set[tuple[int, int]] = set()
    stop = "explored"
    while True:
        cand = {(a, b) for a in range(h) for b in range(w) if frontier_cell(a, b)} - done
        targets: set[tuple[int, int]] = set()
        seen: set[tuple[int, int]] = set()
        for cell in sorted(cand):
            if cell in seen:
                continue
            cluster, queue = [cell], [cell]
            seen.add(cell)
            while queue:
                a, b = queue.pop()
                for da in (-1, 0, 1):
                    for db in (-1, 0, 1):
                        nbr = (a + da, b + db)
                        if nbr in cand and nbr not in seen:
                            seen.add(nbr)
                            cluster.append(nbr)
                            queue.append(nbr)
            if len(cluster) >= min_cells:
                targets.update(cluster)
        # Dijkstra over known cells, 8-connected, no corner cutting; pop order (distance, flat index)
        start = cells[-1]

        def passable(rr, cc, start=start):
            return (rr, cc) == start or known(rr, cc)

        dist = {start: 0.0}
        pred: dict[tuple[int, int], tuple[int, int]] = {}
        heap = [(0.0, start[0] * w + start[1])]
        goal = None
        while heap:
            d, v = heapq.heappop(heap)
            a, b = divmod(v, w)
            if d > dist[(a, b)]:
                continue
            if (a, b) in targets:
                goal = (a, b)
                break
            for da, db in ((-1, 0), (1, 0), (0, -1), (0, 1), (-1, -1), (-1, 1), (1, -1), (1, 1)):
                nb = (a + da, b + db)
                if not passable(*nb) or (da and db and not (passable(a + da, b) and passable(a, b + db))):
                    continue
                nd = d + (math.sqrt(2.0) if da and db else 1.0)
                if nd < dist.get(nb, math.inf):
                    dist[nb] = nd
                    pred[nb] = (a, b)
                    heapq.heappush(heap, (nd, nb[0] * w + nb[1]))
        if goal is None:
            break
        path = [goal]
        while path[-1] != start:
            path.append(pred[path[-1]])
        path.reverse()
        how = "arrived"
        for i in range(1, len(path)):
            step = math.hypot(path[i][0] - path[i - 1][0], path[i][1] - path[i - 1][1]) * res
            if odo + step > frontier.budget + 1e-9:
                how = "budget"
                break
            odo += step
            cells.append(path[i])
            scanned = False
            if odo >= next_view - 1e-9:
                a, b = path[max(i - base, 0)], path[min(i + base, len(path) - 1)]
                heading = math.degrees(math.atan2(b[1] - a[1], -(b[0] - a[0]))) % 360.0
                capture(*path[i], heading)
                while next_view <= odo + 1e-9:
                    next_view += frontier.spacing
            if odo >= next_scan - 1e-9:
                scan(*path[i])
                scanned = True
                while next_scan <= odo + 1e-9:
                    next_scan += settings.spacing
                if i < len(path) - 1 and not frontier_cell(*goal):
                    how = "interrupted"
                    break
        if how == "budget":
            stop = "budget"
            break
        if not scanned:
            scan(*cells[-1])
            scanned = True
        if how == "arrived" and frontier_cell(*goal):
            done.add(goal)
    xz = np.array([world(a, b) for a, b in cells])
    return Exploration(np.array(views, np.float64).reshape(-1, 3), np.array(view_odo), xz, odo, mapper.result(), stop)


__all__ = ["Frontier", "RandomWalk", "Exploration", "explore_frontier_reference", "frontier_cells",
           "heading_offsets", "no_view_on_own_map", "start_cell", "views_on_own_map"]
