"""Object sizes and types from ProcTHOR's asset database (the ``procthor`` package).

The database is read straight from the package's data file, without importing the package
(whose ``__init__`` starts AI2-THOR machinery).
"""

from __future__ import annotations

import importlib.util
import json
import re
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path


@dataclass(frozen=True)
class AssetInfo:
    """Asset type and axis-aligned bounding-box size in metres (x, y, z; y is height)."""

    asset_id: str
    object_type: str
    size: tuple[float, float, float]
    known: bool = True


#: Footprint (x, z) and height in metres used for assets missing from the database,
#: per object type (derived from the assetId prefix); anything else gets ``_GENERIC``.
DEFAULT_SIZES: dict[str, tuple[float, float, float]] = {
    "Bed": (1.6, 0.6, 2.0),
    "Sofa": (2.0, 0.9, 0.9),
    "ArmChair": (0.9, 0.9, 0.9),
    "Chair": (0.5, 0.9, 0.5),
    "DiningTable": (1.6, 0.8, 0.9),
    "CoffeeTable": (1.0, 0.45, 0.6),
    "SideTable": (0.5, 0.6, 0.5),
    "Desk": (1.2, 0.75, 0.6),
    "Dresser": (1.0, 0.9, 0.5),
    "TVStand": (1.4, 0.5, 0.45),
    "Fridge": (0.8, 1.8, 0.75),
    "CounterTop": (1.5, 0.9, 0.65),
    "Toilet": (0.45, 0.8, 0.7),
    "Sink": (0.6, 0.9, 0.5),
    "Bathtub": (1.7, 0.6, 0.8),
    "ShelvingUnit": (1.0, 1.8, 0.4),
    "FloorLamp": (0.4, 1.6, 0.4),
    "HousePlant": (0.4, 0.8, 0.4),
    "GarbageCan": (0.35, 0.5, 0.35),
}
_GENERIC = (0.5, 0.8, 0.5)


def _database_path() -> Path:
    spec = importlib.util.find_spec("procthor")
    if spec is None or not spec.submodule_search_locations:
        raise ImportError("the 'procthor' package (ProcTHOR's asset database) is not installed: pip install procthor")
    path = Path(list(spec.submodule_search_locations)[0]) / "databases" / "asset-database.json"
    if not path.exists():
        raise FileNotFoundError(f"ProcTHOR asset database not found at {path}")
    return path


@lru_cache(maxsize=1)
def asset_database() -> dict[str, AssetInfo]:
    """assetId -> :class:`AssetInfo` for every asset in ProcTHOR's database (cached)."""
    with open(_database_path(), encoding="utf-8") as f:
        raw = json.load(f)
    out: dict[str, AssetInfo] = {}
    for object_type, assets in raw.items():
        for a in assets:
            bb = a["boundingBox"]
            out[a["assetId"]] = AssetInfo(
                a["assetId"], a.get("objectType", object_type), (float(bb["x"]), float(bb["y"]), float(bb["z"]))
            )
    return out


@lru_cache(maxsize=1)
def assets_by_type() -> dict[str, list[AssetInfo]]:
    """objectType -> its assets, sorted by assetId (for generators that pick by type)."""
    out: dict[str, list[AssetInfo]] = {}
    for a in asset_database().values():
        out.setdefault(a.object_type, []).append(a)
    for v in out.values():
        v.sort(key=lambda a: a.asset_id)
    return out


def _type_from_asset_id(asset_id: str) -> str:
    head = re.split(r"[_\d]", asset_id, maxsplit=1)[0]
    return head or asset_id


def asset_info(asset_id: str) -> AssetInfo:
    """Size and type of ``asset_id``; unknown assets get a per-type default (``known=False``)."""
    db = asset_database()
    if asset_id in db:
        return db[asset_id]
    otype = _type_from_asset_id(asset_id)
    # match a known type case-insensitively ("Fridge_99" -> Fridge, "bed_x" -> Bed)
    types = {t.lower(): t for t in assets_by_type()}
    otype = types.get(otype.lower(), otype)
    return AssetInfo(asset_id, otype, DEFAULT_SIZES.get(otype, _GENERIC), known=False)
