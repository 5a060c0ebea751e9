"""The occupancy grid: walkable mask, resolution, origin and world <-> pixel transforms.

Conventions (fixed once, tested in ``tests/test_gridmap.py``):

* World coordinates are the simulator's floor plane: ``x`` (metres) and ``z`` (metres),
  as in AI2-THOR / ProcTHOR (y is up).
* Pixel ``(row, col)``: ``col`` grows with ``x``; ``row`` grows as ``z`` *decreases*, so a
  map drawn with row 0 at the top shows the same picture as AI2-THOR's top-down camera
  (x to the right, z up).
* ``origin = (x0, z0)`` is the world position of the *top-left corner* of pixel (0, 0);
  the centre of pixel (r, c) is ``x = x0 + (c + 0.5) * res``, ``z = z0 - (r + 0.5) * res``.
* Yaw is the simulator's: degrees, 0 faces +z, 90 faces +x (clockwise seen from above).
  On the map a yaw of 0 points up (decreasing row) and 90 points right.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class GridMap:
    """A 2D occupancy grid.

    Attributes:
        walkable: (H, W) bool, True where the robot can stand.
        resolution: metres per pixel.
        origin: world (x, z) in metres of the top-left corner of pixel (0, 0).
    """

    walkable: np.ndarray
    resolution: float
    origin: tuple[float, float]

    def __post_init__(self) -> None:
        w = np.asarray(self.walkable)
        if w.ndim != 2:
            raise ValueError(f"GridMap.walkable must be 2-D (H, W), got shape {w.shape}")
        if w.size == 0:
            raise ValueError("GridMap.walkable is empty (a 0-sized map)")
        if not (np.isfinite(self.resolution) and self.resolution > 0):
            raise ValueError(f"GridMap.resolution must be a positive number of metres/pixel, got {self.resolution}")
        if len(self.origin) != 2 or not np.all(np.isfinite(self.origin)):
            raise ValueError(f"GridMap.origin must be a finite (x, z) pair, got {self.origin}")
        object.__setattr__(self, "walkable", w.astype(bool, copy=False))
        object.__setattr__(self, "origin", (float(self.origin[0]), float(self.origin[1])))
        object.__setattr__(self, "resolution", float(self.resolution))

    @property
    def shape(self) -> tuple[int, int]:
        """(H, W) in pixels."""
        return self.walkable.shape  # type: ignore[return-value]

    @property
    def extent(self) -> tuple[float, float, float, float]:
        """World bounds (x_min, x_max, z_min, z_max) in metres."""
        h, w = self.shape
        x0, z0 = self.origin
        return (x0, x0 + w * self.resolution, z0 - h * self.resolution, z0)

    def world_to_pixel(self, x, z):
        """World (x, z) metres -> continuous pixel (row, col); pixel centres are at .5 + integer - .5.

        Returns float arrays; ``np.floor`` of them gives the pixel index containing the point.
        """
        return self._pixel(np.asarray(x, dtype=float), np.asarray(z, dtype=float))

    def _pixel(self, x, z):
        """The one world -> continuous pixel formula, for arrays and plain floats alike."""
        return (self.origin[1] - z) / self.resolution, (x - self.origin[0]) / self.resolution

    def world_to_cell(self, x, z):
        """World (x, z) metres -> integer pixel (row, col) containing the point."""
        row, col = self.world_to_pixel(x, z)
        return np.floor(row).astype(np.int64), np.floor(col).astype(np.int64)

    def cell_of(self, x: float, z: float) -> tuple[int, int]:
        """:meth:`world_to_cell` of one point, as Python ints, without NumPy's cost per scalar (the
        same IEEE arithmetic on plain floats): for loops over many single points."""
        row, col = self._pixel(float(x), float(z))
        return math.floor(row), math.floor(col)

    def pixel_to_world(self, row, col):
        """Pixel (row, col) -> world (x, z) metres; integer indices give pixel centres."""
        row = np.asarray(row, dtype=float)
        col = np.asarray(col, dtype=float)
        x = self.origin[0] + (col + 0.5) * self.resolution
        z = self.origin[1] - (row + 0.5) * self.resolution
        return x, z

    def in_bounds(self, row, col) -> np.ndarray:
        """True where integer pixel (row, col) lies on the map."""
        row = np.asarray(row)
        col = np.asarray(col)
        h, w = self.shape
        return (row >= 0) & (row < h) & (col >= 0) & (col < w)

    def is_walkable(self, row, col) -> np.ndarray:
        """True where integer pixel (row, col) is on the map and walkable."""
        row, col = np.broadcast_arrays(np.asarray(row, np.int64), np.asarray(col, np.int64))
        ok = self.in_bounds(row, col)
        out = np.zeros(row.shape, dtype=bool)
        out[ok] = self.walkable[row[ok], col[ok]]
        return out

def yaw_to_pixel_direction(yaw_deg):
    """Simulator yaw (degrees) -> unit direction (d_row, d_col) on the map."""
    a = np.deg2rad(np.asarray(yaw_deg, dtype=float))
    return -np.cos(a), np.sin(a)


def pixel_direction_to_yaw(d_row, d_col):
    """Map direction (d_row, d_col) -> simulator yaw in degrees, in [0, 360)."""
    return np.mod(np.rad2deg(np.arctan2(d_col, -np.asarray(d_row, dtype=float))), 360.0)
