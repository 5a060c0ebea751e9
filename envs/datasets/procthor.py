"""ProcTHOR houses from a local house file or from AI2's ``prior`` package."""

from __future__ import annotations

from pathlib import Path

from envs.datasets.base import Environment
from envs.maps.scene import Scene, rasterise_house, scene_on_grid
from envs.world.classes import PAPER_CLASSES
from envs.world.house import House, HouseError, iter_house_file, load_prior_houses, validate_house


class ProcTHOREnv(Environment):
    """ProcTHOR-schema houses, rasterised on demand.

    Args:
        path: a ``.json``/``.jsonl``/``.jsonl.gz`` house file; ``None`` loads
            ``prior.load_dataset(dataset)`` (needs network and ``roomseg-bench[thor]``).
        start, stop: index range of houses (the paper: train[0:100]).
        split, dataset: for ``prior`` only.
        resolution, wall_thickness, clearance, max_object_base: rasterisation parameters
            (metres per pixel, metres, metres, metres); see :func:`envs.maps.scene.rasterise_house`.
        classes: ordered class list.
        name: dataset name in tables.
        occupancy: "floorplan" (rasterised from the house) or "ai2thor" (AI2-THOR's
            reachable positions, ``thor`` = keyword arguments of the AI2-THOR renderer;
            needs the simulator); the ground truth is carried onto that map.

    Houses that fail validation are kept as ids: :meth:`scene` raises their
    :class:`~envs.world.house.HouseError`, so a sweep records the failure for that house alone.
    """

    def __init__(
        self,
        path: str | None = None,
        start: int = 0,
        stop: int | None = None,
        split: str = "train",
        dataset: str = "procthor-10k",
        resolution: float = 0.05,
        wall_thickness: float = 0.1,
        clearance: float = 0.0,
        max_object_base: float = 0.5,
        classes: list[str] | tuple[str, ...] = PAPER_CLASSES,
        name: str = "procthor",
        occupancy: str = "floorplan",
        thor: dict | None = None,
    ):
        if occupancy not in ("floorplan", "ai2thor"):
            raise ValueError(f"occupancy must be 'floorplan' or 'ai2thor', got {occupancy!r}")
        self.name, self.occupancy, self.thor = name, occupancy, dict(thor or {})
        self._renderer = None
        self.raster = dict(resolution=resolution, wall_thickness=wall_thickness,
                           clearance=clearance, max_object_base=max_object_base, classes=tuple(classes))
        if path is None:
            houses = load_prior_houses(dataset, split, start, stop, validate=False)
        else:
            p = Path(path).expanduser()
            houses = []
            for i, h in enumerate(iter_house_file(p, validate=False)):
                if stop is not None and i >= stop:
                    break
                if i >= start:
                    houses.append(h)
        self._houses: dict[str, House] = {h.id: h for h in houses}

    def house_ids(self) -> list[str]:
        return list(self._houses)

    def house(self, house_id: str) -> House:
        if house_id not in self._houses:
            raise KeyError(f"no house {house_id!r} in environment {self.name!r}")
        h = self._houses[house_id]
        validate_house(h.data, h.id)
        return h

    def scene(self, house_id: str) -> Scene:
        house = self.house(house_id)
        scene = rasterise_house(house, **self.raster)
        if self.occupancy == "floorplan":
            return scene
        from envs.render.thor import AI2THORRenderer, reachable_grid  # noqa: PLC0415

        if self._renderer is None:
            self._renderer = AI2THORRenderer(**self.thor)
        grid = reachable_grid(self._renderer.reachable_positions(house), self._renderer.grid_size,
                              self.raster["resolution"])
        return scene_on_grid(scene, grid)


__all__ = ["ProcTHOREnv", "HouseError"]
