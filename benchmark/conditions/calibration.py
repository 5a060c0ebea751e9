"""The simulated scanner fitted to scans (issue 59 item 3): plain functions over arrays.

A fit compares each beam's *measured* range with the range the map *expects* along the same beam
(the first obstacle cell its walk meets, :func:`expected_hits`), and reads off what
:class:`envs.maps.scan.ScanSettings` draws:

* ``dropout`` and ``grazing_dropout``: a beam the map expects to return but that returns nothing
  is a dropout; its chance against ``x = 1 - cos i`` (``i`` the incidence angle on the surface the
  map expects it to hit, :func:`envs.maps.scan.surface_normals`) is the scanner's
  ``dropout + (1 - dropout) * grazing_dropout * x``, a straight line in ``x`` whose least-squares
  fit over the beams gives both (:func:`fit_dropout`);
* the correlation of dropouts along a scan (beam ``b`` and ``b + 1``) and over time (one beam in
  scan ``m`` and ``m + 1``), of what the incidence does not explain (the residuals of that line):
  the simulated scanner draws every beam apart, so both are 0 there (:func:`dropout_correlation`);
* ``range_noise``: the robust standard deviation (1.4826 times the median absolute deviation) of
  measured minus expected range over the beams within ``gate`` metres of the expected range, less
  the map's own quantisation (:func:`fit_range_noise`); beams shorter than that (something not on
  the map: people, furniture moved) and longer (through what the map holds as a wall: glass, a
  door opened since) are counted apart;
* the share of beams returning nothing at all (the max-range share).

The same functions fit the scans of a real log (at its corrected poses, against the map built
from the log, :func:`log_map`) and scans the simulator drew with known settings (the test of the
fit). What a log cannot tell: the scan height (``height``), how often the robot scans
(``spacing`` is the simulator's choice), the mapper's log-odds and thresholds, which furniture
stands on legs (``legs``, ``leg_size``), closed doors and people as such (only the short and long
readings they cause), and ``max_range`` beyond a lower bound (the longest reading seen).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np
from scipy.ndimage import maximum_filter

from envs.kernel_cache import njit
from envs.logs.g2o import edge_errors
from envs.maps.rays import ray_end, trace_ray
from envs.maps.scan import ScanSettings, surface_normals

#: 1.4826 * MAD is the standard deviation of a normal distribution
MAD_TO_SIGMA = 1.482602218505602
#: incidence bins (degrees) of the noise-by-incidence table
INCIDENCE_BINS_DEG = (0.0, 30.0, 50.0, 65.0, 75.0, 90.0)


@njit(cache=True, nogil=True)
def _hits_kernel(obstacles, rows, cols, thetas, range_px, hit_r, hit_c):
    h, w = obstacles.shape
    cap = int(np.ceil(range_px)) + 4
    lr = np.empty(cap, np.int32)
    lc = np.empty(cap, np.int32)
    for m in range(rows.shape[0]):
        r0 = rows[m]
        c0 = cols[m]
        if r0 < 0 or r0 >= h or c0 < 0 or c0 >= w or obstacles[r0, c0]:
            continue
        for b in range(thetas.shape[1]):
            r1, c1 = ray_end(r0, c0, thetas[m, b], range_px)
            _, hr, hc = trace_ray(obstacles, r0, c0, r1, c1, lr, lc)
            hit_r[m, b] = hr
            hit_c[m, b] = hc


def expected_hits(obstacles: np.ndarray, rows: np.ndarray, cols: np.ndarray, thetas: np.ndarray,
                  range_px: float) -> tuple[np.ndarray, np.ndarray]:
    """The first obstacle cell each beam's walk meets (the digital line of
    :func:`envs.maps.rays.trace_ray`, as the simulated scanner walks it).

    Args:
        obstacles: (H, W) bool, what the scan plane hits.
        rows, cols: (M,) the cell of each scan's origin.
        thetas: (M, B) each beam's heading, radians in the yaw convention (0 faces -row, i.e. +z;
            pi/2 faces +col, i.e. +x).
        range_px: a beam's length, pixels.

    Returns:
        (M, B) int rows and columns of the hit cells, -1 where the beam meets nothing within range
        (or its scan starts off the map or on an obstacle).
    """
    th = np.ascontiguousarray(thetas, np.float64)
    hit_r = np.full(th.shape, -1, np.int64)
    hit_c = np.full(th.shape, -1, np.int64)
    _hits_kernel(np.ascontiguousarray(obstacles, np.bool_), np.asarray(rows, np.int64),
                 np.asarray(cols, np.int64), th, float(range_px), hit_r, hit_c)
    return hit_r, hit_c


def incidence_cos(obstacles: np.ndarray, hit_r: np.ndarray, hit_c: np.ndarray, thetas: np.ndarray) -> np.ndarray:
    """(M, B) cosine of each beam's incidence angle on the cell it hits, as the simulated scanner's
    grazing loss computes it (:func:`envs.maps.scan.surface_normals`); NaN where the beam hits
    nothing or the cell has no surface direction."""
    normals = surface_normals(obstacles)
    ok = hit_r >= 0
    out = np.full(hit_r.shape, np.nan)
    n = normals[hit_r[ok], hit_c[ok]]
    nn = np.hypot(n[:, 0], n[:, 1])
    th = np.asarray(thetas, np.float64)[ok]
    with np.errstate(invalid="ignore", divide="ignore"):
        cos_i = np.abs(-n[:, 0] * np.cos(th) + n[:, 1] * np.sin(th)) / nn
    out[ok] = np.where(nn > 0, cos_i, np.nan)
    return out


def cell_ranges(rows: np.ndarray, cols: np.ndarray, hit_r: np.ndarray, hit_c: np.ndarray,
                resolution: float) -> np.ndarray:
    """(M, B) metres from each scan's origin cell to its beams' hit cells, centre to centre (what
    the simulated scanner measures before noise); NaN where nothing is hit."""
    d = np.hypot(hit_r - np.asarray(rows)[:, None], hit_c - np.asarray(cols)[:, None]) * resolution
    return np.where(hit_r >= 0, d, np.nan)


def projected_ranges(rows_f: np.ndarray, cols_f: np.ndarray, hit_r: np.ndarray, hit_c: np.ndarray,
                     thetas: np.ndarray, resolution: float) -> np.ndarray:
    """(M, B) metres from each scan's exact origin (continuous pixel coordinates ``rows_f``,
    ``cols_f``) to its beams' hit cell centres, along the beam (for a real scan, whose pose is not
    a cell centre); NaN where nothing is hit."""
    th = np.asarray(thetas, np.float64)
    dr = hit_r + 0.5 - np.asarray(rows_f)[:, None]
    dc = hit_c + 0.5 - np.asarray(cols_f)[:, None]
    d = (-dr * np.cos(th) + dc * np.sin(th)) * resolution
    return np.where(hit_r >= 0, d, np.nan)


def fit_dropout(measured: np.ndarray, expected: np.ndarray, cos_i: np.ndarray) -> tuple[float, float, int]:
    """``(dropout, grazing_dropout, n)``: the least-squares line of "no return" against
    ``x = 1 - cos i`` over the ``n`` beams the map expects to return at a known incidence
    (module docstring), each clipped to [0, 1)."""
    valid = np.isfinite(expected) & np.isfinite(cos_i)
    y = ~np.isfinite(measured[valid])
    x = 1.0 - cos_i[valid]
    if valid.sum() < 2 or np.ptp(x) == 0:
        d = float(y.mean()) if y.size else math.nan
        return d, 0.0, int(valid.sum())
    slope, intercept = np.polyfit(x, y.astype(np.float64), 1)
    d = float(np.clip(intercept, 0.0, 0.999))
    g = float(np.clip(slope / (1.0 - d), 0.0, 0.999))
    return d, g, int(valid.sum())


def dropout_correlation(measured: np.ndarray, expected: np.ndarray, cos_i: np.ndarray, dropout: float,
                        grazing: float, axis: int) -> float:
    """Pearson correlation of neighbouring beams' dropouts beyond what the incidence explains (the
    residuals of :func:`fit_dropout`'s line), ``axis`` 1 along a scan (beam ``b`` and ``b + 1``),
    0 over time (a beam in scan ``m`` and ``m + 1``); NaN with fewer than 10 pairs."""
    valid = np.isfinite(expected) & np.isfinite(cos_i)
    p = dropout + (1.0 - dropout) * grazing * (1.0 - np.where(valid, cos_i, 1.0))
    res = np.where(valid, (~np.isfinite(measured)).astype(np.float64) - p, np.nan)
    a = np.moveaxis(res, axis, 0)
    u, v = a[:-1].ravel(), a[1:].ravel()
    ok = np.isfinite(u) & np.isfinite(v)
    if ok.sum() < 10 or u[ok].std() == 0 or v[ok].std() == 0:
        return math.nan
    return float(np.corrcoef(u[ok], v[ok])[0, 1])


def fit_range_noise(measured: np.ndarray, expected: np.ndarray, gate: float,
                    quantisation: float = 0.0) -> dict:
    """The range noise of the beams that return where the map expects a hit.

    Args:
        measured, expected: (M, B) metres, NaN for no return / nothing expected.
        gate: metres; a reading within ``gate`` of the expected range is the expected surface,
            one shorter or longer is counted apart.
        quantisation: metres, the standard deviation the map's cells add to the expected range
            (``resolution / sqrt(12)`` for a map built from real scans; 0 for the simulator, whose
            own ranges are cell to cell); taken off in quadrature.

    Returns:
        dict: ``range_noise`` (m, robust sigma), ``range_bias`` (m, median of measured - expected),
        ``short_share`` and ``long_share`` (of the beams that return where a hit is expected), ``n``.
    """
    both = np.isfinite(measured) & np.isfinite(expected)
    res = (measured - expected)[both]
    if res.size == 0:
        return {"range_noise": math.nan, "range_bias": math.nan, "short_share": math.nan, "long_share": math.nan,
                "n": 0}
    inside = np.abs(res) <= gate
    r = res[inside]
    bias = float(np.median(r)) if r.size else math.nan
    sigma = float(MAD_TO_SIGMA * np.median(np.abs(r - bias))) if r.size else math.nan
    sigma = math.sqrt(max(sigma ** 2 - quantisation ** 2, 0.0))
    return {"range_noise": sigma, "range_bias": bias, "short_share": float(np.mean(res < -gate)),
            "long_share": float(np.mean(res > gate)), "n": int(res.size)}


def noise_by_incidence(measured: np.ndarray, expected: np.ndarray, cos_i: np.ndarray, gate: float,
                       bins_deg=INCIDENCE_BINS_DEG) -> list[dict]:
    """Per incidence bin (degrees): beams expected to return, their no-return share and the
    robust range sigma of those within ``gate``."""
    inc = np.rad2deg(np.arccos(np.clip(cos_i, 0.0, 1.0)))
    out = []
    for lo, hi in zip(bins_deg[:-1], bins_deg[1:], strict=True):
        sel = np.isfinite(expected) & np.isfinite(inc) & (inc >= lo) & ((inc < hi) | (hi == bins_deg[-1]))
        n = int(sel.sum())
        m, e = measured[sel], expected[sel]
        r = (m - e)[np.isfinite(m)]
        r = r[np.abs(r) <= gate]
        sigma = float(MAD_TO_SIGMA * np.median(np.abs(r - np.median(r)))) if r.size else math.nan
        out.append({"from_deg": lo, "to_deg": hi, "n": n,
                    "no_return": float(np.mean(~np.isfinite(m))) if n else math.nan, "range_sigma": sigma})
    return out


@dataclass
class ScanFit:
    """What :func:`fit_scans` reads off a set of scans (module docstring); metres and shares."""

    no_return_share: float
    dropout: float
    grazing_dropout: float
    dropout_corr_beam: float
    dropout_corr_scan: float
    range_noise: float
    range_bias: float
    short_share: float
    long_share: float
    longest_reading: float
    n_scans: int
    n_expected: int
    by_incidence: list = field(default_factory=list)

    def settings(self, base: ScanSettings | None = None) -> ScanSettings:
        """``base`` (default :class:`ScanSettings`) with the fields a scan log tells: range noise,
        dropout and grazing dropout (``max_range`` is only bounded below, so it stays)."""
        b = base or ScanSettings()
        return b.replace(range_noise=round(self.range_noise, 4), dropout=round(self.dropout, 4),
                         grazing_dropout=round(self.grazing_dropout, 4)).check()

    def as_dict(self) -> dict:
        return asdict(self)


def fit_scans(measured: np.ndarray, expected: np.ndarray, cos_i: np.ndarray, gate: float = 0.3,
              quantisation: float = 0.0) -> ScanFit:
    """Fit the scanner to scans: ``measured`` (M, B) metres with NaN for no return, ``expected``
    (M, B) the map's ranges along the same beams (NaN: nothing within range), ``cos_i`` (M, B)
    the cosine of the incidence there (:func:`incidence_cos`), scans in time order and beams in
    angle order (for the correlations)."""
    measured = np.asarray(measured, np.float64)
    expected = np.asarray(expected, np.float64)
    cos_i = np.asarray(cos_i, np.float64)
    if not (measured.shape == expected.shape == cos_i.shape) or measured.ndim != 2:
        raise ValueError(f"scan arrays of shapes {measured.shape}, {expected.shape}, {cos_i.shape}: "
                         "expected three (scans, beams) arrays of one shape")
    d, g, n = fit_dropout(measured, expected, cos_i)
    noise = fit_range_noise(measured, expected, gate, quantisation)
    finite = measured[np.isfinite(measured)]
    return ScanFit(no_return_share=float(np.mean(~np.isfinite(measured))), dropout=d, grazing_dropout=g,
                   dropout_corr_beam=dropout_correlation(measured, expected, cos_i, d, g, axis=1),
                   dropout_corr_scan=dropout_correlation(measured, expected, cos_i, d, g, axis=0),
                   range_noise=noise["range_noise"], range_bias=noise["range_bias"],
                   short_share=noise["short_share"], long_share=noise["long_share"],
                   longest_reading=float(finite.max()) if finite.size else math.nan,
                   n_scans=int(measured.shape[0]), n_expected=n,
                   by_incidence=noise_by_incidence(measured, expected, cos_i, gate))


# --------------------------------------------------------------------------- real logs


@dataclass(frozen=True)
class LogMap:
    """An obstacle grid built from a log's own scans: ``obstacles`` (H, W) bool, ``resolution``
    (m / pixel), ``origin`` world (x, y) of pixel (0, 0)'s top-left corner (rows grow to -y)."""

    obstacles: np.ndarray
    resolution: float
    origin: tuple[float, float]

    def cells(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Continuous pixel coordinates (row, col) of world points."""
        return (self.origin[1] - np.asarray(y)) / self.resolution, (np.asarray(x) - self.origin[0]) / self.resolution


def beam_world(poses: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """(M, B) world angles (radians, counter-clockwise from +x) of the beams at ``angles`` (B,)
    relative to each pose's heading (``poses`` (M, 3) x, y, theta as a CARMEN log gives them)."""
    return np.asarray(poses, np.float64)[:, 2:3] + np.asarray(angles, np.float64)[None, :]


def log_map(poses: np.ndarray, ranges: np.ndarray, angles: np.ndarray, resolution: float = 0.02,
            min_hits: int = 2, margin: float = 1.0, peak_share: float = 0.25) -> LogMap:
    """The map built from a log: a cell is an obstacle where at least ``min_hits`` beam ends fall
    and at least ``peak_share`` of the most any cell within 2 cells holds (so that the ends a wall's
    range noise spreads in front of it and behind do not thicken it: a log of many scans puts two
    ends in cells a wall's own cell far outnumbers).

    Args:
        poses: (M, 3) x, y (m), theta (rad) of each scan (the corrected poses).
        ranges: (M, B) metres, NaN for no return.
        angles: (B,) beam angles relative to the heading, radians.
    """
    if not (np.isfinite(resolution) and resolution > 0):
        raise ValueError(f"map resolution {resolution!r}: expected metres > 0")
    p = np.asarray(poses, np.float64)
    phi = beam_world(p, angles)
    rng = np.asarray(ranges, np.float64)
    ok = np.isfinite(rng)
    ex = (p[:, 0:1] + rng * np.cos(phi))[ok]
    ey = (p[:, 1:2] + rng * np.sin(phi))[ok]
    xs = np.concatenate([ex, p[:, 0]])
    ys = np.concatenate([ey, p[:, 1]])
    x0, y1 = xs.min() - margin, ys.max() + margin
    w = int(math.ceil((xs.max() + margin - x0) / resolution)) + 1
    h = int(math.ceil((y1 - (ys.min() - margin)) / resolution)) + 1
    r = np.floor((y1 - ey) / resolution).astype(np.int64)
    c = np.floor((ex - x0) / resolution).astype(np.int64)
    counts = np.bincount(r * w + c, minlength=h * w).reshape(h, w)
    peak = maximum_filter(counts, size=5, mode="constant")
    return LogMap(obstacles=(counts >= min_hits) & (counts >= peak_share * peak), resolution=float(resolution), origin=(float(x0), float(y1)))


def log_scan_arrays(lm: LogMap, poses: np.ndarray, ranges: np.ndarray, angles: np.ndarray,
                    max_range: float) -> tuple[np.ndarray, np.ndarray]:
    """``(expected, cos_i)``, each (M, B): the ranges the log's map expects along each beam of the
    log's scans, from each scan's exact pose, and the cosines of the incidence there."""
    p = np.asarray(poses, np.float64)
    rf, cf = lm.cells(p[:, 0], p[:, 1])
    rows, cols = np.floor(rf).astype(np.int64), np.floor(cf).astype(np.int64)
    # a world angle phi (counter-clockwise from +x) is the yaw heading pi/2 - phi
    thetas = np.pi / 2 - beam_world(p, angles)
    hit_r, hit_c = expected_hits(lm.obstacles, rows, cols, thetas, max_range / lm.resolution)
    expected = projected_ranges(rf, cf, hit_r, hit_c, thetas, lm.resolution)
    expected = np.where(expected <= max_range, expected, np.nan)
    return expected, incidence_cos(lm.obstacles, hit_r, hit_c, thetas)


def fit_log(poses: np.ndarray, ranges: np.ndarray, angles: np.ndarray, max_range: float,
            resolution: float = 0.02, gate: float = 0.3) -> tuple[ScanFit, LogMap]:
    """The scanner fitted to a log's scans at its (corrected) poses against the map built from
    the log (:func:`log_map`); ``max_range`` metres bounds the expected ranges (beams expected
    beyond it count as expecting nothing)."""
    lm = log_map(poses, ranges, angles, resolution)
    expected, cos_i = log_scan_arrays(lm, poses, ranges, angles, max_range)
    return fit_scans(ranges, expected, cos_i, gate, quantisation=resolution / math.sqrt(12.0)), lm




# --------------------------------------------------------------------------- the front end


def residual_summary(errors: np.ndarray, z: np.ndarray) -> dict:
    """Over edges: their errors ``errors`` (E, 3) at a solution (g2o's EdgeSE2 error,
    :func:`envs.logs.g2o.edge_errors`) and their measurements ``z`` (E, 3): the translational (m)
    and rotational (deg) residual's mean, standard deviation and median, with the mean move (m)
    and turn (deg) an edge measures."""
    e = np.asarray(errors, np.float64).reshape(-1, 3)
    z = np.asarray(z, np.float64).reshape(-1, 3)
    if len(e) == 0 or len(e) != len(z):
        raise ValueError(f"{len(e)} edge errors and {len(z)} measurements: expected one of each for 1 edge or more")
    t = np.hypot(e[:, 0], e[:, 1])
    r = np.rad2deg(np.abs(e[:, 2]))
    return {"edges": len(e), "trans_mean_m": float(t.mean()), "trans_std_m": float(t.std()),
            "trans_median_m": float(np.median(t)), "rot_mean_deg": float(r.mean()), "rot_std_deg": float(r.std()),
            "rot_median_deg": float(np.median(r)), "move_m": float(np.hypot(z[:, 0], z[:, 1]).mean()),
            "turn_deg": float(np.rad2deg(np.abs(z[:, 2])).mean())}


def odometry_edge_residuals(graph, states: np.ndarray) -> dict:
    """What a real scan matcher's odometry edges are off by: over the edges of ``graph`` (an
    :class:`envs.logs.g2o.PoseGraphFile`) between consecutive vertex ids, :func:`residual_summary`
    at ``states`` (the solved graph), and ``closures``, the graph's other edges. A residual at the
    solve is a lower bound of the edge's error against the truth (the solve spreads part of it over
    the graph)."""
    odo = (graph.ids[graph.j] - graph.ids[graph.i]) == 1
    if not odo.any():
        raise ValueError(f"{graph.path}: no edge between consecutive vertices: expected odometry edges")
    return {**residual_summary(graph.errors(states)[odo], graph.z[odo]), "closures": int((~odo).sum())}


def chain_edge_errors(states: np.ndarray, z: np.ndarray) -> np.ndarray:
    """(M-1, 3) the errors (:func:`envs.logs.g2o.edge_errors`) at ``states`` (M, 3) SE(2) of the
    odometry edges ``z`` (M-1, 3) between consecutive nodes (a SLAM estimate's: the front end's
    fused moves the back end got, :attr:`benchmark.conditions.slam.SlamEstimate.odometry_edges`)."""
    s = np.asarray(states, np.float64).reshape(-1, 3)
    z = np.asarray(z, np.float64).reshape(-1, 3)
    if len(z) != len(s) - 1:
        raise ValueError(f"{len(z)} odometry edges over {len(s)} nodes: expected one edge between each two consecutive "
                         "nodes")
    k = np.arange(len(z))
    return edge_errors(s, k, k + 1, z)


__all__ = ["expected_hits", "incidence_cos", "cell_ranges", "projected_ranges", "fit_dropout",
           "dropout_correlation", "fit_range_noise", "noise_by_incidence", "ScanFit", "fit_scans", "LogMap",
           "beam_world", "log_map", "log_scan_arrays", "fit_log", "MAD_TO_SIGMA", "odometry_edge_residuals",
           "residual_summary", "chain_edge_errors"]
