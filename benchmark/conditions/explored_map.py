"""``mapping=explored``: the map the exploring robot built for itself.

Under ``viewpoints=frontier`` the robot explores with its own laser and log-odds map
(:class:`benchmark.conditions.exploration.Frontier`). With this mapping stage every method,
the geometric segmenters and the sanity rows included, gets that very map instead of the
house's floor plan: its free cells (occupancy probability below ``free_thresh`` of the
explorer's scanner, ROS ``map_server``'s rule) that are 4-connected to a view
(:mod:`envs.maps.reachable`'s rule, as ``mapping=scan``). A cell is free in that map once the
laser has crossed it often enough (four misses at the default log-odds), while the explorer
plans on any cell crossed once, so the map trails the robot's knowledge by a few scans. Where the robot never looked the
map is unknown, so rooms it never saw get no label and count as missed in matched IoU and PQ;
the row's ``rooms_mapped`` (of ``rooms_total``) says how many rooms the map reaches.

It needs the exploration itself (the harness passes it: ``exploration``, an
:class:`benchmark.conditions.exploration.Exploration` whose ``scan_map`` is set), so it works
with an exploring viewpoints stage only; a SLAM pose error that places the scans at its
estimate is not modelled for the explorer's map (use ``mapping=scan``).
"""

from __future__ import annotations

import numpy as np

from benchmark.conditions.exploration import no_view_on_own_map
from envs.maps.gridmap import GridMap
from envs.maps.reachable import reachable_mask, seed_cells
from envs.maps.scene import Scene


class ExploredMapping:
    """``mapping=explored``: the free cells of the exploring robot's own map (module docstring).

    The map's scanner is the explorer's (``viewpoints.sensor_range``, ``scan_height``, ...);
    this stage has no settings of its own."""

    #: the harness passes this stage the exploration that made the views.
    uses_exploration = True
    #: no scanner of its own (a SLAM estimate and closed doors are the scan mapping's).
    settings = None

    def __call__(self, scene: Scene, poses: np.ndarray, house=None, estimate=None, exploration=None) -> np.ndarray:
        """(H, W) bool free cells of the explorer's map reachable from its views.

        Args:
            poses: (N, 3) the views (x, z metres, yaw degrees), those of ``exploration``.
            exploration: what the exploring viewpoints stage did (its ``scan_map`` is used).

        Raises:
            ValueError: no exploration map (the viewpoints do not explore), or a SLAM estimate."""
        if estimate is not None:
            raise ValueError("mapping=explored: a SLAM pose error that places the scans (pose_error=odometry) is not "
                             "modelled for the explorer's own map; expected mapping=scan with it")
        scan = getattr(exploration, "scan_map", None)
        if scan is None:
            raise ValueError("mapping=explored: the viewpoints stage made no map of its own; expected an exploring "
                             "viewpoints stage (viewpoints=frontier)")
        free = np.asarray(scan.free, bool)
        if free.shape != scene.grid.shape:
            raise ValueError(f"mapping=explored: the explorer's map is {free.shape}, expected the house's grid "
                             f"{scene.grid.shape}")
        no_view = no_view_on_own_map(exploration, scene)  # a budget too short: say the smallest that works
        if no_view is not None:
            raise ValueError(no_view)
        grid = GridMap(free, scene.grid.resolution, scene.grid.origin)
        return reachable_mask(free, seed_cells(grid, np.asarray(poses)[:, :2]))


__all__ = ["ExploredMapping"]
