"""The map a robot's 2D laser scanner builds: scans along a trajectory into a log-odds grid.

What it models (issue #25, item 1):

* **What the scan plane hits** (:func:`scan_obstacles`): a horizontal plane ``height`` metres
  above the floor. Walls always cut it (the wall band of the floor plan, door openings
  already cut out: a door opening never blocks), so does everything outside the floor
  (``scene.rooms < 0``), and so does every object whose box spans the height
  (``base < height < top``): a box standing on the floor blocks, a table top above the
  plane does not (the scan passes under it; with ``legs``, furniture of :data:`LEGGED_TYPES` blocks with its four legs only).
* **Closed doors** (``door_closed``, :func:`closed_doors`): each door closed with that probability
  fills its opening in the wall band: it blocks beams and the route.
* **Grazing incidence** (``grazing_dropout``): a beam hitting a surface at incidence angle i also
  returns nothing with probability ``grazing_dropout * (1 - cos i)`` (:func:`surface_normals`).
* **People** (``people``, ``person_radius``): discs drawn anew for every scan on unblocked cells;
  a beam meeting one first returns from it (transient hits).
* **Surfaces that return little** (``surface_dropout``, :func:`surface_shares`): a beam whose hit
  cell has share ``q`` (glass of a window whose hole spans the scan plane: 1; the room side of a
  wall of a dark material: :data:`DARK_SHARE`) also returns nothing with probability
  ``surface_dropout * q``; with grazing loss ``g`` as well, ``1 - (1 - g)(1 - surface_dropout * q)``
  (one draw per beam).
* **The scanner** (:class:`ScanSettings`): 360 degree scans of ``round(360 / angular_step)``
  beams evenly spread, the first along the pose's yaw, from the centre of the pose's cell.
  A beam is the digital (Bresenham) line of :mod:`envs.maps.rays` from that cell to the
  cell ``max_range`` metres away; its true range is the distance between the centres of the
  start cell and of the first obstacle cell on the line. Beams of one scan are drawn
  independently: with share ``dropout`` a beam returns nothing and adds nothing; otherwise
  the measured range is the true range plus Gaussian noise of sigma ``range_noise`` metres
  (clipped at 0). A beam with no obstacle within ``max_range`` (or before the map edge) is a
  max-range reading and carries no noise.
* **The mapper** (:func:`scan_map`): the measured end cell is the last cell of the beam's line
  not farther than the measured range. Cells before it get free evidence, the end cell gets
  hit evidence. A *short* reading (noise < 0) leaves the cells between the measured end and
  the true obstacle untouched (no evidence); a *long* reading (noise > 0) continues along the
  same line through the obstacle, as a real mapper that trusts the range would. A reading
  beyond the line's end (past ``max_range`` or off the map) is treated as a max-range reading:
  free evidence along the whole line, no hit. Within one scan a cell gets at most one free
  and at most one hit update; the scan's updates are summed per cell and the log-odds is
  clamped to ``[log_odds_min, log_odds_max]`` (OctoMap's update and clamping, Hornung et al.
  2013: hit +0.85 (p = 0.7), miss -0.4 (p = 0.4), clamp -2.0 .. 3.5 (p = 0.12 .. 0.97)).
* **Thresholding** as ROS ``map_server`` reads a trinary map: p = 1 / (1 + exp(-l));
  p > ``occupied_thresh`` (0.65) -> occupied (100), p < ``free_thresh`` (0.196) -> free (0),
  otherwise unknown (-1). A cell no beam reached keeps log-odds 0 (p = 0.5) and is unknown;
  with the defaults a cell needs 4 scans that see it free to become free (one hit makes it
  occupied).

What it leaves out: the robot's own pose error while mapping (scans are placed at the true
poses; pose error is a separate option applied to the views), beam width and incidence angle,
what lies behind glass (a pane only loses beams: ``surface_dropout``), mirrors, people moving during a scan, the scanner's own height above a sloped floor, table legs (without ``legs``),
and the time a scan takes (all beams of a scan share one pose).

The fast path is :class:`ScanMapper` (a numba kernel over :func:`envs.maps.rays.walk_beam`,
incremental: exploration adds scans as it drives); :func:`scan_map_reference` is a slow
pure-Python version with its own line walk, used by the tests and ``make perf``.
"""

from __future__ import annotations

import contextlib
import math
import weakref
import zlib
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Annotated

import numpy as np

from envs.kernel_cache import njit
from envs.maps.gridmap import GridMap
from envs.maps.rays import ray_end_of, walk_beam
from envs.maps.ros import read_ros_map, ros_origin_of, unknown_pixel, write_ros_map
from envs.maps.scene import Scene
from envs.maps.trajectory import trajectory
from envs.memo import ByteLRU
from envs.ranges import DROPOUT, Angle, Between, Metres, NonNegative, Positive

#: Wall height of generated houses (metres); ProcTHOR's walls carry their own (2.51-5.38 m in
#: the 150 shared houses): :func:`house_wall_height`.
DEFAULT_WALL_HEIGHT = 2.6
#: the scan plane's height, metres: above the floor, below the walls of a generated house.
SCAN_HEIGHT = Between(0, DEFAULT_WALL_HEIGHT, low_open=True, high_open=True,
                      what=f"metres, 0 < height < {DEFAULT_WALL_HEIGHT:g} (below the walls)")
#: ROS ``nav_msgs/OccupancyGrid`` values.
UNKNOWN, FREE, OCCUPIED = -1, 0, 100


def _setting_error(key: str, value, expected: str, names: Mapping[str, str] | None = None) -> ValueError:
    name = (names or {}).get(key, f"scan setting {key}")
    return ValueError(f"{name} = {value!r}: expected {expected}")


def _finite_number(v) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


def logit(p: float) -> float:
    """log(p / (1 - p)), the log-odds of probability ``p`` (0 < p < 1)."""
    return math.log(p / (1.0 - p))


