"""ROSE² as a geometric segmenter (``segmenter=rose2``): the user's checkout of ROSE² (Luperto et
al., RA-L 2022; public repository aislabunimi/ROSE2) run in its own isolated environment, one
subprocess per map, through the project's own driver (:mod:`benchmark.segmenters.rose2_driver`;
the project contains none of ROSE²'s code).

What ROSE² gets: the occupancy map the other segmenters get (``grid.walkable``), **resampled to
0.05 m/px** (nearest), the resolution its pixel parameters were tuned for (Hough segment
lengths, offsets, post-processing areas), as the image its ROS node builds from an
``OccupancyGrid``: free (255) = walkable; occupied (0) = the non-walkable cells within
``wall_m`` metres of free space (a wall as a laser map draws it); unknown (200) = the rest, with a
margin of ``margin_m`` metres of unknown around the map (ROSE's contour step needs the map not
to touch the image border). Its rooms (polygons in that image's pixels) are rasterised back onto
the input grid's walkable cells (pixel centres inside a room; a cell in several rooms takes the
first), and rooms under ``min_room_area`` merge into the neighbour sharing the longest border, as
every geometric segmenter here ends (:func:`benchmark.segmenters.common.merge_small_rooms`).
Walkable cells no room covers stay unlabelled (ROSE²'s own output).

A map on which ROSE² fails (two main directions or fewer, "not enough directions", which its ROS
node skips; no wall found; a crash inside it) or which takes longer than ``timeout`` seconds
raises one line with the reason: a failed row of that map, never a crash of the sweep. The
seconds ROSE² took go into the row (``t_rose2``).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import tempfile
import time
from pathlib import Path
from typing import Annotated

import numpy as np
from scipy import ndimage

from benchmark.guarded import run_guarded
from benchmark.interfaces import Segmenter
from benchmark.segmenters.common import check_room_area, clean_dead_tmp, merge_small_rooms
from envs.maps.gridmap import GridMap
from envs.ranges import NonNegative

#: metres per pixel ROSE²'s pixel parameters were tuned for (the maps of its paper).
ROSE2_RESOLUTION = 0.05
#: the environment variable naming the checkout when the config does not.
CHECKOUT_ENV = "ROOMSEG_ROSE2"
#: the interpreter of the isolated environment ``make rose2-env`` creates.
DEFAULT_PYTHON = Path(__file__).resolve().parents[2] / ".venv-rose2" / "bin" / "python"
DRIVER = Path(__file__).with_name("rose2_driver.py")
FREE, UNKNOWN, OCCUPIED = 255, 200, 0
#: name prefix of a driver's folder in the temporary folder: ``roomseg-rose2-<pid>-<random>``.
TMP_PREFIX = "roomseg-rose2-"


def checkout_words(checkout: str | Path) -> str:
    """Which ROSE2 a table's rows come from, in words: ``a ROSE2 checkout at commit 3a010b9e``
    (its git HEAD, 8 hex digits), or ``a ROSE2 checkout of unknown commit`` (no git history)."""
    import subprocess  # noqa: PLC0415

    try:
        head = subprocess.run(["git", "-C", str(Path(checkout).expanduser()), "rev-parse", "--short=8", "HEAD"],
                              capture_output=True, text=True, timeout=30)
    except (OSError, subprocess.SubprocessError):
        return "a ROSE2 checkout of unknown commit"
    sha = head.stdout.strip()
    return f"a ROSE2 checkout at commit {sha}" if head.returncode == 0 and sha else "a ROSE2 checkout of unknown commit"


def clean_rose2_tmp() -> list[Path]:
    """Remove the driver folders (``<tmp>/roomseg-rose2-<pid>-*``) of processes that are gone
    (killed before they could remove their own); returns the folders removed."""
    return clean_dead_tmp(TMP_PREFIX)


def rose2_image(walkable: np.ndarray, resolution: float, wall_m: float = 0.2, margin_m: float = 1.0
                ) -> tuple[np.ndarray, int, int]:
    """The map as ROSE²'s ROS node sees it, at :data:`ROSE2_RESOLUTION`.

    Args:
        walkable: (H, W) bool on a grid of ``resolution`` m/px (row 0 at the top).
        wall_m: non-walkable cells within this distance of free space are occupied, metres.
        margin_m: unknown margin added around the map, metres.

    Returns:
        (image (h, w) uint8: 255 free, 200 unknown, 0 occupied, row 0 at the *bottom* as in an
        ``OccupancyGrid``; the resampled map's height and the margin, both in image pixels).
    """
    h, w = walkable.shape
    scale = resolution / ROSE2_RESOLUTION
    hh, ww = max(1, int(round(h * scale))), max(1, int(round(w * scale)))
    rows = np.minimum(((np.arange(hh) + 0.5) / scale).astype(np.int64), h - 1)
    cols = np.minimum(((np.arange(ww) + 0.5) / scale).astype(np.int64), w - 1)
    free = walkable[rows][:, cols]
    band = max(1, int(round(wall_m / ROSE2_RESOLUTION)))
    pad = max(1, int(round(margin_m / ROSE2_RESOLUTION)))
    free = np.pad(free, pad)
    img = np.full(free.shape, UNKNOWN, np.uint8)
    img[(ndimage.distance_transform_edt(~free) <= band) & ~free] = OCCUPIED  # within wall_m of free space
    img[free] = FREE
    return np.ascontiguousarray(img[::-1]), hh, pad


def rooms_to_instances(rooms: list[dict], grid: GridMap, image_height: int, pad: int) -> np.ndarray:
    """ROSE²'s room polygons (pixels of :func:`rose2_image`'s image) -> (H, W) int32 room ids on
    the grid's walkable cells (-1 elsewhere); a cell inside several rooms takes the first."""
    import shapely

    h, w = grid.shape
    scale = grid.resolution / ROSE2_RESOLUTION
    rr, cc = np.mgrid[0:h, 0:w]
    # the centre of grid cell (r, c) in the image's pixel coordinates (x right, y up from its bottom row)
    x = (cc + 0.5) * scale - 0.5 + pad
    y = (image_height - (rr + 0.5) * scale) - 0.5 + pad
    out = np.full((h, w), -1, np.int32)
    walk = grid.walkable
    for k, room in enumerate(rooms):
        poly = shapely.Polygon(room["exterior"], room.get("interiors") or None)
        if not poly.is_valid:
            poly = poly.buffer(0)  # a self-touching ring: the same area, valid
        if poly.is_empty:
            continue
        inside = shapely.contains_xy(poly, x, y) & walk & (out < 0)
        out[inside] = k
    return out


