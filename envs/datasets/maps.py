"""A folder of a user's occupancy maps as an environment (``env=maps``).

Each map becomes one "house" of the runner, so ``roomseg-bench -m env=maps env.dir=DIR
segmenter=distance,voronoi,morphological`` segments and scores a whole map collection
with caches, tables and figures as for houses.

**Maps.** A ROS ``map_server`` YAML (+ its image; :func:`envs.maps.ros.read_ros_map`), a
plain occupancy image (``.png``/``.pgm``/``.bmp``: free = light, needs ``image_resolution``;
:func:`envs.maps.ros.occupancy_png`, read with ``image_preset`` ``ros`` = as a YAML without
thresholds, or ``white_only`` = only white is free, the convention of ``rooms_white`` map
sets) or a ``.npy`` bool array (True = walkable; needs ``image_resolution``). Every image
and array is checked against ``max_map_pixels`` on its header, before it is decoded. The map's id is the part of the file name that ``{id}`` matches in the
``maps`` pattern: the full stem for ``{id}.yaml``, so ``office_a.yaml`` .. ``office_i.yaml``
are nine maps.

**Pairing.** A naming rule: ``ground_truth``, ``poses``, ``labels``, ``images`` are file
name patterns with ``{id}`` (relative to ``dir``; ``null`` = none); files matching one of
these patterns are never taken as maps. Or a manifest: a CSV with columns ``id, map`` and
optionally ``ground_truth, poses, labels, images`` (paths relative to the manifest's folder;
an empty cell = none). A listed file that does not exist fails that map alone, with a line
naming it.

**Ground truth** (``gt_format``: ``instance`` | ``label`` | ``rooms_white``;
:mod:`envs.maps.ground_truth`) must be pixel-aligned with the map image (same size). It is
carried onto the *input* map: the segmenters take their free space from the map, never
from the ground truth; ground-truth rooms on cells the map calls occupied are dropped, and
walkable cells that no room covers take the nearest room within ``fill_distance`` metres.
A map without ground truth cannot be scored: its scene fails with one line.

**Reachable area** (``reachable``, :mod:`envs.maps.reachable`): ``start`` cuts the map's
free space, and the ground truth scored, to the 4-connected components that hold a view of
the poses file (``poses``, read in ``poses_frame``), or, with no poses file, to the largest
component; ``largest`` always the largest; ``all`` keeps every free cell. Free pockets
enclosed by furniture are then no room for any method.

**Poses, labels, images** are what the other stages read (``viewpoints=file``,
``classifier=labels``, ``renderer=images``) through their own ``{house_id}`` path patterns,
e.g. ``viewpoints.path='${env.dir}/{house_id}_poses.csv' viewpoints.frame=ros``; listed here,
they are checked to exist and their content goes into the cache keys.

**No house.** A map has no floor plan and no furniture list: :meth:`MapsEnv.house` gives a
:class:`MapHouse` (``data = {"map": id, "kind": "occupancy_map"}``) whose ``rooms`` raise a
one-line error, so renderers that need a house (AI2-THOR, Habitat, the floorplan renderer)
cannot render maps; use the image-folder renderer or a labels classifier.
"""

from __future__ import annotations

import csv
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated

import numpy as np

from envs.datasets.base import Environment
from envs.maps.gridmap import GridMap
from envs.maps.ground_truth import FORMATS, read_ground_truth
from envs.maps.pose_files import read_poses
from envs.maps.reachable import RULES as REACHABLE_RULES
from envs.maps.reachable import check_rule, restrict_scene
from envs.maps.ros import (
    grid_from_array,
    image_thresholds,
    occupancy_png,
    read_npy_map,
    read_ros_map,
)
from envs.maps.scene import MAX_MAP_PIXELS, Scene, check_max_map_pixels
from envs.ranges import Integer, OneOf, Share
from envs.world.classes import PAPER_CLASSES
from envs.world.house import House

#: Per-map files besides the map itself, in manifest-column order.
EXTRA_FILES = ("ground_truth", "poses", "labels", "images")
_IMAGE_SUFFIXES = (".png", ".pgm", ".bmp", ".jpg", ".jpeg", ".tif", ".tiff")


class MapHouse(House):
    """The stand-in for a house of a map-folder environment: an id and the map's name, no
    floor plan. Reading ``rooms`` raises a one-line error naming the map."""

    def __init__(self, house_id: str, map_path: Path):
        super().__init__(house_id, {"map": house_id, "file": map_path.name, "kind": "occupancy_map"})

    @property
    def rooms(self) -> list[dict]:
        raise ValueError(f"map {self.id!r} (env maps) is an occupancy map, not a house: it has no floor plan or "
                         f"objects, so renderer=floorplan|ai2thor|habitat cannot render it; use renderer=images "
                         f"or a labels classifier")