@dataclass(frozen=True)
class ScanSettings:
    """A 2D laser scanner and the occupancy mapper that integrates its scans.

    Attributes:
        height: height of the scan plane above the floor, metres (0 < height < wall height).
        max_range: the scanner's maximum range, metres (``math.inf``: unlimited).
        angular_step: angle between beams, degrees (``round(360 / angular_step)`` beams).
        range_noise: Gaussian sigma added to each measured range, metres.
        dropout: share of beams that return nothing, in [0, 1).
        spacing: a scan every this many metres of travel along the trajectory (plus one at
            every view pose), metres.
        occupied_thresh: occupancy probability above which a cell is occupied (ROS 0.65).
        free_thresh: occupancy probability below which a cell is free (ROS 0.196).
        log_odds_hit: log-odds added to the end cell of a beam (0.85: p = 0.7).
        log_odds_miss: log-odds added to each cell a beam passes (-0.4: p = 0.4).
        log_odds_min: lower clamp of a cell's log-odds (-2.0: p = 0.12).
        log_odds_max: upper clamp of a cell's log-odds (3.5: p = 0.97).
        seed: seed of the range noise and dropout draws.
        legs: furniture that stands on legs (:data:`LEGGED_TYPES`) blocks the plane with its four
            legs only, not its whole box (issue 37, item 4).
        leg_size: a leg's square cross-section side, metres.
        door_closed: probability that each door of the house is closed (drawn per door from
            ``seed`` and the door's id): a closed door blocks beams and the robot's route.
        grazing_dropout: extra chance that a beam returns nothing, ``grazing_dropout * (1 - cos i)``
            at incidence angle ``i`` on the surface it hits (:func:`surface_normals`): 0 head on,
            the whole amount along the surface.
        people: people standing in the house during each scan (each scan its own draw of places,
            uniform over the cells the plane does not hit): discs that return a beam first.
        person_radius: metres, a person's radius at scan height.
        surface_dropout: share, in [0, 1]: a beam that hits a cell of surface share ``q``
            (:func:`surface_shares`: glass 1, dark wall material :data:`DARK_SHARE`) returns nothing
            with probability ``surface_dropout * q`` (needs the scene's shares: ``surfaces``).
    """

    height: Annotated[float, SCAN_HEIGHT] = 0.25
    max_range: Annotated[float, Metres(inf_ok=True)] = 10.0
    angular_step: Annotated[float, Angle()] = 1.0
    range_noise: Annotated[float, NonNegative()] = 0.0
    dropout: Annotated[float, DROPOUT] = 0.0
    spacing: Annotated[float, Positive()] = 0.5
    occupied_thresh: float = 0.65
    free_thresh: float = 0.196
    log_odds_hit: float = 0.85
    log_odds_miss: float = -0.4
    log_odds_min: float = -2.0
    log_odds_max: float = 3.5
    seed: int = 0
    legs: bool = False
    leg_size: float = 0.05
    door_closed: float = 0.0
    grazing_dropout: float = 0.0
    people: int = 0
    person_radius: float = 0.2
    surface_dropout: float = 0.0

    def check(self, names: Mapping[str, str] | None = None) -> ScanSettings:
        """Raise a one-line ``ValueError`` naming the first out-of-range setting; return self.

        Args:
            names: how the caller calls a field in its messages (e.g. ``{"max_range":
                "viewpoints.sensor_range"}``); default ``scan setting <field>``.
        """
        def error(key: str, value, expected: str) -> ValueError:
            return _setting_error(key, value, expected, names)

        h = self.height
        if not (_finite_number(h) and 0 < h < DEFAULT_WALL_HEIGHT):
            raise error("height", h, f"metres, 0 < height < {DEFAULT_WALL_HEIGHT} (below the walls)")
        r = self.max_range
        if not (isinstance(r, int | float) and not isinstance(r, bool) and r > 0 and not math.isnan(r)):
            raise error("max_range", r, "metres, > 0 (inf for unlimited)")
        if not (_finite_number(self.angular_step) and 0 < self.angular_step <= 360):
            raise error("angular_step", self.angular_step, "degrees, 0 < angular_step <= 360")
        if not (_finite_number(self.range_noise) and self.range_noise >= 0):
            raise error("range_noise", self.range_noise, "metres, a sigma >= 0")
        if not (_finite_number(self.dropout) and 0 <= self.dropout < 1):
            raise error("dropout", self.dropout, "a share in [0, 1)")
        if not (_finite_number(self.spacing) and self.spacing > 0):
            raise error("spacing", self.spacing, "metres, > 0")
        if not (_finite_number(self.free_thresh) and 0 < self.free_thresh < 0.5):
            raise error("free_thresh", self.free_thresh, "a probability, 0 < free_thresh < 0.5")
        if not (_finite_number(self.occupied_thresh) and 0.5 < self.occupied_thresh < 1):
            raise error("occupied_thresh", self.occupied_thresh,
                        "a probability, 0.5 < occupied_thresh < 1")
        if not (_finite_number(self.log_odds_hit) and self.log_odds_hit > 0):
            raise error("log_odds_hit", self.log_odds_hit, "> 0")
        if not (_finite_number(self.log_odds_miss) and self.log_odds_miss < 0):
            raise error("log_odds_miss", self.log_odds_miss, "< 0")
        if not (_finite_number(self.log_odds_min) and self.log_odds_min < logit(self.free_thresh)):
            raise error("log_odds_min", self.log_odds_min,
                        f"< logit(free_thresh) = {logit(self.free_thresh):.3f} (else no cell can be free)")
        if not (_finite_number(self.log_odds_max) and self.log_odds_max > logit(self.occupied_thresh)):
            raise error("log_odds_max", self.log_odds_max,
                        f"> logit(occupied_thresh) = {logit(self.occupied_thresh):.3f} "
                        f"(else no cell can be occupied)")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int | np.integer) or self.seed < 0:
            raise error("seed", self.seed, "an integer >= 0")
        if not isinstance(self.legs, bool | np.bool_):
            raise error("legs", self.legs, "true or false")
        if not (_finite_number(self.leg_size) and 0 < self.leg_size <= 0.5):
            raise error("leg_size", self.leg_size, "metres, 0 < leg_size <= 0.5")
        if not (_finite_number(self.door_closed) and 0 <= self.door_closed <= 1):
            raise error("door_closed", self.door_closed, "a probability in [0, 1]")
        if not (_finite_number(self.grazing_dropout) and 0 <= self.grazing_dropout <= 1):
            raise error("grazing_dropout", self.grazing_dropout, "a probability in [0, 1]")
        if isinstance(self.people, bool) or not isinstance(self.people, int | np.integer) or self.people < 0:
            raise error("people", self.people, "an integer >= 0")
        if not (_finite_number(self.person_radius) and 0 < self.person_radius <= 1):
            raise error("person_radius", self.person_radius, "metres, 0 < person_radius <= 1")
        if not (_finite_number(self.surface_dropout) and 0 <= self.surface_dropout <= 1):
            raise error("surface_dropout", self.surface_dropout, "a share in [0, 1]")
        return self

    @property
    def n_beams(self) -> int:
        """Beams per scan: ``round(360 / angular_step)``, at least 1."""
        return max(1, int(round(360.0 / self.angular_step)))

    def replace(self, **changes) -> ScanSettings:
        """A copy with some fields changed (checked)."""
        return ScanSettings(**{**asdict(self), **changes}).check()


@dataclass
class ScanMap:
    """A scan-built occupancy map on a :class:`GridMap`'s cells.

    Attributes:
        log_odds: (H, W) float32 accumulated log-odds (0 where no beam reached).
        occupancy: (H, W) int8 as ``nav_msgs/OccupancyGrid``: -1 unknown, 0 free, 100 occupied.
        free: (H, W) bool, ``occupancy == 0``.
        settings: the scanner and mapper settings.
        n_scans: scans integrated.
    """

    log_odds: np.ndarray
    occupancy: np.ndarray
    free: np.ndarray
    settings: ScanSettings
    n_scans: int

    def grid(self, like: GridMap) -> GridMap:
        """The map as the methods see it: walkable = free cells (unknown is not walkable)."""
        return GridMap(self.free, like.resolution, like.origin)


def house_wall_height(house) -> float:
    """The lowest wall top of a ProcTHOR-schema house (metres, from the wall polygons' y);
    :data:`DEFAULT_WALL_HEIGHT` for a house without walls."""
    tops = [max(float(p.get("y", 0.0)) for p in w["polygon"]) for w in house.data.get("walls", []) or []
            if w.get("polygon")]
    return min(tops) if tops else DEFAULT_WALL_HEIGHT


