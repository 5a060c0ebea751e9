"""Real robot data (issue 59 items 1, 2, 4): the CARMEN and g2o / TORO readers on hand-written and
real excerpts (tests/fixtures/real_logs, sources in its README) and on malformed lines; what
gtsam.readG2o accepts; the project's solve on a real graph excerpt against a dense solve; the raw
map of hand-written scans at a known wall; the catalogue's real data entries; the command."""

from __future__ import annotations

import gzip
import hashlib
import http.server
import math
import shutil
import threading
from pathlib import Path

import numpy as np
import pytest

from envs.logs.carmen import CarmenLogError, read_carmen
from envs.logs.g2o import PoseGraphFileError, read_g2o, read_pose_graph, read_toro

FIX = Path(__file__).parent / "fixtures" / "real_logs"


# --- CARMEN ---------------------------------------------------------------------------------------

def test_carmen_reader_on_a_hand_written_log_gives_the_known_values():
    log = read_carmen(FIX / "hand-written.log")
    assert log.params == {"robot_front_laser_max": "50"}
    assert log.skipped == {"NEFF": 1, "SYNC": 1}
    (o,) = log.odometry
    assert o.pose == (1.0, 2.0, 0.5) and (o.tv, o.rv, o.accel) == (0.3, -0.1, 0.0) and o.timestamp == 10.25
    assert o.line == 3
    f, r, rl = log.scans
    assert f.kind == "FLASER" and f.line == 4 and f.ranges.tolist() == [1.5, 2.5, 3.5, 4.5]
    assert f.laser_pose == (1.0, 2.0, 0.5) and f.robot_pose == (0.9, 2.1, 0.4) and f.timestamp == 11.5
    # 4 beams over 180 degrees from -90: 45 degrees apart; no max range in the line
    assert f.angle_min == pytest.approx(-math.pi / 2) and f.angle_increment == pytest.approx(math.pi / 4)
    assert f.max_range is None
    # beam 2 (bearing 0) of 3.5 m from (1, 2) heading 0.5 rad
    assert f.endpoints()[2] == pytest.approx([1 + 3.5 * math.cos(0.5), 2 + 3.5 * math.sin(0.5)])
    assert r.kind == "RLASER" and r.ranges.tolist() == [0.5, 0.6, 0.7] and r.laser_pose == (-1.0, -2.0, 3.0)
    assert r.angle_increment == pytest.approx(math.pi / 2)  # 3 beams (odd): both ends included
    assert rl.kind == "ROBOTLASER1" and rl.ranges.tolist() == [1, 2, 3, 4, 8] and rl.max_range == 8.0
    assert rl.angle_min == -1.5708 and rl.angle_increment == 0.785398
    assert rl.laser_pose == (1.0, 2.0, 0.5) and rl.robot_pose == (0.9, 2.0, 0.5) and rl.timestamp == 12.5
    assert log.laser_poses("ROBOTLASER1").tolist() == [[1.0, 2.0, 0.5]]


def test_carmen_reader_on_the_intel_excerpt_plain_and_gzip(tmp_path):
    gz = tmp_path / "intel.log.gz"
    gz.write_bytes(gzip.compress((FIX / "intel-excerpt.log").read_bytes()))
    for path in (FIX / "intel-excerpt.log", gz):
        log = read_carmen(path)
        assert len(log.scans) == 3 and len(log.odometry) == 191 and log.skipped == {"NEFF": 3}
        s = log.scans[0]
        assert s.line == 175 and len(s.ranges) == 180 and s.ranges[0] == 1.09 and s.ranges[-1] == 1.23
        assert s.laser_pose == (0.600266, -0.0320327, -0.354665) and s.timestamp == 32.9068
        assert s.angle_increment == pytest.approx(math.pi / 180)  # the SICK LMS: 180 beams, 1 degree
        assert log.scan_ranges().shape == (3, 180)


