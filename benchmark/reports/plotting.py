"""Shared figure helpers: class colours, legend, scale bar, segment borders, map display,
saving in several formats (matplotlib).

Colours come from one place, :data:`envs.world.classes.CLASS_COLORS` (Okabe-Ito, colour-blind
safe); every legend names the grey of unlabelled walkable pixels the same way
(:data:`UNLABELLED_LABEL`). Borders are drawn between touching segments, so two rooms of the
same class that touch show as two rooms.
"""

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

#: legend words for the grey of unlabelled walkable pixels (every figure).
UNLABELLED_LABEL = "unlabelled (walkable)"
#: colour (RGB 0-255) of the lines between touching segments.
BORDER_COLOR: tuple[int, int, int] = (25, 25, 25)
#: dots per inch of every PNG (vector formats ignore it).
PNG_DPI = 200
#: zlib level of every PNG: 1 writes them about 3x faster than the default 6 for files about
#: a quarter larger (`make bench`'s 20 figures: 2.4 MB instead of 1.9 MB).
PNG_COMPRESS_LEVEL = 1
#: the formats ``save`` knows.
FORMATS = ("png", "pdf", "svg")


def parse_formats(text: str | Sequence[str] | None) -> tuple[str, ...]:
    """``"png,pdf"`` (or a list) -> ("png", "pdf"); an unknown format is one-line error."""
    if text is None:
        return ("png",)
    items = [t.strip().lower().lstrip(".") for t in (text.split(",") if isinstance(text, str) else text)]
    items = [t for t in items if t]
    bad = [t for t in items if t not in FORMATS]
    if bad or not items:
        raise ValueError(f"--format {text!r}: expected a comma-separated list of {', '.join(FORMATS)}")
    return tuple(dict.fromkeys(items))


def segment_borders(segments: np.ndarray) -> np.ndarray:
    """(H, W) bool: pixels on a border between two different segments.

    ``segments`` (H, W) int, one id per segment, negative outside any (walls, background:
    no border is drawn against them). A pixel is a border pixel when its right or lower
    neighbour belongs to another segment, so a border is one pixel wide.
    """
    s = np.asarray(segments)
    out = np.zeros(s.shape, bool)
    right = (s[:, :-1] != s[:, 1:]) & (s[:, :-1] >= 0) & (s[:, 1:] >= 0)
    down = (s[:-1, :] != s[1:, :]) & (s[:-1, :] >= 0) & (s[1:, :] >= 0)
    out[:, :-1] |= right
    out[:-1, :] |= down
    return out


def label_segments(labels: np.ndarray) -> np.ndarray:
    """(H, W) int segment ids of a label map: connected regions (4-connected) of one label;
    -1 where the label is negative (the metrics' own segments, :func:`benchmark.metrics.segments`)."""
    from benchmark.metrics import segments

    return segments(labels, connectivity=4)


def colorize(labels: np.ndarray, classes: Sequence[str], walkable: np.ndarray | None = None) -> np.ndarray:
    """(H, W) label map -> (H, W, 3) uint8 RGB in the fixed class colours (-1: grey on
    walkable pixels, black elsewhere)."""
    return label_colors_rgb(labels, classes, walkable)


def add_legend(ax, classes: Sequence[str], unlabelled: bool = True, unlabelled_label: str = UNLABELLED_LABEL,
               extra: Sequence[tuple[str, tuple[int, int, int]]] = (), **kw) -> None:
    """Class colour legend on ``ax`` (outside the axes, right); ``unlabelled_label`` names the
    grey of -1 pixels on walkable ground; ``extra`` adds (label, RGB) entries."""
    handles = [Patch(color=np.array(c) / 255, label=n.replace("_", " ")) for c, n in zip(class_colors(classes), classes)]
    if unlabelled:
        handles.append(Patch(color=np.array(UNLABELLED_COLOR) / 255, label=unlabelled_label))
    handles += [Patch(color=np.array(c) / 255, label=t) for t, c in extra]
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
             resolution: float | None = None, title: str | None = None, segments: np.ndarray | None = None,
             borders: bool = True) -> None:
    """Draw a label map in class colours, with borders between touching segments and a scale
    bar when ``resolution`` (m/px) is given.

    ``labels`` (H, W) class index or -1; ``segments`` (H, W) segment ids (e.g. room
    instances of the ground truth); by default the connected regions of one label.
    """
    rgb = colorize(labels, classes, walkable)
    if borders:
        seg = label_segments(labels) if segments is None else np.asarray(segments)
        rgb = rgb.copy()
        rgb[segment_borders(seg)] = BORDER_COLOR
    ax.imshow(rgb, interpolation="nearest")
    ax.set_xticks([])
    ax.set_yticks([])
    if title:
        ax.set_title(title, fontsize=9)
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


def output_paths(path, formats: Sequence[str] | None = None) -> list:
    """The files a figure is saved to: ``path`` with each of ``formats`` as suffix (``path``
    itself when ``formats`` is None)."""
    from pathlib import Path

    path = Path(path)
    if not formats:
        return [path]
    return [path.with_suffix("." + f) for f in parse_formats(formats)]


def occupancy_panels(maps: dict[str, np.ndarray], out, cols: int, panel_in: float, dpi: int,
                     fontsize: float | None = None) -> None:
    """Trinary occupancy maps side by side, ``cols`` panels a row (``panel_in`` inches square
    each), titled by their keys: free (0) white, occupied (100) black, unknown grey; written
    atomically to the PNG ``out`` at ``dpi``.

    Args:
        maps: title -> (H, W) int8 occupancy (-1 / 0 / 100, as ``nav_msgs/OccupancyGrid``)."""
    import io

    from envs.atomic import atomic_write_bytes

    rows = (len(maps) + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(panel_in * cols, panel_in * rows), squeeze=False)
    for ax, (title, occ) in zip(axes.ravel(), maps.items(), strict=False):
        img = np.full(occ.shape, 0.6)
        img[occ == 0], img[occ == 100] = 1.0, 0.0
        ax.imshow(img, cmap="gray", vmin=0, vmax=1, interpolation="nearest")
        ax.set_title(title, **({} if fontsize is None else {"fontsize": fontsize}))
        ax.axis("off")
    for ax in axes.ravel()[len(maps):]:
        ax.axis("off")
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    plt.close(fig)
    atomic_write_bytes(out, buf.getvalue())


def save(fig, path, formats: Sequence[str] | None = None, tight: bool = True) -> list:
    """Save ``fig`` to ``path`` (in each of ``formats``: png at :data:`PNG_DPI` and
    :data:`PNG_COMPRESS_LEVEL`, pdf, svg;
    the folder is created) and close it. ``tight`` crops to the drawn content.

    Returns:
        list of the paths written.
    """
    paths = output_paths(path, formats)
    for p in paths:
        p.parent.mkdir(parents=True, exist_ok=True)
        png = {"pil_kwargs": {"compress_level": PNG_COMPRESS_LEVEL}} if p.suffix == ".png" else {}
        fig.savefig(p, dpi=PNG_DPI, **({"bbox_inches": "tight"} if tight else {}), **png)
    plt.close(fig)
    return paths
