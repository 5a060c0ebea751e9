"""Viewpoints: where the robot takes its pictures.

* :class:`Autotrace` — the paper's wall-following autotrace: the walkable area is shrunk by
  ``offset`` metres (distance transform), the contours of what is left (outer boundaries and
  the rings around furniture islands) form the path, points are sampled every ``spacing``
  metres along each contour, and each point gets ``n_headings`` headings spread over
  ``heading_spread`` degrees around the inward normal (the direction away from the nearest
  wall). Every pose lies on a cell at least ``offset`` metres from any obstacle. A walkable
  region narrower than ``2 * offset`` has no path and gets no viewpoint.
* :class:`FromFile` — poses recorded elsewhere (teleoperation, a robot's log): CSV or JSON
  read by :func:`envs.maps.pose_files.read_poses` in an explicit ``frame``: ``sim``
  (``x, z, yaw``: metres, degrees; the default), ``ros`` (``x, y, theta``: metres, radians
  CCW from +x) or ``pixel`` (``row, col, yaw``). The path may contain ``{house_id}``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import cv2
import numpy as np
from scipy import ndimage

from benchmark.interfaces import Viewpoints
from envs.maps.distance import distance_px
from envs.maps.gridmap import GridMap, pixel_direction_to_yaw
from envs.maps.pose_files import FRAME_COLUMNS, read_poses
from envs.maps.scene import Scene
from envs.ranges import HEADING_SPREAD, Integer, NonNegative, OneOf, Positive


def clearance_px(walkable: np.ndarray) -> np.ndarray:
    """(H, W) float: each cell's distance in pixels to the nearest non-walkable cell, the map's
    edge counting as one (0 on non-walkable cells)."""
    return distance_px(np.pad(walkable, 1))[1:-1, 1:-1]


def trace_path(walkable: np.ndarray, offset_px: float, dist: np.ndarray | None = None) -> list[np.ndarray]:
    """Closed contours (each (L, 2) int (row, col), in order) of the walkable cells whose
    distance to the nearest obstacle is more than ``offset_px`` pixels (``dist``: the
    :func:`clearance_px` of ``walkable`` when the caller has it)."""
    dist = clearance_px(walkable) if dist is None else dist
    inner = (dist > offset_px).astype(np.uint8)
    contours, _ = cv2.findContours(inner, cv2.RETR_LIST, cv2.CHAIN_APPROX_NONE)
    return [c[:, 0, ::-1].astype(np.int64) for c in contours]


def sample_along(contour: np.ndarray, spacing_px: float) -> np.ndarray:
    """Indices of points every ``spacing_px`` pixels of arc length along a closed contour
    (the first at half a spacing; a contour shorter than one spacing gets one point)."""
    n = len(contour)
    if n == 1:
        return np.zeros(1, dtype=np.int64)
    steps = np.linalg.norm(np.diff(np.vstack([contour, contour[:1]]), axis=0), axis=1)
    arc = np.concatenate([[0.0], np.cumsum(steps)[:-1]])
    total = steps.sum()
    targets = np.arange(spacing_px / 2, total, spacing_px) if total >= spacing_px else np.array([0.0])
    return np.unique(np.clip(np.searchsorted(arc, targets), 0, n - 1))


class Autotrace(Viewpoints):
    """Wall-following autotrace viewpoints.

    Args:
        offset: distance of the path from walls and furniture, metres.
        spacing: distance between sampled points along the path, metres.
        n_headings: headings per point.
        heading_spread: total angle the headings span, degrees, centred on the inward normal
            (n_headings=1 looks straight inward).
        min_contour: contours shorter than this (metres) are skipped (tiny islands).
    """

    def __init__(self, offset: Annotated[float, NonNegative()] = 0.5,
                 spacing: Annotated[float, Positive()] = 1.0, n_headings: Annotated[int, Integer(1)] = 3,
                 heading_spread: Annotated[float, HEADING_SPREAD] = 180.0,
                 min_contour: Annotated[float, NonNegative()] = 0.5):
        if offset < 0 or spacing <= 0 or n_headings < 1:
            raise ValueError(f"Autotrace needs offset >= 0, spacing > 0, n_headings >= 1; got "
                             f"offset={offset}, spacing={spacing}, n_headings={n_headings}")
        self.offset, self.spacing, self.n_headings = offset, spacing, n_headings
        self.heading_spread, self.min_contour = heading_spread, min_contour

    def path(self, grid: GridMap, dist: np.ndarray | None = None) -> list[np.ndarray]:
        """The traced contours (pixel (row, col) arrays) long enough to be kept (``dist``: the
        grid's :func:`clearance_px`, when the caller has it)."""
        res = grid.resolution
        cs = trace_path(grid.walkable, self.offset / res, dist)
        return [c for c in cs if len(c) * res >= self.min_contour]

    def generate(self, scene: Scene | GridMap) -> np.ndarray:
        """(N, 3) poses (x, z, yaw degrees) on the traced path."""
        grid = scene.grid if isinstance(scene, Scene) else scene
        res = grid.resolution
        dist = clearance_px(grid.walkable)
        gr, gc = np.gradient(ndimage.gaussian_filter(dist, 1.0))
        pts = []
        for c in self.path(grid, dist):
            idx = sample_along(c, self.spacing / res)
            pts.append(c[idx])
        if not pts:
            return np.zeros((0, 3))
        p = np.vstack(pts)
        inward = pixel_direction_to_yaw(gr[p[:, 0], p[:, 1]], gc[p[:, 0], p[:, 1]])
        if self.n_headings == 1:
            rel = np.zeros(1)
        else:
            full = abs(self.heading_spread) >= 360
            rel = np.linspace(-self.heading_spread / 2, self.heading_spread / 2, self.n_headings,
                              endpoint=not full)
        x, z = grid.pixel_to_world(p[:, 0], p[:, 1])
        yaw = np.mod(inward[:, None] + rel[None, :], 360.0)
        n = len(p)
        return np.column_stack([np.repeat(x, len(rel)), np.repeat(z, len(rel)), yaw.reshape(n * len(rel))])


def load_poses(path: str | Path, frame: str = "sim", grid: GridMap | None = None) -> np.ndarray:
    """Read poses from a CSV or JSON file -> (N, 3) float world x, z (metres), yaw (degrees).

    The file reading (columns per ``frame``: ``sim`` x, z, yaw; ``ros`` x, y, theta;
    ``pixel`` row, col, yaw) is :func:`envs.maps.pose_files.read_poses`.
    """
    return read_poses(path, frame, grid)


class FromFile(Viewpoints):
    """Poses from a file (``path`` may contain ``{house_id}``) in the given ``frame``
    (``sim``: x, z, yaw degrees; ``ros``: x, y, theta radians CCW; ``pixel``: row, col, yaw);
    every pose must be on a walkable cell of the map, or ``off_map="drop"`` drops the others."""

    def __init__(self, path: str, off_map: Annotated[str, OneOf("error", "drop")] = "error",
                 frame: str = "sim"):
        if off_map not in ("error", "drop"):
            raise ValueError(f"off_map must be 'error' or 'drop', got {off_map!r}")
        if frame not in FRAME_COLUMNS:
            raise ValueError(f"viewpoints frame must be one of {list(FRAME_COLUMNS)}, got {frame!r}")
        self.path, self.off_map, self.frame = path, off_map, frame

    def generate(self, scene: Scene) -> np.ndarray:
        path = str(self.path).format(house_id=scene.house_id)
        poses = load_poses(path, self.frame, scene.grid)
        r, c = scene.grid.world_to_cell(poses[:, 0], poses[:, 1])
        ok = scene.grid.is_walkable(r, c)
        if not ok.all():
            bad = np.nonzero(~ok)[0]
            if self.off_map == "error":
                raise ValueError(f"{path}: {len(bad)} of {len(poses)} poses are off the walkable map of house "
                                 f"{scene.house_id!r}, first at index {bad[0]}: x={poses[bad[0], 0]:.3f}, "
                                 f"z={poses[bad[0], 1]:.3f}")
            poses = poses[ok]
        return poses


def room_coverage(scene: Scene, poses: np.ndarray) -> tuple[int, int, list[tuple[int, float]]]:
    """(rooms with a pose, rooms, [(room index, its largest clearance in metres)] for rooms with none)."""
    grid = scene.grid
    r, c = grid.world_to_cell(poses[:, 0], poses[:, 1])
    visited = set(scene.instances[r, c].tolist()) if len(poses) else set()
    dist = clearance_px(grid.walkable) * grid.resolution
    rooms = [k for k in range(len(scene.instance_classes)) if (scene.instances == k).any()]
    missed = [(k, float(dist[scene.instances == k].max())) for k in rooms if k not in visited]
    return len(rooms) - len(missed), len(rooms), missed