@pytest.mark.parametrize("bad, what", [
    ("FLASER 3 1.0 2.0 0 0 0 0 0 0 1.5 host 1.6", "expected 13"),  # one reading missing
    ("FLASER 2 1.0 abc 0 0 0 0 0 0 1.5 host 1.6", "range[1] = 'abc': expected a number"),
    ("FLASER 2 1.0 nan 0 0 0 0 0 0 1.5 host 1.6", "expected a finite number"),
    ("FLASER -2 0 0 0 0 0 0 1.5 host 1.6", "num_readings = '-2'"),
    ("ODOM 1 2 3 0 0 1.5 host 1.6", "expected 9"),
    ("ROBOTLASER1 0 -1.5 3.1 0.78 8 0.01 0 2 1 2 0 1 2 0.5 1 2 0.5 0 0 0.5 0.05 0 12.5 host", "expected 25"),
    ("PARAM lonely", "expected param_name param_value"),
])
def test_a_malformed_carmen_line_is_one_line_naming_its_number(tmp_path, bad, what):
    p = tmp_path / "bad.log"
    p.write_text("# a log\nODOM 0 0 0 0 0 0 1.0 host 1.0\n" + bad + "\nODOM 0 0 0 0 0 0 2.0 host 2.0\n")
    with pytest.raises(CarmenLogError) as e:
        read_carmen(p)
    msg = str(e.value)
    assert "\n" not in msg and str(p) in msg and "line 3 (" in msg and what in msg


# --- g2o / TORO -----------------------------------------------------------------------------------

#: a hand-written information matrix with six different entries (order checks)
INFO = np.array([[10.0, 1.0, 2.0], [1.0, 20.0, 3.0], [2.0, 3.0, 30.0]])


def _hand_written(tmp_path, fmt):
    if fmt == "g2o":
        head, edge, info = "VERTEX_SE2", "EDGE_SE2", "10 1 2 20 3 30"  # I11 I12 I13 I22 I23 I33
    else:
        head, edge, info = "VERTEX2", "EDGE2", "10 1 20 30 2 3"  # I11 I12 I22 I33 I13 I23
    p = tmp_path / f"g.{fmt}"
    p.write_text(f"# comment\n{edge} 7 3 1.0 0.5 0.25 {info}\n{head} 3 0 0 0\n{head} 7 1.0 0.5 0.3\nFIX 3\n")
    return p


def _rotated_by_hand(m, t):
    """R^T m R for R the rotation by ``t`` of x and y, entry by entry (m's xy block turned into
    the frame rotated by t; the cross terms with theta turned as a vector; m33 kept)."""
    c, s = math.cos(t), math.sin(t)
    xx, xy, yy, xr, yr, rr = m[0, 0], m[0, 1], m[1, 1], m[0, 2], m[1, 2], m[2, 2]
    a = c * c * xx + 2 * c * s * xy + s * s * yy
    b = c * s * (yy - xx) + (c * c - s * s) * xy
    d = s * s * xx - 2 * c * s * xy + c * c * yy
    e, f = c * xr + s * yr, -s * xr + c * yr
    return np.array([[a, b, e], [b, d, f], [e, f, rr]])


@pytest.mark.parametrize("fmt", ["g2o", "toro"])
def test_pose_graph_reader_puts_each_formats_information_in_its_place(tmp_path, fmt):
    g = read_pose_graph(_hand_written(tmp_path, fmt))
    assert g.format == fmt and g.ids.tolist() == [3, 7] and g.skipped == {"FIX": 1}
    assert g.initial.tolist() == [[0, 0, 0], [1.0, 0.5, 0.3]]
    assert (g.i.tolist(), g.j.tolist()) == ([1], [0])  # rows of ids 7 and 3
    assert g.z.tolist() == [[1.0, 0.5, 0.25]]
    # a TORO matrix belongs to the residual in pose i's frame: read into the measurement's frame
    expected = INFO if fmt == "g2o" else _rotated_by_hand(INFO, 0.25)
    np.testing.assert_allclose(g.information[0], expected, rtol=1e-14, atol=1e-13)
    # chi2 by hand: vertex 3 seen from vertex 7
    c, s = math.cos(0.3), math.sin(0.3)
    rel = np.array([c * -1.0 + s * -0.5, -s * -1.0 + c * -0.5, -0.3])
    cz, sz = math.cos(0.25), math.sin(0.25)
    dt = rel[:2] - [1.0, 0.5]
    e = np.array([cz * dt[0] + sz * dt[1], -sz * dt[0] + cz * dt[1], -0.3 - 0.25])
    assert g.chi2(g.initial) == pytest.approx(e @ expected @ e, rel=1e-12)
    if fmt == "toro":  # the same cost as the file's matrix on the residual in vertex 7's frame
        e_i = np.array([dt[0], dt[1], e[2]])
        assert g.chi2(g.initial) == pytest.approx(e_i @ INFO @ e_i, rel=1e-12)


