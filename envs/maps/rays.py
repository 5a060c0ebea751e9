"""Digital lines on a grid: the one ray walk (Bresenham rays over a blocking grid, compiled with
numba), on the world side beside the grid map, so that maps, render and the aggregators all call it.

Used by the floorplan renderer (what a camera sees), the vision-cone aggregator (which
cells a view votes for), scan maps (:mod:`envs.maps.scan`: where laser beams end) and view
coverage (which cells some view's cone reaches, walked the vision cone's way). A ray starts at the
camera's cell and walks the Bresenham line (one step: :func:`line_step`) to the cell at
``max_range`` pixels along its heading; it stops *before* the first blocked cell (which it
reports as its hit) or at the map edge (:func:`walk_beam` also walks a few cells past the
hit, for a laser's long readings). The camera's own cell is always visited. Headings are map angles in radians: ``theta`` with direction
``(d_row, d_col) = (-cos theta, sin theta)``, i.e. the simulator yaw converted to radians.
"""

from __future__ import annotations

import numpy as np

from envs.kernel_cache import njit

#: values of a bordered cell state (:func:`ray_state`) besides the ids of the views that saw a
#: cell (>= 0): a walk's one load per cell tells free, blocked or off the map, and seen
FREE, BLOCKED, OUTSIDE = -1, -2, -3


def ray_state(passable: np.ndarray) -> np.ndarray:
    """(H + 2, W + 2) int32: ``FREE`` on passable cells, ``BLOCKED`` on the others, ``OUTSIDE`` on a
    one-cell border (a ray walks one cell per step, so it meets the border before leaving the
    map: no bounds checks in the walk). Cell (r, c) of the map is (r + 1, c + 1) here; a walk
    stamps the cells it sees with its view's id.

    Args:
        passable: (H, W) bool cells a ray walks through.
    """
    st = np.empty((passable.shape[0] + 2, passable.shape[1] + 2), np.int32)
    st[0] = st[-1] = OUTSIDE
    st[:, 0] = st[:, -1] = OUTSIDE
    # FREE is BLOCKED + 1: one pass, in place (no map-sized temporary, no masked copy)
    np.add(np.asarray(passable, np.bool_), BLOCKED, out=st[1:-1, 1:-1], dtype=np.int32)
    return st


@njit(cache=True, nogil=True, inline="always")
def line_start(r0, c0, r1, c1):
    """The digital line from (r0, c0) to (r1, c1) before its first step: its extents
    ``dr = |r1 - r0|``, ``dc = |c1 - c0|``, directions ``sr``, ``sc`` and error term; returns
    ``(dr, dc, sr, sc, err)`` for :func:`line_step`."""
    dr = abs(r1 - r0)
    dc = abs(c1 - c0)
    return dr, dc, 1 if r1 > r0 else -1, 1 if c1 > c0 else -1, dc - dr


@njit(cache=True, nogil=True, inline="always")
def line_step(r, c, err, dr, dc, sr, sc):
    """One step of the Bresenham walk from (r, c) with error term ``err`` on a line of extents
    ``dr = |r1 - r0|``, ``dc = |c1 - c0|`` and directions ``sr``, ``sc``; returns the next
    (r, c, err). After ``i`` row steps and ``j`` column steps from the start the error term is
    ``dc - dr + i * dc - j * dr``."""
    e2 = 2 * err
    if e2 > -dr:
        err -= dr
        c += sc
    if e2 < dc:
        err += dc
        r += sr
    return r, c, err


@njit(cache=True, nogil=True)
def trace_ray(blocked, r0, c0, r1, c1, out_rows, out_cols):
    """Walk the Bresenham line from (r0, c0) to (r1, c1) over ``blocked`` (H, W bool).

    Writes visited free cells to ``out_rows``/``out_cols`` (which must hold at least
    ``max(|r1-r0|, |c1-c0|) + 1`` entries) and returns ``(n_visited, hit_row, hit_col)``,
    where the hit is the first blocked cell met, or (-1, -1) if none (range reached or map
    edge). Starting on a blocked cell visits nothing and reports that cell as the hit.
    Callable from other numba kernels.
    """
    h, w = blocked.shape
    dr, dc, sr, sc, err = line_start(r0, c0, r1, c1)
    r = r0
    c = c0
    n = 0
    while True:
        if r < 0 or r >= h or c < 0 or c >= w:
            return n, -1, -1
        if blocked[r, c]:
            return n, r, c
        out_rows[n] = r
        out_cols[n] = c
        n += 1
        if r == r1 and c == c1:
            return n, -1, -1
        r, c, err = line_step(r, c, err, dr, dc, sr, sc)


