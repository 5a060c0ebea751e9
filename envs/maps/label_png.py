"""Label maps and instance maps as PNG images.

* Label maps (class index per pixel) are written as colour PNGs in the fixed class colours
  of :mod:`envs.world.classes`, with a sidecar ``<name>.json`` (class names, colours, resolution,
  origin) so that :func:`read_label_png` gives back the exact array.
* Instance-coloured maps (one colour per room, black = not walkable), like the SeLRoS
  release, are read with :func:`read_instance_png`. Their edges are anti-aliased: blends of
  two room colours, or of a room and black, appear on thin lines of pixels. **Rule:** a colour
  covering fewer than ``min_pixels`` pixels is not a room; with ``assign="neighbour"``
  (default) each of its pixels joins the nearest pixel of a kept room colour (Euclidean
  distance in pixels), with ``assign="drop"`` it becomes unlabelled (-1). Colours listed in
  ``not_room`` (black always, and e.g. white: the 1-px lines along the border of the SeLRoS
  and VRF outputs) are never rooms and stay unlabelled (-1), whatever their size. Callers that
  score maps set ``min_pixels`` from an area in m² (benchmark.metrics.MetricParams).

Both readers open images through :func:`envs.maps.images.read_image`: a header declaring more
than ``max_pixels`` (default :data:`envs.maps.scene.MAX_MAP_PIXELS`) is refused before
decoding, with one line naming the file, the size and the limit.
"""

from __future__ import annotations

import io
import json
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from PIL import Image
from scipy import ndimage

from envs.atomic import atomic_write_bytes, atomic_write_text
from envs.maps.images import read_image
from envs.maps.scene import MAX_MAP_PIXELS
from envs.world.classes import BACKGROUND_COLOR, UNLABELLED_COLOR, class_colors

#: Default minimum colour count (pixels) for a colour of an instance PNG to be a room.
DEFAULT_MIN_PIXELS = 500


def _atomic_save(img: Image.Image, path: Path) -> None:
    buf = io.BytesIO()
    img.save(buf, format="PNG")
    atomic_write_bytes(path, buf.getvalue())


def _sidecar(path: Path) -> Path:
    return path.with_suffix(".json")


def label_colors_rgb(labels: np.ndarray, classes: Sequence[str], walkable: np.ndarray | None = None) -> np.ndarray:
    """(H, W) labels -> (H, W, 3) uint8 in class colours; -1 is grey on walkable pixels
    (when ``walkable`` is given) and black elsewhere."""
    labels = np.asarray(labels)
    n = len(classes)
    bad = (labels < -1) | (labels >= n)
    if bad.any():
        raise ValueError(f"label map has values outside [-1, {n}): {np.unique(labels[bad])[:5].tolist()}")
    lut = np.array([*class_colors(classes), BACKGROUND_COLOR], dtype=np.uint8)  # index -1 -> last
    rgb = lut[labels]
    if walkable is not None:
        if walkable.shape != labels.shape:
            raise ValueError(f"walkable mask shape {walkable.shape} differs from label map shape {labels.shape}")
        rgb[(labels < 0) & walkable] = UNLABELLED_COLOR
    return rgb


def write_label_png(path: str | Path, labels: np.ndarray, classes: Sequence[str], walkable: np.ndarray | None = None,
                    resolution: float | None = None, origin: tuple[float, float] | None = None,
                    legend: bool = True) -> Path:
    """Write a label map as a colour PNG plus a JSON sidecar (classes, colours, legend, grid).

    With ``legend=True`` a separate ``<name>_legend.png`` (class colour swatches and names)
    is written beside it, so the map PNG itself stays pixel-exact.
    """
    path = Path(path)
    labels = np.asarray(labels)
    if labels.ndim != 2 or labels.size == 0:
        raise ValueError(f"label map must be a non-empty (H, W) array, got shape {labels.shape}")
    rgb = label_colors_rgb(labels, classes, walkable)
    _atomic_save(Image.fromarray(rgb), path)
    meta = {
        "classes": list(classes), "colors": [list(c) for c in class_colors(classes)],
        "unlabelled_color": list(UNLABELLED_COLOR), "background_color": list(BACKGROUND_COLOR),
        "resolution": resolution, "origin": list(origin) if origin else None, "shape": list(labels.shape),
    }
    atomic_write_text(_sidecar(path), json.dumps(meta, indent=1))
    if legend:
        _write_legend(path.with_name(path.stem + "_legend.png"), classes)
    return path


