"""Pose files in: CSV or JSON, in the ROS frame or the simulator (project) frame.

The frame is always given explicitly (no guessing from the column names):

* ``frame="ros"``: columns ``x, y`` (metres) and ``theta`` (radians, counter-clockwise
  from +x), as a ROS ``geometry_msgs/Pose2D`` or a ``tf`` echo gives them; converted with
  :func:`envs.maps.frames.ros_to_world` (world ``z = y``, ``yaw = 90 - degrees(theta)``).
* ``frame="sim"``: columns ``x, z`` (metres) and ``yaw`` (degrees, 0 faces +z, 90 faces
  +x), the project's own convention (AI2-THOR's).
* ``frame="pixel"``: columns ``row, col`` (pixel indices of the map, row 0 on top; the pose
  is the pixel's centre) and ``yaw`` (project degrees); needs the ``grid``.

CSV: a header row naming the columns (case and surrounding spaces ignored; other columns
are allowed and ignored). JSON: a list of objects with those keys, or ``{"poses": [...]}``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd

from envs.maps.frames import ros_to_world
from envs.maps.gridmap import GridMap

#: The columns each frame needs, in order.
FRAME_COLUMNS = {"ros": ("x", "y", "theta"), "sim": ("x", "z", "yaw"), "pixel": ("row", "col", "yaw")}
_UNITS = {"ros": "x, y (metres), theta (radians, CCW from +x)", "sim": "x, z (metres), yaw (degrees)",
          "pixel": "row, col (pixels), yaw (degrees)"}
#: The largest magnitude a pose column may take, and its unit: positions within 1000 km of
#: the origin, headings within a few thousand turns (unwrapped odometry), pixels within 1e8.
#: A value beyond is a corrupt file, refused before any arithmetic can overflow.
LIMITS = {"x": (1e6, "metres"), "y": (1e6, "metres"), "z": (1e6, "metres"), "theta": (1e4, "radians"),
          "yaw": (1e6, "degrees"), "row": (1e8, "pixels"), "col": (1e8, "pixels")}


def read_table(path: str | Path, what: str = "pose", as_text: bool = False) -> pd.DataFrame:
    """A per-view table (poses, labels, images) from ``.csv`` (header row) or ``.json`` (a
    list of objects, or ``{"poses" | "labels" | "views": [...]}``): the one reader of such
    files, used by pose files, the image-folder renderer and the labels-file classifier.

    Args:
        path: the file.
        what: what the file holds, for error messages ("pose", "labels", "image pose").
        as_text: read CSV cells as text (label names stay strings, empty cells stay "").

    Returns:
        The DataFrame, one row per view in file order.

    Raises:
        ValueError: unreadable JSON or CSV, an empty file, or JSON of another shape (one line
            naming the file).
    """
    path = Path(path)
    if path.suffix.lower() == ".json":
        try:
            data = json.loads(path.read_text())
        except json.JSONDecodeError as e:
            raise ValueError(f"{path}: not valid JSON ({e.msg} at line {e.lineno})") from None
        if isinstance(data, dict):
            key = next((k for k in ("poses", "labels", "views") if k in data), None)
            data = data[key] if key else data
        if not isinstance(data, list) or not all(isinstance(d, dict) for d in data):
            raise ValueError(f"{path}: expected a list of {what} objects (one per view) or "
                             f"{{'poses' | 'labels' | 'views': [...]}}")
        return pd.DataFrame(data)
    try:
        kw = {"dtype": str, "keep_default_na": False} if as_text else {}
        return pd.read_csv(path, skipinitialspace=True, **kw)
    except pd.errors.EmptyDataError:
        raise ValueError(f"{path}: empty {what} file; expected a header row and one view per line") from None
    except pd.errors.ParserError as e:
        raise ValueError(f"{path}: not a readable CSV ({str(e).splitlines()[0]})") from None


def read_poses(path: str | Path, frame: str, grid: GridMap | None = None) -> np.ndarray:
    """Read a pose file -> (N, 3) float array of world ``x, z`` (metres), ``yaw`` (degrees).

    Args:
        path: a ``.csv`` or ``.json`` file.
        frame: ``"ros"`` (x, y, theta), ``"sim"`` (x, z, yaw) or ``"pixel"`` (row, col, yaw).
        grid: the map; needed for ``frame="pixel"`` only.

    Returns:
        (N, 3) float64: world x, z in metres and yaw in degrees (``"ros"`` yaws in [0, 360),
        ``"sim"``/``"pixel"`` yaws as written).

    Raises:
        FileNotFoundError: no such file.
        ValueError: one line naming the file and the columns expected and found, or the
            first bad value (row and column).
    """
    if frame not in FRAME_COLUMNS:
        raise ValueError(f"pose frame {frame!r} for {path}; expected one of {list(FRAME_COLUMNS)}")
    if frame == "pixel" and grid is None:
        raise ValueError(f"pose frame 'pixel' for {path} needs the map (grid)")
    path = Path(path).expanduser()
    if not path.is_file():
        raise FileNotFoundError(f"pose file not found: {path}")
    df = read_table(path)
    df.columns = [str(c).strip().lower() for c in df.columns]
    want = FRAME_COLUMNS[frame]
    missing = [c for c in want if c not in df.columns]
    if missing:
        raise ValueError(f"{path}: pose file lacks column(s) {missing} for frame {frame!r}; expected "
                         f"{_UNITS[frame]}, found columns {list(df.columns)}")
    return poses_from_table(df, path, frame, grid)


def _number(v) -> float | None:
    """A cell as a float, or None when it is not a number (text, a list, a bool, empty)."""
    if isinstance(v, bool | np.bool_) or v is None:
        return None
    try:
        return float(v)
    except (TypeError, ValueError):
        return None


def poses_from_table(df: pd.DataFrame, path: str | Path, frame: str, grid: GridMap | None = None) -> np.ndarray:
    """The poses of a per-view table (lower-case column names, the frame's columns present)
    -> (N, 3) float array of world ``x, z`` (metres), ``yaw`` (degrees); see :func:`read_poses`.

    Every cell of the frame's columns is checked before any arithmetic: a number, finite and
    within :data:`LIMITS` (so no NumPy warning can follow).

    Raises:
        ValueError: one line naming the file, the column, the pose (index from 0; for a CSV
            also its line, the header being line 1) and the value.
    """
    path = Path(path)
    arr = np.empty((len(df), 3))
    for j, c in enumerate(FRAME_COLUMNS[frame]):
        limit, unit = LIMITS[c]
        for i, raw in enumerate(df[c].tolist()):
            v = _number(raw)
            where = f"column {c!r} at pose index {i}" + (f" (line {i + 2})" if path.suffix.lower() == ".csv" else "")
            if v is None or not np.isfinite(v):
                what = "non-numeric" if v is None else "non-finite"
                raise ValueError(f"{path}: {what} value {raw!r} in {where}; expected {_UNITS[frame]}")
            if abs(v) > limit:
                raise ValueError(f"{path}: value {v:g} in {where} is out of range; expected |{c}| <= {limit:g} "
                                 f"{unit} ({_UNITS[frame]})")
            arr[i, j] = v
    if frame == "ros":
        x, z, yaw = ros_to_world(arr[:, 0], arr[:, 1], arr[:, 2])
        return np.column_stack([x, z, yaw])
    if frame == "pixel":
        if grid is None:
            raise ValueError(f"pose frame 'pixel' for {path} needs the map (grid)")
        x, z = grid.pixel_to_world(arr[:, 0], arr[:, 1])
        return np.column_stack([x, z, arr[:, 2]])
    return arr


__all__ = ["FRAME_COLUMNS", "LIMITS", "poses_from_table", "read_poses", "read_table"]
