"""A seeded generator of ProcTHOR-schema houses with all seven room classes and open plans.

*Simplified generator* (documented in docs/houses.md): houses are built from axis-aligned
rectangles in three bands along the footprint's long axis (x):

* a **public band** (z from 0): kitchen | dining room | living room, in that order, so the
  kitchen always touches the dining room;
* a **corridor** band (1.2-1.6 m deep) above it;
* a **private band**: bedrooms and bathrooms side by side, each opening onto the corridor
  (bathrooms are off the corridor).

The corridor and private bands may be shorter than the public band at the kitchen end
(an L-shaped footprint) or at both ends (a T). A **balcony** may hang outside the public
band's outer wall next to the living room, or outside a bedroom's outer wall. Walls are
written per room and per shared segment (twin walls with identical coordinates, as in
ProcTHOR), doors join every room to the rest, windows sit on outer walls, and furniture
from ProcTHOR's asset database is placed by room type along the walls (facing the room)
and in open space (dining table with chairs, coffee table), never overlapping another
object, a door's swing area or an open-plan boundary.

**Open plans**: each of the kitchen|dining, dining|living and corridor|living boundaries
has no wall with probability ``open_plan_share``: the rooms are then separated only in the
ground truth and by their furniture.

Same seed, same parameters -> byte-identical house (``json.dumps(house, sort_keys=True)``);
the house id ``synthetic-s<seed>`` encodes the seed.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Annotated

import numpy as np

from envs.datasets.base import Environment
from envs.maps.reachable import RULES as REACHABLE_RULES
from envs.maps.reachable import check_rule, restrict_scene, start_points
from envs.maps.scene import Scene, rasterise_house
from envs.memo import ByteLRU
from envs.ranges import Integer, LowHigh, NonNegative, OneOf, Positive, Share
from envs.world.assets import AssetInfo, assets_by_type
from envs.world.classes import PAPER_CLASSES
from envs.world.house import House

WALL_HEIGHT = 2.6  # metres
DOOR_WIDTH = 0.9  # metres
DOOR_HEIGHT = 2.1  # metres
INSET = 0.07  # metres kept free between furniture and a wall line (half wall + gap)

#: Furniture per room type: (object type, placement) in placement order; "wall" objects
#: stand against a wall facing the room, "centre" objects in open space.
FURNITURE: dict[str, list[tuple[str, str]]] = {
    "Bedroom": [("Bed", "wall"), ("Dresser", "wall"), ("SideTable", "wall"), ("Desk", "wall"),
                ("GarbageCan", "wall")],
    "Bathroom": [("Toilet", "wall"), ("Sink", "wall"), ("GarbageCan", "wall")],
    "Kitchen": [("Fridge", "wall"), ("CounterTop", "wall"), ("CounterTop", "wall"), ("GarbageCan", "wall"),
                ("Stool", "wall")],
    "LivingRoom": [("Sofa", "wall"), ("TVStand", "wall"), ("ArmChair", "wall"), ("CoffeeTable", "centre"),
                   ("FloorLamp", "wall"), ("HousePlant", "wall")],
    "DiningRoom": [("DiningTable", "centre"), ("ShelvingUnit", "wall"), ("HousePlant", "wall")],
    "Corridor": [("HousePlant", "wall"), ("ShelvingUnit", "wall")],
    "Balcony": [("HousePlant", "wall"), ("Chair", "wall"), ("SideTable", "wall")],
}
#: Objects resting on others (parent type -> child type).
CHILDREN = {"TVStand": "Television", "CounterTop": "Microwave", "Desk": "Laptop"}


@dataclass
class Rect:
    """An axis-aligned rectangle in world metres: x in [x0, x1], z in [z0, z1]."""

    x0: float
    z0: float
    x1: float
    z1: float

    def overlaps(self, o: Rect, gap: float = 0.0) -> bool:
        return self.x0 < o.x1 + gap and o.x0 < self.x1 + gap and self.z0 < o.z1 + gap and o.z0 < self.z1 + gap

    def inside(self, o: Rect) -> bool:
        return self.x0 >= o.x0 and self.x1 <= o.x1 and self.z0 >= o.z0 and self.z1 <= o.z1


def seed_from_house_id(house_id: str) -> int:
    """The seed encoded in a synthetic house id (``synthetic-s000042`` -> 42)."""
    m = re.fullmatch(r"synthetic-s(\d+)", str(house_id))
    if not m:
        raise ValueError(f"not a synthetic house id: {house_id!r} (expected 'synthetic-s<seed>')")
    return int(m.group(1))


def house_id_for(seed: int) -> str:
    return f"synthetic-s{seed:06d}"


def _r(v: float) -> float:
    return round(float(v), 4)


def _split(rng: np.random.Generator, total: float, weights: Sequence[float]) -> list[float]:
    w = np.asarray(weights, float) * rng.uniform(0.85, 1.15, len(weights))
    return list(total * w / w.sum())


def _layout(rng: np.random.Generator, length: float, depth: float, shape: str) -> list[tuple[str, Rect]]:
    """Room rectangles (roomType, Rect) of one house."""
    pub = depth * rng.uniform(0.42, 0.52)
    cor = rng.uniform(1.2, 1.6)
    rooms: list[tuple[str, Rect]] = []
    kw, dw, lw = _split(rng, length, [0.27, 0.25, 0.48])
    rooms.append(("Kitchen", Rect(0, 0, kw, pub)))
    rooms.append(("DiningRoom", Rect(kw, 0, kw + dw, pub)))
    rooms.append(("LivingRoom", Rect(kw + dw, 0, length, pub)))
    start, stop = 0.0, length
    if shape in ("L", "T"):
        start = rng.uniform(2.0, max(2.05, min(3.5, kw + dw - 1.5)))
    if shape == "T":
        stop = length - rng.uniform(1.5, max(1.6, lw - 2.0))
    if stop - start < 5.0:  # the private band needs room for a bedroom and a bathroom
        stop = min(length, start + 5.0)
        start = max(0.0, stop - 5.0)
    rooms.append(("Corridor", Rect(start, pub, stop, pub + cor)))
    # private band: bedrooms and bathrooms, at least one of each
    span = stop - start
    n_bed = max(1, int(span // 4.2))
    kinds = ["Bedroom"] * n_bed + ["Bathroom"] * max(1, n_bed // 2 + int(rng.random() < 0.4))
    rng.shuffle(kinds)
    widths = _split(rng, span, [3.6 if k == "Bedroom" else 2.2 for k in kinds])
    while min(widths) < 1.8 and len(kinds) > 2:  # every private room needs room for a door
        drop = int(np.argmin(widths))
        kinds.pop(drop)
        if "Bedroom" not in kinds:
            kinds[0] = "Bedroom"
        if "Bathroom" not in kinds:
            kinds[-1] = "Bathroom"
        widths = _split(rng, span, [3.6 if k == "Bedroom" else 2.2 for k in kinds])
    x = start
    for k, w in zip(kinds, widths):
        rooms.append((k, Rect(x, pub + cor, x + w, depth)))
        x += w
    # balcony outside the living room or a bedroom
    if rng.random() < 0.8:
        if rng.random() < 0.65:
            host = rooms[2][1]
            bw = min(rng.uniform(2.0, 4.0), host.x1 - host.x0 - 0.4)
            bx = host.x0 + 0.2 + rng.uniform(0.0, max(host.x1 - host.x0 - 0.4 - bw, 0.0))
            rooms.append(("Balcony", Rect(bx, -rng.uniform(1.2, 1.8), bx + bw, 0)))
        else:
            beds = [r for k, r in rooms if k == "Bedroom"]
            host = beds[int(rng.integers(len(beds)))]
            bw = min(rng.uniform(1.8, 3.2), host.x1 - host.x0 - 0.4)
            bx = host.x0 + 0.2 + rng.uniform(0.0, max(host.x1 - host.x0 - 0.4 - bw, 0.0))
            rooms.append(("Balcony", Rect(bx, depth, bx + bw, depth + rng.uniform(1.2, 1.6))))
    return [(k, Rect(_r(r.x0), _r(r.z0), _r(r.x1), _r(r.z1))) for k, r in rooms]


def _edge_segments(rooms: list[tuple[str, Rect]]) -> list[list[tuple[tuple, tuple]]]:
    """Per room, its edges cut at every other room's corners, as canonical (p0, p1) pairs."""
    corners = {(r.x0, r.z0) for _, r in rooms} | {(r.x1, r.z1) for _, r in rooms} | \
        {(r.x0, r.z1) for _, r in rooms} | {(r.x1, r.z0) for _, r in rooms}
    out = []
    for _, r in rooms:
        segs = []
        for (ax, az), (bx, bz) in (((r.x0, r.z0), (r.x1, r.z0)), ((r.x1, r.z0), (r.x1, r.z1)),
                                   ((r.x0, r.z1), (r.x1, r.z1)), ((r.x0, r.z0), (r.x0, r.z1))):
            if az == bz:
                cuts = sorted({ax, bx} | {cx for cx, cz in corners if cz == az and ax < cx < bx})
                segs += [((cuts[i], az), (cuts[i + 1], az)) for i in range(len(cuts) - 1)]
            else:
                cuts = sorted({az, bz} | {cz for cx, cz in corners if cx == ax and az < cz < bz})
                segs += [((ax, cuts[i]), (ax, cuts[i + 1])) for i in range(len(cuts) - 1)]
        out.append(segs)
    return out