#: object types that stand on legs: at the scan plane a 2D laser sees their legs, not their box
LEGGED_TYPES = ("Chair", "CoffeeTable", "Desk", "DiningTable", "SideTable", "Stool")


def leg_centres(o, leg_size: float) -> np.ndarray:
    """(4, 2) world (x, z) centres of an object's legs: squares of side ``leg_size`` in the corners
    of its footprint box (its centre when the box is narrower than two legs)."""
    hx, hz = max(o.size[0] / 2 - leg_size / 2, 0.0), max(o.size[2] / 2 - leg_size / 2, 0.0)
    a = np.deg2rad(o.yaw)
    ux, uz = np.array([np.cos(a), -np.sin(a)]), np.array([np.sin(a), np.cos(a)])
    c = np.array(o.center)
    return np.array([c + sx * hx * ux + sz * hz * uz for sx, sz in ((-1, -1), (1, -1), (1, 1), (-1, 1))])


def _mark_legs(block: np.ndarray, grid, o, leg_size: float) -> None:
    """Block each leg's cells: those whose centre lies in the leg's square, and the cell of its centre."""
    h, w = block.shape
    a = np.deg2rad(o.yaw)
    for cx, cz in leg_centres(o, leg_size):
        r, c = grid.world_to_cell(cx, cz)
        k = int(math.ceil(leg_size / grid.resolution)) + 1
        r0, r1, c0, c1 = max(int(r) - k, 0), min(int(r) + k + 1, h), max(int(c) - k, 0), min(int(c) + k + 1, w)
        if r0 < r1 and c0 < c1:
            rr, cc = np.mgrid[r0:r1, c0:c1]
            x, z = grid.pixel_to_world(rr, cc)
            u = (x - cx) * np.cos(a) - (z - cz) * np.sin(a)
            v = (x - cx) * np.sin(a) + (z - cz) * np.cos(a)
            block[r0:r1, c0:c1] |= (np.abs(u) <= leg_size / 2) & (np.abs(v) <= leg_size / 2)
        if 0 <= r < h and 0 <= c < w:
            block[int(r), int(c)] = True


def closed_doors(scene: Scene, door_closed: float, seed: int = 0) -> np.ndarray:
    """(H, W) bool cells of the doors that are closed: each door of ``scene.doors`` independently
    with probability ``door_closed``, its draw seeded by ``seed`` and the door's id (CRC-32), so a
    door is closed or open whatever the other doors and settings; a closed door fills the opening
    its hole cut out of the wall band."""
    out = np.zeros(scene.grid.shape, bool)
    if door_closed <= 0:
        return out
    for door_id, cells in (scene.doors or {}).items():
        u = np.random.default_rng([int(seed), 3, zlib.crc32(str(door_id).encode())]).random()
        if u < door_closed and len(cells):
            out[cells[:, 0], cells[:, 1]] = True
    return out


#: surface share of glass (a window's pane at the scan plane): at ``surface_dropout`` 1 every beam
#: that meets it returns nothing (it passes or reflects away; a 2D laser rarely sees clean glass).
GLASS_SHARE = 1.0
#: surface share of a dark wall material (:data:`envs.maps.scene.DARK_MATERIAL_WORDS`): half the
#: glass loss. Dark paint and stone reflect a few per cent of a scanner's 905 nm light against 60-90 %
#: for white drywall, so more of their returns fall under the detection threshold.
DARK_SHARE = 0.5


def surface_shares(scene: Scene, height: float) -> np.ndarray:
    """(H, W) float64 per cell the share of beams that a surface returning little loses (times
    ``surface_dropout``): :data:`GLASS_SHARE` on the wall cells of a window whose hole spans the
    scan plane (bottom < ``height`` < top; ``Scene.windows``), :data:`DARK_SHARE` on the room side
    of a dark wall (``Scene.dark_walls``), 0 elsewhere (a scene without them: all 0)."""
    out = np.zeros(scene.grid.shape, np.float64)
    dark = getattr(scene, "dark_walls", None)
    if dark is not None and dark.shape == out.shape:
        out[dark] = DARK_SHARE
    for cells, bottom, top in (getattr(scene, "windows", None) or {}).values():
        if bottom < height < top and len(cells):
            out[cells[:, 0], cells[:, 1]] = GLASS_SHARE
    return out


def scan_obstacles(scene: Scene, height: float, wall_height: float = DEFAULT_WALL_HEIGHT, legs: bool = False,
                   leg_size: float = 0.05) -> np.ndarray:
    """What a scan plane ``height`` metres above the floor hits.

    Args:
        scene: the house on its grid. A scene without a wall layer (a user's occupancy map)
            has no house to cut: every non-walkable cell blocks.
        height: scan plane height, metres.
        wall_height: the house's lowest wall top, metres (:func:`house_wall_height`).
        legs: objects of :data:`LEGGED_TYPES` block with their four legs (squares of side
            ``leg_size`` metres in the corners of their box) instead of their whole footprint.

    Returns:
        (H, W) bool: wall bands (door openings are not walls), cells outside the floor
        (``scene.rooms < 0``), and the footprint of every object with ``base < height < top``
        (each footprint rasterised here: a pixel is covered when its centre is inside the box).
    """
    if not (_finite_number(height) and 0 < height < wall_height):
        raise ValueError(f"scan height = {height!r} m: expected 0 < height < {wall_height:g} m "
                         f"(the house's lowest wall top)")
    if scene.walls is None:
        return ~np.asarray(scene.grid.walkable, bool)
    grid = scene.grid
    block = (np.asarray(scene.rooms) < 0) | np.asarray(scene.walls, bool)
    h, w = grid.shape
    for o in scene.objects:
        if not (o.base < height < o.top):
            continue
        if legs and o.object_type in LEGGED_TYPES:
            _mark_legs(block, grid, o, leg_size)
            continue
        cs = o.corners()
        r0, c0 = grid.world_to_cell(cs[:, 0].min(), cs[:, 1].max())
        r1, c1 = grid.world_to_cell(cs[:, 0].max(), cs[:, 1].min())
        r0, c0, r1, c1 = max(int(r0), 0), max(int(c0), 0), min(int(r1) + 1, h), min(int(c1) + 1, w)
        if r0 >= r1 or c0 >= c1:
            continue
        rr, cc = np.mgrid[r0:r1, c0:c1]
        x, z = grid.pixel_to_world(rr, cc)
        block[r0:r1, c0:c1] |= o.contains(x, z)
    return block


#: bytes of scan planes :func:`scan_plane` keeps per process (least recently used dropped first):
#: the jobs of a sweep ask for the same house's plane again (a SLAM condition's route, its
#: estimate and its map, in every method job); a ProcTHOR house's plane is about 0.1 MB
SCAN_PLANE_MEMO_BYTES = 32 * 2**20
#: kept per process: (id of the scene and of the layers it reads, the plane's settings) -> (weak
#: reference to the scene, its plane, read-only); an entry serves only the scene object it was
#: made from (a scene's arrays are not changed in place once built: the harness shares it
#: between jobs as it is)
_SCAN_PLANES = ByteLRU()