@njit(cache=True, nogil=True)
def walk_beam(blocked, r0, c0, r1, c1, extra, out_rows, out_cols):
    """A laser beam's walk: the same digital line as :func:`trace_ray`, through its first
    blocked cell and ``extra`` cells beyond (where a long range reading may end).

    Writes the line's cells in order to ``out_rows``/``out_cols`` (room for
    ``max(|r1-r0|, |c1-c0|) + 1`` entries): every cell up to the first blocked one, that cell,
    and at most ``extra`` further cells whatever they hold; it stops at the end cell or the
    map edge. Returns ``(n_written, k_hit)``: ``k_hit`` is the index of the first blocked cell
    (so ``trace_ray`` would visit ``k_hit`` cells and report ``out[k_hit]``), -1 if none.
    Callable from other numba kernels.
    """
    n, hr, hc = trace_ray(blocked, r0, c0, r1, c1, out_rows, out_cols)
    if hr < 0:
        return n, -1
    h, w = blocked.shape
    dr, dc, sr, sc, err = line_start(r0, c0, r1, c1)
    # the same line continued from the hit: its error term there (see line_step)
    err += abs(hr - r0) * dc - abs(hc - c0) * dr
    r = hr
    c = hc
    k_hit = n
    out_rows[n] = r
    out_cols[n] = c
    n += 1
    for _ in range(extra):
        if r == r1 and c == c1:
            break
        r, c, err = line_step(r, c, err, dr, dc, sr, sc)
        if r < 0 or r >= h or c < 0 or c >= w:
            break
        out_rows[n] = r
        out_cols[n] = c
        n += 1
    return n, k_hit


@njit(cache=True, nogil=True)
def ray_end(r0, c0, theta, max_range):
    """Integer end cell of a ray of ``max_range`` pixels from cell (r0, c0) along ``theta``."""
    return ray_end_of(r0, c0, np.cos(theta), np.sin(theta), max_range)


@njit(cache=True, nogil=True, inline="always")
def ray_end_of(r0, c0, cos_theta, sin_theta, max_range):
    """:func:`ray_end` from the heading's cosine and sine (``np.cos(theta)``, ``np.sin(theta)``),
    for rays whose headings repeat (a scanner's fixed beams): the same cell."""
    r1 = int(np.floor(r0 + 0.5 - cos_theta * max_range))
    c1 = int(np.floor(c0 + 0.5 + sin_theta * max_range))
    return r1, c1


#: how close (pixels) an end's coordinate may come to a cell boundary before :func:`cone_end`
#: computes it as :func:`ray_end` does: far above the error of the angle-sum formula (about
#: 1e-11 px at 30,000 px, with headings within ``CONE_END_YAW`` radians)
CONE_END_TOL = 1e-6
#: headings (radians, absolute) beyond which :func:`cone_end` always calls :func:`ray_end`
CONE_END_YAW = 1e3


@njit(cache=True, nogil=True, inline="always")
def cone_end(r0, c0, yaw, cy, sy, off, co, so, max_range):
    """``ray_end(r0, c0, yaw + off, max_range)`` without a cosine and sine per ray: the heading's
    cosine and sine by the angle-sum formula from the view's (``cy``, ``sy`` = cos, sin of ``yaw``)
    and the ray offset's (``co``, ``so``). Where either coordinate lies within ``CONE_END_TOL``
    pixels of a cell boundary (or the heading is beyond ``CONE_END_YAW``, or not finite), it
    returns :func:`ray_end` itself: the same cell in every case."""
    fr = r0 + 0.5 - (cy * co - sy * so) * max_range
    fc = c0 + 0.5 + (sy * co + cy * so) * max_range
    r1 = np.floor(fr)
    c1 = np.floor(fc)
    if (abs(yaw) <= CONE_END_YAW and CONE_END_TOL < fr - r1 < 1.0 - CONE_END_TOL
            and CONE_END_TOL < fc - c1 < 1.0 - CONE_END_TOL):
        return int(r1), int(c1)
    return ray_end(r0, c0, yaw + off, max_range)