def _wall(room_id: str, p0: tuple, p1: tuple) -> dict:
    wid = f"wall|{room_id.split('|')[1]}|{p0[0]:.2f}|{p0[1]:.2f}|{p1[0]:.2f}|{p1[1]:.2f}"
    poly = [{"x": p0[0], "y": 0, "z": p0[1]}, {"x": p1[0], "y": 0, "z": p1[1]},
            {"x": p0[0], "y": WALL_HEIGHT, "z": p0[1]}, {"x": p1[0], "y": WALL_HEIGHT, "z": p1[1]}]
    return {"id": wid, "roomId": room_id, "polygon": poly, "material": {"name": "PureWhite"}}


def _pick_asset(rng: np.random.Generator, otype: str, max_w: float, max_d: float) -> AssetInfo | None:
    fits = [a for a in assets_by_type().get(otype, []) if a.size[0] <= max_w and a.size[2] <= max_d]
    return fits[int(rng.integers(len(fits)))] if fits else None


def _place(rng, otype: str, how: str, room: Rect, taken: list[Rect], keep_out: list[Rect],
           tries: int = 20) -> tuple[AssetInfo, float, float, float, Rect] | None:
    """A free placement (asset, x, z, yaw, footprint) of one object in ``room``, or None."""
    inner = Rect(room.x0 + INSET, room.z0 + INSET, room.x1 - INSET, room.z1 - INSET)
    w, d = inner.x1 - inner.x0, inner.z1 - inner.z0
    for _ in range(tries):
        if how == "centre":
            a = _pick_asset(rng, otype, 0.6 * w, 0.6 * d)
            if a is None:
                return None
            yaw = 0.0
            ex, ez = a.size[0], a.size[2]
            x = rng.uniform(inner.x0 + 0.45 * w - 0.1, inner.x0 + 0.55 * w + 0.1)
            z = rng.uniform(inner.z0 + 0.45 * d - 0.1, inner.z0 + 0.55 * d + 0.1)
        else:
            side = int(rng.integers(4))  # 0: z0 wall, 1: z1 wall, 2: x0 wall, 3: x1 wall
            along, across = (w, d) if side < 2 else (d, w)
            a = _pick_asset(rng, otype, along, 0.45 * across)
            if a is None:
                continue
            yaw = (0.0, 180.0, 90.0, 270.0)[side]
            ex, ez = (a.size[0], a.size[2]) if side < 2 else (a.size[2], a.size[0])
            if side == 0:
                x, z = rng.uniform(inner.x0 + ex / 2, inner.x1 - ex / 2), inner.z0 + ez / 2
            elif side == 1:
                x, z = rng.uniform(inner.x0 + ex / 2, inner.x1 - ex / 2), inner.z1 - ez / 2
            elif side == 2:
                x, z = inner.x0 + ex / 2, rng.uniform(inner.z0 + ez / 2, inner.z1 - ez / 2)
            else:
                x, z = inner.x1 - ex / 2, rng.uniform(inner.z0 + ez / 2, inner.z1 - ez / 2)
        fp = Rect(x - ex / 2, z - ez / 2, x + ex / 2, z + ez / 2)
        if fp.inside(inner) and not any(fp.overlaps(t, 0.05) for t in taken) and \
                not any(fp.overlaps(k) for k in keep_out):
            return a, x, z, yaw, fp
    return None