class Rose2(Segmenter):
    """ROSE² on the grid's walkable map (module doc).

    Args:
        checkout: the ROSE2 repository checkout (its ``src/`` holds ``rose_v1_repo`` and
            ``rose_v2_repo``); None: ``$ROOMSEG_ROSE2``.
        python: the isolated environment's interpreter (``make rose2-env``); None: ``.venv-rose2``.
        timeout: seconds per map before it is stopped (a failed row).
        filter: ROSE's filter level (0..1: the share of non-structural pixels removed).
        wall_m, margin_m: how the map is drawn for ROSE² (metres; module doc).
        min_room_area: smaller rooms merge into a neighbour, square metres.
    """

    def __init__(self, checkout: str | None = None, python: str | None = None, timeout: float = 300.0,
                 filter: float = 0.18, wall_m: float = 0.2, margin_m: float = 1.0,
                 min_room_area: Annotated[float, NonNegative()] = 1.0):
        checkout = checkout or os.environ.get(CHECKOUT_ENV)
        if not checkout:
            raise ValueError(f"segmenter=rose2 needs a ROSE2 checkout: set segmenter.checkout=PATH or {CHECKOUT_ENV}=PATH "
                             f"(git clone https://github.com/aislabunimi/ROSE2), then make rose2-env")
        src = Path(checkout).expanduser() / "src"
        if not (src / "rose_v2_repo" / "minibatch.py").is_file() or not (src / "rose_v1_repo").is_dir():
            raise ValueError(f"segmenter.checkout={checkout}: not a ROSE2 checkout (no src/rose_v2_repo/minibatch.py)")
        py = Path(python).expanduser() if python else DEFAULT_PYTHON
        if not py.is_file():
            raise ValueError(f"segmenter.python={py}: no interpreter there; run `make rose2-env ROSE2={checkout}` "
                             f"(an isolated environment with the versions ROSE2 needs)")
        if not (isinstance(timeout, int | float) and timeout > 0):
            raise ValueError(f"segmenter.timeout={timeout!r}: expected seconds > 0")
        if not 0 <= filter <= 1:
            raise ValueError(f"segmenter.filter={filter!r}: expected a share in [0, 1]")
        if wall_m <= 0 or margin_m <= 0:
            raise ValueError(f"segmenter.wall_m={wall_m!r}, margin_m={margin_m!r}: expected metres > 0")
        self.checkout, self.python, self.timeout = Path(checkout).expanduser(), py, float(timeout)
        self.filter, self.wall_m, self.margin_m = float(filter), float(wall_m), float(margin_m)
        self.min_room_area = check_room_area(min_room_area)
        self.last_info: dict[str, float] = {}

    def run_driver(self, image: np.ndarray) -> dict:
        """One subprocess of the driver on ``image``; the driver's JSON result.

        The driver runs under :func:`benchmark.guarded.run_guarded`: in a process
        group of its own, killed whole (with whatever ROSE² started) on a timeout or when this
        process dies, its output bounded; its folder ``<tmp>/roomseg-rose2-<pid>-*`` goes with
        it, and folders of processes that are gone are removed first (:func:`clean_rose2_tmp`).

        Raises:
            RuntimeError: a timeout, or the driver could not run (one line)."""
        clean_rose2_tmp()
        tmp = Path(tempfile.mkdtemp(prefix=f"{TMP_PREFIX}{os.getpid()}-"))
        try:
            np.save(tmp / "map.npy", image)
            (tmp / "params.json").write_text(json.dumps({"filter": self.filter}))
            cmd = [str(self.python), str(DRIVER), "--rose2", str(self.checkout), "--map", str(tmp / "map.npy"),
                   "--params", str(tmp / "params.json"), "--out", str(tmp / "out.json")]
            try:
                r = run_guarded(cmd, timeout=self.timeout, remove=[str(tmp)],
                                env={**os.environ, "PYTHONPATH": "", "MPLBACKEND": "Agg"})
            except subprocess.TimeoutExpired:
                raise RuntimeError(f"ROSE2 timed out after {self.timeout:g} s (segmenter.timeout)") from None
            if r.returncode != 0 or not (tmp / "out.json").is_file():
                last = (r.stderr.strip().splitlines() or ["no output"])[-1]
                raise RuntimeError(f"the ROSE2 driver failed (exit {r.returncode}): {last[:300]}")
            return json.loads((tmp / "out.json").read_text())
        finally:
            shutil.rmtree(tmp, ignore_errors=True)

    def __call__(self, grid: GridMap) -> np.ndarray:
        t = time.perf_counter()
        image, height, pad = rose2_image(np.asarray(grid.walkable, bool), grid.resolution, self.wall_m, self.margin_m)
        out = self.run_driver(image)
        self.last_info = {"t_rose2": round(time.perf_counter() - t, 3)}
        if out.get("status") != "ok":
            raise RuntimeError(f"ROSE2: {out.get('error', 'failed')}")
        rooms = rooms_to_instances(out.get("rooms", []), grid, height, pad)
        return merge_small_rooms(rooms, grid.walkable, self.min_room_area / grid.resolution ** 2)


__all__ = ["Rose2", "rose2_image", "rooms_to_instances", "ROSE2_RESOLUTION", "CHECKOUT_ENV"]
