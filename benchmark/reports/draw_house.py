"""Draw one house: occupancy map, ground truth in class colours, room names, legend, scale bar.

``python -m benchmark.commands.draw_house --houses FILE --index 0 --out docs/figures/house.png``
"""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from benchmark.reports.plotting import (
    BORDER_COLOR,
    add_legend,
    add_scale_bar,
    colorize,
    save,
    segment_borders,
)
from envs.maps.scene import Scene

#: colour (RGB) of pixels inside a room that are not walkable (furniture, wall bands): not
#: the grey of unlabelled walkable pixels, so that one grey means one thing in every figure.
IN_ROOM_NOT_WALKABLE = (105, 105, 105)


def draw_scene(scene: Scene, path: str | Path) -> None:
    """Two panels: the walkable map, and the ground truth with room names and borders
    between touching rooms (PNG, or any suffix matplotlib writes)."""
    fig, axes = plt.subplots(1, 2, figsize=(11, 5.2))
    axes[0].imshow(scene.grid.walkable, cmap="gray", interpolation="nearest")
    axes[0].set_title(f"{scene.house_id}: walkable map", fontsize=10)
    rgb = colorize(scene.semantic, scene.classes, scene.grid.walkable).copy()
    rgb[(scene.rooms >= 0) & ~scene.grid.walkable] = IN_ROOM_NOT_WALKABLE
    rgb[segment_borders(scene.instances)] = BORDER_COLOR
    axes[1].imshow(rgb, interpolation="nearest")
    axes[1].set_title("ground truth", fontsize=10)
    for i, rid in enumerate(scene.room_ids):
        rr, cc = np.nonzero(scene.instances == i)
        if len(rr):
            name = scene.classes[int(scene.instance_classes[i])].replace("_", " ")
            axes[1].text(np.median(cc), np.median(rr), f"{name}\n{rid}", ha="center", va="center", fontsize=7,
                         bbox=dict(facecolor="white", alpha=0.7, pad=1, lw=0))
    for ax in axes:
        ax.set_xticks([])
        ax.set_yticks([])
        add_scale_bar(ax, scene.grid.resolution, color="white", outline="black")
    add_legend(axes[1], scene.classes, unlabelled=False,
               extra=[("in a room, not walkable", IN_ROOM_NOT_WALKABLE), ("border between rooms", BORDER_COLOR)])
    save(fig, path)
