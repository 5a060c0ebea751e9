"""House -> :class:`Scene`: occupancy map plus room ground truth, by rasterising the house.

Walkable = inside some room's floor polygon, minus walls (a band of ``wall_thickness``
centred on each wall line, with door openings cut out; walls ProcTHOR marks ``empty``, fully
opened between two rooms of an open plan, are not drawn), minus the footprints of floor
furniture (rotated boxes sized from ProcTHOR's asset database), optionally eroded by a
robot ``clearance`` radius. A pixel belongs to the room whose floor polygon contains its
centre (the first such room in the house's room order, for pixels on a shared edge).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import shapely
from scipy import ndimage

from envs.maps.distance import distance_px
from envs.maps.gridmap import GridMap
from envs.world.assets import asset_info
from envs.world.classes import PAPER_CLASSES, ROOM_TYPE_TO_CLASS, room_type_to_class_index
from envs.world.house import House, HouseError, floor_polygon, validate_house

#: Peak memory of :func:`rasterise_house` per map pixel, in bytes: 100 B/px growth of the
#: process's maximum resident set (88 B/px traced by tracemalloc) rasterising one 100 x 100 m
#: room at 0.05 m/px (2010 x 2010 pixels), where each room and wall window spans the map.
RASTER_BYTES_PER_PIXEL = 100

#: Default ``max_map_pixels``: the largest map (H x W pixels) rasterised, so that the
#: rasterisation's arrays fit in 2 GB (20 M pixels x 100 B; at 0.05 m/px about 223 x 223 m).
MAX_MAP_PIXELS = 2_000_000_000 // RASTER_BYTES_PER_PIXEL

#: words that mark a dark wall material in a ProcTHOR wall's ``material.name`` (case ignored):
#: DarkGranite, DarkTiles, Porcelain_Black_Mat, ... (about 4 % of the shared houses' wall sides).
#: Dark surfaces reflect little of a laser scanner's near-infrared light and return less often.
DARK_MATERIAL_WORDS = ("dark", "black")


def check_max_map_pixels(value, setting: str = "max_map_pixels") -> int | None:
    """``value`` as a positive int, or ``None`` for no limit; one-line error otherwise.

    Returns:
        the limit in pixels, or ``None``.
    """
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int) or value <= 0:
        raise ValueError(f"{setting} must be a positive number of pixels or null (no limit), got {value!r}")
    return value


@dataclass(frozen=True)
class ObjectFootprint:
    """A top-level object of the house, on the floor plane.

    ``center`` is world (x, z) in metres, ``yaw`` degrees (simulator convention), ``size``
    the asset's (x, y, z) box size in metres, ``base``/``top`` the box's bottom and top
    heights in metres, ``children`` the object types resting on it.
    """

    id: str
    asset_id: str
    object_type: str
    center: tuple[float, float]
    yaw: float
    size: tuple[float, float, float]
    base: float
    top: float
    children: tuple[str, ...] = ()
    known_asset: bool = True

    def corners(self) -> np.ndarray:
        """(4, 2) world (x, z) corners of the footprint box."""
        hx, hz = self.size[0] / 2, self.size[2] / 2
        a = np.deg2rad(self.yaw)
        ux = np.array([np.cos(a), -np.sin(a)])  # local +x in world (x, z)
        uz = np.array([np.sin(a), np.cos(a)])  # local +z in world (x, z)
        c = np.array(self.center)
        return np.array([c + sx * hx * ux + sz * hz * uz for sx, sz in ((-1, -1), (1, -1), (1, 1), (-1, 1))])

    def contains(self, x: np.ndarray, z: np.ndarray) -> np.ndarray:
        """True where world points (x, z) lie inside the footprint box."""
        a = np.deg2rad(self.yaw)
        dx = np.asarray(x) - self.center[0]
        dz = np.asarray(z) - self.center[1]
        u = dx * np.cos(a) - dz * np.sin(a)
        v = dx * np.sin(a) + dz * np.cos(a)
        return (np.abs(u) <= self.size[0] / 2) & (np.abs(v) <= self.size[2] / 2)


@dataclass
class Scene:
    """A house on a grid: map, ground truth and what the renderer needs.

    Attributes:
        house_id: the house's id.
        grid: the occupancy map.
        rooms: (H, W) int32 room index whose floor polygon holds the pixel centre, -1 outside.
        instances: (H, W) int32 ground-truth room instance on walkable pixels, -1 elsewhere.
        instance_classes: (R,) int class index of each room.
        room_ids: the house's room ids, in room-index order.
        classes: the ordered class names that class indices refer to.
        walls: (H, W) bool wall band (door openings cut out).
        objects: the house's top-level objects.
        object_map: (H, W) int32 index into ``objects`` of the footprint covering the pixel
            (floor objects drawn over raised ones), -1 for none.
        start: the robot's start pose (world x, z metres, yaw degrees) from the house's
            ``metadata.agent``, or None when the house gives none.
        doors: door id -> (K, 2) int (row, col) cells its opening cut out of the wall band
            (what a closed door fills again; :func:`envs.maps.scan.closed_doors`).
        windows: window id -> ((K, 2) int (row, col) wall-band cells over the window's hole, the
            hole's bottom and top above the floor in metres): glass where a scan plane lies
            between them (:func:`envs.maps.scan.surface_shares`).
        dark_walls: (H, W) bool wall-band cells on the room side of a wall whose material is dark
            (:data:`DARK_MATERIAL_WORDS` in its name), or None (no wall layer).
    """

    house_id: str
    grid: GridMap
    rooms: np.ndarray
    instances: np.ndarray
    instance_classes: np.ndarray
    room_ids: list[str]
    classes: tuple[str, ...] = PAPER_CLASSES
    walls: np.ndarray | None = None
    objects: list[ObjectFootprint] = field(default_factory=list)
    object_map: np.ndarray | None = None
    start: tuple[float, float, float] | None = None
    doors: dict[str, np.ndarray] = field(default_factory=dict)
    windows: dict[str, tuple[np.ndarray, float, float]] = field(default_factory=dict)
    dark_walls: np.ndarray | None = None

    @property
    def semantic(self) -> np.ndarray:
        """(H, W) int32 ground-truth class index on walkable pixels, -1 elsewhere."""
        out = np.full(self.instances.shape, -1, dtype=np.int32)
        m = self.instances >= 0
        out[m] = np.asarray(self.instance_classes)[self.instances[m]]
        return out


def _wall_segment(wall: dict) -> tuple[np.ndarray, np.ndarray]:
    pts = wall["polygon"]
    ys = [float(p.get("y", 0.0)) for p in pts]
    y0 = min(ys)
    base = [(float(p["x"]), float(p["z"])) for p, y in zip(pts, ys) if abs(y - y0) < 1e-6]
    # keep the first point's order: the door hole offset is measured from polygon[0]
    uniq = []
    for p in base:
        if not uniq or np.hypot(p[0] - uniq[-1][0], p[1] - uniq[-1][1]) > 1e-9:
            uniq.append(p)
    if len(uniq) < 2:
        uniq = [(float(pts[0]["x"]), float(pts[0]["z"])), (float(pts[1]["x"]), float(pts[1]["z"]))]
    return np.array(uniq[0]), np.array(uniq[-1])


def _pixel_window(grid: GridMap, xmin: float, xmax: float, zmin: float, zmax: float):
    """Pixel index window covering a world box, and its pixel-centre coordinates: x (1, w) per
    column and z (h, 1) per row, which broadcast to the window's (h, w)."""
    h, w = grid.shape
    r0, c0 = grid.cell_of(xmin, zmax)
    r1, c1 = grid.cell_of(xmax, zmin)
    r0, c0 = max(r0 - 1, 0), max(c0 - 1, 0)
    r1, c1 = min(r1 + 2, h), min(c1 + 2, w)
    if r0 >= r1 or c0 >= c1:
        return None
    x, z = grid.pixel_to_world(np.arange(r0, r1)[:, None], np.arange(c0, c1)[None, :])
    return (slice(r0, r1), slice(c0, c1)), x, z


def _segment_band(grid: GridMap, p0: np.ndarray, p1: np.ndarray, half: float, t_range=None):
    """Pixels within ``half`` metres of segment p0-p1 (optionally only where the projection
    along the segment, in metres from p0, lies in ``t_range``)."""
    pad = half + grid.resolution
    win = _pixel_window(grid, min(p0[0], p1[0]) - pad, max(p0[0], p1[0]) + pad,
                        min(p0[1], p1[1]) - pad, max(p0[1], p1[1]) + pad)
    if win is None:
        return None, None
    sl, x, z = win
    d = p1 - p0
    length = float(np.hypot(*d))
    if length < 1e-9:
        return sl, np.hypot(x - p0[0], z - p0[1]) <= half
    u = d / length
    t = (x - p0[0]) * u[0] + (z - p0[1]) * u[1]
    perp = np.abs((x - p0[0]) * u[1] - (z - p0[1]) * u[0])
    if t_range is None:
        tc = np.clip(t, 0.0, length)
        dist = np.hypot(x - (p0[0] + tc * u[0]), z - (p0[1] + tc * u[1]))
        return sl, dist <= half
    return sl, (perp <= half) & (t >= t_range[0]) & (t <= t_range[1])


def inside_or_on(polygon: np.ndarray, x: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Points inside ``polygon`` or on its boundary (``shapely.intersects_xy``).

    A polygon of 4 corners whose edges lie along the axes, turning at every corner (a
    rectangle: every room of the generated houses, about a third of ProcTHOR's), is tested by
    comparing coordinates with its sides, which is exact: a point is on such an edge when its
    coordinate equals the edge's. Any other polygon goes to GEOS (prepared: an indexed
    point-in-area test).

    Args:
        polygon: (V, 2) x, z vertices, metres.
        x, z: point coordinates, metres, broadcastable to one shape.

    Returns:
        bool array of the broadcast shape.
    """
    if len(polygon) == 4:
        nxt = np.roll(polygon, -1, axis=0)
        along_x = polygon[:, 1] == nxt[:, 1]  # the edge from each corner keeps z
        # each edge along one axis (not both: no zero length), turning at every corner: a rectangle
        if (along_x != (polygon[:, 0] == nxt[:, 0])).all() and (along_x != np.roll(along_x, -1)).all():
            lo, hi = polygon.min(axis=0), polygon.max(axis=0)
            return (x >= lo[0]) & (x <= hi[0]) & (z >= lo[1]) & (z <= hi[1])
    shape = shapely.Polygon(polygon)
    shapely.prepare(shape)
    return shapely.intersects_xy(shape, x, z)


def rasterise_house(
    house: House,
    resolution: float = 0.05,
    wall_thickness: float = 0.1,
    clearance: float = 0.0,
    max_object_base: float = 0.5,
    margin: float = 0.25,
    classes: Sequence[str] = PAPER_CLASSES,
    room_types: dict[str, str] | None = None,
    max_map_pixels: int | None = MAX_MAP_PIXELS,
    layers: str = "all",
) -> Scene:
    """Rasterise a ProcTHOR-schema house into a :class:`Scene`.

    Args:
        house: the house (validated here).
        resolution: metres per pixel.
        wall_thickness: total wall thickness in metres (half on each side of the wall line).
        clearance: robot radius in metres; walkable pixels closer than this to an obstacle
            are removed (0 keeps the full free space).
        max_object_base: objects whose box bottom is below this height (metres) block the
            floor; higher ones (paintings, wall shelves) do not.
        margin: empty border around the house in metres.
        classes: ordered class names for ``instance_classes``.
        room_types: dataset roomType -> class name (default:
            :data:`~envs.world.classes.ROOM_TYPE_TO_CLASS`).
        max_map_pixels: the largest map (H x W pixels) to rasterise, ``None`` for no limit;
            a larger house raises :class:`HouseError` before any array is allocated
            (default :data:`MAX_MAP_PIXELS`, about 2 GB at :data:`RASTER_BYTES_PER_PIXEL`).
        layers: ``all``; or ``rooms``: only the room raster, the room classes and the object
            list, each as ``all`` computes them (walls, the object map and ``clearance`` are
            skipped: the grid's walkable cells are the floor, ``walls`` and ``object_map``
            are None). What a classifier's training needs to place objects in rooms.

    Returns:
        :class:`Scene` on a grid of ``resolution`` metres per pixel.
    """
    if layers not in ("all", "rooms"):
        raise ValueError(f"layers must be 'all' or 'rooms', got {layers!r}")
    room_types = dict(room_types or ROOM_TYPE_TO_CLASS)
    hid = house.id
    data = house.data
    validate_house(data, hid, room_types, classes)
    if not resolution > 0:
        raise ValueError(f"resolution must be positive metres/pixel, got {resolution}")
    max_map_pixels = check_max_map_pixels(max_map_pixels)

    polys = [floor_polygon(r, hid) for r in data["rooms"]]
    allpts = np.array([p for poly in polys for p in poly])
    xmin, zmin = allpts.min(axis=0) - margin
    xmax, zmax = allpts.max(axis=0) + margin
    wf, hf = np.ceil((xmax - xmin) / resolution), np.ceil((zmax - zmin) / resolution)
    if max_map_pixels is not None and not wf * hf <= max_map_pixels:
        raise HouseError(
            hid, "map size",
            f"extent {xmax - xmin:.2f} x {zmax - zmin:.2f} m (x by z, {margin} m margin included) at "
            f"{resolution} m/px is {wf:.0f} x {hf:.0f} = {wf * hf:.0f} pixels, over the limit "
            f"max_map_pixels={max_map_pixels} (env.max_map_pixels; about {RASTER_BYTES_PER_PIXEL} bytes per pixel)")
    w, h = int(wf), int(hf)
    grid0 = GridMap(np.zeros((h, w), bool), resolution, (float(xmin), float(zmax)))

    # rooms: pixel centre inside the floor polygon or on its edge, first room wins
    rooms = np.full((h, w), -1, dtype=np.int32)
    for i, poly in enumerate(polys):
        arr = np.array(poly)
        win = _pixel_window(grid0, arr[:, 0].min(), arr[:, 0].max(), arr[:, 1].min(), arr[:, 1].max())
        if win is None:
            continue
        sl, x, z = win
        inside = inside_or_on(arr, x, z)
        sub = rooms[sl]
        sub[inside & (sub < 0)] = i
    floor = rooms >= 0
    objects = _object_footprints(data)
    instance_classes = np.array(
        [room_type_to_class_index(r["roomType"], classes, room_types) for r in data["rooms"]], dtype=np.int64)
    if layers == "rooms":
        return Scene(house_id=hid, grid=GridMap(floor, resolution, grid0.origin), rooms=rooms,
                     instances=rooms.copy(), instance_classes=instance_classes,
                     room_ids=[str(r["id"]) for r in data["rooms"]], classes=tuple(classes), objects=objects)

    # walls, minus door openings
    walls = np.zeros((h, w), dtype=bool)
    wall_seg = {}
    half = wall_thickness / 2.0
    for wall in data.get("walls", []) or []:
        p0, p1 = _wall_segment(wall)
        wall_seg[wall["id"]] = (p0, p1)
        if wall.get("empty"):  # ProcTHOR's open plan: a wall fully opened between two rooms
            continue
        if half > 0:
            sl, band = _segment_band(grid0, p0, p1, half)
            if sl is not None:
                walls[sl] |= band
    doors: dict[str, np.ndarray] = {}
    for k, door in enumerate(data.get("doors", []) or []):
        hole = door["holePolygon"]
        t0, t1 = sorted((float(hole[0]["x"]), float(hole[-1]["x"])))
        cut = np.zeros((h, w), bool)
        for key in ("wall0", "wall1"):
            if door.get(key) in wall_seg:
                p0, p1 = wall_seg[door[key]]
                sl, band = _segment_band(grid0, p0, p1, half + 1.5 * resolution, (t0, t1))
                if sl is not None:
                    cut[sl] |= walls[sl] & band
                    walls[sl] &= ~band
        doors[str(door.get("id", k))] = np.argwhere(cut)
    windows: dict[str, tuple[np.ndarray, float, float]] = {}
    for k, window in enumerate(data.get("windows", []) or []):
        hole = window.get("holePolygon") or []
        if len(hole) < 2:
            continue
        t0, t1 = sorted((float(hole[0]["x"]), float(hole[-1]["x"])))
        y0, y1 = sorted((float(hole[0].get("y", 0.0)), float(hole[-1].get("y", 0.0))))
        glass = np.zeros((h, w), bool)
        for key in ("wall0", "wall1"):
            if window.get(key) in wall_seg:
                p0, p1 = wall_seg[window[key]]
                sl, band = _segment_band(grid0, p0, p1, half + 1.5 * resolution, (t0, t1))
                if sl is not None:
                    glass[sl] |= walls[sl] & band
        windows[str(window.get("id", k))] = (np.argwhere(glass), y0, y1)
    dark_walls = np.zeros((h, w), bool)
    room_index = {str(r["id"]): i for i, r in enumerate(data["rooms"])}
    for wall in data.get("walls", []) or []:
        name = str((wall.get("material") or {}).get("name", "")) if isinstance(wall.get("material"), dict) \
            else str(wall.get("material") or "")
        i = room_index.get(str(wall.get("roomId")))
        if i is None or wall.get("empty") or half <= 0 or not any(s in name.lower() for s in DARK_MATERIAL_WORDS):
            continue
        p0, p1 = wall_seg[wall["id"]]
        sl, band = _segment_band(grid0, p0, p1, half)
        if sl is not None:  # the wall cells its room's beams meet: those next to the room's floor
            facing = ndimage.binary_dilation((rooms[sl] == i) & ~walls[sl], np.ones((3, 3), bool))
            dark_walls[sl] |= walls[sl] & band & facing

    # objects
    object_map = np.full((h, w), -1, dtype=np.int32)
    order = sorted(range(len(objects)), key=lambda k: objects[k].base < max_object_base)
    for k in order:
        o = objects[k]
        c = o.corners()
        win = _pixel_window(grid0, c[:, 0].min(), c[:, 0].max(), c[:, 1].min(), c[:, 1].max())
        if win is None:
            continue
        sl, x, z = win
        object_map[sl][o.contains(x, z)] = k
    blocking = np.array([o.base < max_object_base for o in objects] + [False])
    furniture = blocking[object_map]  # index -1 -> the trailing False

    walkable = floor & ~walls & ~furniture
    if clearance > 0:
        dist = distance_px(walkable) * resolution
        walkable &= dist > clearance
    instances = np.where(walkable, rooms, -1).astype(np.int32)
    grid = GridMap(walkable, resolution, grid0.origin)
    return Scene(
        house_id=hid, grid=grid, rooms=rooms, instances=instances, instance_classes=instance_classes,
        room_ids=[str(r["id"]) for r in data["rooms"]], classes=tuple(classes), walls=walls,
        objects=objects, object_map=object_map, start=_agent_start(data), doors=doors, windows=windows,
        dark_walls=dark_walls,
    )


def _agent_start(data: dict) -> tuple[float, float, float] | None:
    """The house's agent start pose (x, z metres, yaw degrees) from ``metadata.agent``, or None."""
    agent = (data.get("metadata") or {}).get("agent") or {}
    pos, rot = agent.get("position") or {}, agent.get("rotation") or {}
    try:
        start = (float(pos["x"]), float(pos["z"]), float(rot.get("y", 0.0)))
    except (KeyError, TypeError, ValueError):
        return None
    return start if all(np.isfinite(start)) else None


def _object_footprints(data: dict) -> list[ObjectFootprint]:
    """The house's top-level objects, in the house's order."""
    objects: list[ObjectFootprint] = []
    for obj in data.get("objects", []) or []:
        info = asset_info(obj["assetId"])
        pos = obj["position"]
        yaw = float((obj.get("rotation") or {}).get("y", 0.0))
        y = float(pos.get("y", info.size[1] / 2))
        children = tuple(asset_info(c["assetId"]).object_type for c in obj.get("children", []) or [] if "assetId" in c)
        objects.append(ObjectFootprint(
            id=str(obj.get("id", len(objects))), asset_id=obj["assetId"], object_type=info.object_type,
            center=(float(pos["x"]), float(pos["z"])), yaw=yaw, size=info.size,
            base=y - info.size[1] / 2, top=y + info.size[1] / 2, children=children, known_asset=info.known,
        ))
    return objects


def scene_on_grid(scene: Scene, grid: GridMap) -> Scene:
    """The same house on another occupancy map (e.g. from a simulator's reachable
    positions): each cell of ``grid`` takes the room of the ``scene`` cell under its centre;
    walkable cells outside every room keep no room (-1)."""
    rr, cc = np.mgrid[: grid.shape[0], : grid.shape[1]]
    x, z = grid.pixel_to_world(rr, cc)
    r, c = scene.grid.world_to_cell(x, z)
    ok = scene.grid.in_bounds(r, c)
    rooms = np.full(grid.shape, -1, np.int32)
    rooms[ok] = scene.rooms[r[ok], c[ok]]
    walls = np.zeros(grid.shape, bool)
    omap = np.full(grid.shape, -1, np.int32)
    if scene.walls is not None:
        walls[ok] = scene.walls[r[ok], c[ok]]
    if scene.object_map is not None:
        omap[ok] = scene.object_map[r[ok], c[ok]]
    return Scene(scene.house_id, grid, rooms, np.where(grid.walkable, rooms, -1).astype(np.int32),
                 scene.instance_classes, scene.room_ids, scene.classes, walls, scene.objects, omap, scene.start)


def room_polygon_areas(house: House) -> np.ndarray:
    """Floor polygon area of each room in square metres, in room order."""
    return np.array([shapely.Polygon(floor_polygon(r, house.id)).area for r in house.rooms])


__all__ = ["ObjectFootprint", "Scene", "inside_or_on", "rasterise_house", "room_polygon_areas", "scene_on_grid", "HouseError",
           "MAX_MAP_PIXELS", "RASTER_BYTES_PER_PIXEL", "check_max_map_pixels"]