def scan_plane(scene: Scene, settings: ScanSettings, wall_height: float) -> np.ndarray:
    """(H, W) bool what the scan plane of ``settings`` hits: :func:`scan_obstacles` at its height
    (legs as it says) with the doors :func:`closed_doors` closes. Kept per process for this scene
    object and these settings (:data:`SCAN_PLANE_MEMO_BYTES`); each call gets its own copy.

    Raises:
        ValueError: the scan height is not below ``wall_height`` (:func:`scan_obstacles`)."""
    # the scene object and what it holds (an attribute set anew is another plane)
    held = tuple(id(getattr(scene, k, None)) for k in ("grid", "rooms", "walls", "objects", "doors"))
    key = (id(scene), held, float(settings.height), float(wall_height), bool(settings.legs), float(settings.leg_size),
           float(settings.door_closed), int(settings.seed))
    kept = _SCAN_PLANES.get(key)
    if kept is not None and kept[0]() is scene:
        return kept[1].copy()
    plane = scan_obstacles(scene, settings.height, wall_height, settings.legs, settings.leg_size)
    plane |= closed_doors(scene, settings.door_closed, settings.seed)
    with contextlib.suppress(TypeError):  # a scene that cannot be weakly referenced is not kept
        master = plane.copy()
        master.setflags(write=False)
        _SCAN_PLANES.put(key, (weakref.ref(scene), master), master.nbytes + 256, SCAN_PLANE_MEMO_BYTES)
    return plane


def occupancy_from_log_odds(log_odds: np.ndarray, settings: ScanSettings) -> np.ndarray:
    """(H, W) int8 -1 / 0 / 100 by ``map_server``'s trinary thresholds on p = 1 / (1 + exp(-l))."""
    p = 1.0 / (1.0 + np.exp(-np.asarray(log_odds, np.float64)))
    occ = np.full(p.shape, UNKNOWN, np.int8)
    occ[p > settings.occupied_thresh] = OCCUPIED
    occ[p < settings.free_thresh] = FREE
    return occ


def _range_px(settings: ScanSettings, shape: tuple[int, int], resolution: float) -> float:
    """A beam's length in pixels: ``max_range`` or, when unlimited, past every map corner."""
    if math.isinf(settings.max_range):
        return float(math.ceil(math.hypot(*shape)) + 2)
    return settings.max_range / resolution


def _beam_draws(settings: ScanSettings, noise_rng, drop_rng, m: int) -> tuple[np.ndarray, np.ndarray]:
    """(m, n_beams) range noise (metres) and dropout flags for the next ``m`` scans."""
    nb = settings.n_beams
    noise = (noise_rng.normal(0.0, settings.range_noise, (m, nb)) if settings.range_noise > 0
             else np.zeros((m, nb)))
    drop = drop_rng.random((m, nb)) < settings.dropout if settings.dropout > 0 else np.zeros((m, nb), np.bool_)
    return noise, drop


def surface_normals(obstacles: np.ndarray) -> np.ndarray:
    """(H, W, 2) float64 (d_row, d_col) surface direction of each obstacle cell: the sum of the
    offsets to its free 8-neighbours (off-map neighbours count as blocked), zero for cells with no
    free neighbour and for free cells. Not normalised."""
    ob = np.asarray(obstacles, bool)
    free = np.pad(~ob, 1, constant_values=False)
    h, w = ob.shape
    out = np.zeros((h, w, 2))
    for dr in (-1, 0, 1):
        for dc in (-1, 0, 1):
            if dr or dc:
                nb = free[1 + dr:1 + dr + h, 1 + dc:1 + dc + w]
                out[..., 0] += dr * nb
                out[..., 1] += dc * nb
    out[~ob] = 0.0
    return out


def _grazing_draws(settings: ScanSettings, rng, m: int) -> np.ndarray:
    """(m, n_beams) uniform draws of the grazing and surface dropout (zeros when both are off:
    nothing drawn)."""
    if settings.grazing_dropout > 0 or settings.surface_dropout > 0:
        return rng.random((m, settings.n_beams))
    return np.zeros((m, settings.n_beams))


def people_draws(settings: ScanSettings, rng, obstacles: np.ndarray, resolution: float, m: int) -> np.ndarray:
    """(m, people, 3) per scan the people's (row, col) centres in continuous pixels (a uniform
    cell the plane does not hit, its centre) and radius in pixels; (m, 0, 3) without people."""
    if settings.people <= 0:
        return np.zeros((m, 0, 3))
    free = np.flatnonzero(~np.asarray(obstacles, bool).ravel())
    if len(free) == 0:
        return np.zeros((m, 0, 3))
    cells = free[rng.integers(0, len(free), (m, settings.people))]
    w = obstacles.shape[1]
    out = np.empty((m, settings.people, 3))
    out[..., 0], out[..., 1] = cells // w + 0.5, cells % w + 0.5
    out[..., 2] = settings.person_radius / resolution
    return out


def exact_scanner(settings: ScanSettings) -> bool:
    """True when ``settings`` draw nothing per beam (no range noise, dropout, grazing or surface
    loss, people): two scans from one cell then measure the same ranges, beam for beam."""
    s = settings
    return (s.range_noise == 0 and s.dropout == 0 and s.grazing_dropout == 0 and s.people == 0
            and s.surface_dropout == 0)


def _surface_array(surfaces, settings: ScanSettings, shape: tuple[int, int]) -> np.ndarray:
    """The kernels' per-cell surface shares: ``surfaces`` as float64 where ``surface_dropout`` is on
    (checked: the map's shape, shares in [0, 1]), else a (1, 1) zero that is never read."""
    if settings.surface_dropout <= 0 or surfaces is None:
        return np.zeros((1, 1))
    out = np.ascontiguousarray(surfaces, np.float64)
    if out.shape != tuple(shape):
        raise ValueError(f"surface shares shape {out.shape} != grid shape {tuple(shape)}")
    if not (np.isfinite(out).all() and (out >= 0).all() and (out <= 1).all()):
        raise ValueError("surface shares: expected shares in [0, 1] per cell")
    return out



def scan_draws(s: ScanSettings, obstacles: np.ndarray, grid: GridMap, surfaces, m: int) -> tuple:
    """The random draws of ``m`` whole scans at once, from ``s.seed``'s streams (as the mapper draws
    them): (noise (m, B), drop (m, B), grazing uniforms, surface normals, people, surface shares).
    One place for the scans measured at a SLAM estimate and the scans the front end matches."""
    noise_rng, drop_rng = _draw_streams(s.seed)
    noise, drop = _beam_draws(s, noise_rng, drop_rng, m)
    graze_u = _grazing_draws(s, np.random.default_rng([int(s.seed), 4]), m)
    normals = surface_normals(obstacles) if s.grazing_dropout > 0 else np.zeros((1, 1, 2))
    persons = people_draws(s, np.random.default_rng([int(s.seed), 5]), obstacles, grid.resolution, m)
    return noise, drop, graze_u, normals, persons, _surface_array(surfaces, s, grid.shape)

def _draw_streams(seed: int):
    """Separate generators for range noise and dropout, so that adding scans in chunks draws
    the same numbers as adding them all at once."""
    return np.random.default_rng([int(seed), 1]), np.random.default_rng([int(seed), 2])


@njit(cache=True, nogil=True, inline="always")
def beam_headings(n_beams):
    """The cosines and sines of a scanner's ``n_beams`` beam headings, ``2 pi b / n_beams`` for
    beam ``b`` (the same in every scan, and the same values as ``np.cos`` of each heading):
    two (n_beams,) float64 arrays."""
    cos_b = np.empty(n_beams, np.float64)
    sin_b = np.empty(n_beams, np.float64)
    for b in range(n_beams):
        theta = 2.0 * np.pi * b / n_beams
        cos_b[b] = np.cos(theta)
        sin_b[b] = np.sin(theta)
    return cos_b, sin_b