def test_toro_information_is_rotated_by_the_measured_angle(tmp_path):
    """An anisotropic xy block with cross terms and dtheta = -0.7 rad: the matrix read is the TORO
    one rotated by hand; dtheta = 0 leaves it as written."""
    p = tmp_path / "g.graph"
    p.write_text("VERTEX2 0 0 0 0\nVERTEX2 1 1 0 0\nVERTEX2 2 2 0 0\n"
                 "EDGE2 0 1 1.0 0.2 -0.7 50 -4 2 9 0.5 -0.3\nEDGE2 1 2 1.0 0.0 0.0 50 -4 2 9 0.5 -0.3\n")
    g = read_toro(p)
    toro = np.array([[50.0, -4.0, 0.5], [-4.0, 2.0, -0.3], [0.5, -0.3, 9.0]])
    np.testing.assert_allclose(g.information[0], _rotated_by_hand(toro, -0.7), rtol=1e-14, atol=1e-13)
    assert not np.allclose(g.information[0], toro, atol=1.0)
    np.testing.assert_array_equal(g.information[1], toro)


@pytest.mark.parametrize("toro, g2o", [("csail-excerpt.graph", "csail-excerpt.g2o"),
                                       ("m3500-excerpt.graph", "manhattan-excerpt.g2o")])
def test_toro_reading_matches_the_datasets_own_g2o_versions(toro, g2o):
    """The same graphs in g2o by their author (SE-Sync's data/CSAIL.g2o, data/manhattan.g2o; sources
    in the fixtures' README): edge for edge the same measurements, and our TORO information equals
    theirs to the files' 6 decimals (unrotated it is off by up to thousands)."""
    g = read_toro(FIX / toro)
    rows = np.loadtxt(FIX / g2o, usecols=range(1, 12), ndmin=2)  # EDGE_SE2 lines only
    assert len(rows) == len(g.i) and (g.ids[g.i] == rows[:, 0]).all() and (g.ids[g.j] == rows[:, 1]).all()
    np.testing.assert_array_equal(g.z, rows[:, 2:5])
    theirs = np.zeros((len(rows), 3, 3))
    for k, (r, c) in enumerate(((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))):
        theirs[:, r, c] = theirs[:, c, r] = rows[:, 5 + k]
    np.testing.assert_allclose(g.information, theirs, rtol=0, atol=1e-6)


def test_the_real_excerpts_agree_on_the_first_intel_edge():
    g2o, toro = read_g2o(FIX / "intel-excerpt.g2o"), read_toro(FIX / "intel-excerpt.graph")
    assert g2o.n == toro.n == 20 and len(g2o.i) == 19
    # EDGE_SE2 0 1 ... 11.111271 -0.249667 0 399.999840 0 2496.793089 / EDGE2 0 1 0 0 -0.000642 11.111111 0 1e8
    # 2496.793089 0 0 (the g2o file of Intel is no rotation of the TORO one: its I22 is 400, not 1e8)
    np.testing.assert_array_equal(g2o.information[0], [[11.111271, -0.249667, 0], [-0.249667, 399.99984, 0],
                                                       [0, 0, 2496.793089]])
    np.testing.assert_allclose(toro.information[0], _rotated_by_hand(np.diag([11.111111, 1e8, 2496.793089]), -0.000642),
                               rtol=1e-14, atol=1e-9)
    np.testing.assert_allclose(g2o.initial, toro.initial, atol=1e-5)  # the two files round differently


@pytest.mark.parametrize("bad, what", [
    ("EDGE_SE2 0 1 1 0 0 1 0 0 1 0", "10 fields: expected 11"),
    ("EDGE_SE2 0 1 1 x 0 1 0 0 1 0 1", "dy = 'x': expected a number"),
    ("EDGE_SE2 0 1 1 0 0 1 0 0 -1 0 1", "not positive definite"),
    ("EDGE_SE2 0 9 1 0 0 1 0 0 1 0 1", "j = 9: expected the id of a vertex"),
    ("VERTEX_SE2 0 1 1 1", "vertex 0 a second time"),
    ("VERTEX2 5 0 0 0", "a toro line in a g2o file"),
    ("VERTEX_SE2 five 0 0 0", "id = 'five': expected a whole number"),
])
def test_a_malformed_pose_graph_line_is_one_line_naming_its_number(tmp_path, bad, what):
    p = tmp_path / "bad.g2o"
    p.write_text("VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\n" + bad + "\n")
    with pytest.raises(PoseGraphFileError) as e:
        read_pose_graph(p)
    msg = str(e.value)
    assert "\n" not in msg and str(p) in msg and "line 3 (" in msg and what in msg


