"""The cells of every ray of one range, relative to its camera, shared by the walks that cast
many rays of that range (the vision cone, view coverage, the floorplan renderer).

A ray from a camera to the end cell of :func:`envs.maps.rays.ray_end` walks the digital line of
:func:`envs.maps.rays.trace_ray`; that line depends only on the end's offset from the camera.
:func:`ray_paths` lists those lines once per range, and for each pair of neighbouring ends the
indices where their lines differ, followed by the indices where one line goes on beyond the
other's end: neighbouring rays of a cone end on neighbouring cells, so a walk looks up only
those indices (below where the ray before stopped) instead of every cell.
"""

from __future__ import annotations

import functools

import numpy as np

from envs.kernel_cache import njit
from envs.maps.rays import line_start, line_step

#: the most bytes :func:`ray_paths` keeps for one range; beyond it (ranges of several thousand
#: pixels) the walks walk every ray whole
PATH_CACHE_BYTES = 64 * 2**20


@njit(cache=True, nogil=True)
def _fill_paths(ends_r, ends_c, pr, pc, plen):
    """Cells of the digital line from (0, 0) to each end (``line_start``/``line_step``)."""
    for s in range(ends_r.shape[0]):
        er = ends_r[s]
        ec = ends_c[s]
        dr, dc, sr, sc, err = line_start(0, 0, er, ec)
        r = 0
        c = 0
        j = 0
        while True:
            pr[s, j] = r
            pc[s, j] = c
            j += 1
            if r == er and c == ec:
                break
            r, c, err = line_step(r, c, err, dr, dc, sr, sc)
        plen[s] = j


@njit(cache=True, nogil=True)
def _fill_diffs(ends_r, ends_c, slot, k, pr, pc, plen, dstart, dj, count_only):
    """For each path and each of the 3 x 3 end cells around its own: the indices j (below both
    lengths) where the two paths' cells differ, then the indices of this path beyond the other's
    length, with this path's minor coordinate there; returns their number (``count_only``:
    only that)."""
    n = 0
    for s in range(ends_r.shape[0]):
        rmaj = abs(ends_r[s]) > abs(ends_c[s])
        for q in range(9):
            x = -1
            rr = ends_r[s] + q // 3 - 1 + k
            cc = ends_c[s] + q % 3 - 1 + k
            if q != 4 and 0 <= rr < slot.shape[0] and 0 <= cc < slot.shape[1]:
                x = slot[rr, cc]
            if not count_only:
                dstart[s, q] = n
            if x >= 0:
                for j in range(plen[s]):  # differences below both lengths, then this path's cells beyond x's
                    if j >= plen[x] or pr[s, j] != pr[x, j] or pc[s, j] != pc[x, j]:
                        if not count_only:
                            dj[2 * n] = j
                            dj[2 * n + 1] = pc[s, j] if rmaj else pr[s, j]
                        n += 1
            if not count_only:
                dstart[s, q + 1] = n
    return n


def _no_paths():
    out = (-1, np.zeros((0, 0), np.int32), np.zeros((0, 0), np.int16), np.zeros((0, 4), np.int64),
           np.zeros(0, np.int32), np.zeros((0, 10), np.int32), np.zeros(0, np.int16))
    for a in out[1:]:
        a.setflags(write=False)  # the same kernel signature as with paths
    return out


