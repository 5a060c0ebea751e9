"""Segmented maps out, for robots: index label PNGs, rooms as GeoJSON polygons, and the
segmentation as a ROS ``map_server`` map. Writers and readers only (no command code).

* **Index PNG** (:func:`write_index_png`): one grey value per pixel, the class index (label
  maps) or the segment id (instance maps). The value :data:`NO_VALUE_8` (255) marks a pixel
  with none (unlabelled, or not walkable); the image is 8-bit when every value fits in
  0..254, else 16-bit with :data:`NO_VALUE_16` (65535) as the marker.
* **Rooms GeoJSON** (:func:`rooms_geojson`): one Feature per segment, its geometry the exact
  union of the segment's pixel squares (a Polygon with holes, or a MultiPolygon where the
  segment's pixels touch only at a corner), in world metres of the map's frame: GeoJSON
  ``[x, y]`` = project world ``(x, z)`` = ROS map frame ``(x, y)``
  (:mod:`envs.maps.frames`). A pixel (r, c) is the square with corners
  ``x0 + c * res .. x0 + (c + 1) * res`` and ``z0 - (r + 1) * res .. z0 - r * res``, so
  rasterising the polygons at pixel centres gives back the segment map exactly.
  Exterior rings are counter-clockwise, holes clockwise (RFC 7946).
* **ROS segmentation map** (:func:`write_ros_segmentation`): the index values in a ``raw``
  mode ``map_server`` map with the grid's origin and resolution. ``map_server`` reads a raw
  value 0..100 as is and any other value (our 255) as unknown (-1), so a map with at most
  :data:`ROS_MAX_VALUES` (101) classes / segments loads in ROS with its class index (or
  segment id) as the cell value; more cannot be written.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np
import shapely
from scipy import ndimage
from shapely.geometry import Polygon, mapping
from shapely.geometry.polygon import orient

from envs.atomic import atomic_write_bytes, atomic_write_text
from envs.maps.gridmap import GridMap
from envs.maps.images import read_image
from envs.maps.ros import ros_origin_of, write_ros_map
from envs.maps.scene import MAX_MAP_PIXELS

#: Index-PNG value of a pixel with no class / segment (8-bit images).
NO_VALUE_8 = 255
#: Index-PNG value of a pixel with no class / segment (16-bit images, more than 255 values).
NO_VALUE_16 = 65535
#: Largest number of distinct values (0..100) a raw ROS map keeps.
ROS_MAX_VALUES = 101


def _check_index_map(values: np.ndarray, what: str) -> np.ndarray:
    v = np.asarray(values)
    if v.ndim != 2 or v.size == 0:
        raise ValueError(f"{what}: expected a non-empty (H, W) array, got shape {v.shape}")
    if not np.issubdtype(v.dtype, np.integer):
        raise ValueError(f"{what}: expected integer values (-1 = none), got dtype {v.dtype}")
    if v.size and v.min() < -1:
        raise ValueError(f"{what}: values below -1 ({int(v.min())}); expected -1 (none) or an index >= 0")
    return v  # its own integer type: no 8-byte-per-pixel copy of a large map


#: rows of a map :func:`value_counts` counts at a time
COUNT_BAND_ROWS = 1024


def value_counts(values: np.ndarray, n: int, band_rows: int = COUNT_BAND_ROWS) -> np.ndarray:
    """(n,) int64: how many pixels of the (H, W) int map ``values`` hold each value 0..n - 1
    (negative values are not counted; every value must be < n). ``np.bincount`` of the
    values >= 0, ``band_rows`` rows at a time: its 64-bit copy of the values is a band's, not
    the map's."""
    counts = np.zeros(n, np.int64)
    for r0 in range(0, values.shape[0], max(int(band_rows), 1)):
        band = values[r0:r0 + max(int(band_rows), 1)]
        counts += np.bincount(band[band >= 0].ravel(), minlength=n)
    return counts


def _marked(v: np.ndarray, dtype, marker: int) -> np.ndarray:
    """``v`` (values -1..marker - 1) as ``dtype`` with ``marker`` for -1, without an int64
    temporary (a large map's image costs its own bytes and a bool mask)."""
    img = v.astype(dtype)
    img[v < 0] = marker
    return img


def index_image(values: np.ndarray) -> tuple[np.ndarray, int]:
    """(H, W) int map (-1 = none) -> (image, no-value marker).

    Returns:
        (H, W) uint8 with 255 for -1 when every value is <= 254, else (H, W) uint16 with
        65535 for -1; and the marker used. ValueError for a value above 65534.
    """
    v = _check_index_map(values, "index map")
    top = int(v.max())
    if top < NO_VALUE_8:
        return _marked(v, np.uint8, NO_VALUE_8), NO_VALUE_8
    if top < NO_VALUE_16:
        return _marked(v, np.uint16, NO_VALUE_16), NO_VALUE_16
    raise ValueError(f"index map: value {top} does not fit a 16-bit PNG (at most {NO_VALUE_16 - 1})")