@njit(cache=True, nogil=True)
def cone_ends(r0, c0, yaw, offsets, cos_off, sin_off, max_range, ends_r, ends_c, exact):
    """:func:`cone_end` of every ray of a view at once: ``ends_r[t], ends_c[t]`` become the end
    cell of the ray of heading ``yaw + offsets[t]``, as an offset from the view's cell (r0, c0).
    First every ray by the angle-sum formula, in a loop without a branch (the compiler does
    several rays an instruction), marking in ``exact`` the ends that lie clear of a cell
    boundary; then :func:`ray_end` for the others (none when the heading is beyond
    ``CONE_END_YAW`` or not finite: then every ray). The same cells as :func:`cone_end` ray by
    ray; the vision cone and the floorplan renderer find their ends here.

    Args:
        r0, c0: the view's cell.
        yaw: its heading, radians.
        offsets, cos_off, sin_off: (R,) the rays' headings around ``yaw`` and their cosines and sines.
        max_range: ray length, pixels.
        ends_r, ends_c: (R,) int64, written.
        exact: (R,) bool scratch, written.
    """
    cy = np.cos(yaw)
    sy = np.sin(yaw)
    gr = r0 + 0.5
    gc = c0 + 0.5
    for t in range(offsets.shape[0]):
        fr = gr - (cy * cos_off[t] - sy * sin_off[t]) * max_range
        fc = gc + (sy * cos_off[t] + cy * sin_off[t]) * max_range
        r1 = np.floor(fr)
        c1 = np.floor(fc)
        ends_r[t] = np.int64(r1) - r0
        ends_c[t] = np.int64(c1) - c0
        a = fr - r1
        b = fc - c1
        exact[t] = (CONE_END_TOL < a) & (a < 1.0 - CONE_END_TOL) & (CONE_END_TOL < b) & (b < 1.0 - CONE_END_TOL)
    every = not abs(yaw) <= CONE_END_YAW
    for t in range(offsets.shape[0]):
        if every or not exact[t]:
            r1, c1 = ray_end(r0, c0, yaw + offsets[t], max_range)
            ends_r[t] = r1 - r0
            ends_c[t] = c1 - c0


@njit(cache=True, nogil=True)
def _cast(blocked, r0, c0, thetas, max_range):
    n_rays = thetas.shape[0]
    cap = int(np.ceil(max_range)) + 2
    rows = np.empty(n_rays * cap, np.int32)
    cols = np.empty(n_rays * cap, np.int32)
    offsets = np.zeros(n_rays + 1, np.int64)
    hits = np.full((n_rays, 2), -1, np.int32)
    buf_r = np.empty(cap, np.int32)
    buf_c = np.empty(cap, np.int32)
    k = 0
    for i in range(n_rays):
        r1, c1 = ray_end(r0, c0, thetas[i], max_range)
        n, hr, hc = trace_ray(blocked, r0, c0, r1, c1, buf_r, buf_c)
        for j in range(n):
            rows[k] = buf_r[j]
            cols[k] = buf_c[j]
            k += 1
        offsets[i + 1] = k
        hits[i, 0] = hr
        hits[i, 1] = hc
    return rows[:k], cols[:k], offsets, hits


def cast_rays(
    blocked: np.ndarray, row: int, col: int, thetas: np.ndarray, max_range: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Cast rays from cell (row, col) at map headings ``thetas`` (radians), ``max_range`` pixels.

    Returns ``(rows, cols, offsets, hits)``: the visited cells of ray ``i`` are
    ``rows[offsets[i]:offsets[i+1]]`` (and ``cols``), in order from the camera; ``hits`` is
    (n_rays, 2) int32, the first blocked cell each ray met or (-1, -1).
    """
    blocked = np.ascontiguousarray(blocked, dtype=np.bool_)
    thetas = np.ascontiguousarray(np.atleast_1d(thetas), dtype=np.float64)
    if max_range < 0:
        raise ValueError(f"max_range must be >= 0 pixels, got {max_range}")
    return _cast(blocked, int(row), int(col), thetas, float(max_range))


def cone_thetas(yaw_deg: float, fov_deg: float, max_range: float, oversample: float = 2.0) -> np.ndarray:
    """Ray headings (radians) spanning a ``fov_deg`` cone centred on ``yaw_deg``, spaced so
    that neighbouring rays are at most ``1 / oversample`` pixels apart at ``max_range``."""
    fov = np.deg2rad(fov_deg)
    n = max(int(np.ceil(fov * max(max_range, 1.0) * oversample)) + 1, 2)
    return np.deg2rad(yaw_deg) + np.linspace(-fov / 2, fov / 2, n)