@functools.lru_cache(maxsize=4)
def ray_paths(max_range: float, budget_bytes: int = PATH_CACHE_BYTES):
    """The cells of every ray of ``max_range`` pixels, relative to its camera, kept per range.

    A ray from (r0, c0) ends at :func:`envs.maps.rays.ray_end`'s cell, at most 0.71 px (plus
    rounding) from the circle of radius ``max_range`` around the camera; its digital line
    depends only on the end's offset (er, ec) from the camera. Every offset within 1 px of that
    circle gets a path (in order of angle), its cells as a minor coordinate per index (the
    major one is the index, with the end's sign), and, for each of the 3 x 3 offsets around
    it, the indices where the two paths differ, then those of this path beyond the other's
    length (neighbouring rays of a cone end on neighbouring cells; a ray after one that saw its
    whole path looks up only these).

    Returns:
        ``(k, slot, pm, geo, plen, dstart, dj)``: ``slot`` (2k + 1, 2k + 1) int32 path of
        offset (er, ec) at [er + k, ec + k] (-1: none); ``pm`` (S, k + 1) int16 minor
        coordinates; ``geo`` (S, 4) int64 (row step, column step per index, row and column
        factor of the minor coordinate); ``plen`` (S,) int32 cells per path; ``dstart`` (S, 10)
        int32 where each neighbour's differences start in ``dj`` (neighbour q = 3 (da + 1) +
        db + 1, ending at ``dstart[s, q + 1]``); ``dj`` int16 pairs (index, minor coordinate),
        in order of index: the differences below both lengths, then the indices beyond the
        neighbour's length.
        About 12 bytes per path cell (5.7 MB at 200 px, 34.6 MB at 500 px, the arrays'
        ``nbytes``), counted as 20 against ``budget_bytes`` (the build's work arrays too); over
        it (or ranges beyond int16) no paths (``k = -1``): every ray is walked.
    """
    k = int(np.ceil(max_range)) + 1
    g = np.arange(-k, k + 1)
    d2 = g[:, None] ** 2 + g[None, :] ** 2
    ring = (d2 >= max(max_range - 1.0, 0.0) ** 2) & (d2 <= (max_range + 1.0) ** 2)
    er, ec = np.nonzero(ring)
    er, ec = (er - k).astype(np.int64), (ec - k).astype(np.int64)
    if k > 30000 or len(er) * (k + 1) * 20 > budget_bytes:
        return _no_paths()
    o = np.argsort(np.arctan2(ec, -er), kind="stable")  # neighbouring rays read neighbouring rows
    er, ec = er[o], ec[o]
    slot = np.full((2 * k + 1, 2 * k + 1), -1, np.int32)
    slot[er + k, ec + k] = np.arange(len(er), dtype=np.int32)
    pr = np.zeros((len(er), k + 1), np.int16)
    pc = np.zeros((len(er), k + 1), np.int16)
    plen = np.zeros(len(er), np.int32)
    _fill_paths(er, ec, pr, pc, plen)
    dstart = np.zeros((len(er), 10), np.int32)
    n = _fill_diffs(er, ec, slot, k, pr, pc, plen, dstart, np.zeros(0, np.int16), True)
    dj = np.zeros(2 * n, np.int16)
    _fill_diffs(er, ec, slot, k, pr, pc, plen, dstart, dj, False)
    rmaj = np.abs(er) > np.abs(ec)  # the major axis is the rows: cell j is (sign(er) j, minor)
    pm = np.ascontiguousarray(np.where(rmaj[:, None], pc, pr))
    sgn = np.where(rmaj, np.sign(er), np.sign(ec))
    geo = np.stack([np.where(rmaj, sgn, 0), np.where(rmaj, 0, sgn), np.where(rmaj, 0, 1),
                    np.where(rmaj, 1, 0)], 1).astype(np.int64)
    out = (k, slot, pm, geo, plen, dstart, dj)
    for a in out[1:]:
        a.setflags(write=False)
    return out


@njit(cache=True, nogil=True)
def end_paths(ends_r, ends_c, max_range, k, slot, out):
    """Into ``out[t]``: the path (row of :func:`ray_paths`' tables) of the ray ending
    (``ends_r[t]``, ``ends_c[t]``) from its camera, -1 where that end has none (or there are no
    tables). The ends are those of :func:`envs.maps.rays.cone_ends` for rays of ``max_range``
    pixels: within ``ceil(max_range)`` px of the camera along both axes (``floor(0.5 +- max_range
    cos)``), so the tables are read without a bounds test once their reach ``k`` is checked;
    tables of a shorter range raise ``ValueError``.

    Args:
        ends_r, ends_c: (R,) int64 the rays' ends, offsets from the camera's cell.
        max_range: the rays' length, pixels.
        k, slot: :func:`ray_paths`' reach and table of paths.
        out: (R,) int64, written.
    """
    if k >= 0 and k < np.ceil(max_range):
        raise ValueError("the ray paths' tables are for a shorter range than the cone's")
    for t in range(ends_r.shape[0]):
        out[t] = slot[np.uint64(ends_r[t] + k), np.uint64(ends_c[t] + k)] if k >= 0 else -1


@njit(cache=True, nogil=True, inline="always")
def path_steps(geo, s, width):
    """Path ``s``'s steps in a row-major array ``width`` cells wide: ``(step, mstep)``, so that cell
    ``j`` of the path, with minor coordinate ``minor``, lies at ``base + j * step + minor * mstep``
    where ``base`` is the camera cell's flat index."""
    return geo[s, 0] * width + geo[s, 1], geo[s, 2] * width + geo[s, 3]


