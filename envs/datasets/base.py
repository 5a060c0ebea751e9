"""The environment contract: a set of houses, each with a ProcTHOR-schema dict and a Scene."""

from __future__ import annotations

from typing import Protocol, runtime_checkable

from envs.maps.scene import Scene
from envs.world.house import House


@runtime_checkable
class Environment(Protocol):
    """A dataset of houses, configured from ``conf/env/*.yaml`` via ``_target_``.

    The bundled environments subclass it; a user's own needs only the three methods and
    a ``name``.
    """

    #: short dataset name used in tables (e.g. "procthor", "synthetic").
    name: str = "env"

    def house_ids(self) -> list[str]:
        """Ids of the houses in this environment, in a fixed order."""
        ...

    def house(self, house_id: str) -> House:
        """The ProcTHOR-schema house (what simulators and the floorplan renderer load)."""
        ...

    def scene(self, house_id: str) -> Scene:
        """The occupancy map and ground truth of one house."""
        ...