@njit(cache=True, nogil=True, inline="always")
def _mark(state, touched_r, touched_c, nt, r, c, s, flag):
    """Flag cell (r, c) for scan ``s`` (``state = 4 * s + flags``; flag 1 free, 2 hit); a cell
    met for the first time in this scan joins the touched list. Returns the list's length."""
    v = state[r, c]
    if v >> 2 != s:
        state[r, c] = (s << 2) | flag
        touched_r[nt] = r
        touched_c[nt] = c
        return nt + 1
    state[r, c] = v | flag
    return nt


@njit(cache=True, nogil=True)
def _apply_scan(log_odds, state, touched_r, touched_c, nt, l_hit, l_miss, l_min, l_max):
    """Add one scan's evidence (the flags in ``state`` of its ``nt`` touched cells), clamped."""
    for t in range(nt):
        rr = touched_r[t]
        cc = touched_c[t]
        v = state[rr, cc]
        d = 0.0
        if v & 1:
            d += l_miss
        if v & 2:
            d += l_hit
        x = log_odds[rr, cc] + d
        log_odds[rr, cc] = min(max(x, l_min), l_max)


@njit(cache=True, nogil=True)
def person_first(persons, m, r0, c0, theta, lr, lc, n):
    """Index of the first of the ``n`` line cells at or past the nearest person disc the beam
    from cell (r0, c0) along ``theta`` meets (distances between cell centres), -1 if none."""
    dr = -np.cos(theta)
    dc = np.sin(theta)
    best = np.inf
    for p in range(persons.shape[1]):
        vr = persons[m, p, 0] - (r0 + 0.5)
        vc = persons[m, p, 1] - (c0 + 0.5)
        rad = persons[m, p, 2]
        t = vr * dr + vc * dc
        perp2 = vr * vr + vc * vc - t * t
        if t <= 0.0 or perp2 > rad * rad:
            continue
        d = t - np.sqrt(rad * rad - perp2)
        if 0.0 < d < best:
            best = d
    if best == np.inf:
        return -1
    for j in range(n):
        if np.hypot(lr[j] - r0, lc[j] - c0) >= best:
            return j
    return -1


@njit(cache=True, nogil=True, inline="always")
def grazes(normals, r, c, theta, grazing, u):
    """True when a beam along ``theta`` hitting cell (r, c) returns nothing: ``u`` below
    ``grazing * (1 - cos i)``, ``i`` the angle between the beam and the cell's surface normal
    (:func:`surface_normals`; a cell without one never grazes)."""
    nr = normals[r, c, 0]
    nc = normals[r, c, 1]
    nn = np.sqrt(nr * nr + nc * nc)
    if nn == 0.0:
        return False
    cos_i = abs(-nr * np.cos(theta) + nc * np.sin(theta)) / nn
    return u < grazing * (1.0 - cos_i)


@njit(cache=True, nogil=True, inline="always")
def beam_return(persons, m, r0, c0, theta, lr, lc, n, k_hit, normals, grazing, u, surfaces, surface_dropout):
    """What a beam walked from cell (r0, c0) along ``theta`` returns: ``(k, returned)``, ``k``
    the index of the line cell it returns from (a person standing in its way before the hit
    :func:`walk_beam` found at ``k_hit``, else ``k_hit``; -1: nothing within range) and
    ``returned`` False when its hit surface loses it: ``u`` below the grazing loss g
    (:func:`grazes`) combined with the surface loss s = ``surface_dropout`` x the cell's share in
    ``surfaces`` as ``g + s - g s`` (either loses it; g alone where ``surface_dropout`` is 0).
    Shared by the scan mapper and the mapper at a SLAM estimate."""
    kp = person_first(persons, m, r0, c0, theta, lr, lc, n if k_hit < 0 else k_hit) if persons.shape[1] > 0 else -1
    if kp >= 0:
        return kp, True  # a person stands in the beam's way: it returns from them
    if k_hit < 0:
        return k_hit, True
    if surface_dropout > 0.0:
        r = lr[k_hit]
        c = lc[k_hit]
        g = 0.0
        if grazing > 0.0:
            nr = normals[r, c, 0]
            nc = normals[r, c, 1]
            nn = np.sqrt(nr * nr + nc * nc)
            if nn > 0.0:
                g = grazing * (1.0 - abs(-nr * np.cos(theta) + nc * np.sin(theta)) / nn)
        s = surface_dropout * surfaces[r, c]
        if u < g + s - g * s:
            return k_hit, False
        return k_hit, True
    if grazing > 0.0 and grazes(normals, lr[k_hit], lc[k_hit], theta, grazing, u):
        return k_hit, False
    return k_hit, True


@njit(cache=True, nogil=True)
def _scan_kernel(obstacles, rows, cols, n_beams, range_px, res, max_range_m, noise, drop, exact,
                 l_hit, l_miss, l_min, l_max, log_odds, state, touched_r, touched_c, first_scan, last,
                 normals, grazing, graze_u, persons, surfaces, surface_dropout):
    h, w = obstacles.shape
    cap = int(np.ceil(range_px)) + 2
    lr = np.empty(cap, np.int32)
    lc = np.empty(cap, np.int32)
    two_pi = 2.0 * np.pi
    cos_b, sin_b = beam_headings(n_beams)
    done = 0
    for m in range(rows.shape[0]):
        r0 = rows[m]
        c0 = cols[m]
        if r0 < 0 or r0 >= h or c0 < 0 or c0 >= w or obstacles[r0, c0]:
            continue
        done += 1
        if exact and r0 == last[0] and c0 == last[1]:
            # no noise, no dropout, same cell as the previous scan: the same beams, the same cells
            _apply_scan(log_odds, state, touched_r, touched_c, last[2], l_hit, l_miss, l_min, l_max)
            continue
        s = first_scan + done - 1
        nt = 0
        for b in range(n_beams):
            if drop[m, b]:
                continue
            theta = two_pi * b / n_beams
            r1, c1 = ray_end_of(r0, c0, cos_b[b], sin_b[b], range_px)
            # cells past the hit a long reading may reach: the distance from the start grows by
            # at least 1/sqrt(2) px per step of the line, less 1/8 px for its sideways wobble
            extra = 0
            if noise[m, b] > 0:
                extra = int(1.4143 * (noise[m, b] / res + 0.125)) + 2
            n, k_hit = walk_beam(obstacles, r0, c0, r1, c1, extra, lr, lc)
            k_hit, returned = beam_return(persons, m, r0, c0, theta, lr, lc, n, k_hit, normals, grazing,
                                          graze_u[m, b], surfaces, surface_dropout)
            if not returned:
                continue  # a grazing beam, or one on glass or a dark wall, returned nothing
            n_free = n
            end_r = -1
            end_c = -1
            if k_hit >= 0:
                n_free = k_hit
                d_true = np.hypot(lr[k_hit] - r0, lc[k_hit] - c0) * res
                d_m = max(d_true + noise[m, b], 0.0)
                k = k_hit
                if d_m < d_true:
                    # a short reading: the end is the last line cell not farther than d_m
                    k = k_hit - 1
                    while k > 0 and np.hypot(lr[k] - r0, lc[k] - c0) * res > d_m:
                        k -= 1
                elif d_m > d_true:
                    # a long reading: the same line walked through the obstacle, unless its end
                    # lies past max_range or off the map (then a max-range reading: the whole line)
                    pr = r0 + 0.5 - cos_b[b] * (d_m / res)
                    pc = c0 + 0.5 + sin_b[b] * (d_m / res)
                    if d_m <= max_range_m and pr >= 0.0 and pr < h and pc >= 0.0 and pc < w:
                        k = n - 1
                        while np.hypot(lr[k] - r0, lc[k] - c0) * res > d_m:
                            k -= 1
                    else:
                        k = -1
                        n_free, _ = walk_beam(obstacles, r0, c0, r1, c1, cap, lr, lc)
                if k >= 0:
                    n_free = k
                    end_r = lr[k]
                    end_c = lc[k]
            for j in range(n_free):
                nt = _mark(state, touched_r, touched_c, nt, lr[j], lc[j], s, 1)
            if end_r >= 0:
                nt = _mark(state, touched_r, touched_c, nt, end_r, end_c, s, 2)
        _apply_scan(log_odds, state, touched_r, touched_c, nt, l_hit, l_miss, l_min, l_max)
        last[0] = r0
        last[1] = c0
        last[2] = nt
    return done


