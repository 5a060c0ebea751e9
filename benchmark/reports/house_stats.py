"""Statistics of generated houses beside the shared ProcTHOR houses, and a grid figure.

``python -m benchmark.commands.house_stats [--synthetic 200] [--procthor FILE] [--figure docs/figures/synthetic_grid.png]``
prints rooms per house, room area per class (square metres, from the floor polygons) and
top-level objects per room, as Markdown, one column per source; and the generation time.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from benchmark.reports.plotting import add_legend, save, show_map
from envs.maps.scene import rasterise_house, room_polygon_areas
from envs.world.classes import ROOM_TYPE_TO_CLASS
from envs.world.house import House


def stats(houses: list[House]) -> dict[str, str]:
    """Mean ± std of rooms per house, objects per room, and room area per class."""
    rooms = [len(h.rooms) for h in houses]
    out = {"houses": f"{len(houses)}", "rooms per house": f"{np.mean(rooms):.2f} ± {np.std(rooms):.2f}"}
    per_room_objects, areas = [], {}
    for h in houses:
        scene = rasterise_house(h, resolution=0.1)
        counts = np.zeros(len(h.rooms))
        for o in scene.objects:
            r, c = scene.grid.world_to_cell(*o.center)
            if scene.grid.in_bounds(r, c) and scene.rooms[r, c] >= 0:
                counts[scene.rooms[r, c]] += 1
        per_room_objects += counts.tolist()
        for room, a in zip(h.rooms, room_polygon_areas(h)):
            areas.setdefault(ROOM_TYPE_TO_CLASS[room["roomType"]], []).append(a)
    out["objects per room"] = f"{np.mean(per_room_objects):.2f} ± {np.std(per_room_objects):.2f}"
    for cls in sorted(set(ROOM_TYPE_TO_CLASS.values())):
        v = areas.get(cls, [])
        out[f"{cls} area m² (rooms/house)"] = (f"{np.mean(v):.1f} ± {np.std(v):.1f} ({len(v) / len(houses):.2f})"
                                               if v else "–")
    return out


def grid_figure(houses: list[House], path: Path, cols: int = 4) -> None:
    rows = int(np.ceil(len(houses) / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(3.4 * cols, 3.0 * rows))
    for ax, h in zip(np.ravel(axes), houses):
        s = rasterise_house(h, resolution=0.05)
        show_map(ax, s.semantic, s.classes, s.rooms >= 0, s.grid.resolution,
                 f"{h.id} ({h.data['metadata']['shape']}, open: {len(h.data['metadata']['openPlan'])})")
        ax.title.set_fontsize(7)
    for ax in np.ravel(axes)[len(houses):]:
        ax.axis("off")
    add_legend(np.ravel(axes)[cols - 1], houses and rasterise_house(houses[0], resolution=0.2).classes)
    save(fig, path)
