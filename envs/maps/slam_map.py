"""The map a SLAM robot builds: ranges measured from where it was, inserted where it thinks it was.

:func:`scan_map_at_estimate` is :func:`envs.maps.scan.scan_map` with two poses per scan: the
*true* pose, from which each beam's range is measured (the same scanner: fixed beam headings in
the world, range noise, dropout, max-range readings, the same draws), and the *estimated* pose,
at which the reading is inserted. A beam leaving the true pose at map heading ``theta`` left the
robot at ``theta - yaw_true``; it is inserted at heading ``theta - yaw_true + yaw_est`` from the
estimated pose's cell, along the digital line to ``max_range`` (obstacles play no part in the
insertion: the mapper only knows its ranges). The end cell is the last cell of that line not
farther than the measured range; cells before it get free evidence and the end cell hit evidence
(a max-range reading, or a reading whose end lies past ``max_range`` or off the map: free along
the whole line, no hit). The log-odds update, clamping and thresholds are
:mod:`envs.maps.scan`'s.

With the estimate equal to the truth the map is :func:`envs.maps.scan.scan_map`'s, cell for cell
(distances along a digital line grow strictly, so the last cell within the true range is the
obstacle cell). With pose error a wall seen twice from poses that disagree shows twice (a
doubled or bent wall), as in a real SLAM map.

The map lives in the estimate's frame (the robot's start pose is exact, :mod:`benchmark.conditions.slam`),
on the house grid's cells; a scan whose true cell is off the map or on an obstacle measures
nothing, and one whose estimated cell is off the map inserts nothing (their draws are consumed
all the same).
"""

from __future__ import annotations

import numpy as np

from envs.kernel_cache import njit
from envs.maps.gridmap import GridMap
from envs.maps.rays import cone_end, line_start, line_step, ray_end_of, walk_beam
from envs.maps.scan import (
    FREE,
    ScanMap,
    ScanSettings,
    _apply_scan,
    _mark,
    _range_px,
    beam_headings,
    beam_return,
    exact_scanner,
    occupancy_from_log_odds,
    scan_draws,
)


@njit(cache=True, nogil=True)
def _estimate_kernel(obstacles, rows, cols, erows, ecols, dyaw, n_beams, range_px, res, max_range_m, noise, drop,
                     l_hit, l_miss, l_min, l_max, log_odds, state, touched_r, touched_c, normals, grazing, graze_u,
                     persons, exact, surfaces, surface_dropout):
    h, w = obstacles.shape
    cap = int(np.ceil(range_px)) + 2
    lr = np.empty(cap, np.int32)
    lc = np.empty(cap, np.int32)
    # an exact scanner's readings from one cell (``exact``: no noise, dropout, grazing loss or
    # people): the beams' headings are fixed in the world, so a scan from the cell of the
    # previous one measures what it measured; only the insertion differs
    seen_hit = np.zeros(n_beams, np.bool_)
    seen_d = np.zeros(n_beams, np.float64)
    seen_r = -1
    seen_c = -1
    two_pi = 2.0 * np.pi
    cos_b, sin_b = beam_headings(n_beams)  # the same in every scan
    done = 0
    for m in range(rows.shape[0]):
        r0 = rows[m]
        c0 = cols[m]
        if r0 < 0 or r0 >= h or c0 < 0 or c0 >= w or obstacles[r0, c0]:
            continue
        e0 = erows[m]
        f0 = ecols[m]
        if e0 < 0 or e0 >= h or f0 < 0 or f0 >= w:
            continue
        done += 1
        s = done - 1
        nt = 0
        again = exact and r0 == seen_r and c0 == seen_c
        turn = dyaw[m]
        cos_turn = np.cos(turn)
        sin_turn = np.sin(turn)
        for b in range(n_beams):
            if drop[m, b]:
                continue
            theta = two_pi * b / n_beams
            if again:
                hit = seen_hit[b]
                d_true = seen_d[b]
                d_m = d_true
            else:
                # measure from the true cell
                r1, c1 = ray_end_of(r0, c0, cos_b[b], sin_b[b], range_px)
                n, k_hit = walk_beam(obstacles, r0, c0, r1, c1, 0, lr, lc)
                k_hit, returned = beam_return(persons, m, r0, c0, theta, lr, lc, n, k_hit, normals, grazing,
                                              graze_u[m, b], surfaces, surface_dropout)
                if not returned:
                    continue  # a grazing beam, or one on glass or a dark wall, returned nothing
                hit = k_hit >= 0
                d_m = 0.0
                d_true = 0.0
                if hit:
                    d_true = np.hypot(lr[k_hit] - r0, lc[k_hit] - c0) * res
                    d_m = max(d_true + noise[m, b], 0.0)
                seen_hit[b] = hit
                seen_d[b] = d_true
            long_reading = False
            # insert from the estimated cell
            phi = theta + turn
            r1, c1 = cone_end(e0, f0, turn, cos_turn, sin_turn, theta, cos_b[b], sin_b[b], range_px)  # ray_end's at phi
            if hit and d_m > d_true:
                # a long reading (as scan.py): its end must lie within max_range and on the map
                long_reading = True
                pr = e0 + 0.5 - np.cos(phi) * (d_m / res)
                pc = f0 + 0.5 + np.sin(phi) * (d_m / res)
                if not (d_m <= max_range_m and pr >= 0.0 and pr < h and pc >= 0.0 and pc < w):
                    hit = False
            # the digital line to the end cell, within the map; a reading with a hit stops at the
            # first cell farther than its range (distances along the line grow strictly, so the
            # cells beyond play no part: the line only walks as far as the reading reaches)
            # with a hit, its cell is the last one within the range (cell 0 is at distance 0): each
            # cell but the last is free, marked as the walk moves past it
            dr, dc, sr, sc, err = line_start(e0, f0, r1, c1)
            r = e0
            c = f0
            n = 0
            last_r = -1
            last_c = -1
            beyond = False
            # cell j lies at most j sqrt(2) px from the start: below ``sure`` it is within range;
            # past it, the squared distance in whole pixels settles the test unless it lies within
            # a billionth of the range's square, where the distance itself decides (the same
            # answer as that test at every cell, without a square root at most of them)
            sure = int(d_m / res / 1.4142135623730951 * (1.0 - 1e-9)) - 1 if hit else 0
            reach2 = (d_m / res) * (d_m / res)
            inside2 = reach2 * (1.0 - 1e-9)
            outside2 = reach2 * (1.0 + 1e-9)
            while r >= 0 and r < h and c >= 0 and c < w:
                if hit and n > sure:
                    q = (r - e0) * (r - e0) + (c - f0) * (c - f0)
                    if q > inside2 and (q > outside2 or np.hypot(r - e0, c - f0) * res > d_m):
                        beyond = True
                        break
                if n > 0:
                    nt = _mark(state, touched_r, touched_c, nt, last_r, last_c, s, 1)
                last_r = r
                last_c = c
                n += 1
                if r == r1 and c == c1:
                    break
                r, c, err = line_step(r, c, err, dr, dc, sr, sc)
            if hit and not beyond and not long_reading:
                # the inserted line must reach the measured range before leaving the map
                hit = np.hypot(last_r - e0, last_c - f0) * res >= d_m
            if n > 0:
                nt = _mark(state, touched_r, touched_c, nt, last_r, last_c, s, 2 if hit else 1)
        _apply_scan(log_odds, state, touched_r, touched_c, nt, l_hit, l_miss, l_min, l_max)
        seen_r = r0
        seen_c = c0
    return done