class ScanMapper:
    """Integrates scans into a log-odds grid, a batch at a time (the fast path).

    Args:
        obstacles: (H, W) bool, what the scan plane hits (:func:`scan_obstacles`).
        grid: the map's geometry (resolution, origin).
        settings: scanner and mapper settings (checked here).
        surfaces: (H, W) per-cell surface shares (:func:`surface_shares`) that
            ``settings.surface_dropout`` scales; None: no surface loss.

    The range noise and dropout draws come from two generators seeded from
    ``settings.seed``: the map after ``add(a); add(b)`` equals the map after ``add(a + b)``.
    """

    def __init__(self, obstacles: np.ndarray, grid: GridMap, settings: ScanSettings,
                 surfaces: np.ndarray | None = None):
        self.settings = settings.check()
        self.obstacles = np.ascontiguousarray(obstacles, dtype=np.bool_)
        if self.obstacles.shape != grid.shape:
            raise ValueError(f"obstacles shape {self.obstacles.shape} != grid shape {grid.shape}")
        self._surfaces = _surface_array(surfaces, settings, grid.shape)
        self.grid = grid
        self.log_odds = np.zeros(grid.shape, np.float64)
        self._state = np.full(grid.shape, -1, np.int32)
        self._touched_r = np.empty(grid.shape[0] * grid.shape[1], np.int32)
        self._touched_c = np.empty(grid.shape[0] * grid.shape[1], np.int32)
        self._last = np.array([-1, -1, 0], np.int64)  # the previous scan's cell and its touched count
        self._noise_rng, self._drop_rng = _draw_streams(settings.seed)
        self._graze_rng = np.random.default_rng([int(settings.seed), 4])
        self._people_rng = np.random.default_rng([int(settings.seed), 5])
        self._normals = surface_normals(self.obstacles) if settings.grazing_dropout > 0 else np.zeros((1, 1, 2))
        self.n_scans = 0
        self.free_level = logit(settings.free_thresh)
        self.occupied_level = logit(settings.occupied_thresh)

    def add(self, scan_poses: np.ndarray) -> int:
        """Integrate 360 degree scans from (M, 3) poses (x, z metres, yaw degrees); poses off
        the map or on an obstacle cell scan nothing (their draws are still consumed).

        Returns:
            the number of scans integrated.
        """
        poses = np.asarray(scan_poses, np.float64).reshape(-1, 3)
        s = self.settings
        noise, drop = _beam_draws(s, self._noise_rng, self._drop_rng, len(poses))
        r, c = self.grid.world_to_cell(poses[:, 0], poses[:, 1])
        res = self.grid.resolution
        exact = exact_scanner(s)
        graze_u = _grazing_draws(s, self._graze_rng, len(poses))
        persons = people_draws(s, self._people_rng, self.obstacles, self.grid.resolution, len(poses))
        done = _scan_kernel(self.obstacles, r.astype(np.int64), c.astype(np.int64), s.n_beams,
                            _range_px(s, self.grid.shape, res), res, float(s.max_range), noise, drop, exact,
                            float(s.log_odds_hit), float(s.log_odds_miss), float(s.log_odds_min),
                            float(s.log_odds_max), self.log_odds, self._state, self._touched_r, self._touched_c,
                            self.n_scans, self._last, self._normals, float(s.grazing_dropout), graze_u, persons,
                            self._surfaces, float(s.surface_dropout) if self._surfaces.shape == self.grid.shape else 0.0)
        self.n_scans += int(done)
        return int(done)

    def free(self) -> np.ndarray:
        """(H, W) bool cells free now (p < free_thresh)."""
        return self.log_odds < self.free_level

    def unknown(self) -> np.ndarray:
        """(H, W) bool cells neither free nor occupied now."""
        return (self.log_odds >= self.free_level) & (self.log_odds <= self.occupied_level)

    def result(self) -> ScanMap:
        """The map so far."""
        occ = occupancy_from_log_odds(self.log_odds, self.settings)
        return ScanMap(self.log_odds.astype(np.float32), occ, occ == FREE, self.settings, self.n_scans)


def scan_map(obstacles: np.ndarray, grid: GridMap, scan_poses: np.ndarray, settings: ScanSettings,
             surfaces: np.ndarray | None = None) -> ScanMap:
    """Build the occupancy map 360 degree scans from ``scan_poses`` give (module docstring).

    Args:
        obstacles: (H, W) bool, what the scan plane hits (:func:`scan_obstacles`).
        grid: the map's geometry.
        scan_poses: (M, 3) x, z (metres), yaw (degrees), in scan order (see
            :func:`envs.maps.trajectory.trajectory`).
        settings: scanner and mapper settings.
        surfaces: per-cell surface shares (:func:`surface_shares`), or None (no surface loss).

    Returns:
        :class:`ScanMap` on ``grid``'s cells. Deterministic for ``settings.seed``.
    """
    mapper = ScanMapper(obstacles, grid, settings, surfaces)
    mapper.add(scan_poses)
    return mapper.result()


def robot_scan_map(scene: Scene, poses: np.ndarray, settings: ScanSettings,
                   wall_height: float = DEFAULT_WALL_HEIGHT) -> tuple[ScanMap, np.ndarray]:
    """The map a robot builds driving through its views: :func:`scan_obstacles` at the scan
    height, the :func:`envs.maps.trajectory.trajectory` through ``poses`` on the walkable cells
    every ``settings.spacing`` metres, and :func:`scan_map` along it.

    Args:
        scene: the house on its grid.
        poses: (N, 3) views in capture order (x, z metres, yaw degrees).
        settings: scanner and mapper settings.
        wall_height: the house's lowest wall top, metres (:func:`house_wall_height`).

    Returns:
        (the scan map, the (M, 3) scan poses).
    """
    settings.check()
    obstacles = scan_plane(scene, settings, wall_height)  # a closed door blocks beams, and the route:
    closed = closed_doors(scene, settings.door_closed, settings.seed)  # the robot cannot pass it
    scans = trajectory(scene.grid.walkable & ~closed, scene.grid, poses, settings.spacing)
    surfaces = surface_shares(scene, settings.height) if settings.surface_dropout > 0 else None
    return scan_map(obstacles, scene.grid, scans, settings, surfaces), scans


