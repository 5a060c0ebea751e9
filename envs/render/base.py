"""The renderer contract: what the camera sees at each pose.

A renderer is any object with ``render(house, scene, poses) -> list[Observation]``; the
floorplan, AI2-THOR and Habitat renderers state it by subclassing :class:`Renderer`, a
user's own renderer need not (it is a :class:`typing.Protocol`).
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

from envs.maps.scene import Scene
from envs.render.observation import Observation
from envs.world.house import House


@runtime_checkable
class Renderer(Protocol):
    """What the camera sees at each pose."""

    def render(self, house: House, scene: Scene, poses: np.ndarray) -> list[Observation]:
        """One :class:`Observation` per pose, in pose order.

        Args:
            house: the ProcTHOR-schema house (simulators load it; may be ignored).
            scene: its occupancy map and ground truth.
            poses: (N, 3) float, world x, z (metres) and yaw (degrees, simulator convention).

        Returns:
            list of N observations; a pose the renderer cannot reach gives an observation
            with ``meta["refused"] = True`` (and no image) instead of raising.
        """
        ...