def scan_map_at_estimate(obstacles: np.ndarray, grid: GridMap, true_poses: np.ndarray, est_poses: np.ndarray,
                         settings: ScanSettings, surfaces: np.ndarray | None = None) -> ScanMap:
    """The occupancy map of scans measured at ``true_poses`` and inserted at ``est_poses``.

    Args:
        obstacles: (H, W) bool, what the scan plane hits (:func:`envs.maps.scan.scan_obstacles`).
        grid: the map's geometry.
        true_poses: (M, 3) x, z (metres), yaw (degrees): where each scan was taken.
        est_poses: (M, 3) the same scans' estimated poses (same units, same order).
        settings: scanner and mapper settings (the draws follow ``settings.seed`` as in
            :func:`envs.maps.scan.scan_map`).
        surfaces: per-cell surface shares (:func:`envs.maps.scan.surface_shares`) that
            ``settings.surface_dropout`` scales, or None (no surface loss).

    Returns:
        :class:`envs.maps.scan.ScanMap` on ``grid``'s cells, in the estimate's frame.
    """
    s = settings.check()
    true = np.asarray(true_poses, np.float64).reshape(-1, 3)
    est = np.asarray(est_poses, np.float64).reshape(-1, 3)
    if true.shape != est.shape:
        raise ValueError(f"true poses {true.shape} and estimated poses {est.shape} must both be (M, 3)")
    obstacles = np.ascontiguousarray(obstacles, np.bool_)
    if obstacles.shape != grid.shape:
        raise ValueError(f"obstacles shape {obstacles.shape} != grid shape {grid.shape}")
    noise, drop, graze_u, normals, persons, sf = scan_draws(s, obstacles, grid, surfaces, len(true))
    r, c = grid.world_to_cell(true[:, 0], true[:, 1])
    er, ec = grid.world_to_cell(est[:, 0], est[:, 1])
    dyaw = np.deg2rad(est[:, 2] - true[:, 2])
    log_odds = np.zeros(grid.shape, np.float64)
    state = np.full(grid.shape, -1, np.int32)
    size = grid.shape[0] * grid.shape[1]
    done = _estimate_kernel(obstacles, r.astype(np.int64), c.astype(np.int64), er.astype(np.int64),
                            ec.astype(np.int64), dyaw, s.n_beams, _range_px(s, grid.shape, grid.resolution),
                            grid.resolution, float(s.max_range), noise, drop, float(s.log_odds_hit),
                            float(s.log_odds_miss), float(s.log_odds_min), float(s.log_odds_max), log_odds, state,
                            np.empty(size, np.int32), np.empty(size, np.int32), normals,
                            float(s.grazing_dropout), graze_u, persons, exact_scanner(s), sf,
                            float(s.surface_dropout) if sf.shape == grid.shape else 0.0)
    occ = occupancy_from_log_odds(log_odds, s)
    return ScanMap(log_odds.astype(np.float32), occ, occ == FREE, s, int(done))


__all__ = ["scan_map_at_estimate"]