def test_gtsam_readG2o_matches_our_g2o_reading_and_reads_toro_in_g2o_order(tmp_path):
    """Our check of what gtsam.readG2o accepts: a g2o file gives our information matrices edge
    for edge; a TORO file's EDGE2 lines are read in g2o order (so its information lands in the wrong
    places, or GTSAM refuses it): TORO files are read by envs.logs.g2o only."""
    gtsam = pytest.importorskip("gtsam")
    ours = read_g2o(FIX / "intel-excerpt.g2o")
    fg, values = gtsam.readG2o(str(FIX / "intel-excerpt.g2o"), False)
    assert fg.size() == len(ours.i) and values.size() == ours.n
    for k in range(fg.size()):
        f = fg.at(k)
        r = f.noiseModel().R()
        np.testing.assert_allclose(r.T @ r, ours.information[k], rtol=1e-9, atol=1e-6)
        m = f.measured()
        np.testing.assert_allclose([m.x(), m.y(), m.theta()], ours.z[k], atol=1e-12)
    with pytest.raises(RuntimeError, match="not G2O matrix order"):
        gtsam.readG2o(str(FIX / "intel-excerpt.graph"), False)  # TORO I13 = I23 = 0 read as g2o I22, I33
    p = tmp_path / "plain.graph"
    p.write_text("VERTEX2 0 0 0 0\nVERTEX2 1 1.0 0.5 0.3\nEDGE2 1 0 1.0 0.5 0.25 10 1 20 30 2 3\n")
    fg, _ = gtsam.readG2o(str(p), False)
    assert fg.size() == 1
    np.testing.assert_allclose(read_toro(p).information[0], _rotated_by_hand(INFO, 0.25), rtol=1e-14, atol=1e-13)
    r = fg.at(0).noiseModel().R()
    assert not np.allclose(r.T @ r, INFO, atol=1e-3)  # read in g2o order: not the TORO file's matrix


# --- the solve on a real graph ---------------------------------------------------------------------

def _log_between(z, xi, xj):
    """(E, 3) SE(2) logarithm of Z^-1 X_i^-1 X_j per edge, by rotation matrices: the relative
    pose's translation t and angle th, then u = V(th)^-1 t (V = [[a, -b], [b, a]], a = sin th / th,
    b = (1 - cos th) / th)."""
    def inv_apply(p, q):  # p^-1 q for rows (x, y, theta)
        c, s = np.cos(p[:, 2]), np.sin(p[:, 2])
        d = q[:, :2] - p[:, :2]
        return np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1], q[:, 2] - p[:, 2]])

    e = inv_apply(z, inv_apply(xi, xj))
    th = np.arctan2(np.sin(e[:, 2]), np.cos(e[:, 2]))
    small = np.abs(th) < 1e-10
    ts = np.where(small, 1.0, th)
    a = np.where(small, 1.0, np.sin(ts) / ts)
    b = np.where(small, 0.0, (1 - np.cos(ts)) / ts)
    det = a * a + b * b
    return np.column_stack([(a * e[:, 0] + b * e[:, 1]) / det, (-b * e[:, 0] + a * e[:, 1]) / det, th])


def _dense_solve(g, iterations=20):
    """Gauss-Newton on every edge's whitened Log(Z^-1 X_i^-1 X_j), node 0 fixed, central-difference
    Jacobian, NumPy's dense solver: the reference for the GTSAM back end."""
    sqrt_info = np.transpose(np.linalg.cholesky(g.information), (0, 2, 1))

    def residuals(v):
        x = np.vstack([g.initial[:1], v.reshape(-1, 3)])
        return np.einsum("eij,ej->ei", sqrt_info, _log_between(g.z, x[g.i], x[g.j])).ravel()

    v = g.initial[1:].ravel().copy()
    for _ in range(iterations):
        r = residuals(v)
        jac = np.empty((len(r), len(v)))
        for k in range(len(v)):
            d = np.zeros(len(v))
            d[k] = 1e-7
            jac[:, k] = (residuals(v + d) - residuals(v - d)) / 2e-7
        step = np.linalg.solve(jac.T @ jac, -jac.T @ r)
        v = v + step
        if np.abs(step).max() < 1e-10:
            break
    r = residuals(v)
    return np.vstack([g.initial[:1], v.reshape(-1, 3)]), float(r @ r)


