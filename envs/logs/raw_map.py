"""Raw occupancy maps from real laser scans at their logged poses: the project's scan mapper's
update rule (:mod:`envs.maps.scan`) on measured ranges instead of simulated ones.

API::

    from envs.logs.carmen import read_carmen
    from envs.logs.raw_map import raw_map, raw_map_from_log
    occ, origin = raw_map_from_log(read_carmen(path), resolution=0.05)   # (H, W) int8 -1/0/100
    occ, origin = raw_map(poses, ranges, angles, resolution=0.05, settings=ScanSettings())

The grid: column = floor((x - x0) / resolution), row = floor((y0 - y) / resolution) (north up,
as a map image), ``origin = (x0, y0)`` the world position of the top-left corner of cell (0, 0);
the grid covers every laser pose with ``settings.max_range`` plus one cell of margin around.

Per beam (the scan mapper's rule, :mod:`envs.maps.scan` "The mapper"): the digital (Bresenham)
line of :mod:`envs.maps.rays` from the laser's cell to the cell of the beam's end point; the cells
before the end get free evidence, the end cell hit evidence. A reading at or beyond
``settings.max_range`` (the real scanner's no-return readings, 50 to 81.91 m in the Radish
logs, included) is a max-range reading: free evidence along the line to ``max_range``, no hit,
as the simulated scanner treats a beam with nothing within ``max_range``. Within one scan a cell
gets at most one free and one hit update; log-odds ``settings.log_odds_hit`` / ``log_odds_miss``,
clamped to ``[log_odds_min, log_odds_max]``, then ``map_server``'s trinary thresholds
(:func:`envs.maps.scan.occupancy_from_log_odds`). Nothing is edited by hand: no filtering of
specks, people or glass; the poses are the log's (in the corrected logs, the corrected ones).
"""

from __future__ import annotations

import math

import numpy as np

from envs.kernel_cache import njit
from envs.maps.rays import line_start, line_step
from envs.maps.scan import ScanSettings, _apply_scan, _mark, occupancy_from_log_odds


@njit(cache=True, nogil=True)
def _raw_kernel(px, py, heading, ranges, angles, max_range, x0, y0, res, l_hit, l_miss, l_min, l_max, log_odds,
                state, touched_r, touched_c):
    h, w = log_odds.shape
    for m in range(px.shape[0]):
        r0 = int(np.floor((y0 - py[m]) / res))
        c0 = int(np.floor((px[m] - x0) / res))
        if r0 < 0 or r0 >= h or c0 < 0 or c0 >= w:
            continue
        nt = 0
        for b in range(ranges.shape[1]):
            d = ranges[m, b]
            if not np.isfinite(d) or d < 0.0:
                continue
            hit = d < max_range
            if not hit:
                d = max_range
            a = heading[m] + angles[b]
            r1 = int(np.floor((y0 - (py[m] + d * np.sin(a))) / res))
            c1 = int(np.floor((px[m] + d * np.cos(a) - x0) / res))
            dr, dc, sr, sc, err = line_start(r0, c0, r1, c1)
            r = r0
            c = c0
            while True:
                if r < 0 or r >= h or c < 0 or c >= w:
                    break
                if r == r1 and c == c1:
                    nt = _mark(state, touched_r, touched_c, nt, r, c, m, 2 if hit else 1)
                    break
                nt = _mark(state, touched_r, touched_c, nt, r, c, m, 1)
                r, c, err = line_step(r, c, err, dr, dc, sr, sc)
        _apply_scan(log_odds, state, touched_r, touched_c, nt, l_hit, l_miss, l_min, l_max)


def raw_log_odds(poses: np.ndarray, ranges: np.ndarray, angles: np.ndarray, resolution: float = 0.05,
                 settings: ScanSettings | None = None) -> tuple[np.ndarray, tuple[float, float]]:
    """(log-odds (H, W) float64, origin (x0, y0)) of the scans: ``poses`` (N, 3) laser x, y, theta
    (metres, radians), ``ranges`` (N, B) metres, ``angles`` (B,) beam bearings in the laser's
    frame (radians counter-clockwise); see the module docstring."""
    s = settings or ScanSettings()
    poses = np.asarray(poses, np.float64).reshape(-1, 3)
    ranges = np.ascontiguousarray(ranges, np.float64).reshape(len(poses), -1)
    angles = np.ascontiguousarray(angles, np.float64).reshape(-1)
    if ranges.shape[1] != len(angles):
        raise ValueError(f"ranges have {ranges.shape[1]} beams, angles {len(angles)}: expected one angle a beam")
    if not (isinstance(resolution, int | float) and math.isfinite(resolution) and resolution > 0):
        raise ValueError(f"resolution = {resolution!r}: expected metres per cell > 0")
    if not math.isfinite(s.max_range):
        raise ValueError("scan.max_range = inf: expected a finite range for real scans (their no-return "
                         "readings need one)")
    if len(poses) == 0:
        raise ValueError("no scans: expected at least one laser scan")
    reach = s.max_range + resolution
    x0 = math.floor((poses[:, 0].min() - reach) / resolution) * resolution
    y0 = math.ceil((poses[:, 1].max() + reach) / resolution) * resolution
    w = int(math.ceil((poses[:, 0].max() + reach - x0) / resolution)) + 1
    h = int(math.ceil((y0 - (poses[:, 1].min() - reach)) / resolution)) + 1
    log_odds = np.zeros((h, w), np.float64)
    state = np.full((h, w), -1, np.int64)
    cap = min(h * w, ranges.shape[1] * (2 * int(math.ceil(s.max_range / resolution)) + 4))  # cells a scan touches
    touched_r = np.empty(cap, np.int32)
    touched_c = np.empty(cap, np.int32)
    _raw_kernel(poses[:, 0].copy(), poses[:, 1].copy(), poses[:, 2].copy(), ranges, angles, float(s.max_range),
                float(x0), float(y0), float(resolution), s.log_odds_hit, s.log_odds_miss, s.log_odds_min,
                s.log_odds_max, log_odds, state, touched_r, touched_c)
    return log_odds, (float(x0), float(y0))


def raw_map(poses: np.ndarray, ranges: np.ndarray, angles: np.ndarray, resolution: float = 0.05,
            settings: ScanSettings | None = None) -> tuple[np.ndarray, tuple[float, float]]:
    """(occupancy (H, W) int8 -1 / 0 / 100, origin (x0, y0)): :func:`raw_log_odds` thresholded."""
    s = settings or ScanSettings()
    lo, origin = raw_log_odds(poses, ranges, angles, resolution, s)
    return occupancy_from_log_odds(lo, s), origin


def raw_map_from_log(log, resolution: float = 0.05, settings: ScanSettings | None = None,
                     kind: str = "FLASER") -> tuple[np.ndarray, tuple[float, float]]:
    """:func:`raw_map` of the scans of ``kind`` of a :class:`envs.logs.carmen.CarmenLog` at their
    laser poses (the scans of one kind share one beam layout)."""
    scans = log.of_kind(kind)
    if not scans:
        raise ValueError(f"{log.path}: no {kind} scans: expected a log with laser scans")
    return raw_map(log.laser_poses(kind), log.scan_ranges(kind), scans[0].angles(), resolution, settings)
