"""Occupancy maps in: ROS ``map_server`` YAML + image, plain occupancy PNGs and NumPy arrays;
and ROS maps out.

ROS ``map_server`` map (YAML + PGM/PNG/BMP), as the ROS ``map_server`` documentation defines it:

* YAML fields: ``image`` (path, absolute or relative to the YAML file), ``resolution``
  (metres/pixel), ``origin: [x, y, yaw]`` (pose of the bottom-left corner of the bottom-left
  pixel; yaw radians CCW), ``negate`` (0/1 or true/false) are required; ``occupied_thresh``,
  ``free_thresh`` (probabilities in [0, 1]) default to :data:`ROS_OCCUPIED_THRESH` 0.65 and
  :data:`ROS_FREE_THRESH` 0.196 (the values ROS ``map_saver`` writes; ROS 1 ``map_server``
  itself requires them); ``mode``: ``trinary`` (default), ``scale`` or ``raw``.
* Each pixel's value ``v`` (0..255) is the mean of its colour channels (integer division,
  alpha not included). Occupancy probability ``p = (255 - v) / 255``, or ``p = v / 255``
  with ``negate``.
* ``trinary``: ``p > occupied_thresh`` -> 100 (occupied); ``p < free_thresh`` -> 0 (free);
  otherwise -1 (unknown).
* ``scale``: as trinary, but in-between pixels get ``1 + int(98 * (p - free) / (occ - free))``
  (1..99, as ROS 1 ``map_server`` computes it, so an in-between cell never reads as free
  or occupied); a pixel with any transparency (alpha < 255) is unknown (-1).
* ``raw``: the value itself (``255 - v`` with ``negate``, as ``map_server`` applies negate
  first): 0..100 is the occupancy, 101..255 is unknown (-1).
* A non-zero origin yaw is refused with one line (ROS's own ``map_server`` users mostly
  ignore it; rotating the grid would resample it): set it to 0 after checking the map.

Walkable = free cells (occupancy 0); unknown cells (-1) are obstacles, or walkable with
``unknown_as="free"``; in-between cells (1..99) are obstacles.

**Plain images** (no YAML, :func:`occupancy_png`) are read as a trinary ``map_server`` map
with a *preset* of thresholds (:data:`IMAGE_PRESETS`):

* ``ros`` (default): exactly as a YAML that leaves out ``occupied_thresh`` and
  ``free_thresh``: occupied above p = 0.65 (grey <= 89), free below p = 0.196 (grey >= 206),
  unknown in between; so ROS ``map_saver``'s 205 reads as unknown.
* ``white_only``: only white is free, anything else is an obstacle (free below p = 0.02:
  grey >= 250; occupied above 0.02): the convention of the IPA room-segmentation test maps
  and their ``rooms_white`` ground truth, and of many published maps that draw furniture in
  grey.

``free_thresh`` / ``occupied_thresh`` given explicitly override the preset's. When a plain
image holds a large share (:data:`GREY_WARN_SHARE`, 2 %) of grey pixels (not white, p >=
0.02, and not occupied: grey furniture, ``map_saver``'s 205 unknown) a ``UserWarning`` names
the file, the commonest grey levels and the share read as free (:func:`grey_pixels_note`).

Every image is opened through :func:`envs.maps.images.open_image`: a header declaring more
than ``max_pixels`` (default :data:`envs.maps.scene.MAX_MAP_PIXELS`) is refused before
decoding with one line naming the file, the size and the limit.

The grid has the image's shape, row 0 = the image's top row; the frame conversion is in
:mod:`envs.maps.frames`.
"""

from __future__ import annotations

import io
import math
import warnings
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml
from PIL import Image

from envs.atomic import atomic_write_bytes, atomic_write_chunks, atomic_write_text
from envs.maps.frames import grid_origin_to_ros_origin, ros_origin_to_grid_origin
from envs.maps.gridmap import GridMap
from envs.maps.images import open_image
from envs.maps.scene import MAX_MAP_PIXELS, check_max_map_pixels

