"""The ArchitecTHOR houses: scenes rendered by AI2-THOR (by name) or Habitat-Sim
(ai2thor-hab), ground truth from annotation folders (:mod:`envs.annotations`)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from envs.base import Environment
from envs.classes import PAPER_CLASSES
from envs.house import House
from envs.scene import Scene

#: The 10 ArchitecTHOR houses as AI2-THOR names them (5 validation, 5 test).
ARCHITECTHOR_SCENES = tuple([f"ArchitecTHOR-Val-{i:02d}" for i in range(5)] +
                            [f"ArchitecTHOR-Test-{i:02d}" for i in range(5)])


class ArchitecTHOREnv(Environment):
    """Args: annotations (root with one annotation folder per house), houses (names),
    classes. ``house()`` returns a House whose data is ``{"scene": name}`` (renderers load
    the scene by name); ``scene()`` reads the annotation, one clear error when it is missing."""

    def __init__(self, annotations: str, houses: Sequence[str] = ARCHITECTHOR_SCENES,
                 classes: Sequence[str] = PAPER_CLASSES, name: str = "architecthor"):
        self.root, self.names, self.classes, self.name = Path(annotations), list(houses), tuple(classes), name

    def house_ids(self) -> list[str]:
        return list(self.names)

    def house(self, house_id: str) -> House:
        if house_id not in self.names:
            raise KeyError(f"no house {house_id!r} in environment {self.name!r}")
        return House(house_id, {"scene": house_id})

    def scene(self, house_id: str) -> Scene:
        from envs.annotations import load_annotation  # noqa: PLC0415

        return load_annotation(self.root / house_id, house_id, self.classes)
