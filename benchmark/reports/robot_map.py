"""Figure: a house's floor-plan map beside the maps a robot builds, with its path and views.

Three panels: the floor plan (ground truth in class colours, as ``draw_house`` shows it), the
scan map built along the autotrace views' trajectory, and the map a frontier-exploring robot
built itself, with the path it drove and the views it captured. Scan maps show free, occupied
and unknown cells in three colours (:data:`SCAN_COLORS`).
"""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.patches import Patch

from benchmark.reports.plotting import (
    BORDER_COLOR,
    add_scale_bar,
    colorize,
    draw_poses,
    save,
    segment_borders,
)
from envs.maps.scan import FREE, OCCUPIED, UNKNOWN, ScanMap
from envs.maps.scene import Scene

#: RGB of free, occupied and unknown scan-map cells.
SCAN_COLORS = {FREE: (250, 250, 250), OCCUPIED: (20, 20, 20), UNKNOWN: (150, 170, 205)}
#: RGB of in-room cells that are not walkable on the floor plan (as ``draw_house``).
IN_ROOM_NOT_WALKABLE = (105, 105, 105)


def scan_rgb(scan: ScanMap) -> np.ndarray:
    """(H, W, 3) uint8 picture of a scan map in :data:`SCAN_COLORS`."""
    rgb = np.zeros((*scan.occupancy.shape, 3), np.uint8)
    for value, color in SCAN_COLORS.items():
        rgb[scan.occupancy == value] = color
    return rgb


def draw_robot_map(scene: Scene, scan: ScanMap, trajectory: np.ndarray, explored: ScanMap, path: np.ndarray,
                   views: np.ndarray, out: str | Path, titles: tuple[str, str, str]) -> list:
    """Save the three-panel figure (module docstring).

    Args:
        scene: the house on its grid.
        scan: the scan map along ``trajectory`` ((M, 3) scan poses, x, z metres).
        explored: the frontier robot's own map; ``path`` (K, 2) world (x, z) it drove;
            ``views`` (N, 3) the views it captured.
        out: the figure file.
        titles: the three panel titles.

    Returns:
        the paths written.
    """
    grid = scene.grid
    fig, axes = plt.subplots(1, 3, figsize=(15, 5.4))
    rgb = colorize(scene.semantic, scene.classes, grid.walkable).copy()
    rgb[(scene.rooms >= 0) & ~grid.walkable] = IN_ROOM_NOT_WALKABLE
    rgb[segment_borders(scene.instances)] = BORDER_COLOR
    axes[0].imshow(rgb, interpolation="nearest")
    axes[1].imshow(scan_rgb(scan), interpolation="nearest")
    tr, tc = grid.world_to_pixel(trajectory[:, 0], trajectory[:, 1])
    axes[1].plot(tc - 0.5, tr - 0.5, color=(0.85, 0.37, 0.0), lw=0.8)
    axes[2].imshow(scan_rgb(explored), interpolation="nearest")
    pr, pc = grid.world_to_pixel(path[:, 0], path[:, 1])
    axes[2].plot(pc - 0.5, pr - 0.5, color=(0.85, 0.37, 0.0), lw=1.0)
    vr, vc = grid.world_to_pixel(views[:, 0], views[:, 1])
    draw_poses(axes[2], vr - 0.5, vc - 0.5, views[:, 2], colors=[(0.0, 0.45, 0.7)], size=6.0, arrow_px=8.0)
    axes[2].scatter([pc[0] - 0.5], [pr[0] - 0.5], s=40, marker="*", c=[(0.8, 0.1, 0.1)], zorder=4)
    for ax, title in zip(axes, titles):
        ax.set_title(title, fontsize=9)
        ax.set_xticks([])
        ax.set_yticks([])
        add_scale_bar(ax, grid.resolution, color="white", outline="black")
    handles = [Patch(color=np.array(SCAN_COLORS[v]) / 255, label=name)
               for v, name in ((FREE, "free"), (OCCUPIED, "occupied"), (UNKNOWN, "unknown"))]
    handles += [plt.Line2D([], [], color=(0.85, 0.37, 0.0), label="path driven"),
                plt.Line2D([], [], marker="o", ls="", color=(0.0, 0.45, 0.7), label="views"),
                plt.Line2D([], [], marker="*", ls="", color=(0.8, 0.1, 0.1), label="start")]
    fig.legend(handles=handles, loc="lower center", ncol=6, fontsize=8, frameon=False)
    return save(fig, out)