@njit(cache=True, nogil=True, inline="always")
def path_index(base, step, mstep, j, minor):
    """The flat index of cell ``j`` of a path, with minor coordinate ``minor``, in an array whose
    camera cell is at ``base`` (steps of :func:`path_steps`): unsigned, so that numba skips its
    test for negative indices on each cell (a tenth of the walk)."""
    return np.uint64(base + step * j + mstep * minor)


@njit(cache=True, nogil=True, inline="always")
def differences(s, prev, a, b, plen, pstop, dstart):
    """Where path ``s`` differs from ``prev``, the path of the ray before (its end (a, b) cells
    from s's, each within one), that stopped at index ``pstop``: ``(m, lim, i, e)``: the
    shorter length ``m``, the limit ``lim`` below which the differences matter (the ray before
    saw its cells up to there), and the pairs ``dj[2 i:2 e]`` to look up (index, minor; those
    at ``m`` and beyond are this path's cells past the end of ``prev``)."""
    nq = (1 - a) * 3 + (1 - b)
    m = min(plen[s], plen[prev])
    return m, min(pstop, m), dstart[s, nq], dstart[s, nq + 1]


@njit(cache=True, nogil=True, inline="always")
def after_differences(i, e, dj, pstop, m):
    """How a ray goes on when none of its differences below ``lim`` was blocked (``i``: the first
    pair not looked up): ``(walk_from, stop)``. The ray before stopped at ``pstop`` < ``m``: this
    one stops there too (``stop = pstop``) unless that cell is one of its differences, then it
    walks on from there; the ray before went at least ``m`` cells: this one walks on from ``m``.
    Without a branch on the array, as is :func:`after_neighbour_list`: numba counts a reference
    to an array passed to a helper that branches, an atomic increment and decrement on every
    call (in the vision cone's ray loop, with the path lookup then made the same way, about a
    tenth of its time)."""
    on = (i < e) & (_pair_index(dj, i, e) == pstop)
    short = pstop < m
    return (pstop if on else 0) if short else m, (-1 if on else pstop) if short else -1


@njit(cache=True, nogil=True, inline="always")
def neighbour_list(s, prev, a, b, plen, pstop, dstart):
    """What path ``s`` looks up after ``prev``, the path of the ray before (its end (a, b)
    cells from s's, each within one), that stopped at index ``pstop``, when the cells beyond
    ``prev``'s end are looked up from the list too (no walk on after a whole path):
    ``(whole, lim, i, e)``: whether the ray before saw its whole path (``pstop`` its length),
    the limit ``lim`` below which the list's pairs ``dj[2 i:2 e]`` are looked up (s's length
    after a whole path, else ``pstop``)."""
    nq = (1 - a) * 3 + (1 - b)
    whole = pstop >= plen[prev]
    return whole, plen[s] if whole else pstop, dstart[s, nq], dstart[s, nq + 1]


@njit(cache=True, nogil=True, inline="always")
def after_neighbour_list(whole, i, e, dj, pstop, n):
    """How a ray of ``n`` cells goes on when none of its :func:`neighbour_list` pairs below
    ``lim`` was blocked (``i``: the first pair not looked up): ``(walk_from, stop)``. After a
    whole path, or one that stopped at or beyond this one's end, it saw its whole path
    (``stop = n``); else the ray before stopped at ``pstop``: this one stops there too unless
    that cell is one of its differences, then it walks on from there (``stop = -1``). Without a
    branch on the array (:func:`after_differences` says why)."""
    on = (i < e) & (_pair_index(dj, i, e) == pstop)
    seen = whole | (pstop >= n)
    return 0 if seen else (pstop if on else 0), n if seen else (-1 if on else pstop)


@njit(cache=True, nogil=True, inline="always")
def _pair_index(dj, i, e):
    """The index of pair ``i`` of a list ending at ``e`` (the pair before the end when ``i`` is
    ``e``, -1 when no list has a pair: the callers test ``i < e`` too), read without a branch."""
    return np.int64(dj[np.uint64(2 * min(i, e - 1))]) if e > 0 else -1


__all__ = ["PATH_CACHE_BYTES", "after_differences", "after_neighbour_list", "differences", "neighbour_list",
           "end_paths", "path_index", "path_steps", "ray_paths"]