def _object(oid: str, a: AssetInfo, x: float, z: float, yaw: float, base: float = 0.0) -> dict:
    return {"id": oid, "assetId": a.asset_id, "kinematic": True, "layer": "Procedural0", "children": [],
            "position": {"x": _r(x), "y": _r(base + a.size[1] / 2), "z": _r(z)},
            "rotation": {"x": 0, "y": yaw, "z": 0}}


def generate_house(seed: int, length: tuple[float, float] = (9.0, 14.0), depth: tuple[float, float] = (8.0, 11.0),
                   open_plan_share: float = 0.5, shapes: Sequence[str] = ("rect", "L", "T")) -> House:
    """Generate the house of ``seed`` (see the module docstring).

    Args:
        seed: the seed (>= 0); the house id is ``synthetic-s<seed>``.
        length, depth: footprint size ranges in metres (long and short side).
        open_plan_share: probability that each kitchen/dining, dining/living and
            corridor/living boundary has no wall.
        shapes: footprint shapes to draw from ("rect", "L", "T").
    """
    if seed < 0:
        raise ValueError(f"seed must be >= 0, got {seed}")
    if not 0.0 <= open_plan_share <= 1.0:
        raise ValueError(f"open_plan_share must be in [0, 1], got {open_plan_share}")
    if length[0] < 7.0 or depth[0] < 6.5 or length[1] < length[0] or depth[1] < depth[0]:
        raise ValueError(f"need 7 <= length[0] <= length[1] and 6.5 <= depth[0] <= depth[1] metres, "
                         f"got length={length}, depth={depth}")
    rng = np.random.default_rng(seed)
    shape = str(shapes[int(rng.integers(len(shapes)))])
    rooms = _layout(rng, rng.uniform(*length), rng.uniform(*depth), shape)
    ids = [f"room|{i + 2}" for i in range(len(rooms))]
    kind = [k for k, _ in rooms]
    open_pairs = set()
    for a, b in (("Kitchen", "DiningRoom"), ("DiningRoom", "LivingRoom"), ("Corridor", "LivingRoom")):
        if rng.random() < open_plan_share:
            open_pairs.add(frozenset((kind.index(a), kind.index(b))))
    segs = _edge_segments(rooms)
    owners: dict[tuple, list[int]] = {}
    for i, ss in enumerate(segs):
        for s in ss:
            owners.setdefault(s, []).append(i)
    walls, wall_id = [], {}
    for i, ss in enumerate(segs):
        for s in ss:
            others = [j for j in owners[s] if j != i]
            if others and frozenset((i, others[0])) in open_pairs:
                continue
            w = _wall(ids[i], *s)
            walls.append(w)
            wall_id[(i, s)] = w["id"]
    # doors: every private room and the living room to the corridor; kitchen-dining-living;
    # the balcony to its host (open-plan pairs need no door)
    cor = kind.index("Corridor")
    need = [(i, cor) for i, k in enumerate(kind) if k in ("Bedroom", "Bathroom", "LivingRoom")]
    need += [(kind.index("Kitchen"), kind.index("DiningRoom")), (kind.index("DiningRoom"), kind.index("LivingRoom"))]
    if "Balcony" in kind:
        b = kind.index("Balcony")
        host = next(j for s in segs[b] for j in owners[s] if j != b)
        need.append((host, b))
    doors, keep_out = [], {i: [] for i in range(len(rooms))}
    for a, b in need:
        if frozenset((a, b)) in open_pairs:
            continue
        shared = [s for s in segs[a] if b in owners[s] and np.hypot(s[1][0] - s[0][0], s[1][1] - s[0][1]) >= DOOR_WIDTH + 0.6]
        if not shared:
            raise RuntimeError(f"synthetic seed {seed}: rooms {kind[a]} and {kind[b]} share no wall for a door")
        s = max(shared, key=lambda s: np.hypot(s[1][0] - s[0][0], s[1][1] - s[0][1]))
        seg_len = np.hypot(s[1][0] - s[0][0], s[1][1] - s[0][1])
        t0 = rng.uniform(0.3, seg_len - 0.3 - DOOR_WIDTH)
        doors.append({"id": f"door|{ids[a].split('|')[1]}|{ids[b].split('|')[1]}", "room0": ids[a], "room1": ids[b],
                      "wall0": wall_id[(a, s)], "wall1": wall_id[(b, s)], "assetId": "Doorway_1",
                      "holePolygon": [{"x": _r(t0), "y": 0, "z": 0}, {"x": _r(t0 + DOOR_WIDTH), "y": DOOR_HEIGHT, "z": 0}],
                      "assetPosition": {"x": _r(t0 + DOOR_WIDTH / 2), "y": DOOR_HEIGHT / 2, "z": 0},
                      "openable": False, "openness": 1})
        (x0, z0), (x1, z1) = s
        ux, uz = (x1 - x0) / seg_len, (z1 - z0) / seg_len
        ax, az = x0 + ux * t0, z0 + uz * t0
        bx, bz = x0 + ux * (t0 + DOOR_WIDTH), z0 + uz * (t0 + DOOR_WIDTH)
        swing = Rect(min(ax, bx) - DOOR_WIDTH * abs(uz), min(az, bz) - DOOR_WIDTH * abs(ux),
                     max(ax, bx) + DOOR_WIDTH * abs(uz), max(az, bz) + DOOR_WIDTH * abs(ux))
        keep_out[a].append(swing)
        keep_out[b].append(swing)
    for pair in open_pairs:  # keep open boundaries passable
        a, b = sorted(pair)
        for s in segs[a]:
            if b in owners[s]:
                (x0, z0), (x1, z1) = s
                band = Rect(min(x0, x1) - 0.6, min(z0, z1) - 0.6, max(x0, x1) + 0.6, max(z0, z1) + 0.6)
                keep_out[a].append(band)
                keep_out[b].append(band)
    # windows on outer walls of bedrooms and living rooms
    windows = []
    for i, k in enumerate(kind):
        if k not in ("Bedroom", "LivingRoom"):
            continue
        outer = [s for s in segs[i] if len(owners[s]) == 1 and (i, s) in wall_id and
                 np.hypot(s[1][0] - s[0][0], s[1][1] - s[0][1]) >= 1.6]
        if outer:
            s = outer[int(rng.integers(len(outer)))]
            seg_len = np.hypot(s[1][0] - s[0][0], s[1][1] - s[0][1])
            t0 = rng.uniform(0.3, seg_len - 1.3)
            windows.append({"id": f"window|{ids[i].split('|')[1]}|{len(windows)}", "assetId": "Window_Fixed_48x36",
                            "room0": ids[i], "room1": ids[i], "wall0": wall_id[(i, s)],
                            "wall1": "wall|exterior" + wall_id[(i, s)][wall_id[(i, s)].index("|", 5):],
                            "holePolygon": [{"x": _r(t0), "y": 0.9, "z": 0}, {"x": _r(t0 + 1.0), "y": 1.9, "z": 0}],
                            "assetPosition": {"x": _r(t0 + 0.5), "y": 1.4, "z": 0}})
    # furniture
    objects = []
    for i, (k, r) in enumerate(rooms):
        taken: list[Rect] = []
        n = 0
        for otype, how in FURNITURE[k]:
            got = _place(rng, otype, how, r, taken, keep_out[i])
            if got is None:
                continue
            a, x, z, yaw, fp = got
            obj = _object(f"{ids[i].split('|')[1]}|{n}", a, x, z, yaw)
            n += 1
            child_t = CHILDREN.get(otype)
            if child_t and assets_by_type().get(child_t):
                ca = _pick_asset(rng, child_t, a.size[0], a.size[2])
                if ca is not None:
                    obj["children"].append(_object(f"{obj['id']}|c", ca, x, z, yaw, base=a.size[1]))
            objects.append(obj)
            taken.append(fp)
            if otype == "DiningTable":
                for side in range(4):
                    ch = _pick_asset(rng, "Chair", 0.6, 0.6)
                    if ch is None:
                        break
                    off = [(0, -1), (0, 1), (-1, 0), (1, 0)][side]
                    cx = x + off[0] * ((fp.x1 - fp.x0) / 2 + ch.size[2] / 2 + 0.05)
                    cz = z + off[1] * ((fp.z1 - fp.z0) / 2 + ch.size[2] / 2 + 0.05)
                    ex, ez = (ch.size[0], ch.size[2]) if off[0] == 0 else (ch.size[2], ch.size[0])
                    cfp = Rect(cx - ex / 2, cz - ez / 2, cx + ex / 2, cz + ez / 2)
                    inner = Rect(r.x0 + INSET, r.z0 + INSET, r.x1 - INSET, r.z1 - INSET)
                    if cfp.inside(inner) and not any(cfp.overlaps(t, 0.05) for t in taken) and \
                            not any(cfp.overlaps(q) for q in keep_out[i]):
                        cyaw = {(0, -1): 0.0, (0, 1): 180.0, (-1, 0): 90.0, (1, 0): 270.0}[off]
                        objects.append(_object(f"{ids[i].split('|')[1]}|{n}", ch, cx, cz, cyaw))
                        n += 1
                        taken.append(cfp)
    living = rooms[kind.index("LivingRoom")][1]
    house = {
        "id": house_id_for(seed),
        "rooms": [{"id": ids[i], "roomType": k, "children": [], "ceilings": [], "layer": "Procedural0",
                   "floorMaterial": {"name": "OakWood"},
                   "floorPolygon": [{"x": r.x0, "y": 0, "z": r.z0}, {"x": r.x0, "y": 0, "z": r.z1},
                                    {"x": r.x1, "y": 0, "z": r.z1}, {"x": r.x1, "y": 0, "z": r.z0}]}
                  for i, (k, r) in enumerate(rooms)],
        "walls": walls, "doors": doors, "windows": windows, "objects": objects,
        "metadata": {"schema": "1.0.0", "generator": "roomseg-bench synthetic", "seed": int(seed), "shape": shape,
                     "openPlan": sorted(sorted(kind[j] for j in p) for p in open_pairs),
                     "agent": {"position": {"x": _r((living.x0 + living.x1) / 2), "y": 0.95,
                                            "z": _r((living.z0 + living.z1) / 2)},
                               "rotation": {"x": 0, "y": 0, "z": 0}, "standing": True, "horizon": 0}},
    }
    return House(house["id"], house)


