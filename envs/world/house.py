"""Load and validate ProcTHOR-schema houses (``.json``, ``.jsonl``, ``.jsonl.gz``, ``prior``).

A house is kept as the plain ProcTHOR dict (schema 1.0.0) plus an ``id``; every other stage
consumes that dict. :func:`validate_house` raises :class:`HouseError` naming the house id
and the offending field.
"""

from __future__ import annotations

import gzip
import json
import math
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from envs.world.classes import ROOM_TYPE_TO_CLASS


class HouseError(ValueError):
    """A malformed house: the message names the house id and the field."""

    def __init__(self, house_id: str, field: str, problem: str):
        self.house_id = house_id
        self.field = field
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


def validate_house(data: Any, house_id: str, room_types: Mapping[str, str] = ROOM_TYPE_TO_CLASS) -> None:
    """Check a house dict; raise :class:`HouseError` naming ``house_id`` and the field.

    Checks: ``rooms`` present and non-empty; each room has an ``id``, a known ``roomType``
    and a non-degenerate ``floorPolygon`` with finite coordinates; ``walls`` (if present)
    have finite polygons; doors reference existing walls; objects have finite positions.
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
        if rtype not in room_types:
            raise HouseError(
                house_id, f"rooms[{rid}].roomType",
                f"unknown room type {rtype!r}; expected one of {sorted(room_types)}",
            )
        floor_polygon(room, house_id)
    wall_ids = set()
    for i, wall in enumerate(data.get("walls", []) or []):
        wid = wall.get("id", f"#{i}") if isinstance(wall, Mapping) else f"#{i}"
        poly = wall.get("polygon") if isinstance(wall, Mapping) else None
        if not isinstance(poly, Sequence) or len(poly) < 2:
            raise HouseError(house_id, f"walls[{wid}].polygon", "missing or fewer than 2 points")
        for j, p in enumerate(poly):
            _xz(p, house_id, f"walls[{wid}].polygon[{j}]")
        wall_ids.add(wid)
    for i, door in enumerate(data.get("doors", []) or []):
        did = door.get("id", f"#{i}")
        w0 = door.get("wall0")
        if w0 not in wall_ids:
            raise HouseError(house_id, f"doors[{did}].wall0", f"references unknown wall {w0!r}")
        hole = door.get("holePolygon")
        if not isinstance(hole, Sequence) or len(hole) < 2:
            raise HouseError(house_id, f"doors[{did}].holePolygon", "missing or fewer than 2 points")
        for j, p in enumerate(hole):
            _xz({"x": p.get("x"), "z": p.get("y", 0.0)}, house_id, f"doors[{did}].holePolygon[{j}]")
    for i, obj in enumerate(data.get("objects", []) or []):
        oid = obj.get("id", f"#{i}")
        if "assetId" not in obj:
            raise HouseError(house_id, f"objects[{oid}].assetId", "missing")
        _xz(obj.get("position"), house_id, f"objects[{oid}].position")


def _parse(text: str, source: str) -> Any:
    try:
        return json.loads(text)
    except json.JSONDecodeError as e:
        raise ValueError(f"{source}: not valid JSON ({e})") from None


def iter_house_file(path: str | Path, prefix: str | None = None, validate: bool = True) -> Iterator[House]:
    """Houses from a ``.json`` (one house or a list), ``.jsonl`` or ``.jsonl.gz`` file.

    House ids are ``<prefix>-<index>`` (prefix defaults to the file's stem), unless the
    house dict carries its own ``id``.
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"house file not found: {path}")
    name = path.name
    stem = name.split(".")[0]
    prefix = prefix or stem
    if name.endswith(".jsonl.gz") or name.endswith(".jsonl"):
        opener = gzip.open if name.endswith(".gz") else open
        with opener(path, "rt", encoding="utf-8") as f:
            for i, line in enumerate(f):
                if not line.strip():
                    continue
                data = _parse(line, f"{path}:{i + 1}")
                yield _make(data, f"{prefix}-{i:05d}", validate)
    elif name.endswith(".json") or name.endswith(".json.gz"):
        opener = gzip.open if name.endswith(".gz") else open
        with opener(path, "rt", encoding="utf-8") as f:
            data = _parse(f.read(), str(path))
        if isinstance(data, list):
            for i, d in enumerate(data):
                yield _make(d, f"{prefix}-{i:05d}", validate)
        else:
            yield _make(data, prefix, validate)
    else:
        raise ValueError(f"house file {path}: expected .json, .jsonl or .jsonl.gz")


def _make(data: Any, default_id: str, validate: bool) -> House:
    hid = str(data["id"]) if isinstance(data, Mapping) and data.get("id") else default_id
    if validate:
        validate_house(data, hid)
    return House(hid, data)


def load_houses(
    path: str | Path,
    start: int = 0,
    stop: int | None = None,
    prefix: str | None = None,
    validate: bool = True,
) -> list[House]:
    """Houses ``[start:stop]`` of a house file (indices count every house in the file)."""
    out = []
    for i, h in enumerate(iter_house_file(path, prefix, validate=False)):
        if stop is not None and i >= stop:
            break
        if i >= start:
            if validate:
                validate_house(h.data, h.id)
            out.append(h)
    return out


def load_prior_houses(
    dataset: str = "procthor-10k", split: str = "train", start: int = 0, stop: int | None = 100,
    revision: str | None = None, validate: bool = True,
) -> list[House]:
    """Houses from AI2's ``prior`` package (needs ``pip install roomseg-bench[thor]``, network
    access and git-lfs). The paper uses ``procthor-10k`` train[0:100]."""
    try:
        import prior  # noqa: PLC0415
    except ImportError:
        raise ImportError("loading ProcTHOR-10k needs the 'prior' package: pip install 'roomseg-bench[thor]'") from None
    kwargs = {"revision": revision} if revision else {}
    ds = prior.load_dataset(dataset, **kwargs)
    if split not in ds:
        raise ValueError(f"{dataset} has no split {split!r}; expected one of {list(ds)}")
    data = ds[split]
    stop = len(data) if stop is None else min(stop, len(data))
    out = []
    for i in range(start, stop):
        h = House(f"{dataset}-{split}-{i:05d}", data[i])
        if validate:
            validate_house(h.data, h.id)
        out.append(h)
    return out
