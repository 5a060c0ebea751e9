"""Shared figure helpers: class colours, legend, scale bar, map display (matplotlib)."""

from __future__ import annotations

from collections.abc import Sequence

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib import patheffects  # noqa: E402
from matplotlib.patches import Patch, Rectangle  # noqa: E402

from envs.maps.label_png import label_colors_rgb  # noqa: E402
from envs.world.classes import UNLABELLED_COLOR, class_colors  # noqa: E402


def colorize(labels: np.ndarray, classes: Sequence[str], walkable: np.ndarray | None = None) -> np.ndarray:
    """(H, W) label map -> (H, W, 3) uint8 RGB in the fixed class colours (-1: grey on
    walkable pixels, black elsewhere)."""
    return label_colors_rgb(labels, classes, walkable)


def add_legend(ax, classes: Sequence[str], unlabelled: bool = True, unlabelled_label: str = "unlabelled",
               **kw) -> None:
    """Class colour legend on ``ax`` (outside the axes, right); ``unlabelled_label`` names the
    grey of -1 pixels on walkable ground."""
    handles = [Patch(color=np.array(c) / 255, label=n.replace("_", " ")) for c, n in zip(class_colors(classes), classes)]
    if unlabelled:
        handles.append(Patch(color=np.array(UNLABELLED_COLOR) / 255, label=unlabelled_label))
    opts = dict(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
    opts.update(kw)
    ax.legend(handles=handles, **opts)


def add_scale_bar(ax, resolution: float, length_m: float | None = None, color: str = "white",
                  outline: str = "black") -> None:
    """A scale bar of ``length_m`` metres (default: a round length near 1/5 of the width)
    in the lower-left corner of an image axis drawn at ``resolution`` metres per pixel;
    bar and text are edged in ``outline`` so they show on any map colour."""
    if not resolution or resolution <= 0:
        raise ValueError(f"scale bar needs a resolution > 0 (metres per pixel), got {resolution}")
    x0, x1 = sorted(ax.get_xlim())
    y_lo, y_hi = sorted(ax.get_ylim())
    width_m = (x1 - x0) * resolution
    if length_m is None:
        target = width_m / 5
        length_m = max(v for v in (0.5, 1, 2, 5, 10, 20, 50) if v <= max(target, 0.5))
    px = length_m / resolution
    pad = 0.04 * (x1 - x0)
    y = y_hi - pad
    ax.add_patch(Rectangle((x0 + pad, y - 0.012 * (y_hi - y_lo)), px, 0.012 * (y_hi - y_lo), facecolor=color,
                           edgecolor=outline, linewidth=0.8, zorder=4))
    ax.text(x0 + pad + px / 2, y - 0.02 * (y_hi - y_lo), f"{length_m:g} m", color=color, ha="center",
            va="bottom", fontsize=8, zorder=4, path_effects=[patheffects.withStroke(linewidth=2, foreground=outline)])


def show_map(ax, labels: np.ndarray, classes: Sequence[str], walkable: np.ndarray | None = None,
             resolution: float | None = None, title: str | None = None) -> None:
    """Draw a label map in class colours (with a scale bar when ``resolution`` is given)."""
    ax.imshow(colorize(labels, classes, walkable), interpolation="nearest")
    ax.set_xticks([])
    ax.set_yticks([])
    if title:
        ax.set_title(title, fontsize=10)
    if resolution:
        add_scale_bar(ax, resolution)


def draw_poses(ax, rows: np.ndarray, cols: np.ndarray, yaw_deg: np.ndarray | None = None,
               colors=None, size: float = 8.0, arrow_px: float = 6.0) -> None:
    """Viewpoints on a map axis: dots at (row, col), with short heading arrows when ``yaw_deg``."""
    ax.scatter(cols, rows, s=size, c=colors if colors is not None else "k", edgecolors="k", linewidths=0.3,
               zorder=3)
    if yaw_deg is not None:
        a = np.deg2rad(yaw_deg)
        ax.quiver(cols, rows, np.sin(a) * arrow_px, -np.cos(a) * arrow_px, angles="xy", scale_units="xy",
                  scale=1, width=0.002, color="k", zorder=3)


def save(fig, path) -> None:
    """Save and close a figure (creates the folder)."""
    from pathlib import Path

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=130, bbox_inches="tight")
    plt.close(fig)
