"""Ground-truth room maps in, one reader per format, chosen explicitly.

Formats (``format=``):

* ``"instance"``: one colour per room (the SeLRoS release, VRF, ROSE²), read by
  :func:`envs.maps.label_png.read_instance_png`; ``not_room_colours`` (black and white by
  default) are never a room; colours on less than ``min_room_m2`` are anti-aliasing and
  join the nearest room. No room classes (``instance_classes`` are -1).
* ``"label"``: a class label map: a colour PNG written by
  :func:`envs.maps.label_png.write_label_png` (with its ``.json`` sidecar naming the
  classes), or a single-channel index PNG (pixel value = class index into ``classes``,
  ``unlabelled_value`` = no room). Rooms are the 4-connected regions of one class.
* ``"rooms_white"``: the IPA room-segmentation test-map style: rooms are white, black
  lines (and the walls) separate them. Rooms are the 4-connected regions of light pixels
  (grey value, the mean of the colour channels, at least ``light_threshold``) of at least
  ``min_room_m2``; everything else is border. No room classes.

Carried onto a map (``grid`` given, same shape as the image): room pixels that are not
walkable in the map are dropped (-1); walkable map pixels that no room covers (the border
lines, anti-aliased edges, specks) take the room of the nearest room pixel (Euclidean, in
pixels) when it is at most ``fill_distance`` metres away (``None``: any distance), else
stay -1 (not scored). Without ``grid``, instances are the rooms as drawn.

Images are opened through :func:`envs.maps.images.read_image`: one declaring more than
``max_pixels`` (default :data:`envs.maps.scene.MAX_MAP_PIXELS`) is refused on its header,
before decoding, with one line naming the file, the size and the limit.

Sanity checks, each a ``UserWarning`` naming the file: more than ``MANY_COLOURS`` distinct
colours in an instance map (probably not instance-coloured); the ground truth scored
against itself (each 4-connected region of one room id against its room, IoU averaged over
regions of at least ``min_room_m2``) below 99 % (one room id drawn as several separate
regions: probably the wrong format).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import ndimage
from skimage import measure

from envs.maps.gridmap import GridMap
from envs.maps.images import open_image, read_image
from envs.maps.label_png import read_instance_png, read_label_png
from envs.maps.scene import MAX_MAP_PIXELS

FORMATS = ("instance", "label", "rooms_white")
#: An instance map with more distinct colours than this draws a warning.
MANY_COLOURS = 100
#: Below this self-score (mean IoU of each room's connected regions against the room) a warning.
SELF_IOU_WARN = 0.99
#: Pixel-count floor for rooms/colours when no resolution is known (as read_instance_png's).
FALLBACK_MIN_PIXELS = 500
_FOUR = ndimage.generate_binary_structure(2, 1)


@dataclass
class GroundTruth:
    """Room ground truth read from a file.

    Attributes:
        instances: (H, W) int32 room id 0..K-1, -1 where there is no room (or, on a grid,
            not walkable).
        instance_classes: (K,) int64 class index into ``classes`` of each room, -1 where the
            format has no classes.
        classes: the class names ``instance_classes`` refers to (None: format without classes).
        path: the file read.
        format: the format used.
        n_colours: distinct colours (or grey values) in the image.
        self_iou: the ground truth scored against itself (see the module doc), in [0, 1].
    """

    instances: np.ndarray
    instance_classes: np.ndarray
    classes: tuple[str, ...] | None
    path: Path
    format: str
    n_colours: int
    self_iou: float


def _min_pixels(min_room_m2: float, resolution: float | None) -> int:
    if resolution is None:
        return FALLBACK_MIN_PIXELS
    return max(1, int(math.ceil(min_room_m2 / resolution ** 2 - 1e-9)))


def _open_rgb(path: Path, max_pixels: int | None = MAX_MAP_PIXELS) -> np.ndarray:
    return read_image(path, "the ground-truth image", "RGB", max_pixels)


def _n_colours(rgb: np.ndarray) -> int:
    key = (rgb[..., 0].astype(np.int64) << 16) | (rgb[..., 1].astype(np.int64) << 8) | rgb[..., 2]
    return int(len(np.unique(key)))


def self_iou(instances: np.ndarray, min_px: int = 1) -> float:
    """The instance map scored against itself with 4-connected segments.

    Each 4-connected region of one room id is a segment; its best room is its own, so its
    IoU is ``|region| / |room|``. Returns the mean over regions of at least ``min_px``
    pixels (1.0 when every room is one connected region; NaN with no region).
    """
    inst = np.asarray(instances, dtype=np.int64)
    if not (inst >= 0).any():
        return float("nan")
    regions = measure.label(inst, background=-1, connectivity=1)  # one pass, regions of equal value
    m = regions > 0
    size = np.bincount(regions[m])
    room_of = np.zeros(len(size), np.int64)
    room_of[regions[m]] = inst[m]
    room_size = np.bincount(inst[m])
    keep = np.nonzero(size >= max(min_px, 1))[0]
    keep = keep[keep > 0]
    return float(np.mean(size[keep] / room_size[room_of[keep]])) if len(keep) else float("nan")


def _relabel(lab: np.ndarray) -> np.ndarray:
    """Ids >= 0 renumbered 0..K-1 in order of first appearance (row-major); -1 kept."""
    out = np.full(lab.shape, -1, np.int32)
    m = lab >= 0
    if m.any():
        ids, first = np.unique(lab[m], return_index=True)
        order = ids[np.argsort(first)]
        remap = np.full(int(lab.max()) + 1, -1, np.int64)
        remap[order] = np.arange(len(order))
        out[m] = remap[lab[m]]
    return out


def _rooms_white(path: Path, light_threshold: int, min_px: int, max_pixels: int | None) -> tuple[np.ndarray, int]:
    rgb = _open_rgb(path, max_pixels)
    grey = rgb.astype(np.int64).sum(axis=-1) // 3
    light = grey >= light_threshold
    lab, n = ndimage.label(light, _FOUR)
    sizes = np.bincount(lab.ravel(), minlength=n + 1)
    keep = np.zeros(n + 1, bool)
    keep[1:] = sizes[1:] >= min_px
    rooms = np.where(keep[lab], lab - 1, -1)
    return _relabel(rooms), _n_colours(rgb)


def _label(path: Path, classes: Sequence[str] | None, unlabelled_value: int, max_pixels: int | None
           ) -> tuple[np.ndarray, np.ndarray, tuple[str, ...], int]:
    """-> (instances, instance_classes, classes, n_colours) of a label map."""
    side = path.with_suffix(".json")
    if side.exists():
        labels, gt_classes = read_label_png(path, max_pixels)
        n_col = _n_colours(_open_rgb(path, max_pixels))
        if classes is None:
            classes = tuple(gt_classes)
        unknown = [c for c in gt_classes if c not in classes]
        if unknown:
            raise ValueError(f"{path}: classes {unknown} of its sidecar {side.name} are not in the class list "
                             f"{list(classes)}")
        remap = np.array([list(classes).index(c) for c in gt_classes] + [-1], np.int64)
        labels = remap[labels]  # -1 -> the trailing -1
    else:
        if classes is None:
            raise ValueError(f"{path}: an index label PNG without a .json sidecar needs the class list (classes)")
        with open_image(path, "the ground-truth image", max_pixels) as img:
            if img.mode not in ("L", "P", "I", "I;16"):
                raise ValueError(f"{path}: image mode {img.mode!r} for an index label PNG with no sidecar; "
                                 f"expected one channel (class index per pixel)")
        raw = read_image(path, "the ground-truth image", None, max_pixels).astype(np.int64)
        n_col = int(len(np.unique(raw)))
        bad = (raw != unlabelled_value) & ((raw < 0) | (raw >= len(classes)))
        if bad.any():
            raise ValueError(f"{path}: pixel values {np.unique(raw[bad])[:5].tolist()} are neither a class index "
                             f"(0..{len(classes) - 1}) nor the unlabelled value {unlabelled_value}")
        labels = np.where(raw == unlabelled_value, -1, raw)
    classes = tuple(classes)
    inst = np.full(labels.shape, -1, np.int64)
    inst_cls: list[int] = []
    for c in range(len(classes)):
        lab, n = ndimage.label(labels == c, _FOUR)
        if n:
            inst[lab > 0] = lab[lab > 0] - 1 + len(inst_cls)
            inst_cls.extend([c] * n)
    order_inst = _relabel(inst)
    # instance classes follow the renumbering
    cls = np.full(int(order_inst.max()) + 1 if (order_inst >= 0).any() else 0, -1, np.int64)
    m = inst >= 0
    cls[order_inst[m]] = np.asarray(inst_cls, np.int64)[inst[m]]
    return order_inst, cls, classes, n_col


def carry_onto_grid(instances: np.ndarray, grid: GridMap, fill_distance: float | None = 0.5) -> np.ndarray:
    """Ground-truth rooms onto a map of the same shape (see the module doc).

    Args:
        instances: (H, W) int room ids, -1 no room.
        grid: the input map; its walkable mask decides which pixels are scored.
        fill_distance: metres; walkable pixels with no room take the nearest room within it
            (None: any distance).

    Returns:
        (H, W) int32 room id on walkable pixels, -1 elsewhere.
    """
    inst = np.asarray(instances)
    walk = grid.walkable
    out = np.where(walk, inst, -1).astype(np.int32)
    hole = walk & (inst < 0)
    if hole.any() and (inst >= 0).any():
        dist, (rr, cc) = ndimage.distance_transform_edt(inst < 0, return_indices=True)
        take = hole if fill_distance is None else hole & (dist * grid.resolution <= fill_distance + 1e-9)
        out[take] = inst[rr[take], cc[take]]
    return out


def read_ground_truth(path: str | Path, format: str, grid: GridMap | None = None, *,
                      classes: Sequence[str] | None = None, resolution: float | None = None,
                      min_room_m2: float = 0.2, light_threshold: int = 230, unlabelled_value: int = 255,
                      not_room_colours: Sequence = ("#000000", "#ffffff"), fill_distance: float | None = 0.5,
                      warn: bool = True, max_pixels: int | None = MAX_MAP_PIXELS) -> GroundTruth:
    """Read a ground-truth room map in the given format (see the module doc).

    Args:
        path: the image.
        format: ``"instance"``, ``"label"`` or ``"rooms_white"`` (no guessing).
        grid: the input map to carry the rooms onto (its shape must be the image's), or None.
        classes: the class list (label format: the sidecar's classes must be in it; an index
            PNG's values index it).
        resolution: metres per pixel when no grid is given (for ``min_room_m2``).
        min_room_m2: smallest room (rooms_white) or colour (instance), square metres.
        light_threshold: rooms_white: grey value (0..255) from which a pixel is a room.
        unlabelled_value: label index PNGs: the pixel value of "no room".
        not_room_colours: instance format: colours that are never a room (``"#rrggbb"``,
            ``[r, g, b]`` or packed ints); black is always one.
        fill_distance: metres, see :func:`carry_onto_grid`.
        warn: emit the sanity-check warnings.
        max_pixels: the largest image (width x height) read, checked on its header before
            decoding; ``None``: no limit.

    Returns:
        :class:`GroundTruth` (instances on ``grid`` when given).

    Raises:
        FileNotFoundError / ValueError: one line naming the file and what was expected.
    """
    path = Path(path).expanduser()
    if format not in FORMATS:
        raise ValueError(f"ground-truth format {format!r} for {path}; expected one of {list(FORMATS)}")
    if not path.is_file():
        raise FileNotFoundError(f"ground-truth map not found: {path}")
    if not 0 <= light_threshold <= 255:
        raise ValueError(f"light_threshold is {light_threshold}; expected a grey value in 0..255")
    res = grid.resolution if grid is not None else resolution
    min_px = _min_pixels(min_room_m2, res)
    gt_classes: tuple[str, ...] | None = None
    if format == "instance":
        inst = read_instance_png(path, min_pixels=min_px, not_room=tuple(not_room_colours), max_pixels=max_pixels)
        n_col = _n_colours(_open_rgb(path, max_pixels))
        cls = np.full(int(inst.max()) + 1 if (inst >= 0).any() else 0, -1, np.int64)
    elif format == "rooms_white":
        inst, n_col = _rooms_white(path, light_threshold, min_px, max_pixels)
        cls = np.full(int(inst.max()) + 1 if (inst >= 0).any() else 0, -1, np.int64)
    else:
        inst, cls, gt_classes, n_col = _label(path, classes, unlabelled_value, max_pixels)
    if not (inst >= 0).any():
        hint = (" (rooms drawn white between black lines are format 'rooms_white'; white is a not-room colour "
                "of format 'instance')" if format == "instance" else "")
        raise ValueError(f"{path}: no room found reading it as format {format!r}{hint}")
    score = self_iou(inst, min_px)
    if warn and format == "instance" and n_col - 1 > MANY_COLOURS:
        warnings.warn(f"{path}: {n_col} distinct colours, {len(cls)} became rooms; is it instance-coloured "
                      f"ground truth (format 'instance')?", UserWarning, stacklevel=2)
    if warn and score < SELF_IOU_WARN:
        hint = " (rooms drawn white between black lines are format 'rooms_white')" if format != "rooms_white" else ""
        warnings.warn(f"{path}: the ground truth scored against itself gives IoU {100 * score:.1f} % (< 99 %): "
                      f"a room id covers several separate regions; wrong format {format!r}?{hint}",
                      UserWarning, stacklevel=2)
    if grid is not None:
        if grid.shape != inst.shape:
            raise ValueError(f"{path}: ground truth is {inst.shape[0]} x {inst.shape[1]} pixels but the map is "
                             f"{grid.shape[0]} x {grid.shape[1]}; expected the same grid")
        if fill_distance is not None and not (math.isfinite(fill_distance) and fill_distance >= 0):
            raise ValueError(f"fill_distance is {fill_distance!r}; expected metres >= 0 or None")
        inst = carry_onto_grid(inst, grid, fill_distance)
    return GroundTruth(instances=inst.astype(np.int32), instance_classes=cls, classes=gt_classes, path=path,
                       format=format, n_colours=n_col, self_iou=score)


def describe(gt: GroundTruth) -> str:
    """One line: file, format, rooms, colours and self-score."""
    return (f"{gt.path.name}: format {gt.format}, {len(gt.instance_classes)} rooms from {gt.n_colours} colours, "
            f"self-IoU {100 * gt.self_iou:.1f} %")


__all__ = ["FORMATS", "GroundTruth", "carry_onto_grid", "describe", "read_ground_truth", "self_iou"]