def test_the_solve_on_a_real_graph_excerpt_matches_a_dense_solve():
    """M3500's first 40 poses (odometry and 6 loop closures) from the file's own initial guess."""
    from benchmark.conditions.pose_graph import graph_of_file, solve

    g = read_toro(FIX / "m3500-excerpt.graph")
    assert g.n == 40 and int((np.abs(g.i - g.j) > 1).sum()) == 6
    states, info = solve(graph_of_file(g), g.initial, kernel="none")
    ref, chi2 = _dense_solve(g)
    assert info["converged"] and info["dof"] == 3 * len(g.i) - 3 * (g.n - 1)
    assert info["chi2"] == pytest.approx(chi2, rel=1e-6)
    # LM stops when the cost falls by less than 1e-6 of itself: the states agree to 1e-4
    np.testing.assert_allclose(states[:, :2], ref[:, :2], atol=1e-4)
    np.testing.assert_allclose(np.angle(np.exp(1j * (states[:, 2] - ref[:, 2]))), 0, atol=1e-5)
    # 5.05 from 1061 at the file's initial guess (information in the measurement's frame)
    assert info["chi2"] < 1e-2 * solve(graph_of_file(g), g.initial, kernel="none", max_iterations=0)[1]["chi2"]


# --- raw maps --------------------------------------------------------------------------------------

def test_the_raw_map_of_scans_at_a_known_wall(tmp_path):
    """A robot at (0, 0) heading +x, 4 scans of 181 beams: a wall along x = 2.025 m (|y| < 3 m),
    no return elsewhere (81.91 m, the logs' no-return reading). Free before the wall, occupied on
    it, unknown behind it; a no-return beam frees its line up to max_range (10 m) and no further."""
    from envs.logs.raw_map import raw_map_from_log
    from envs.maps.scan import ScanSettings

    angles = np.deg2rad(np.arange(-90, 91))
    ranges = []
    for a in angles:
        d = 2.025 / math.cos(a) if abs(math.cos(a)) > 1e-9 else math.inf
        ranges.append(d if d < math.hypot(2.025, 3.0) else 81.91)
    line = "FLASER 181 " + " ".join(f"{r:.4f}" for r in ranges) + " 0 0 0 0 0 0 {t} host {t}\n"
    p = tmp_path / "wall.log"
    p.write_text("".join(line.format(t=k) for k in range(4)))
    occ, (x0, y0) = raw_map_from_log(read_carmen(p), 0.05, ScanSettings())

    def cell(x, y):
        return occ[int(math.floor((y0 - y) / 0.05)), int(math.floor((x - x0) / 0.05))]

    assert cell(1.0, 0.0) == 0 and cell(1.9, 1.0) == 0  # free before the wall
    assert cell(2.025, 0.0) == 100 and cell(2.025, -1.0) == 100 and cell(2.025, 1.5) == 100  # the wall
    assert cell(2.5, 0.0) == -1 and cell(3.0, 1.0) == -1  # behind it: never seen
    assert cell(0.0, 5.0) == 0 and cell(0.0, 9.5) == 0  # the no-return beam at +90 degrees: free to 10 m
    r, c = np.nonzero(occ == 0)
    far = np.hypot(x0 + (c + 0.5) * 0.05, y0 - (r + 0.5) * 0.05).max()
    assert 9.9 < far < 10.0 + 0.05  # and no further


# --- the catalogue ----------------------------------------------------------------------------------