@njit(cache=True, nogil=True)
def _ranges_kernel(obstacles, rows, cols, beams, n_beams, range_px, res, max_range_m, noise, drop, normals, grazing,
                   graze_u, persons, surfaces, surface_dropout, out):
    h, w = obstacles.shape
    cap = int(np.ceil(range_px)) + 2
    lr = np.empty(cap, np.int32)
    lc = np.empty(cap, np.int32)
    cos_b, sin_b = beam_headings(n_beams)
    for m in range(rows.shape[0]):
        r0 = rows[m]
        c0 = cols[m]
        if r0 < 0 or r0 >= h or c0 < 0 or c0 >= w or obstacles[r0, c0]:
            continue
        for t in range(beams.shape[0]):
            b = beams[t]
            if drop[m, b]:
                continue
            r1, c1 = ray_end_of(r0, c0, cos_b[b], sin_b[b], range_px)
            n, k_hit = walk_beam(obstacles, r0, c0, r1, c1, 0, lr, lc)
            k_hit, returned = beam_return(persons, m, r0, c0, 2.0 * np.pi * b / n_beams, lr, lc, n, k_hit, normals,
                                          grazing, graze_u[m, b], surfaces, surface_dropout)
            if not returned or k_hit < 0:
                continue
            d = max(np.hypot(lr[k_hit] - r0, lc[k_hit] - c0) * res + noise[m, b], 0.0)
            if d <= max_range_m:
                out[m, t] = d


