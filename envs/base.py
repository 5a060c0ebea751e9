"""The environment interface: a set of houses, each with a ProcTHOR-schema dict and a Scene."""

from __future__ import annotations

from abc import ABC, abstractmethod

from envs.house import House
from envs.scene import Scene


class Environment(ABC):
    """A dataset of houses. Configured from ``conf/env/*.yaml`` via ``_target_``."""

    #: short dataset name used in tables (e.g. "procthor", "synthetic").
    name: str = "env"

    @abstractmethod
    def house_ids(self) -> list[str]:
        """Ids of the houses in this environment, in a fixed order."""

    @abstractmethod
    def house(self, house_id: str) -> House:
        """The ProcTHOR-schema house (what simulators and the floorplan renderer load)."""

    @abstractmethod
    def scene(self, house_id: str) -> Scene:
        """The occupancy map and ground truth of one house."""
