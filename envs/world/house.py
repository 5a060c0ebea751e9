"""The ProcTHOR house schema: :class:`House` and its validation.

A house is kept as the plain ProcTHOR dict (schema 1.0.0) plus an ``id``; every other stage
consumes that dict. :func:`validate_house` raises :class:`HouseError` naming the house id
and the offending field. Reading house files (``.json``, ``.jsonl``, folders, split
dictionaries, ``prior``) lives in :mod:`envs.datasets.house_files`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from envs.world.classes import ROOM_TYPE_TO_CLASS, ROOM_TYPES_SETTING


class HouseError(ValueError):
    """A malformed house: the message names the house id and the field."""

    def __init__(self, house_id: str, field: str, problem: str):
        self.house_id = house_id
        self.field = field
        self.problem = problem
        super().__init__(f"house {house_id!r}: {field}: {problem}")


@dataclass(frozen=True)
class House:
    """A ProcTHOR-schema house with an id (``data`` is the house dict, not copied)."""

    id: str
    data: dict

    @property
    def rooms(self) -> list[dict]:
        return self.data["rooms"]


def _xz(point: Any, house_id: str, field: str) -> tuple[float, float]:
    if not isinstance(point, Mapping) or "x" not in point or "z" not in point:
        raise HouseError(house_id, field, f"expected a point with 'x' and 'z', got {point!r}")
    try:
        x, z = float(point["x"]), float(point["z"])
    except (TypeError, ValueError):
        raise HouseError(house_id, field, f"coordinates are not numbers: {point!r}") from None
    if not (math.isfinite(x) and math.isfinite(z)):
        raise HouseError(house_id, field, f"non-finite coordinate in {point!r}")
    return x, z


def polygon_area(points: Sequence[tuple[float, float]]) -> float:
    """Unsigned shoelace area of a polygon given as (x, z) points, in square metres."""
    s = 0.0
    n = len(points)
    for i in range(n):
        x0, z0 = points[i]
        x1, z1 = points[(i + 1) % n]
        s += x0 * z1 - x1 * z0
    return abs(s) / 2.0


def floor_polygon(room: Mapping, house_id: str = "?") -> list[tuple[float, float]]:
    """The room's floor polygon as a list of (x, z) metres (validated)."""
    rid = room.get("id", "?")
    poly = room.get("floorPolygon")
    field = f"rooms[{rid}].floorPolygon"
    if not isinstance(poly, Sequence) or isinstance(poly, str | bytes):
        raise HouseError(house_id, field, "missing or not a list of points")
    pts = [_xz(p, house_id, f"{field}[{i}]") for i, p in enumerate(poly)]
    if len(pts) < 3:
        raise HouseError(house_id, field, f"degenerate polygon: {len(pts)} points, need at least 3")
    if polygon_area(pts) < 1e-6:
        raise HouseError(house_id, field, "degenerate polygon: zero area")
    return pts


def validate_house(
    data: Any,
    house_id: str,
    room_types: Mapping[str, str] = ROOM_TYPE_TO_CLASS,
    classes: Sequence[str] | None = None,
) -> None:
    """Check a house dict; raise :class:`HouseError` naming ``house_id`` and the field.

    Checks: ``rooms`` present and non-empty; each room has an ``id``, a ``roomType`` that
    ``room_types`` maps to a class (one of ``classes`` when given) and a non-degenerate
    ``floorPolygon`` with finite coordinates; ``walls`` (if present) have finite polygons;
    doors reference existing walls; objects have finite positions.

    Returns:
        None; raises :class:`HouseError` on the first problem found.
    """
    if not isinstance(data, Mapping):
        raise HouseError(house_id, "<root>", f"expected a JSON object, got {type(data).__name__}")
    rooms = data.get("rooms")
    if not isinstance(rooms, Sequence) or isinstance(rooms, str) or len(rooms) == 0:
        raise HouseError(house_id, "rooms", "missing or empty; a house needs at least one room")
    seen = set()
    for i, room in enumerate(rooms):
        if not isinstance(room, Mapping):
            raise HouseError(house_id, f"rooms[{i}]", "not an object")
        rid = room.get("id")
        if rid is None:
            raise HouseError(house_id, f"rooms[{i}].id", "missing")
        if rid in seen:
            raise HouseError(house_id, f"rooms[{rid}].id", "duplicate room id")
        seen.add(rid)
        rtype = room.get("roomType")
        if not isinstance(rtype, str) or rtype not in room_types:
            raise HouseError(
                house_id, f"rooms[{rid}].roomType",
                f"unknown room type {rtype!r}: map it to a class in {ROOM_TYPES_SETTING} "
                f"(known types: {sorted(room_types)})",
            )
        if classes is not None and room_types[rtype] not in classes:
            raise HouseError(
                house_id, f"rooms[{rid}].roomType",
                f"room type {rtype!r} maps to class {room_types[rtype]!r}, which is not in classes "
                f"{list(classes)}; change {ROOM_TYPES_SETTING} or the class list",
            )
        floor_polygon(room, house_id)
    wall_ids = set()
    for i, wall in enumerate(_items(data, "walls", house_id)):
        wid = wall.get("id", f"#{i}")
        poly = wall.get("polygon")
        if not isinstance(poly, Sequence) or isinstance(poly, str) or len(poly) < 2:
            raise HouseError(house_id, f"walls[{wid}].polygon", "missing or fewer than 2 points")
        for j, p in enumerate(poly):
            _xz(p, house_id, f"walls[{wid}].polygon[{j}]")
        wall_ids.add(wid)
    for i, door in enumerate(_items(data, "doors", house_id)):
        did = door.get("id", f"#{i}")
        w0 = door.get("wall0")
        if w0 not in wall_ids:
            raise HouseError(house_id, f"doors[{did}].wall0", f"references unknown wall {w0!r}")
        hole = door.get("holePolygon")
        if not isinstance(hole, Sequence) or isinstance(hole, str) or len(hole) < 2:
            raise HouseError(house_id, f"doors[{did}].holePolygon", "missing or fewer than 2 points")
        for j, p in enumerate(hole):
            field = f"doors[{did}].holePolygon[{j}]"
            if not isinstance(p, Mapping):
                raise HouseError(house_id, field, f"expected a point with 'x' and 'y', got {p!r}")
            _xz({"x": p.get("x"), "z": p.get("y", 0.0)}, house_id, field)
    for i, obj in enumerate(_items(data, "objects", house_id)):
        oid = obj.get("id", f"#{i}")
        if "assetId" not in obj:
            raise HouseError(house_id, f"objects[{oid}].assetId", "missing")
        _xz(obj.get("position"), house_id, f"objects[{oid}].position")


def _items(data: Mapping, key: str, house_id: str) -> list[Mapping]:
    """``data[key]`` as a list of objects (absent or null -> empty); HouseError otherwise."""
    items = data.get(key) or []
    if not isinstance(items, Sequence) or isinstance(items, str):
        raise HouseError(house_id, key, f"expected a list, got {type(items).__name__}")
    for i, item in enumerate(items):
        if not isinstance(item, Mapping):
            raise HouseError(house_id, f"{key}[{i}]", f"expected an object, got {type(item).__name__}")
    return list(items)