def write_index_png(path: str | Path, values: np.ndarray) -> Path:
    """Write an (H, W) int map (class index or segment id per pixel, -1 = none) as a grey PNG,
    atomically: 8-bit with 255 = none, or 16-bit with 65535 = none when a value exceeds 254.

    Returns:
        The path written.
    """
    path = Path(path)
    img, _ = index_image(values)
    ok, buf = cv2.imencode(".png", img)
    if not ok:
        raise ValueError(f"{path}: OpenCV could not encode the index PNG")
    atomic_write_bytes(path, buf.tobytes())
    return path


def read_index_png(path: str | Path, max_pixels: int | None = MAX_MAP_PIXELS) -> np.ndarray:
    """Read an index PNG written by :func:`write_index_png`.

    Args:
        path: the PNG.
        max_pixels: the largest image read, checked on its header before decoding
            (:func:`envs.maps.images.read_image`); ``None``: no limit.

    Returns:
        (H, W) int32: the value per pixel, -1 where the image holds its no-value marker (255
        in an 8-bit image, 65535 in a 16-bit one).
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"index PNG not found: {path}")
    img = read_image(path, "the index PNG", None, max_pixels)
    if img.ndim != 2 or img.dtype not in (np.uint8, np.uint16):
        raise ValueError(f"{path}: expected a single-channel (grey) 8- or 16-bit index PNG, got shape {img.shape} "
                         f"dtype {img.dtype}")
    marker = NO_VALUE_8 if img.dtype == np.uint8 else NO_VALUE_16
    out = img.astype(np.int32)
    out[img == marker] = -1
    return out


# --------------------------------------------------------------------------- polygons


def mask_polygon(mask: np.ndarray) -> shapely.Geometry:
    """The exact outline of a mask's pixels, in pixel-edge coordinates.

    Pixel (r, c) is the unit square ``[c, c + 1] x [r, r + 1]`` in (x = column, y = row).
    The outline is traced with ``cv2.findContours`` on the mask enlarged 2x (each pixel a
    2 x 2 block), whose boundary sub-pixels at 2k and 2k + 1 lie a quarter pixel inside the
    pixel edges k and k + 1; ``(i + 1) // 2`` of a sub-pixel coordinate ``i`` snaps it
    onto the edge.

    Args:
        mask: (H, W) bool.

    Returns:
        A valid Polygon / MultiPolygon (empty when the mask is) whose area equals the pixel
        count and whose interior holds exactly the centres of the mask's pixels.
    """
    m = np.asarray(mask, dtype=np.uint8)
    if not m.any():
        return Polygon()
    up = np.pad(np.repeat(np.repeat(m, 2, axis=0), 2, axis=1), 1)
    contours, hier = cv2.findContours(up, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_SIMPLE)
    # padding shifts sub-pixel indices by 1: edge = ((i - 1) + 1) // 2 = i // 2
    rings = [c[:, 0, :] // 2 for c in contours]
    parts = []
    for i, h in enumerate(hier[0]):
        if h[3] >= 0 or len(rings[i]) < 3:
            continue
        holes = [rings[j] for j, hj in enumerate(hier[0]) if hj[3] == i and len(rings[j]) >= 3]
        parts.append(shapely.make_valid(Polygon(rings[i], holes)))
    geom = shapely.union_all(parts)
    # drop the repeated and collinear vertices the hole traces leave (tolerance 0: exact)
    return shapely.normalize(shapely.simplify(geom, 0.0, preserve_topology=True))


def pixel_to_world_geometry(geom: shapely.Geometry, grid: GridMap, decimals: int = 9) -> shapely.Geometry:
    """Pixel-edge (x = column, y = row) geometry -> world metres ``(x, z)`` of ``grid``:
    ``x = x0 + col * res``, ``z = z0 - row * res``, rounded to ``decimals``; rings
    re-oriented (exterior counter-clockwise)."""
    x0, z0 = grid.origin
    res = grid.resolution

    def tf(xy: np.ndarray) -> np.ndarray:
        return np.round(np.column_stack([x0 + xy[:, 0] * res, z0 - xy[:, 1] * res]), decimals)

    out = shapely.transform(geom, tf)
    if out.geom_type == "Polygon":
        return orient(out, 1.0)
    if out.geom_type == "MultiPolygon":
        return shapely.MultiPolygon([orient(p, 1.0) for p in out.geoms])
    return out


def rooms_geojson(segments: np.ndarray, grid: GridMap, segment_classes: Sequence[str | None] | None = None,
                  frame: str = "map", extra: dict | None = None) -> dict:
    """Segments -> a GeoJSON FeatureCollection, one Feature per segment id present.

    Args:
        segments: (H, W) int segment ids 0..S-1 (-1 = none), on ``grid``.
        grid: the map (resolution, origin); the geometry is in its world metres.
        segment_classes: class name of each segment id (None for none), or None for an
            instance map with no classes.
        frame: the frame name stored in the collection's ``frame`` member.
        extra: more top-level members (e.g. the input map's path).

    Returns:
        ``{"type": "FeatureCollection", "frame", "resolution", "features": [...]}``; each
        Feature's properties: ``segment`` (id), ``class`` (name or None), ``area_m2``
        (pixel count x res^2, equal to the polygon's area), ``pixels``.
    """
    seg = _check_index_map(segments, "segment map")
    if seg.shape != grid.shape:
        raise ValueError(f"segment map shape {seg.shape} differs from the map's {grid.shape}")
    n = int(seg.max()) + 1 if (seg >= 0).any() else 0
    if segment_classes is not None and len(segment_classes) < n:
        raise ValueError(f"segment map has {n} segments but {len(segment_classes)} segment classes")
    boxes = ndimage.find_objects(seg + 1, max_label=n) if n else []
    feats = []
    counts = value_counts(seg, n)
    for k in range(n):
        if boxes[k] is None:
            continue
        rs, cs = boxes[k]
        local = mask_polygon(seg[rs, cs] == k)
        geom = pixel_to_world_geometry(_translate(local, cs.start, rs.start), grid)
        props = {"segment": k,
                 "class": (segment_classes[k] if segment_classes is not None else None),
                 "area_m2": round(float(counts[k]) * grid.resolution ** 2, 6),
                 "pixels": int(counts[k])}
        feats.append({"type": "Feature", "id": k, "properties": props, "geometry": mapping(geom)})
    out = {"type": "FeatureCollection", "frame": frame, "resolution": grid.resolution,
           "grid_origin": list(grid.origin), "grid_shape": list(grid.shape)}
    out.update(extra or {})
    out["features"] = feats
    return out


def _translate(geom: shapely.Geometry, dx: float, dy: float) -> shapely.Geometry:
    return shapely.transform(geom, lambda xy: xy + np.array([dx, dy], dtype=float))


def write_rooms_geojson(path: str | Path, segments: np.ndarray, grid: GridMap,
                        segment_classes: Sequence[str | None] | None = None, frame: str = "map",
                        extra: dict | None = None) -> Path:
    """:func:`rooms_geojson` written to ``path`` atomically.

    Returns:
        The path written.
    """
    path = Path(path)
    gj = rooms_geojson(segments, grid, segment_classes, frame, extra)
    atomic_write_text(path, json.dumps(gj, separators=(",", ":")))
    return path


def write_ros_segmentation(yaml_path: str | Path, values: np.ndarray, grid: GridMap,
                           ros_origin: tuple[float, float, float] | None = None,
                           image_name: str | None = None) -> Path:
    """Write an index map (class index or segment id, -1 = none) as a raw-mode ROS map.

    Args:
        yaml_path: the YAML to write (the image beside it, ``<stem>.png`` by default).
        values: (H, W) int on ``grid``, values in -1..100.
        grid: the map; the ROS origin is the grid's (:func:`envs.maps.ros.ros_origin_of`)
            unless ``ros_origin`` (x, y, yaw) is given (e.g. the input YAML's).
        image_name: the image file name.

    Returns:
        The YAML path. ValueError when a value exceeds 100 (ROS reads it as unknown).
    """
    yaml_path = Path(yaml_path)
    v = _check_index_map(values, f"{yaml_path}: segmentation")
    if v.shape != grid.shape:
        raise ValueError(f"{yaml_path}: segmentation shape {v.shape} differs from the map's {grid.shape}")
    if int(v.max()) >= ROS_MAX_VALUES:
        raise ValueError(f"{yaml_path}: value {int(v.max())} does not fit a raw ROS map (0..100 are read as is, "
                         f"others as unknown)")
    img = _marked(v, np.uint8, NO_VALUE_8)
    origin = tuple(ros_origin) if ros_origin is not None else ros_origin_of(grid)
    return write_ros_map(yaml_path, img, grid.resolution, origin, negate=False, mode="raw",
                         image_name=image_name or yaml_path.stem + ".png")


__all__ = ["NO_VALUE_8", "NO_VALUE_16", "ROS_MAX_VALUES", "index_image", "mask_polygon", "pixel_to_world_geometry",
           "read_index_png", "rooms_geojson", "write_index_png", "write_rooms_geojson", "write_ros_segmentation"]
