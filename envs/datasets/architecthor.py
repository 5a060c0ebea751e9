"""The ArchitecTHOR houses: 10 human-designed houses (5 validation, 5 test) rendered by
Habitat-Sim (ai2thor-hab) or AI2-THOR, with ground truth from annotation folders
(:mod:`envs.maps.annotations`).

There is no ProcTHOR house JSON for these houses here: :meth:`ArchitecTHOREnv.house`
returns a :class:`~envs.world.house.House` whose data is ``{"scene": name}``, which both
simulator renderers load by name (AI2-THOR scene ``ArchitecTHOR-Val-00``, ai2thor-hab scene
id ``ArchitecTHOR-Val-00``). The floorplan renderer needs a house dict and cannot render them.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Annotated

from envs.datasets.base import Environment
from envs.maps.reachable import RULES as REACHABLE_RULES
from envs.maps.reachable import check_rule, restrict_scene
from envs.maps.scene import Scene
from envs.ranges import OneOf
from envs.world.classes import PAPER_CLASSES
from envs.world.house import House

#: The 10 ArchitecTHOR houses as AI2-THOR (5.0 names) and ai2thor-hab name them.
ARCHITECTHOR_SCENES = tuple([f"ArchitecTHOR-Val-{i:02d}" for i in range(5)] +
                            [f"ArchitecTHOR-Test-{i:02d}" for i in range(5)])


class ArchitecTHOREnv(Environment):
    """Args: annotations (root folder with one annotation folder per house, named as the
    house), houses (names; each must be one of :data:`ARCHITECTHOR_SCENES`), classes,
    name (dataset name in tables), reachable (``largest`` | ``start`` | ``all``,
    :mod:`envs.maps.reachable`: the annotations carry no start pose, so ``start`` is the
    largest 4-connected component too)."""

    def __init__(self, annotations: str, houses: Sequence[str] = ARCHITECTHOR_SCENES,
                 classes: Sequence[str] = PAPER_CLASSES, name: str = "architecthor",
                 reachable: Annotated[str, OneOf(*REACHABLE_RULES)] = "largest"):
        names = list(houses)
        unknown = [h for h in names if h not in ARCHITECTHOR_SCENES]
        if unknown:
            raise ValueError(f"unknown ArchitecTHOR house(s) {unknown}; expected names from {list(ARCHITECTHOR_SCENES)}")
        if len(set(names)) != len(names) or not names:
            raise ValueError(f"ArchitecTHOR houses must be a non-empty list without repeats, got {names}")
        self.root, self.names, self.classes, self.name = Path(annotations).expanduser(), names, tuple(classes), name
        self.reachable = check_rule(reachable)

    def house_ids(self) -> list[str]:
        return list(self.names)

    def house(self, house_id: str) -> House:
        """A House with data ``{"scene": house_id}`` (renderers load the scene by name)."""
        if house_id not in self.names:
            raise KeyError(f"no house {house_id!r} in environment {self.name!r}")
        return House(house_id, {"scene": house_id})

    def scene(self, house_id: str) -> Scene:
        """The annotated map and ground truth of one house (``<annotations>/<house_id>/``)."""
        from envs.maps.annotations import load_annotation  # noqa: PLC0415

        if house_id not in self.names:
            raise KeyError(f"no house {house_id!r} in environment {self.name!r}")
        return restrict_scene(load_annotation(self.root / house_id, house_id, self.classes), self.reachable)

    def input_files(self, house_id: str) -> list[Path]:
        """The annotation files the scene of ``house_id`` is read from (the run's caches follow
        their content: editing an annotation recomputes that house)."""
        folder = self.root / house_id
        return sorted(p for p in folder.iterdir() if p.is_file()) if folder.is_dir() else []

    def missing(self) -> list[str]:
        """Houses whose annotation folder has no ``labels.png`` yet."""
        return [h for h in self.names if not (self.root / h / "labels.png").is_file()]