#: generated houses a :class:`SyntheticEnv` keeps (a few hundred kB each)
RECENT_HOUSES = 4


class SyntheticEnv(Environment):
    """``n_houses`` generated houses with seeds ``seed_start``, ``seed_start + 1``, ...

    Generation and rasterisation parameters as in :func:`generate_house` and
    :class:`envs.datasets.procthor.ProcTHOREnv`; ``reachable`` as there (every generated
    house has a start pose: the living room's centre, moved to the nearest free cell when
    furniture stands there).
    """

    def __init__(self, n_houses: Annotated[int, Integer(1)] = 20, seed_start: Annotated[int, Integer(0)] = 0,
                 length: Annotated[Sequence[float], LowHigh()] = (9.0, 14.0),
                 depth: Annotated[Sequence[float], LowHigh()] = (8.0, 11.0),
                 open_plan_share: Annotated[float, Share()] = 0.5, shapes: Sequence[str] = ("rect", "L", "T"),
                 resolution: Annotated[float, Positive()] = 0.05,
                 wall_thickness: Annotated[float, NonNegative()] = 0.1,
                 clearance: Annotated[float, NonNegative()] = 0.0,
                 max_object_base: Annotated[float, NonNegative()] = 0.5,
                 classes: Sequence[str] = PAPER_CLASSES, name: str = "synthetic",
                 reachable: Annotated[str, OneOf(*REACHABLE_RULES)] = "start"):
        if n_houses < 1 or seed_start < 0:
            raise ValueError(f"n_houses must be >= 1 and seed_start >= 0, got {n_houses}, {seed_start}")
        self.name = name
        self.reachable = check_rule(reachable)
        self.gen = dict(length=tuple(length), depth=tuple(depth), open_plan_share=float(open_plan_share),
                        shapes=tuple(shapes))
        self.raster = dict(resolution=resolution, wall_thickness=wall_thickness, clearance=clearance,
                           max_object_base=max_object_base, classes=tuple(classes))
        self.seeds = list(range(seed_start, seed_start + n_houses))
        self._recent = ByteLRU()

    def house_ids(self) -> list[str]:
        return [house_id_for(s) for s in self.seeds]

    def house(self, house_id: str) -> House:
        """The generated house; the last :data:`RECENT_HOUSES` are kept, so a run that asks for a
        house's content and then its scene generates it once. ``data`` is shared by the calls
        (as a ProcTHOR environment shares the dict it read): read-only to every stage."""
        house = self._recent.get(house_id)
        if house is None:
            house = generate_house(seed_from_house_id(house_id), **self.gen)
            self._recent.put(house_id, house, 1, RECENT_HOUSES)  # (counted, one "byte" a house)
        return house

    def scene(self, house_id: str) -> Scene:
        house = self.house(house_id)
        return restrict_scene(rasterise_house(house, **self.raster), self.reachable, start_points(house.data))