def test_the_catalogue_knows_the_real_logs_and_graphs_with_their_sources():
    from envs.datasets.download import load_catalogue

    cat = load_catalogue()
    logs, graphs = cat["real_logs"], cat["real_graphs"]
    assert logs.folder == "real_logs" and "acschaefer/ple" in logs.source
    assert {f.path for f in logs.files} == {"aces-corrected.log.gz", "csail-corrected.log.gz",
                                            "freiburg-079-corrected.log.gz", "intel-corrected.log.gz"}
    for f in logs.files:
        assert f.url == ("https://raw.githubusercontent.com/acschaefer/ple/8af88b28759f8a48b1bf33083a85f2013907c41d/"
                         f"data/carmen/{f.path}")
    urls = {f.path: f.url for f in graphs.files}
    base = "https://raw.githubusercontent.com/israni/Submapping--Graph-SLAM/"
    assert urls["input_INTEL_g2o.g2o"] == base + "88bc46e769ba93829ef1eea3d487a033cc93a0fa/input_INTEL_g2o.g2o"
    for name in ("INTEL", "CSAIL", "M3500"):
        assert urls[f"{name}_P_toro.graph"] == (base + "24314204efca179240af65022698fb7399dc4c1c/Datasets/"
                                                f"{name}_P_toro.graph")
    assert "lucacarlone.mit.edu" in graphs.source


def test_the_real_logs_fetch_from_a_local_server_is_verified(tmp_path, capsys):
    """The catalogue's real_logs entry fetched from a server on 127.0.0.1 serving the shared copies
    at the entry's URL paths: sizes and SHA-256 match (those of SHA256SUMS beside them)."""
    from benchmark.commands.data import main
    from benchmark.paths import data_dir
    from envs.datasets.download import CATALOGUE, load_catalogue

    shared = data_dir() / "real_logs"
    if not (shared / "SHA256SUMS").is_file():
        pytest.skip(f"shared real logs not found under {shared}")
    sums = dict(line.split()[::-1] for line in (shared / "SHA256SUMS").read_text().splitlines() if line.strip())
    ds = load_catalogue()["real_logs"]
    assert {f.path: f.sha256 for f in ds.files} == sums
    prefix = "/acschaefer/ple/8af88b28759f8a48b1bf33083a85f2013907c41d/data/carmen/"
    files = {prefix + f.path: (shared / f.path).read_bytes() for f in ds.files}
    assert all(hashlib.sha256(b).hexdigest() == sums[k.rsplit("/", 1)[1]] for k, b in files.items())

    class Handler(http.server.BaseHTTPRequestHandler):
        def do_GET(self):  # noqa: N802
            body = files.get(self.path)
            if body is None:
                self.send_error(404)
                return
            self.send_response(200)
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body)

        def log_message(self, *args):
            pass

    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Handler)
    threading.Thread(target=httpd.serve_forever, daemon=True).start()
    try:
        text = CATALOGUE.read_text().replace("https://raw.githubusercontent.com/",
                                             f"http://127.0.0.1:{httpd.server_address[1]}/")
        cat = tmp_path / "catalogue.yaml"
        cat.write_text(text)
        assert main(["--root", str(tmp_path / "data"), "--catalogue", str(cat), "fetch", "real_logs",
                     "--no-progress"]) == 0
    finally:
        httpd.shutdown()
        httpd.server_close()
    assert "real_logs: fetched and verified" in capsys.readouterr().out
    for f in ds.files:
        assert (tmp_path / "data" / "real_logs" / f.path).read_bytes() == files[prefix + f.path]


# --- SE-Sync's cost -----------------------------------------------------------------------------------

def test_sesync_cost_on_a_hand_made_graph(tmp_path):
    """Poses (0, 0, 0), (1, 0, 0), (1, 1, pi/2); per edge kappa 4 (1 - cos(theta_j - theta_i -
    dtheta)) + tau |t_j - t_i - R_i t~|^2 with tau = 2 / tr(inverse xy information):
    0->1 exact: 0; 1->2 (1, 0, 0), diag(2, 2, 3): 3 * 4 * 1 + 2 * |(-1, 1)|^2 = 16;
    0->2 (1, 1, pi), diag(1, 4, 5): 5 * 4 * 1 + 1.6 * 0 = 20;
    2->0 (1, 1, -pi/2), diag(4, 4, 7): 0 + 4 * |(-1, -1) - R(pi/2)(1, 1)|^2 = 4 * |(0, -2)|^2 = 16."""
    from benchmark.commands.real_logs import sesync_cost

    p = tmp_path / "three.g2o"
    h = math.pi / 2
    p.write_text(f"VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\nVERTEX_SE2 2 1 1 {h!r}\n"
                 "EDGE_SE2 0 1 1 0 0 9 0 0 9 0 9\n"
                 "EDGE_SE2 1 2 1 0 0 2 0 0 2 0 3\n"
                 f"EDGE_SE2 0 2 1 1 {math.pi!r} 1 0 0 4 0 5\n"
                 f"EDGE_SE2 2 0 1 1 {-h!r} 4 0 0 4 0 7\n")
    g = read_g2o(p)
    assert sesync_cost(g, g.initial) == pytest.approx(52.0, rel=1e-12)
    # vertex 1 at (1.5, 0, 0): edge 0->1 off by (0.5, 0) with tau = 2 / (1/9 + 1/9) = 9, edge 1->2 by
    # (-1.5, 1) instead of (-1, 1)
    moved = g.initial.copy()
    moved[1] = [1.5, 0.0, 0.0]
    assert sesync_cost(g, moved) == pytest.approx(52.0 + 9 * 0.25 + 2 * (3.25 - 2.0), rel=1e-12)