MODES = ("trinary", "scale", "raw")
UNKNOWN_AS = ("obstacle", "free")
#: Pixel values written for free and occupied cells (ROS map_saver's trinary values).
FREE_PIXEL, OCCUPIED_PIXEL = 254, 0
#: Thresholds of a map YAML that leaves them out: the values ROS ``map_saver`` writes
#: (occupancy probability; free below 0.196 = grey >= 206, occupied above 0.65 = grey <= 89).
ROS_OCCUPIED_THRESH, ROS_FREE_THRESH = 0.65, 0.196
#: Plain-image presets: name -> (free_thresh, occupied_thresh). ``white_only``: free below
#: p = 0.02 (grey >= 250), everything else occupied (no 8-bit grey has p exactly 0.02).
IMAGE_PRESETS = {"ros": (ROS_FREE_THRESH, ROS_OCCUPIED_THRESH), "white_only": (0.02, 0.02)}
#: Occupancy probability below which a pixel counts as white (not grey) for the warning.
WHITE_P = 0.02
#: Share of an image's pixels that are grey (p >= WHITE_P, not occupied) from which a plain
#: image draws the grey-pixel warning.
GREY_WARN_SHARE = 0.02
_REQUIRED = ("image", "resolution", "origin", "negate")


@dataclass
class RosMap:
    """A ROS ``map_server`` map, read.

    Attributes:
        grid: the project's occupancy map (walkable = free cells), (H, W) like the image.
        occupancy: (H, W) int8 ROS occupancy: -1 unknown, 0 free, 100 occupied, 1..99
            in-between (scale and raw modes); row 0 = the image's top row.
        image_path: the image file read.
        yaml_path: the YAML file read.
        resolution: metres per pixel.
        origin: ROS origin (x, y, yaw): metres, metres, radians.
        negate, occupied_thresh, free_thresh, mode: the YAML's values (``mode`` after any
            override).
    """

    grid: GridMap
    occupancy: np.ndarray
    image_path: Path
    yaml_path: Path
    resolution: float
    origin: tuple[float, float, float]
    negate: bool
    occupied_thresh: float
    free_thresh: float
    mode: str


# --------------------------------------------------------------------------- reading


def _number(yaml_path: Path, field: str, value, lo: float | None = None, hi: float | None = None,
            positive: bool = False) -> float:
    """A finite float from a YAML field, or one line naming the file, field and value."""
    try:
        if isinstance(value, bool):
            raise TypeError
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{yaml_path}: field '{field}' is {value!r}; expected a number") from None
    if not math.isfinite(v) or (positive and v <= 0) or (lo is not None and v < lo) or (hi is not None and v > hi):
        want = "a positive number" if positive else f"a number in [{lo}, {hi}]"
        raise ValueError(f"{yaml_path}: field '{field}' is {value!r}; expected {want}")
    return v


def _negate(yaml_path: Path, value) -> bool:
    if isinstance(value, bool):
        return value
    if isinstance(value, int) and value in (0, 1):
        return bool(value)
    raise ValueError(f"{yaml_path}: field 'negate' is {value!r}; expected 0, 1, true or false")


def _origin(yaml_path: Path, value) -> tuple[float, float, float]:
    if not isinstance(value, (list, tuple)) or len(value) != 3:
        raise ValueError(f"{yaml_path}: field 'origin' is {value!r}; expected [x, y, yaw] (metres, metres, radians)")
    x, y, yaw = (_number(yaml_path, f"origin[{i}]", v) for i, v in enumerate(value))
    if abs(yaw) > 1e-9:
        raise ValueError(f"{yaml_path}: field 'origin' has yaw {yaw!r}; only yaw 0 is supported (a rotated map is "
                         f"not read; set the yaw to 0 if the map is axis-aligned)")
    return x, y, 0.0


