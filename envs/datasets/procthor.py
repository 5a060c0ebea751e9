"""ProcTHOR houses from a local house file or folder, or from AI2's ``prior`` package."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Annotated

from envs.datasets.base import Environment
from envs.datasets.house_files import (
    HouseRecord,
    load_prior_dataset,
    prior_records,
    read_house_records,
)
from envs.maps.reachable import RULES as REACHABLE_RULES
from envs.maps.reachable import check_rule, restrict_scene, start_points
from envs.maps.scene import (
    MAX_MAP_PIXELS,
    Scene,
    check_max_map_pixels,
    rasterise_house,
    scene_on_grid,
)
from envs.ranges import Integer, NonNegative, OneOf, Positive
from envs.world.classes import PAPER_CLASSES, room_type_mapping
from envs.world.house import House, HouseError


class ProcTHOREnv(Environment):
    """ProcTHOR-schema houses, rasterised on demand.

    Args:
        path: a house file or folder in any layout of :mod:`envs.datasets.house_files`
            (``.json``, ``.json.gz``, ``.jsonl``, ``.jsonl.gz``, a folder of ``.json``/``.json.gz``,
            a split dictionary); ``None`` loads ``prior.load_dataset(dataset)`` (needs network
            and ``roomseg-bench[thor]``).
        start, stop: index range of houses (the paper: train[0:100]).
        split: the split of a split-dictionary file, or of ``prior`` (``None``: train there);
            must be ``None`` for the other layouts.
        dataset: for ``prior`` only.
        resolution, wall_thickness, clearance, max_object_base: rasterisation parameters
            (metres per pixel, metres, metres, metres); see :func:`envs.maps.scene.rasterise_house`.
        classes: ordered class list.
        room_types: room type -> class name added to (or, with ``None``, removed from) the
            defaults :data:`envs.world.classes.ROOM_TYPE_TO_CLASS`.
        max_map_pixels: the largest map (pixels) a house may rasterise to, ``None`` for no
            limit; a larger house fails alone.
        name: dataset name in tables.
        occupancy: "floorplan" (rasterised from the house) or "ai2thor" (AI2-THOR's
            reachable positions, ``thor`` = keyword arguments of the AI2-THOR renderer;
            needs the simulator); the ground truth is carried onto that map.
        reachable: ``start`` | ``largest`` | ``all``: the scene's free space (and the
            ground truth scored) is cut to the cells reachable from the house's start pose
            (``metadata.agent.position``; the largest component when the house has none), to
            the largest 4-connected component, or kept whole
            (:mod:`envs.maps.reachable`).

    Houses that cannot be read (a line that is not valid JSON) or fail validation (an
    unmapped room type, a map over ``max_map_pixels``, ...) are kept as ids: :meth:`house`
    and :meth:`scene` raise their :class:`~envs.world.house.HouseError`, so a sweep records
    the failure for that house alone.
    """

    def __init__(
        self,
        path: str | None = None,
        start: Annotated[int, Integer(0)] = 0,
        stop: Annotated[int | None, Integer(0)] = None,
        split: str | None = None,
        dataset: str = "procthor-10k",
        resolution: Annotated[float, Positive()] = 0.05,
        wall_thickness: Annotated[float, NonNegative()] = 0.1,
        clearance: Annotated[float, NonNegative()] = 0.0,
        max_object_base: Annotated[float, NonNegative()] = 0.5,
        classes: list[str] | tuple[str, ...] = PAPER_CLASSES,
        room_types: Mapping[str, str | None] | None = None,
        max_map_pixels: Annotated[int | None, Integer(1)] = MAX_MAP_PIXELS,
        name: str = "procthor",
        occupancy: str = "floorplan",
        thor: dict | None = None,
        reachable: Annotated[str, OneOf(*REACHABLE_RULES)] = "start",
    ):
        if occupancy not in ("floorplan", "ai2thor"):
            raise ValueError(f"occupancy must be 'floorplan' or 'ai2thor', got {occupancy!r}")
        self.name, self.occupancy, self.thor = name, occupancy, dict(thor or {})
        self.reachable = check_rule(reachable)
        self._renderer = None
        self.classes = tuple(classes)
        self.room_types = room_type_mapping(room_types)
        self.raster = dict(resolution=resolution, wall_thickness=wall_thickness,
                           clearance=clearance, max_object_base=max_object_base, classes=self.classes,
                           room_types=self.room_types,
                           max_map_pixels=check_max_map_pixels(max_map_pixels, "env.max_map_pixels"))
        if path is None:
            records = prior_records(load_prior_dataset(dataset), dataset, split or "train", start, stop)
        else:
            records = read_house_records(Path(path).expanduser(), start, stop, split=split)
        self._records: dict[str, HouseRecord] = {r.id: r for r in records}

    def house_ids(self) -> list[str]:
        return list(self._records)

    def house(self, house_id: str) -> House:
        """The house, validated (``data`` is the dict exactly as read).

        Returns:
            :class:`House`; raises :class:`HouseError` for an unreadable or invalid house.
        """
        if house_id not in self._records:
            raise KeyError(f"no house {house_id!r} in environment {self.name!r}")
        return self._records[house_id].house(room_types=self.room_types, classes=self.classes)

    def scene(self, house_id: str) -> Scene:
        """The house rasterised (or on AI2-THOR's reachable positions), cut to the reachable
        area of ``reachable``."""
        house = self.house(house_id)
        scene = rasterise_house(house, **self.raster)
        if self.occupancy == "ai2thor":
            from envs.render.thor import AI2THORRenderer, reachable_grid  # noqa: PLC0415

            if self._renderer is None:
                self._renderer = AI2THORRenderer(**self.thor)
            grid = reachable_grid(self._renderer.reachable_positions(house), self._renderer.grid_size,
                                  self.raster["resolution"])
            scene = scene_on_grid(scene, grid)
        return restrict_scene(scene, self.reachable, start_points(house.data))


__all__ = ["ProcTHOREnv", "HouseError"]