@dataclass(frozen=True)
class MapEntry:
    """One map of the folder: its id and files (None: not given)."""

    id: str
    map: Path
    files: dict[str, Path | None] = field(default_factory=dict)


def _pattern_regex(pattern: str, what: str) -> re.Pattern:
    if pattern.count("{id}") != 1 or "/" in pattern:
        raise ValueError(f"env.{what} pattern {pattern!r} must contain '{{id}}' once and no folder")
    return re.compile("^" + re.escape(pattern).replace(r"\{id\}", "(?P<id>.+)") + "$")


class MapsEnv(Environment):
    """A folder of occupancy maps (see the module doc).

    Args:
        dir: the folder.
        maps: map file name pattern with ``{id}`` (``{id}.yaml``, ``{id}.png``, ``{id}.npy``).
        manifest: a CSV (path, relative to ``dir`` or absolute) listing the maps instead of
            the naming rule; ``null`` to use the patterns.
        ground_truth, poses, labels, images: file name patterns with ``{id}``, or null.
        gt_format: ``instance`` | ``label`` | ``rooms_white``.
        image_resolution: metres per pixel of plain images and ``.npy`` maps (ROS YAMLs carry
            theirs).
        origin: world (x0, z0) metres of the top-left corner of plain images and ``.npy``
            maps; null puts their bottom-left corner at (0, 0).
        image_preset: plain images: ``ros`` (thresholds of a YAML that leaves them out: free
            below p = 0.196, occupied above 0.65) | ``white_only`` (only grey >= 250 is free).
        free_thresh, occupied_thresh: plain images: occupancy thresholds overriding the
            preset's (null: the preset's); negate: dark = free.
        mode: override every ROS YAML's ``mode`` (null: each YAML's own).
        unknown_as: ``obstacle`` | ``free``: unknown map cells.
        min_room_m2, light_threshold, fill_distance, not_room_colours: ground-truth reading
            (:func:`envs.maps.ground_truth.read_ground_truth`).
        classes: ordered class names (label ground truth maps onto them).
        name: dataset name in tables.
        max_map_pixels: the largest map, ground-truth image or array (width x height pixels)
            read, checked on the file's header before decoding; null: no limit.
        reachable: ``start`` | ``largest`` | ``all`` (module doc).
        poses_frame: the frame of the poses files (``ros`` | ``sim`` | ``pixel``, as
            ``viewpoints.frame``), read for ``reachable=start``.
    """

    def __init__(self, dir: str, maps: str = "{id}.yaml", manifest: str | None = None,
                 ground_truth: str | None = "{id}_gt.png", poses: str | None = None,
                 labels: str | None = None, images: str | None = None, gt_format: str = "instance",
                 image_resolution: float | None = None, origin: Sequence[float] | None = None,
                 image_preset: Annotated[str, OneOf("ros", "white_only")] = "ros",
                 free_thresh: Annotated[float | None, Share()] = None,
                 occupied_thresh: Annotated[float | None, Share()] = None, negate: bool = False,
                 mode: str | None = None, unknown_as: str = "obstacle", min_room_m2: float = 0.2,
                 light_threshold: int = 230, fill_distance: float | None = 0.5,
                 not_room_colours: Sequence = ("#000000", "#ffffff"), classes: Sequence[str] = PAPER_CLASSES,
                 name: str = "maps", max_map_pixels: Annotated[int | None, Integer(1)] = MAX_MAP_PIXELS,
                 reachable: Annotated[str, OneOf(*REACHABLE_RULES)] = "start",
                 poses_frame: Annotated[str, OneOf("ros", "sim", "pixel")] = "ros"):
        if dir is None or str(dir) in ("", "???"):
            raise ValueError("env.dir is not set; expected the folder of maps (env.dir=DIR)")
        self.dir = Path(str(dir)).expanduser()
        if not self.dir.is_dir():
            raise FileNotFoundError(f"env.dir: map folder not found: {self.dir}")
        if gt_format not in FORMATS:
            raise ValueError(f"env.gt_format is {gt_format!r}; expected one of {list(FORMATS)}")
        if image_resolution is not None and not (np.isfinite(image_resolution) and image_resolution > 0):
            raise ValueError(f"env.image_resolution is {image_resolution!r}; expected a positive number of "
                             f"metres/pixel or null")
        if origin is not None and len(origin) != 2:
            raise ValueError(f"env.origin is {origin!r}; expected [x0, z0] (metres) or null")
        self.name, self.classes, self.gt_format = name, tuple(classes), gt_format
        self.resolution, self.origin = image_resolution, (None if origin is None else tuple(map(float, origin)))
        image_thresholds(image_preset, free_thresh, occupied_thresh, "env.")  # one line when they are bad
        self.max_pixels = check_max_map_pixels(max_map_pixels, "env.max_map_pixels")
        self.png = dict(preset=image_preset, free_thresh=free_thresh, occupied_thresh=occupied_thresh,
                        negate=bool(negate), unknown_as=unknown_as, max_pixels=self.max_pixels, where="env.")
        self.mode, self.unknown_as = mode, unknown_as
        self.gt_opts = dict(min_room_m2=min_room_m2, light_threshold=light_threshold, fill_distance=fill_distance,
                            not_room_colours=tuple(not_room_colours), max_pixels=self.max_pixels)
        self.reachable = check_rule(reachable)
        if poses_frame not in ("ros", "sim", "pixel"):
            raise ValueError(f"env.poses_frame is {poses_frame!r}; expected ros, sim or pixel")
        self.poses_frame = poses_frame
        patterns = {"ground_truth": ground_truth, "poses": poses, "labels": labels, "images": images}
        if manifest:
            entries = self._from_manifest(Path(str(manifest)).expanduser())
        else:
            entries = self._from_patterns(maps, patterns)
        self._entries: dict[str, MapEntry] = {e.id: e for e in entries}

    # ----------------------------------------------------------------- pairing

    def _from_patterns(self, maps: str, patterns: dict[str, str | None]) -> list[MapEntry]:
        rx = _pattern_regex(maps, "maps")
        others = {k: _pattern_regex(p, k) for k, p in patterns.items() if p}
        entries = []
        for p in sorted(self.dir.iterdir()):
            m = rx.match(p.name)
            if not m or not p.is_file() or any(o.match(p.name) for o in others.values()):
                continue
            mid = m.group("id")
            files = {k: (self.dir / patterns[k].replace("{id}", mid) if patterns[k] else None) for k in EXTRA_FILES}
            entries.append(MapEntry(mid, p, files))
        if not entries:
            raise FileNotFoundError(f"env.dir {self.dir}: no map file matches env.maps {maps!r}")
        return entries

    def _from_manifest(self, path: Path) -> list[MapEntry]:
        path = path if path.is_absolute() else self.dir / path
        if not path.is_file():
            raise FileNotFoundError(f"env.manifest not found: {path}")
        with path.open(newline="") as f:
            reader = csv.DictReader(f)
            cols = [c.strip() for c in (reader.fieldnames or [])]
            if "id" not in cols or "map" not in cols:
                raise ValueError(f"{path}: manifest needs columns 'id' and 'map' (optional {list(EXTRA_FILES)}), "
                                 f"found {cols}")
            unknown = [c for c in cols if c not in ("id", "map", *EXTRA_FILES)]
            if unknown:
                raise ValueError(f"{path}: unknown manifest column(s) {unknown}; expected id, map, "
                                 f"{', '.join(EXTRA_FILES)}")
            rows = [{(k or "").strip(): (v or "").strip() for k, v in r.items()} for r in reader]
        if not rows:
            raise ValueError(f"{path}: the manifest lists no map")
        ids = [r["id"] for r in rows]
        dup = sorted({i for i in ids if ids.count(i) > 1})
        if dup or "" in ids:
            raise ValueError(f"{path}: manifest ids must be unique and non-empty; repeated or empty: {dup or ['']}")

        def resolve(v: str) -> Path | None:
            return None if not v else (Path(v) if Path(v).is_absolute() else path.parent / v)

        out = []
        for i, r in enumerate(rows):
            if not r["map"]:
                raise ValueError(f"{path}: row {i + 2} (id {r['id']!r}) has an empty 'map'")
            out.append(MapEntry(r["id"], resolve(r["map"]), {k: resolve(r.get(k, "")) for k in EXTRA_FILES}))
        return out

    # ----------------------------------------------------------------- the contract

    def house_ids(self) -> list[str]:
        return list(self._entries)

    def entry(self, house_id: str) -> MapEntry:
        """The map's files."""
        if house_id not in self._entries:
            raise KeyError(f"no map {house_id!r} in environment {self.name!r} ({self.dir})")
        return self._entries[house_id]

    def house(self, house_id: str) -> House:
        """A :class:`MapHouse` (no floor plan; see the module doc)."""
        return MapHouse(house_id, self.entry(house_id).map)

    def input_files(self, house_id: str) -> list[Path]:
        """Every file this map's scene and stages read (for cache keys); each must exist.

        Raises:
            FileNotFoundError: one line naming the missing file and its role.
        """
        e = self.entry(house_id)
        out = [e.map]
        if e.map.suffix.lower() in (".yaml", ".yml") and e.map.is_file():
            import yaml  # noqa: PLC0415

            try:
                img = (yaml.safe_load(e.map.read_text()) or {}).get("image")
            except (yaml.YAMLError, AttributeError):
                img = None
            if isinstance(img, str) and img:
                out.append(Path(img) if Path(img).is_absolute() else e.map.parent / img)
        out += [p for p in e.files.values() if p is not None]
        for role, p in [("map", e.map), *e.files.items()]:
            if p is not None and not p.exists():
                raise FileNotFoundError(f"map {house_id!r}: {role} file not found: {p}")
        return [p for p in out if p.exists()]

    def grid(self, house_id: str) -> GridMap:
        """The input map as a GridMap."""
        path = self.entry(house_id).map
        if not path.is_file():
            raise FileNotFoundError(f"map {house_id!r}: map file not found: {path}")
        suffix = path.suffix.lower()
        if suffix in (".yaml", ".yml"):
            return read_ros_map(path, mode=self.mode, unknown_as=self.unknown_as, max_pixels=self.max_pixels).grid
        if self.resolution is None:
            raise ValueError(f"{path}: a {suffix} map has no resolution; set env.image_resolution (metres/pixel)")
        if suffix == ".npy":
            arr = read_npy_map(path, self.max_pixels)
            if arr.dtype != bool:
                raise ValueError(f"{path}: .npy map has dtype {arr.dtype}; expected bool (True = walkable)")
            return grid_from_array(arr, self.resolution, self.origin)
        if suffix in _IMAGE_SUFFIXES:
            return occupancy_png(path, self.resolution, self.origin, **self.png)
        raise ValueError(f"{path}: unknown map file type {suffix!r}; expected .yaml, .npy or an image")

    def seeds(self, house_id: str, grid: GridMap) -> np.ndarray | None:
        """World (x, z) of the views in the map's poses file (the reachable area's seeds), or
        None without a poses file."""
        path = self.entry(house_id).files.get("poses")
        if path is None:
            return None
        return read_poses(path, self.poses_frame, grid)[:, :2]

    def scene(self, house_id: str) -> Scene:
        """The map and its ground truth carried onto it, cut to the reachable area.

        Returns:
            :class:`Scene` with ``grid`` = the input map's reachable free cells
            (``reachable``), ``instances`` = the ground-truth rooms on them, ``rooms`` = the
            ground-truth rooms on every free cell of the map, no walls, no objects.

        Raises:
            FileNotFoundError / ValueError: one line naming the map's file and the problem
            (no ground truth, missing file, bad field).
        """
        e = self.entry(house_id)
        self.input_files(house_id)  # every listed file exists
        grid = self.grid(house_id)
        gt_path = e.files.get("ground_truth")
        if gt_path is None:
            raise ValueError(f"map {house_id!r}: no ground truth (env.ground_truth / manifest column "
                             f"'ground_truth'); the runner scores every map against its ground truth")
        gt = read_ground_truth(gt_path, self.gt_format, grid, classes=self.classes, **self.gt_opts)
        inst = gt.instances
        if not (inst >= 0).any():
            raise ValueError(f"{gt_path}: no ground-truth room lies on a walkable cell of the map {e.map.name}")
        # rooms that lost every pixel to the map's obstacles are dropped, ids kept dense
        present = np.unique(inst[inst >= 0])
        remap = np.full(len(gt.instance_classes), -1, np.int32)
        remap[present] = np.arange(len(present), dtype=np.int32)
        inst = np.where(inst >= 0, remap[np.maximum(inst, 0)], -1).astype(np.int32)
        classes = np.asarray(gt.instance_classes, np.int64)[present]
        scene = Scene(house_id=house_id, grid=grid, rooms=inst.copy(), instances=inst, instance_classes=classes,
                      room_ids=[f"room{int(k)}" for k in present], classes=self.classes)
        seeds = self.seeds(house_id, grid) if self.reachable == "start" else None
        return restrict_scene(scene, self.reachable, seeds)


__all__ = ["MapEntry", "MapHouse", "MapsEnv"]