def scan_ranges(obstacles: np.ndarray, grid: GridMap, scan_poses: np.ndarray,
                settings: ScanSettings, surfaces: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The range readings of the scans :func:`scan_map` integrates (the same beams, walk and draws,
    ``settings.seed``'s streams), for a scan matcher.

    Args:
        obstacles: (H, W) bool, what the scan plane hits (:func:`scan_obstacles`).
        grid: the map's geometry.
        scan_poses: (M, 3) x, z (metres), yaw (degrees): where each scan is taken (its true pose).
        settings: the scanner (checked); a matcher subsamples beams with a coarser ``angular_step``.
        surfaces: per-cell surface shares (:func:`surface_shares`), or None (no surface loss).

    Returns:
        ``(ranges, headings, origins)``: (M, B) metres measured by the beams (NaN: no return,
        i.e. dropout, grazing loss, nothing within ``max_range``, a reading past it, or a scan from
        off the map or an obstacle cell), (B,) each beam's map heading (radians, the yaw
        convention: 0 faces +z, pi/2 faces +x; fixed in the world as :func:`beam_headings`),
        (M, 2) world x, z of each scan's origin (the centre of its pose's cell).
    """
    s = settings.check()
    poses = np.asarray(scan_poses, np.float64).reshape(-1, 3)
    obstacles = np.ascontiguousarray(obstacles, np.bool_)
    if obstacles.shape != grid.shape:
        raise ValueError(f"obstacles shape {obstacles.shape} != grid shape {grid.shape}")
    noise, drop, graze_u, normals, persons, sf = scan_draws(s, obstacles, grid, surfaces, len(poses))
    r, c = grid.world_to_cell(poses[:, 0], poses[:, 1])
    beams = np.arange(s.n_beams, dtype=np.int64)
    out = np.full((len(poses), len(beams)), np.nan)
    _ranges_kernel(obstacles, r.astype(np.int64), c.astype(np.int64), beams, s.n_beams,
                   _range_px(s, grid.shape, grid.resolution), grid.resolution, float(s.max_range), noise, drop,
                   normals, float(s.grazing_dropout), graze_u, persons, sf,
                   float(s.surface_dropout) if sf.shape == grid.shape else 0.0, out)
    res = grid.resolution
    origins = np.column_stack([grid.origin[0] + (c + 0.5) * res, grid.origin[1] - (r + 0.5) * res])
    return out, 2.0 * np.pi * beams / s.n_beams, origins


# --------------------------------------------------------------------------- slow reference


def _reference_line(r0: int, c0: int, r1: int, c1: int) -> list[tuple[int, int]]:
    """The digital line from (r0, c0) to (r1, c1) from its definition: one cell per step along
    the major axis, the minor coordinate the integer nearest the exact line (ties toward the start)."""
    dr, dc = r1 - r0, c1 - c0
    n = max(abs(dr), abs(dc))
    if n == 0:
        return [(r0, c0)]

    def nearest(start: int, delta: int, i: int) -> int:
        low, rem = divmod(delta * i, n)
        if 2 * rem < n:
            return start + low
        if 2 * rem > n:
            return start + low + 1
        return start + (low if delta > 0 else low + 1)

    if abs(dc) >= abs(dr):
        step = 1 if dc > 0 else -1
        return [(nearest(r0, dr, i), c0 + step * i) for i in range(n + 1)]
    step = 1 if dr > 0 else -1
    return [(r0 + step * i, nearest(c0, dc, i)) for i in range(n + 1)]


class ReferenceScanMapper:
    """The slow reference of :class:`ScanMapper`: plain Python per beam and per cell, its own
    line walk (:func:`_reference_line`), sets per scan and a dict of log-odds. Same inputs,
    same random draws, same map."""

    def __init__(self, obstacles: np.ndarray, grid: GridMap, settings: ScanSettings,
                 surfaces: np.ndarray | None = None):
        self.settings = settings.check()
        self.obstacles = np.asarray(obstacles, bool)
        self.grid = grid
        self.surfaces = None if surfaces is None else np.asarray(surfaces, float).tolist()
        self.cells: dict[tuple[int, int], float] = {}
        self._noise_rng, self._drop_rng = np.random.default_rng([int(settings.seed), 1]), \
            np.random.default_rng([int(settings.seed), 2])
        self._graze_rng = np.random.default_rng([int(settings.seed), 4])
        self._people_rng = np.random.default_rng([int(settings.seed), 5])
        self.n_scans = 0

    def _draws(self, m: int):
        s, nb = self.settings, self.settings.n_beams
        noise = self._noise_rng.normal(0.0, s.range_noise, (m, nb)) if s.range_noise > 0 else np.zeros((m, nb))
        drop = self._drop_rng.random((m, nb)) < s.dropout if s.dropout > 0 else np.zeros((m, nb), bool)
        return noise, drop

    def add(self, scan_poses) -> int:
        s = self.settings
        h, w = self.obstacles.shape
        res = self.grid.resolution
        blocked = self.obstacles.tolist()
        poses = np.asarray(scan_poses, float).reshape(-1, 3)
        noise, drop = self._draws(len(poses))
        graze_u = (self._graze_rng.random((len(poses), s.n_beams)) if s.grazing_dropout > 0 or s.surface_dropout > 0
                   else np.zeros((len(poses), s.n_beams)))
        persons = []  # per scan: [(row, col, radius px)], centres of uniformly drawn unblocked cells
        if s.people > 0:
            unblocked = [r * w + c for r in range(h) for c in range(w) if not blocked[r][c]]
            idx = self._people_rng.integers(0, len(unblocked), (len(poses), s.people)) if unblocked else None
            for m in range(len(poses)):
                persons.append([] if idx is None else [(unblocked[i] // w + 0.5, unblocked[i] % w + 0.5,
                                                        s.person_radius / res) for i in idx[m]])
        length = math.ceil(math.hypot(h, w)) + 2 if math.isinf(s.max_range) else s.max_range / res
        done = 0
        for m, (x, z, _yaw) in enumerate(poses.tolist()):
            col = math.floor((x - self.grid.origin[0]) / res)
            row = math.floor((self.grid.origin[1] - z) / res)
            if not (0 <= row < h and 0 <= col < w) or blocked[row][col]:
                continue
            done += 1
            passed: set[tuple[int, int]] = set()
            ends: set[tuple[int, int]] = set()
            for b in range(s.n_beams):
                if drop[m, b]:
                    continue
                theta = 2.0 * math.pi * b / s.n_beams
                r1 = math.floor(row + 0.5 - math.cos(theta) * length)
                c1 = math.floor(col + 0.5 + math.sin(theta) * length)
                line = []
                for r, c in _reference_line(row, col, r1, c1):
                    if not (0 <= r < h and 0 <= c < w):
                        break
                    line.append((r, c))
                dist = [math.hypot(r - row, c - col) * res for r, c in line]
                hit = next((k for k, (r, c) in enumerate(line) if blocked[r][c]), None)
                person = None
                for pr, pc, rad in (persons[m] if persons else []):
                    vr, vc = pr - (row + 0.5), pc - (col + 0.5)
                    t = -vr * math.cos(theta) + vc * math.sin(theta)
                    perp2 = vr * vr + vc * vc - t * t
                    if t > 0 and perp2 <= rad * rad and 0 < t - math.sqrt(rad * rad - perp2):
                        d = t - math.sqrt(rad * rad - perp2)
                        person = d if person is None else min(person, d)
                if person is not None:
                    upto = len(line) if hit is None else hit
                    kp = next((k for k in range(upto) if math.hypot(line[k][0] - row, line[k][1] - col) >= person),
                              None)
                    if kp is not None:
                        hit = kp
                        person = True
                if hit is None:  # nothing within range: free evidence up to the line's end
                    passed.update(line)
                    continue
                if (s.grazing_dropout > 0 or s.surface_dropout > 0) and person is not True:
                    hr, hc = line[hit]
                    lost = 0.0  # the chance this hit returns nothing: grazing, then glass or a dark wall
                    if s.grazing_dropout > 0:
                        nr = sum(dr for dr in (-1, 0, 1) for dc in (-1, 0, 1) if (dr or dc) and 0 <= hr + dr < h
                                 and 0 <= hc + dc < w and not blocked[hr + dr][hc + dc])
                        nc = sum(dc for dr in (-1, 0, 1) for dc in (-1, 0, 1) if (dr or dc) and 0 <= hr + dr < h
                                 and 0 <= hc + dc < w and not blocked[hr + dr][hc + dc])
                        if nr or nc:
                            cos_i = abs(-nr * math.cos(theta) + nc * math.sin(theta)) / math.hypot(nr, nc)
                            lost = s.grazing_dropout * (1.0 - cos_i)
                    if s.surface_dropout > 0 and self.surfaces is not None:
                        q = s.surface_dropout * self.surfaces[hr][hc]
                        lost = lost + q - lost * q
                    if graze_u[m, b] < lost:
                        continue
                measured = max(dist[hit] + noise[m, b], 0.0)
                if measured > dist[hit]:
                    px = row + 0.5 - math.cos(theta) * (measured / res)
                    pc = col + 0.5 + math.sin(theta) * (measured / res)
                    if measured > s.max_range or not (0 <= px < h and 0 <= pc < w):  # a max-range reading
                        passed.update(line)
                        continue
                    reach = line
                else:
                    reach = line[: hit + 1]
                k = max(i for i, d in enumerate(dist[: len(reach)]) if d <= measured)
                passed.update(reach[:k])
                ends.add(reach[k])
            for cell in passed | ends:
                v = self.cells.get(cell, 0.0)
                d = (s.log_odds_miss if cell in passed else 0.0) + (s.log_odds_hit if cell in ends else 0.0)
                self.cells[cell] = min(max(v + d, s.log_odds_min), s.log_odds_max)
            self.n_scans += 1
        return done

    def log_odds(self) -> np.ndarray:
        out = np.zeros(self.grid.shape, np.float64)
        for (r, c), v in self.cells.items():
            out[r, c] = v
        return out

    def result(self) -> ScanMap:
        lo = self.log_odds()
        s = self.settings
        occ = np.full(lo.shape, UNKNOWN, np.int8)
        for (r, c), v in self.cells.items():
            p = 1.0 / (1.0 + math.exp(-v))
            occ[r, c] = OCCUPIED if p > s.occupied_thresh else FREE if p < s.free_thresh else UNKNOWN
        return ScanMap(lo.astype(np.float32), occ, occ == FREE, s, self.n_scans)


def scan_map_reference(obstacles: np.ndarray, grid: GridMap, scan_poses: np.ndarray,
                       settings: ScanSettings, surfaces: np.ndarray | None = None) -> ScanMap:
    """Slow, obviously correct :func:`scan_map` (pure Python, its own line walk); same result."""
    mapper = ReferenceScanMapper(obstacles, grid, settings, surfaces)
    mapper.add(scan_poses)
    return mapper.result()


# --------------------------------------------------------------------------- writing


def write_scan_map(path_yaml: str | Path, scan: ScanMap, grid: GridMap, image_name: str | None = None) -> Path:
    """Write a scan map as a ROS ``map_server`` map (trinary: occupied 0, free 254, unknown 205),
    with the scan's thresholds in the YAML, so ``map_server`` (and :func:`read_ros_map`) read
    back the same free / occupied / unknown cells.

    Args:
        path_yaml: the YAML file.
        scan: the map.
        grid: its geometry (resolution, origin).
        image_name: image file name beside the YAML (``.pgm`` default, or ``.png``).

    Returns:
        The YAML path.
    """
    s = scan.settings
    unknown = unknown_pixel(s.free_thresh, s.occupied_thresh)
    img = np.full(scan.occupancy.shape, unknown, np.uint8)
    img[scan.occupancy == FREE] = 254
    img[scan.occupancy == OCCUPIED] = 0
    return write_ros_map(path_yaml, img, grid.resolution, ros_origin_of(grid), occupied_thresh=s.occupied_thresh,
                         free_thresh=s.free_thresh, image_name=image_name)


def read_scan_occupancy(path_yaml: str | Path) -> np.ndarray:
    """(H, W) int8 -1 / 0 / 100 of a written scan map, as ``map_server`` reads it."""
    return read_ros_map(path_yaml).occupancy


__all__ = ["ScanSettings", "ScanMap", "ScanMapper", "ReferenceScanMapper", "scan_obstacles", "scan_plane", "scan_map", "robot_scan_map",
           "scan_map_reference", "surface_shares", "GLASS_SHARE", "DARK_SHARE", "write_scan_map", "read_scan_occupancy", "house_wall_height",
           "occupancy_from_log_odds", "logit", "scan_ranges", "DEFAULT_WALL_HEIGHT", "UNKNOWN", "FREE", "OCCUPIED"]