def _grey_and_alpha(img: Image.Image, image_path: Path) -> tuple[np.ndarray, np.ndarray | None]:
    """(H, W) uint8 grey value 0..255 (integer mean of the colour channels) and (H, W) uint8
    alpha, or None for an image without an alpha channel (opaque). One byte a pixel each: a
    map of 16000 x 16000 pixels is read without 64-bit copies."""
    if img.mode == "P":
        img = img.convert("RGBA")
    elif img.mode == "1":
        img = img.convert("L")
    if img.mode not in ("L", "LA", "RGB", "RGBA"):
        raise ValueError(f"{image_path}: image mode {img.mode!r}; expected an 8-bit grey or colour image "
                         f"(PGM/PNG/BMP: L, LA, RGB, RGBA or palette)")
    a = np.asarray(img)
    if a.size == 0:
        raise ValueError(f"{image_path}: empty image")
    if a.ndim == 2:
        return a.astype(np.uint8), None
    has_alpha = img.mode in ("LA", "RGBA")
    colour = a[..., :-1] if has_alpha else a
    if colour.shape[-1] == 1:
        grey = colour[..., 0].astype(np.uint8)
    else:  # the sum of at most three channels fits 16 bits, their integer mean 8
        grey = (colour.sum(axis=-1, dtype=np.uint16) // colour.shape[-1]).astype(np.uint8)
    alpha = a[..., -1].astype(np.uint8) if has_alpha else None
    return grey, alpha


def _read_grey(image_path: Path, what: str, max_pixels: int | None = MAX_MAP_PIXELS
               ) -> tuple[np.ndarray, np.ndarray]:
    """Open an occupancy image (size checked before decoding, :func:`open_image`) and
    return :func:`_grey_and_alpha` of it.

    Raises:
        ValueError: the file cannot be read as an image, or declares more than
            ``max_pixels`` (``what`` says whose image it is)."""
    with open_image(image_path, what, max_pixels) as img:
        try:
            img.load()
            return _grey_and_alpha(img, image_path)
        except OSError as e:
            raise ValueError(f"{image_path}: cannot read {what} ({e})") from None


def image_to_occupancy(grey: np.ndarray, alpha: np.ndarray | None, negate: bool, occupied_thresh: float,
                       free_thresh: float, mode: str) -> np.ndarray:
    """Pixel values -> ROS occupancy, as ``map_server`` interprets them (see the module doc).

    Args:
        grey: (H, W) int pixel values 0..255.
        alpha: (H, W) int alpha 0..255, or None (opaque).
        negate, occupied_thresh, free_thresh, mode: as in the map YAML.

    Returns:
        (H, W) int8 occupancy: -1 unknown, 0 free, 100 occupied, 1..99 in-between.

    A uint8 image is read through a 256-entry table (this function on the values 0..255), so
    a large map needs no map-sized temporaries beyond the result.
    """
    if mode not in MODES:
        raise ValueError(f"map mode {mode!r}; expected one of {list(MODES)}")
    grey = np.asarray(grey)
    if grey.dtype == np.uint8:
        out = _values_to_occupancy(np.arange(256), negate, occupied_thresh, free_thresh, mode)[grey]
        if mode == "scale" and alpha is not None:
            out[np.asarray(alpha) < 255] = -1
        return out
    out = _values_to_occupancy(grey, negate, occupied_thresh, free_thresh, mode)
    if mode == "scale" and alpha is not None:
        out = np.where(np.asarray(alpha) < 255, np.int8(-1), out)
    return out.astype(np.int8)


def _values_to_occupancy(grey: np.ndarray, negate: bool, occupied_thresh: float, free_thresh: float,
                         mode: str) -> np.ndarray:
    """:func:`image_to_occupancy` without alpha, element by element on int pixel values."""
    grey = np.asarray(grey, dtype=np.int64)
    if mode == "raw":
        v = 255 - grey if negate else grey
        return np.where(v <= 100, v, -1).astype(np.int8)
    p = grey / 255.0 if negate else (255 - grey) / 255.0
    out = np.full(grey.shape, -1, dtype=np.int8)
    if mode == "scale":
        ratio = (p - free_thresh) / (occupied_thresh - free_thresh) if occupied_thresh > free_thresh else 0.0
        mid = (1 + np.floor(98 * np.clip(ratio, 0.0, 1.0))).astype(np.int8)
        out = mid
    out = np.where(p > occupied_thresh, np.int8(100), out)
    out = np.where(p < free_thresh, np.int8(0), out)
    return out.astype(np.int8)


def walkable_from_occupancy(occupancy: np.ndarray, unknown_as: str = "obstacle") -> np.ndarray:
    """(H, W) bool: free cells (occupancy 0), plus unknown cells (-1) if ``unknown_as="free"``."""
    if unknown_as not in UNKNOWN_AS:
        raise ValueError(f"unknown_as is {unknown_as!r}; expected one of {list(UNKNOWN_AS)}")
    occ = np.asarray(occupancy)
    walk = occ == 0
    if unknown_as == "free":
        walk |= occ == -1
    return walk


def read_ros_map(yaml_path: str | Path, mode: str | None = None, unknown_as: str = "obstacle",
                 max_pixels: int | None = MAX_MAP_PIXELS) -> RosMap:
    """Read a ROS ``map_server`` map (YAML + image).

    Args:
        yaml_path: the map's YAML file.
        mode: ``trinary`` | ``scale`` | ``raw`` to override the YAML's ``mode`` (None: the
            YAML's, default ``trinary``).
        unknown_as: ``obstacle`` (default) or ``free``: whether unknown cells are walkable.
        max_pixels: the largest image (width x height) read, checked on its header before
            decoding; ``None``: no limit.

    Returns:
        A :class:`RosMap`; ``grid.origin`` is the top-left corner of pixel (0, 0) computed
        from the ROS origin (:func:`envs.maps.frames.ros_origin_to_grid_origin`).

    Raises:
        FileNotFoundError / ValueError: one line naming the file, the field and the value.
    """
    yaml_path = Path(yaml_path).expanduser()
    if not yaml_path.is_file():
        raise FileNotFoundError(f"map YAML not found: {yaml_path}")
    try:
        meta = yaml.safe_load(yaml_path.read_text())
    except yaml.YAMLError as e:
        first = str(e).splitlines()[0] if str(e) else type(e).__name__
        raise ValueError(f"{yaml_path}: not valid YAML ({first})") from None
    if not isinstance(meta, dict):
        raise ValueError(f"{yaml_path}: expected a mapping with fields {list(_REQUIRED)}, got {type(meta).__name__}")
    missing = [f for f in _REQUIRED if f not in meta]
    if missing:
        raise ValueError(f"{yaml_path}: missing field(s) {missing}; a map_server YAML needs {list(_REQUIRED)} "
                         f"(occupied_thresh, free_thresh, mode optional)")
    if not isinstance(meta["image"], str) or not meta["image"].strip():
        raise ValueError(f"{yaml_path}: field 'image' is {meta['image']!r}; expected an image file name")
    resolution = _number(yaml_path, "resolution", meta["resolution"], positive=True)
    origin = _origin(yaml_path, meta["origin"])
    negate = _negate(yaml_path, meta["negate"])
    occ_th = _number(yaml_path, "occupied_thresh", meta.get("occupied_thresh", ROS_OCCUPIED_THRESH), 0.0, 1.0)
    free_th = _number(yaml_path, "free_thresh", meta.get("free_thresh", ROS_FREE_THRESH), 0.0, 1.0)
    if free_th > occ_th:
        raise ValueError(f"{yaml_path}: field 'free_thresh' is {free_th} > occupied_thresh {occ_th}; "
                         f"expected free_thresh <= occupied_thresh")
    yaml_mode = meta.get("mode", "trinary")
    if not isinstance(yaml_mode, str) or yaml_mode.lower() not in MODES:
        raise ValueError(f"{yaml_path}: field 'mode' is {yaml_mode!r}; expected one of {list(MODES)}")
    if mode is not None and mode not in MODES:
        raise ValueError(f"map mode override {mode!r} for {yaml_path}; expected one of {list(MODES)}")
    mode = mode or yaml_mode.lower()
    if unknown_as not in UNKNOWN_AS:
        raise ValueError(f"unknown_as is {unknown_as!r} for {yaml_path}; expected one of {list(UNKNOWN_AS)}")

    image_path = Path(meta["image"]).expanduser()
    if not image_path.is_absolute():
        image_path = yaml_path.parent / image_path
    if not image_path.is_file():
        raise FileNotFoundError(f"{yaml_path}: field 'image' names {meta['image']!r}, which does not exist "
                                f"(looked for {image_path})")
    grey, alpha = _read_grey(image_path, f"the image named by {yaml_path}", max_pixels)
    occupancy = image_to_occupancy(grey, alpha, negate, occ_th, free_th, mode)
    walkable = walkable_from_occupancy(occupancy, unknown_as)
    grid = GridMap(walkable, resolution, ros_origin_to_grid_origin(origin[:2], occupancy.shape[0], resolution))
    return RosMap(grid=grid, occupancy=occupancy, image_path=image_path, yaml_path=yaml_path,
                  resolution=resolution, origin=origin, negate=negate, occupied_thresh=occ_th,
                  free_thresh=free_th, mode=mode)


# --------------------------------------------------------------------------- writing


def grid_to_ros_image(grid: GridMap) -> np.ndarray:
    """A grid as a trinary ROS image: (H, W) uint8, free (walkable) 254, occupied 0.

    Row 0 is the grid's row 0 (the top of the picture), as ``map_server`` expects.
    """
    return np.where(np.asarray(grid.walkable), np.uint8(FREE_PIXEL), np.uint8(OCCUPIED_PIXEL)).astype(np.uint8)


def unknown_pixel(free_thresh: float = ROS_FREE_THRESH, occupied_thresh: float = ROS_OCCUPIED_THRESH,
                  negate: bool = False) -> int:
    """A pixel value that ``map_server`` reads as unknown (-1) in trinary mode under these
    thresholds: ROS ``map_saver``'s 205 when it qualifies (it does for free_thresh 0.196,
    not for 0.25), otherwise the value nearest the middle of the unknown band.

    Returns:
        An int 0..255; ValueError when no 8-bit value falls in the unknown band.
    """
    vals = np.arange(256)
    occ = image_to_occupancy(vals[None, :], None, negate, occupied_thresh, free_thresh, "trinary")[0]
    ok = vals[occ == -1]
    if ok.size == 0:
        raise ValueError(f"no 8-bit pixel value is unknown for free_thresh={free_thresh}, "
                         f"occupied_thresh={occupied_thresh}")
    if 205 in ok:
        return 205
    return int(ok[np.argmin(np.abs(ok - ok.mean()))])


def ros_origin_of(grid: GridMap) -> tuple[float, float, float]:
    """The ROS ``origin`` ``(x, y, 0.0)`` of a grid (bottom-left corner of its bottom-left pixel)."""
    x, y = grid_origin_to_ros_origin(grid.origin, grid.shape[0], grid.resolution)
    return x, y, 0.0


def _fmt(v: float) -> str:
    return repr(float(v))


def write_ros_map(yaml_path: str | Path, values: np.ndarray, resolution: float,
                  origin: tuple[float, float, float] = (0.0, 0.0, 0.0), negate: bool = False,
                  occupied_thresh: float = ROS_OCCUPIED_THRESH, free_thresh: float = ROS_FREE_THRESH,
                  mode: str = "trinary",
                  image_name: str | None = None) -> Path:
    """Write a ROS ``map_server`` map: the image, then the YAML naming it (each atomically).

    Args:
        yaml_path: the YAML file to write (``.yaml``).
        values: (H, W) uint8 image exactly as it is to be stored (row 0 = top); use
            :func:`grid_to_ros_image` for a grid.
        resolution: metres per pixel.
        origin: ROS origin (x, y, yaw): metres, metres, radians (bottom-left corner).
        negate, occupied_thresh, free_thresh, mode: written to the YAML as given.
        image_name: the image file name, relative to the YAML's folder (default
            ``<yaml stem>.pgm``); its suffix picks the format (``.pgm`` binary P5,
            ``.png``).

    Returns:
        The YAML path.
    """
    yaml_path = Path(yaml_path)
    values = np.asarray(values)
    if values.ndim != 2 or values.size == 0 or values.dtype != np.uint8:
        raise ValueError(f"{yaml_path}: values must be a non-empty (H, W) uint8 image, got shape {values.shape} "
                         f"dtype {values.dtype}")
    image_name = _check_map_fields(yaml_path, resolution, origin, occupied_thresh, free_thresh, mode, image_name)
    fmt = {".pgm": "PPM", ".png": "PNG"}[Path(image_name).suffix.lower()]
    buf = io.BytesIO()
    Image.fromarray(values, mode="L").save(buf, format=fmt)
    atomic_write_bytes(yaml_path.parent / image_name, buf.getvalue())
    return _write_map_yaml(yaml_path, image_name, resolution, origin, negate, occupied_thresh, free_thresh, mode)


def write_ros_map_rows(yaml_path: str | Path, shape: tuple[int, int], bands: Iterable[np.ndarray],
                       resolution: float, origin: tuple[float, float, float] = (0.0, 0.0, 0.0),
                       negate: bool = False, occupied_thresh: float = ROS_OCCUPIED_THRESH,
                       free_thresh: float = ROS_FREE_THRESH, mode: str = "trinary",
                       image_name: str | None = None) -> Path:
    """:func:`write_ros_map` of an image given as bands of rows, top band first, each written
    as it comes (a map larger than the memory one band takes); binary PGM (P5) only, the same
    bytes :func:`write_ros_map` writes for the whole image.

    Args:
        shape: (H, W) of the whole image, pixels.
        bands: (h_k, W) uint8 arrays whose rows add up to H, in order from row 0.
        Others: as :func:`write_ros_map` (``image_name`` must end in ``.pgm``).

    Raises:
        ValueError: a band of another width or type, or rows that do not add up to H (no
            image file is left).
    """
    yaml_path = Path(yaml_path)
    h, w = (int(v) for v in shape)
    if h <= 0 or w <= 0:
        raise ValueError(f"{yaml_path}: shape {tuple(shape)}; expected (H, W) > 0")
    image_name = _check_map_fields(yaml_path, resolution, origin, occupied_thresh, free_thresh, mode, image_name)
    if Path(image_name).suffix.lower() != ".pgm":
        raise ValueError(f"{yaml_path}: image name {image_name!r}; writing by bands of rows needs a .pgm file name")

    def chunks():
        yield b"P5\n%d %d\n255\n" % (w, h)
        rows = 0
        for band in bands:
            band = np.asarray(band)
            if band.ndim != 2 or band.shape[1] != w or band.dtype != np.uint8:
                raise ValueError(f"{yaml_path}: band of shape {band.shape} dtype {band.dtype} at row {rows}; "
                                 f"expected (rows, {w}) uint8")
            rows += band.shape[0]
            if rows > h:
                raise ValueError(f"{yaml_path}: bands hold more than the {h} rows of the image")
            yield np.ascontiguousarray(band).tobytes()
        if rows != h:
            raise ValueError(f"{yaml_path}: bands hold {rows} rows; expected {h}")

    atomic_write_chunks(yaml_path.parent / image_name, chunks())
    return _write_map_yaml(yaml_path, image_name, resolution, origin, negate, occupied_thresh, free_thresh, mode)


def _check_map_fields(yaml_path: Path, resolution: float, origin, occupied_thresh: float, free_thresh: float,
                      mode: str, image_name: str | None) -> str:
    """Refuse bad map settings in one line; the image file name (default ``<yaml stem>.pgm``)."""
    if mode not in MODES:
        raise ValueError(f"{yaml_path}: mode {mode!r}; expected one of {list(MODES)}")
    if not (math.isfinite(resolution) and resolution > 0):
        raise ValueError(f"{yaml_path}: resolution {resolution!r}; expected a positive number of metres/pixel")
    if not (0.0 <= free_thresh <= occupied_thresh <= 1.0):
        raise ValueError(f"{yaml_path}: thresholds free={free_thresh}, occupied={occupied_thresh}; expected "
                         f"0 <= free_thresh <= occupied_thresh <= 1")
    if len(origin) != 3 or not all(math.isfinite(float(v)) for v in origin):
        raise ValueError(f"{yaml_path}: origin {origin!r}; expected finite (x, y, yaw)")
    image_name = image_name or yaml_path.stem + ".pgm"
    if Path(image_name).suffix.lower() not in (".pgm", ".png"):
        raise ValueError(f"{yaml_path}: image name {image_name!r}; expected a .pgm or .png file name")
    return image_name


def _write_map_yaml(yaml_path: Path, image_name: str, resolution: float, origin, negate: bool,
                    occupied_thresh: float, free_thresh: float, mode: str) -> Path:
    text = (f"image: {image_name}\n"
            f"mode: {mode}\n"
            f"resolution: {_fmt(resolution)}\n"
            f"origin: [{_fmt(origin[0])}, {_fmt(origin[1])}, {_fmt(origin[2])}]\n"
            f"negate: {1 if negate else 0}\n"
            f"occupied_thresh: {_fmt(occupied_thresh)}\n"
            f"free_thresh: {_fmt(free_thresh)}\n")
    atomic_write_text(yaml_path, text)
    return yaml_path


def write_grid_ros(yaml_path: str | Path, grid: GridMap, image_name: str | None = None) -> Path:
    """Write a grid as a trinary ROS map (free 254, occupied 0) whose origin reproduces
    ``grid.origin`` when read back with :func:`read_ros_map`.

    Returns:
        The YAML path.
    """
    return write_ros_map(yaml_path, grid_to_ros_image(grid), grid.resolution, ros_origin_of(grid),
                         image_name=image_name)


# --------------------------------------------------------------------------- plain images and arrays


def _default_origin(origin, height_px: int, resolution: float) -> tuple[float, float]:
    if origin is None:  # bottom-left corner at world (0, 0), as a ROS map with origin [0, 0, 0]
        return ros_origin_to_grid_origin((0.0, 0.0), height_px, resolution)
    if len(origin) != 2:
        raise ValueError(f"origin {origin!r}; expected the (x0, z0) world position of the top-left corner")
    return float(origin[0]), float(origin[1])


def image_thresholds(preset: str = "ros", free_thresh: float | None = None, occupied_thresh: float | None = None,
                     where: str = "") -> tuple[float, float]:
    """The (free_thresh, occupied_thresh) a plain image is read with: the preset's
    (:data:`IMAGE_PRESETS`), each overridden by an explicit value.

    Args:
        preset: ``ros`` | ``white_only``.
        free_thresh, occupied_thresh: occupancy probabilities in [0, 1], or None (the preset's).
        where: prefix of the error lines (e.g. ``"env."``), naming the settings as the user
            writes them.

    Raises:
        ValueError: one line naming the setting, its value and what was expected.
    """
    if preset not in IMAGE_PRESETS:
        raise ValueError(f"{where}image_preset is {preset!r}; expected one of {list(IMAGE_PRESETS)}")
    free, occ = IMAGE_PRESETS[preset]
    for name, v in (("free_thresh", free_thresh), ("occupied_thresh", occupied_thresh)):
        if v is not None and (isinstance(v, bool) or not isinstance(v, (int, float)) or not 0.0 <= v <= 1.0):
            raise ValueError(f"{where}{name} is {v!r}; expected an occupancy probability in [0, 1] or null "
                             f"(the preset's)")
    free = free if free_thresh is None else float(free_thresh)
    occ = occ if occupied_thresh is None else float(occupied_thresh)
    if free > occ:
        raise ValueError(f"{where}free_thresh {free} > {where}occupied_thresh {occ} (preset {preset!r} and the "
                         f"values given); expected free_thresh <= occupied_thresh")
    return free, occ


def grey_pixels_note(grey: np.ndarray, free_thresh: float, occupied_thresh: float, negate: bool = False,
                     unknown_as: str = "obstacle", share: float = GREY_WARN_SHARE, top: int = 4) -> str | None:
    """What a plain image's grey pixels become, when they are many; else None.

    A pixel is *grey* when it is neither white (occupancy probability p < :data:`WHITE_P`
    = 0.02, grey >= 250 without ``negate``) nor read as occupied (p > ``occupied_thresh``):
    grey furniture, ``map_saver``'s 205 unknown, light anti-aliasing.

    Args:
        grey: (H, W) int pixel values 0..255.
        free_thresh, occupied_thresh, negate, unknown_as: how the image is read (with
            ``unknown_as="free"`` grey pixels between the thresholds are read as free too).
        share: the share of all pixels from which grey pixels are "many".
        top: how many of the commonest grey levels to name.

    Returns:
        None below ``share``; else one line: the share of grey pixels, the commonest grey
        levels with their shares, and the share of the image that is grey *and read as free*
        (``"... grey levels 178 (20.1 %), 211 (3.0 %); 3.0 % of the image is grey read as
        free ..."``).
    """
    g = np.asarray(grey, dtype=np.int64)
    p = g / 255.0 if negate else (255 - g) / 255.0
    is_grey = (p >= WHITE_P) & ~(p > occupied_thresh)
    n = g.size
    if not n or is_grey.sum() < share * n:
        return None
    counts = np.bincount(g[is_grey], minlength=256)
    levels = np.argsort(-counts, kind="stable")[:top]
    levels = [int(v) for v in levels if counts[v]]
    read_free = p < free_thresh if unknown_as != "free" else ~(p > occupied_thresh)
    free_grey = int((is_grey & read_free).sum())
    named = ", ".join(f"{v} ({100 * counts[v] / n:.1f} %)" for v in levels)
    return (f"{100 * is_grey.sum() / n:.1f} % of the pixels are grey (neither white nor occupied; commonest "
            f"levels {named}); {100 * free_grey / n:.1f} % of the image is grey read as free "
            f"(free_thresh {free_thresh:g}, occupied_thresh {occupied_thresh:g}, unknown_as {unknown_as})")


def occupancy_png(path: str | Path, resolution: float, origin: tuple[float, float] | None = None, *,
                  preset: str = "ros", free_thresh: float | None = None, occupied_thresh: float | None = None,
                  negate: bool = False, unknown_as: str = "obstacle", max_pixels: int | None = MAX_MAP_PIXELS,
                  warn: bool = True, where: str = "") -> GridMap:
    """A plain occupancy image (no YAML): free = light, occupied = dark.

    Pixels are interpreted as a ROS trinary map: with ``p = (255 - v) / 255`` (``v / 255``
    with ``negate``), free if ``p < free_thresh``, occupied if ``p > occupied_thresh``,
    unknown otherwise (an obstacle unless ``unknown_as="free"``). The thresholds are the
    ``preset``'s (:data:`IMAGE_PRESETS`: ``ros`` = a YAML without thresholds, 0.196 / 0.65;
    ``white_only`` = only grey >= 250 is free), each replaced by an explicit value.

    Args:
        path: the image (PNG, PGM, BMP; grey or colour).
        resolution: metres per pixel.
        origin: world (x0, z0) in metres of the top-left corner of pixel (0, 0); None puts
            the bottom-left corner of the image at world (0, 0).
        preset, free_thresh, occupied_thresh: see above (:func:`image_thresholds`).
        max_pixels: the largest image (width x height), checked on the header before
            decoding; ``None``: no limit.
        warn: warn (``UserWarning``, one line naming the file) when many pixels are grey
            (:func:`grey_pixels_note`).
        where: prefix of the settings named in error lines (``"env."``).

    Returns:
        The GridMap, (H, W) like the image.
    """
    path = Path(path).expanduser()
    if not path.is_file():
        raise FileNotFoundError(f"occupancy image not found: {path}")
    free, occ = image_thresholds(preset, free_thresh, occupied_thresh, where)
    grey, _ = _read_grey(path, "the map image", max_pixels)
    if warn:
        note = grey_pixels_note(grey, free, occ, negate, unknown_as)
        if note:
            warnings.warn(f"{path}: {note}; if only white is free in this map, read it with "
                          f"{where}image_preset=white_only", UserWarning, stacklevel=2)
    occ_map = image_to_occupancy(grey, None, negate, occ, free, "trinary")
    walk = walkable_from_occupancy(occ_map, unknown_as)
    return GridMap(walk, resolution, _default_origin(origin, walk.shape[0], resolution))


def read_npy_map(path: str | Path, max_pixels: int | None = MAX_MAP_PIXELS) -> np.ndarray:
    """A 2-D ``.npy`` map array, its declared shape checked against ``max_pixels`` before the
    data is read.

    Returns:
        The (H, W) array as stored.

    Raises:
        FileNotFoundError / ValueError: one line naming the file (missing, not a ``.npy``
        array, not 2-D, over the limit, truncated).
    """
    path = Path(path).expanduser()
    limit = check_max_map_pixels(max_pixels)
    if not path.is_file():
        raise FileNotFoundError(f"map not found: {path}")
    try:
        with path.open("rb") as f:
            fmt = np.lib.format
            version = fmt.read_magic(f)
            header = fmt.read_array_header_1_0 if version == (1, 0) else fmt.read_array_header_2_0
            shape, _, _ = header(f)  # the header only: no data read
    except (ValueError, OSError) as e:
        raise ValueError(f"{path}: not a .npy array ({e})") from None
    if len(shape) != 2:
        raise ValueError(f"{path}: .npy map has shape {shape}; expected a 2-D (H, W) array")
    if limit is not None and shape[0] * shape[1] > limit:
        raise ValueError(f"{path}: the .npy map declares {shape[1]} x {shape[0]} = {shape[0] * shape[1]} pixels, "
                         f"over the map-size limit of {limit} pixels (max_map_pixels); expected a smaller map, or "
                         f"raise max_map_pixels")
    try:
        return np.load(path, allow_pickle=False)
    except (ValueError, OSError) as e:
        raise ValueError(f"{path}: cannot read the .npy map ({e})") from None


def grid_from_array(array: np.ndarray, resolution: float, origin: tuple[float, float] | None = None, *,
                    free_value=None) -> GridMap:
    """A GridMap from a NumPy array.

    Args:
        array: (H, W) bool, True = walkable; or any (H, W) array with ``free_value`` given
            (walkable where ``array == free_value``, e.g. ``free_value=0`` for a ROS
            occupancy array). Row 0 is the top of the map.
        resolution: metres per pixel.
        origin: world (x0, z0) in metres of the top-left corner of pixel (0, 0); None puts
            the bottom-left corner at world (0, 0).

    Returns:
        The GridMap.
    """
    a = np.asarray(array)
    if a.ndim != 2 or a.size == 0:
        raise ValueError(f"map array must be a non-empty (H, W) array, got shape {a.shape}")
    if free_value is None:
        if a.dtype != bool:
            raise ValueError(f"map array has dtype {a.dtype}; expected bool (True = walkable), or pass free_value "
                             f"(the value of free cells)")
        walk = a
    else:
        walk = a == free_value
    return GridMap(walk, resolution, _default_origin(origin, a.shape[0], resolution))


__all__ = ["GREY_WARN_SHARE", "IMAGE_PRESETS", "MODES", "ROS_FREE_THRESH", "ROS_OCCUPIED_THRESH", "RosMap",
           "grey_pixels_note", "grid_from_array", "grid_to_ros_image", "image_thresholds", "image_to_occupancy",
           "occupancy_png", "read_npy_map", "read_ros_map", "ros_origin_of", "unknown_pixel",
           "walkable_from_occupancy", "write_grid_ros", "write_ros_map"]