def _write_legend(path: Path, classes: Sequence[str]) -> None:
    """A small legend image: one colour swatch and name per class."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch

    fig = plt.figure(figsize=(2.6, 0.28 * (len(classes) + 1)))
    handles = [Patch(color=np.array(c) / 255, label=n) for c, n in zip(class_colors(classes), classes)]
    handles.append(Patch(color=np.array(UNLABELLED_COLOR) / 255, label="unlabelled"))
    fig.legend(handles=handles, loc="center", frameon=False)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    plt.close(fig)


def read_label_png(path: str | Path, max_pixels: int | None = MAX_MAP_PIXELS) -> tuple[np.ndarray, list[str]]:
    """Read a label PNG written by :func:`write_label_png` -> (labels (H, W) int32, classes).

    Colours are matched exactly against the sidecar's class colours; unlabelled and
    background colours become -1; any other colour is an error naming it. ``max_pixels``:
    the largest image read (checked on the header; ``None``: no limit).
    """
    path = Path(path)
    side = _sidecar(path)
    if not side.exists():
        raise FileNotFoundError(f"{path}: no sidecar {side.name} with the class list; write maps with write_label_png")
    meta = json.loads(side.read_text())
    rgb = read_image(path, "the label PNG", "RGB", max_pixels)
    key = _pack(rgb)
    labels = np.full(key.shape, -2, dtype=np.int32)
    for i, c in enumerate(meta["colors"]):
        labels[key == _pack(np.array(c))] = i
    for c in (meta["unlabelled_color"], meta["background_color"]):
        labels[key == _pack(np.array(c))] = -1
    if (labels == -2).any():
        bad = np.unique(key[labels == -2])[:3]
        raise ValueError(f"{path}: colours not in its legend: {[f'#{int(b):06x}' for b in bad]}")
    return labels, list(meta["classes"])


def _pack(rgb: np.ndarray) -> np.ndarray:
    rgb = np.asarray(rgb).astype(np.int64)
    return (rgb[..., 0] << 16) | (rgb[..., 1] << 8) | rgb[..., 2]


def read_instance_png(path: str | Path, min_pixels: int = DEFAULT_MIN_PIXELS, assign: str = "neighbour",
                      return_colors: bool = False, not_room: Sequence = (0x000000,), return_info: bool = False,
                      max_pixels: int | None = MAX_MAP_PIXELS):
    """Read an instance-coloured map -> (H, W) int32 instance ids (0..K-1), -1 not a room.

    Args:
        path: the PNG (any mode; read as RGB).
        min_pixels: colours on fewer pixels are anti-aliasing, not rooms: ``assign``
            ``"neighbour"`` gives each such pixel the instance of the nearest kept pixel,
            ``"drop"`` leaves it -1.
        not_room: colours that are never a room (packed 0xRRGGBB ints or ``"#rrggbb"``); their
            pixels are -1. Black is always among them (not walkable).
        return_colors: also return the (K, 3) uint8 RGB colour of each instance.
        return_info: also return a dict: ``rooms`` (colours that became rooms),
            ``antialias_px`` (pixels of colours under ``min_pixels``), ``unassigned_px``
            (pixels of ``not_room`` colours other than black).
        max_pixels: the largest image read (checked on the header; ``None``: no limit).
    Returns: ``inst``, then ``colors`` and/or ``info`` when asked, in that order. Instances
        are numbered by decreasing pixel count.
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"instance map not found: {path}")
    if assign not in ("neighbour", "drop"):
        raise ValueError(f"assign must be 'neighbour' or 'drop', got {assign!r}")
    skip = {0} | {colour_int(c) for c in not_room}
    rgb = read_image(path, "the instance map", "RGB", max_pixels)
    if rgb.size == 0:
        raise ValueError(f"{path}: empty image")
    key = _pack(rgb)
    colors, inverse, counts = np.unique(key.ravel(), return_inverse=True, return_counts=True)
    inverse = inverse.reshape(key.shape)
    order = np.argsort(-counts, kind="stable")
    ids = np.full(len(colors), -1, dtype=np.int32)
    k = 0
    kept = []
    antialias = unassigned = 0
    for ci in order:
        if int(colors[ci]) in skip:
            unassigned += int(counts[ci]) if colors[ci] != 0 else 0
            continue
        if counts[ci] < min_pixels:
            antialias += int(counts[ci])
            continue
        ids[ci] = k
        kept.append(colors[ci])
        k += 1
    inst = ids[inverse]
    not_room_px = np.isin(key, np.array(sorted(skip), dtype=np.int64))
    stray = ~not_room_px & (inst < 0)
    if assign == "neighbour" and stray.any() and k > 0:
        _, (rr, cc) = ndimage.distance_transform_edt(inst < 0, return_indices=True)
        inst[stray] = inst[rr[stray], cc[stray]]
    extra = []
    if return_colors:
        kc = np.array(kept, dtype=np.int64)
        extra.append(np.stack([(kc >> 16) & 255, (kc >> 8) & 255, kc & 255], axis=-1).astype(np.uint8))
    if return_info:
        extra.append({"rooms": k, "antialias_px": antialias, "unassigned_px": unassigned})
    return (inst, *extra) if extra else inst


def colour_int(c) -> int:
    """0xRRGGBB int, ``"#rrggbb"`` or ``[r, g, b]`` -> packed int."""
    if isinstance(c, (int, np.integer)):
        if not 0 <= int(c) <= 0xFFFFFF:
            raise ValueError(f"colour must be in 0x000000-0xffffff, got {c!r}")
        return int(c)
    if isinstance(c, str):
        s = c.strip().lstrip("#")
        try:
            if len(s) == 6:
                return int(s, 16)
        except ValueError:
            pass
        raise ValueError(f"colour must look like '#rrggbb', got {c!r}")
    v = [int(x) for x in c]
    if len(v) != 3 or not all(0 <= x <= 255 for x in v):
        raise ValueError(f"colour must be '#rrggbb' or [r, g, b] in 0-255, got {c!r}")
    return (v[0] << 16) | (v[1] << 8) | v[2]