def test_sesync_weighted_carries_tau_tau_and_twice_kappa(tmp_path):
    """The hand-made graph above reweighted: diag(tau, tau, 2 kappa) per edge, the rest as read; a
    g2o cross term or an anisotropic block leaves only tau."""
    from benchmark.commands.real_logs import sesync_weighted

    p = tmp_path / "two.g2o"
    p.write_text("VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\n"
                 "EDGE_SE2 0 1 1 0 0 2 0 0 2 0 3\n"
                 "EDGE_SE2 1 0 -1 0 0.1 1 0 0.5 4 0.2 5\n")
    g = read_g2o(p)
    w = sesync_weighted(g)
    np.testing.assert_allclose(w.information[0], np.diag([2.0, 2.0, 6.0]), rtol=1e-14)
    np.testing.assert_allclose(w.information[1], np.diag([1.6, 1.6, 10.0]), rtol=1e-14)
    np.testing.assert_array_equal(w.z, g.z)
    assert (w.i.tolist(), w.j.tolist()) == (g.i.tolist(), g.j.tolist())
    np.testing.assert_array_equal(g.information[1], [[1, 0, 0.5], [0, 4, 0.2], [0.5, 0.2, 5]])  # g untouched


# --- the command ------------------------------------------------------------------------------------

def test_the_graphs_command_writes_its_table_and_refuses_a_bad_line_in_one_line(tmp_path, capsys):
    from benchmark.commands.real_logs import main

    d = tmp_path / "graphs"
    d.mkdir()
    shutil.copy(FIX / "m3500-excerpt.graph", d)
    shutil.copy(FIX / "intel-excerpt.g2o", d)
    out = tmp_path / "real_graphs.md"
    assert main(["graphs", "--dir", str(d), "--out", str(out)]) == 0
    text = out.read_text()
    assert text.startswith(f"Written by `python -m benchmark.commands.real_logs graphs --dir {d} --out {out}`.")
    rows = {line.split("|")[1].strip(): [c.strip() for c in line.split("|")[1:-1]] for line in text.splitlines()
            if line.startswith("| m3500") or line.startswith("| intel")}
    m = rows["m3500-excerpt.graph"]
    assert m[1:4] == ["toro", "40", "45"] and m[9] == "yes"
    assert float(m[6]) == pytest.approx(float(m[10]), rel=1e-5)  # ours == readG2o + LM
    assert m[11:14] == ["–", "–", "–"]  # SE-Sync publishes no optimum of this graph
    (d / "broken.g2o").write_text("VERTEX_SE2 0 0 0 0\nEDGE_SE2 0 0 1 0\n")
    assert main(["graphs", "--dir", str(d)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "broken.g2o: line 2 (EDGE_SE2)" in err


def test_the_maps_command_on_the_intel_excerpt(tmp_path, capsys):
    from benchmark.commands.real_logs import main

    d = tmp_path / "logs"
    d.mkdir()
    shutil.copy(FIX / "intel-excerpt.log", d)
    assert main(["maps", "--dir", str(d), "--out-dir", str(tmp_path / "maps")]) == 0
    out = capsys.readouterr().out
    assert "intel-excerpt (raw)" in out and "wall_thickness_m" in out
    from envs.maps.ros import read_ros_map

    assert read_ros_map(tmp_path / "maps" / "intel-excerpt_raw.yaml") is not None
    assert main(["maps", "--dir", str(tmp_path / "nothing")]) == 2
    assert "log folder not found" in capsys.readouterr().err
