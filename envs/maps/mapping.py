"""The ``mapping`` stage: which occupancy map the methods and the geometric segmenters see.

Without it (``mapping: null``, the default) they see the house's floor plan, rasterised
(:mod:`envs.maps.scene`): the perfect robot. ``mapping=scan`` (:class:`ScanMapping`) gives them
the map a 2D laser builds along the robot's path through its views instead
(:func:`envs.maps.scan.robot_scan_map`: what it models and leaves out is written there): free
cells 4-connected to the robot's views are walkable (:mod:`envs.maps.reachable`'s rule: a free
pocket the laser saw under a table is not), unknown and occupied ones are not. The ground truth, and the area scored,
stay the house's.

A mapping stage is any object with ``__call__(scene, poses, house=None) -> (H, W) bool`` free
cells on the scene's grid; the harness caches its output per house, views and settings.
"""

from __future__ import annotations

from typing import Annotated

import numpy as np

from envs.maps.gridmap import GridMap
from envs.maps.reachable import reachable_mask, seed_cells
from envs.maps.scan import (
    DEFAULT_WALL_HEIGHT,
    ScanSettings,
    house_wall_height,
    robot_scan_map,
    scan_plane,
    surface_shares,
)
from envs.maps.scene import Scene
from envs.maps.slam_map import scan_map_at_estimate
from envs.ranges import OneOf

#: where a scan-mapping robot drives: along its views, or along its own exploration.
ROUTES = ("views", "explore")


class ScanMapping:
    """``mapping=scan``: the free cells of the map a laser builds along the robot's views.

    Args:
        route: ``views``: the scans are taken along the views' path (the default); ``explore``:
            along the route of a frontier exploration with no budget, the mapping run a robot
            makes before it is asked anything (one pose a metre driven; the harness makes the
            route, :func:`benchmark.conditions.exploration.exploration_route`, and passes it
            as ``poses``). A sparser route than a dense view path: each place is scanned fewer
            times, so the scanner's noise stays in the map.
        **settings: the fields of :class:`envs.maps.scan.ScanSettings` (scan height, max range,
            angular step, range noise, dropout, scan spacing, thresholds, log-odds, seed), each
            checked (one line naming ``mapping.<key>``, its value and the expected range).
    """

    #: the dataclass ``**settings`` go to: the configuration check
    #: (``benchmark.harness.typed.check_targets``) takes its fields, with their types and
    #: ranges, for the keys of ``mapping``.
    SETTINGS = ScanSettings

    def __init__(self, route: Annotated[str, OneOf(*ROUTES)] = "views", **settings):
        if route not in ROUTES:
            raise ValueError(f"mapping.route={route!r}: expected one of {', '.join(ROUTES)}")
        self.route = route
        unknown = sorted(set(settings) - set(ScanSettings.__dataclass_fields__))
        if unknown:
            raise ValueError(f"mapping: unknown setting(s) {unknown}; expected {sorted(ScanSettings.__dataclass_fields__)}")
        self.settings = ScanSettings(**settings).check({k: f"mapping.{k}" for k in ScanSettings.__dataclass_fields__})

    def __call__(self, scene: Scene, poses: np.ndarray, house=None,
                 estimate: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None) -> np.ndarray:
        """(H, W) bool free cells of the scan map built along ``poses`` (capture order), those
        4-connected to a view (a view within 1 m of free space snaps to it).

        Args:
            estimate: a SLAM robot's ``(true (M, 3), estimated (M, 3), view index (N,))`` scan
                poses (:class:`benchmark.conditions.slam.OdometrySlam`): scans are measured at the true
                poses and inserted at the estimated ones
                (:func:`envs.maps.slam_map.scan_map_at_estimate`), and the views' estimated
                positions seed the reachable area. None: scans at the true poses.

        Raises:
            ValueError: the scan plane is not below the house's walls (one line)."""
        wall = house_wall_height(house) if house is not None else DEFAULT_WALL_HEIGHT
        if not self.settings.height < wall:
            raise ValueError(f"mapping.height = {self.settings.height!r}: expected metres below the house's walls "
                             f"({wall:g} m)")
        if estimate is not None:
            true, est, views = (np.asarray(a) for a in estimate)
            obstacles = scan_plane(scene, self.settings, wall)  # walls, furniture, legs, closed doors
            surfaces = surface_shares(scene, self.settings.height) if self.settings.surface_dropout > 0 else None
            scan = scan_map_at_estimate(obstacles, scene.grid, true, est, self.settings, surfaces)
            grid = GridMap(scan.free, scene.grid.resolution, scene.grid.origin)
            return reachable_mask(scan.free, seed_cells(grid, est[views][:, :2]))
        scan, _ = robot_scan_map(scene, poses, self.settings, wall)
        # free pockets the laser saw but the robot cannot drive to (under a table, behind a
        # ring of chairs) are left out, as the environment's reachable-area rule does
        grid = GridMap(scan.free, scene.grid.resolution, scene.grid.origin)
        return reachable_mask(scan.free, seed_cells(grid, np.asarray(poses)[:, :2]))


__all__ = ["ROUTES", "ScanMapping"]
