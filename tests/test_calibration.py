"""Issue 59 items 3, 5, 6: the relative pose error of Kümmerle et al. (2009) and the fits of the
simulated scanner to real scans (benchmark/conditions/relative_error.py, calibration.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from benchmark.conditions.relative_error import consecutive_pairs, distance_pairs, relative_error


def _se2(rows):
    return np.asarray(rows, np.float64)


def test_relative_error_known_answer_translation():
    """A straight path of 1 m moves; the estimate's last pose is 0.1 m off sideways: of the two
    consecutive relations one is off by 0.1 m, none by any angle."""
    truth = _se2([[0, 0, 0], [1, 0, 0], [2, 0, 0]])
    est = _se2([[0, 0, 0], [1, 0, 0], [2, 0.1, 0]])
    e = relative_error(est, truth, consecutive_pairs(3))
    assert e.n == 2
    assert e.trans_mean_m == pytest.approx(0.05)
    assert e.trans_std_m == pytest.approx(0.05)
    assert e.trans_sq_m2 == pytest.approx(0.005)
    assert e.rot_mean_deg == pytest.approx(0.0, abs=1e-12)


def test_relative_error_heading_error_counts_once():
    """A heading error of 0.1 rad at the middle pose, with the rest of the path carried along
    (what a wrong turn does): the relation (0, 1) is off by 0.1 rad and nothing else, the relation
    (1, 2) is exact; the absolute error of pose 2 (0.1 m and 0.1 rad) is not what is measured."""
    truth = _se2([[0, 0, 0], [1, 0, 0], [2, 0, 0]])
    est = _se2([[0, 0, 0], [1, 0, 0.1], [1 + math.cos(0.1), math.sin(0.1), 0.1]])
    e = relative_error(est, truth, consecutive_pairs(3))
    assert e.rot_mean_deg == pytest.approx(math.degrees(0.1) / 2)
    assert e.rot_sq_deg2 == pytest.approx(math.degrees(0.1) ** 2 / 2)
    assert e.trans_mean_m == pytest.approx(0.0, abs=1e-12)
    # the relation (0, 2): the estimate went to (1 + cos .1, sin .1) instead of (2, 0)
    e02 = relative_error(est, truth, np.array([[0, 2]]))
    assert e02.trans_mean_m == pytest.approx(math.hypot(1 - math.cos(0.1), math.sin(0.1)))


def test_relative_error_ignores_a_global_transform():
    """The whole estimate moved and turned: every relation is exact (unlike the ATE)."""
    rng = np.random.default_rng(0)
    truth = np.column_stack([np.cumsum(rng.uniform(0, 1, 30)), np.cumsum(rng.uniform(-1, 1, 30)),
                             rng.uniform(-math.pi, math.pi, 30)])
    a, tx, ty = 0.7, 5.0, -3.0
    est = np.column_stack([math.cos(a) * truth[:, 0] - math.sin(a) * truth[:, 1] + tx,
                           math.sin(a) * truth[:, 0] + math.cos(a) * truth[:, 1] + ty, truth[:, 2] + a])
    e = relative_error(est, truth, distance_pairs(truth, 2.0))
    assert e.n > 10
    assert e.trans_mean_m < 1e-9 and e.rot_mean_deg < 1e-9


def test_distance_pairs_and_bad_relations():
    path = _se2([[0, 0, 0], [0.5, 0, 0], [1.0, 0, 0], [2.5, 0, 0]])
    assert distance_pairs(path, 1.0).tolist() == [[0, 2], [1, 3], [2, 3]]
    with pytest.raises(ValueError, match="relation index 7"):
        relative_error(path, path, np.array([[0, 7]]))
    with pytest.raises(ValueError, match="estimate has 3 poses, reference 4"):
        relative_error(path[:3], path, np.array([[0, 1]]))
    with pytest.raises(ValueError, match="relation distance"):
        distance_pairs(path, 0.0)


# --------------------------------------------------------------------------- the scanner's fit

from benchmark.conditions.calibration import (  # noqa: E402
    cell_ranges,
    expected_hits,
    fit_log,
    fit_scans,
    incidence_cos,
)
from envs.maps.gridmap import GridMap  # noqa: E402
from envs.maps.scan import ScanSettings, scan_ranges  # noqa: E402


def _rooms(res=0.05):
    """Two rooms of 6 x 5 m joined by a door, with two pillars and a slanted wall piece."""
    h, w = int(5.4 / res), int(12.4 / res)
    ob = np.zeros((h, w), bool)
    ob[:4, :] = ob[-4:, :] = True
    ob[:, :4] = ob[:, -4:] = True
    ob[:, w // 2 - 2:w // 2 + 2] = True
    ob[h // 2 - 10:h // 2 + 10, w // 2 - 2:w // 2 + 2] = False  # the door
    ob[30:36, 40:46] = ob[60:70, 180:186] = True
    for k in range(30):
        ob[70 + k, 140 + k:143 + k] = True  # a wall at 45 degrees
    return ob, GridMap(~ob, res, (0.0, 5.4))


def _poses(grid, ob, n, seed):
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < n:
        x, z = rng.uniform(0.3, 12.1), rng.uniform(0.3, 5.1)
        r, c = grid.cell_of(x, z)
        if not ob[max(r - 3, 0):r + 4, max(c - 3, 0):c + 4].any():
            out.append((x, z, rng.uniform(0, 360)))
    return np.array(out)


def _simulated(settings, n=150, seed=0):
    ob, grid = _rooms()
    poses = _poses(grid, ob, n, seed)
    measured, headings, _ = scan_ranges(ob, grid, poses, settings)
    exact = settings.replace(range_noise=0.0, dropout=0.0, grazing_dropout=0.0)
    r, c = grid.world_to_cell(poses[:, 0], poses[:, 1])
    thetas = np.broadcast_to(headings, measured.shape)
    hr, hc = expected_hits(ob, r, c, thetas, settings.max_range / grid.resolution)
    expected = cell_ranges(r, c, hr, hc, grid.resolution)
    expected = np.where(expected <= settings.max_range, expected, np.nan)
    return measured, expected, incidence_cos(ob, hr, hc, thetas), scan_ranges(ob, grid, poses, exact)[0]


def test_expected_hits_walk_as_the_scanner_does():
    """Without noise and dropout the map's expected ranges are the simulated scanner's, beam for beam."""
    measured, expected, cos_i, exact = _simulated(ScanSettings(max_range=20.0, angular_step=2.0), n=40)
    assert np.array_equal(np.isfinite(exact), np.isfinite(expected))
    assert np.allclose(exact[np.isfinite(exact)], expected[np.isfinite(expected)])
    assert np.isfinite(cos_i[np.isfinite(expected)]).mean() > 0.95


@pytest.mark.parametrize("noise, dropout, grazing", [(0.03, 0.10, 0.0), (0.01, 0.02, 0.5), (0.0, 0.0, 0.0)])
def test_fit_recovers_known_scanner(noise, dropout, grazing):
    """Scans simulated with known settings: the fit recovers range_noise within 10 % (or 2 mm),
    dropout within 0.015, grazing_dropout within 0.08, and finds no correlation of dropouts
    (|r| < 0.05) along a scan or over time, which the simulator draws apart."""
    s = ScanSettings(max_range=20.0, angular_step=1.0, range_noise=noise, dropout=dropout,
                     grazing_dropout=grazing, seed=3)
    measured, expected, cos_i, _ = _simulated(s)
    fit = fit_scans(measured, expected, cos_i, gate=0.3)
    assert fit.range_noise == pytest.approx(noise, rel=0.10, abs=0.002)
    assert fit.dropout == pytest.approx(dropout, abs=0.015)
    assert fit.grazing_dropout == pytest.approx(grazing, abs=0.08)
    if dropout or grazing:
        assert abs(fit.dropout_corr_beam) < 0.05 and abs(fit.dropout_corr_scan) < 0.05
    assert fit.short_share < 0.01 and fit.long_share < 0.01
    got = fit.settings(s.replace(range_noise=0.0, dropout=0.0, grazing_dropout=0.0))
    assert got.range_noise == pytest.approx(noise, rel=0.10, abs=0.002)


def test_fit_sees_correlated_dropout():
    """Dropouts in runs along the scan (whole blocks of 6 beams lost, as a real scanner loses a dark
    surface) read as a strong correlation along the scan, not over time."""
    s = ScanSettings(max_range=20.0, angular_step=1.0, range_noise=0.01, seed=1)
    measured, expected, cos_i, _ = _simulated(s)
    rng = np.random.default_rng(5)
    blocks = rng.random((measured.shape[0], measured.shape[1] // 6)) < 0.1
    lost = np.repeat(blocks, 6, axis=1)
    fit = fit_scans(np.where(lost, np.nan, measured), expected, cos_i)
    assert fit.dropout_corr_beam > 0.6
    assert abs(fit.dropout_corr_scan) < 0.05
    assert fit.dropout == pytest.approx(0.1, abs=0.02)


def test_fit_log_on_scans_of_a_known_room():
    """A log through the two rooms, 180 beams over 180 degrees each (as FLASER lines) with 2 cm
    noise and 5 % dropout, poses at cell centres and whole degrees so the simulator's beams are the
    log's: the map built from the log and the fit at its poses give the dropout within 0.02 and the
    noise within 10 mm: the map built from noisy ends moves some wall cells by a cell, which the
    fit counts as noise (measured here: 2.8 cm for 2 cm at 5 cm cells)."""
    ob, grid = _rooms()
    poses = _poses(grid, ob, 300, 7)
    r, c = grid.world_to_cell(poses[:, 0], poses[:, 1])
    poses[:, 0] = grid.origin[0] + (c + 0.5) * grid.resolution
    poses[:, 1] = grid.origin[1] - (r + 0.5) * grid.resolution
    poses[:, 2] = np.rint(poses[:, 2]) % 360
    s = ScanSettings(max_range=20.0, angular_step=1.0, range_noise=0.02, dropout=0.05, seed=2)
    full, _, _ = scan_ranges(ob, grid, poses, s)
    # beam b faces yaw b degrees; the log's beam k faces yaw (heading yaw) + 90 - k degrees
    idx = np.mod(np.rint(poses[:, 2])[:, None].astype(int) + 90 - np.arange(180)[None, :], 360)
    ranges = np.take_along_axis(full, idx, axis=1)
    xy = np.column_stack([poses[:, 0], poses[:, 1], np.deg2rad(90.0 - poses[:, 2])])
    angles = np.deg2rad(np.arange(-90, 90))
    fit, lm = fit_log(xy, ranges, angles, 20.0, resolution=0.05)
    assert lm.obstacles.sum() > 500
    assert fit.dropout == pytest.approx(0.05, abs=0.02)
    assert fit.range_noise == pytest.approx(0.02, abs=0.01)


def test_calibrate_without_the_logs_is_one_line(tmp_path, capsys):
    from benchmark.commands import calibrate

    assert calibrate.main(["--logs", str(tmp_path), "--out", str(tmp_path / "c.md")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"error: FileNotFoundError: real log not found: {tmp_path / 'intel-corrected.log.gz'} "
                   "(expected the shared logs; set --logs)"]
    assert not (tmp_path / "c.md").exists()


def test_odometry_edge_residuals_known_answer(tmp_path):
    """Three poses 1 m apart read from a TORO file, the last one 0.1 m further than its edge says:
    the two odometry edges are off by 0 and 0.1 m; the loop edge (0, 2) is not an odometry edge."""
    from benchmark.conditions.calibration import odometry_edge_residuals
    from envs.logs.g2o import read_toro

    info = "1 0 1 1 0 0"
    path = tmp_path / "g.graph"
    path.write_text("VERTEX2 0 0 0 0\nVERTEX2 1 1 0 0\nVERTEX2 2 2 0 0\n"
                    f"EDGE2 0 1 1 0 0 {info}\nEDGE2 1 2 1 0 0 {info}\nEDGE2 0 2 2 0 0.5 {info}\n")
    g = read_toro(path)
    r = odometry_edge_residuals(g, np.array([[0, 0, 0], [1, 0, 0], [2.1, 0, 0]]))
    assert r["edges"] == 2
    assert r["trans_mean_m"] == pytest.approx(0.05) and r["trans_median_m"] == pytest.approx(0.05)
    assert r["rot_mean_deg"] == pytest.approx(0.0) and r["move_m"] == pytest.approx(1.0)


@pytest.mark.slow
def test_the_published_calibration_is_what_the_command_writes(tmp_path, monkeypatch, capsys):
    """results/published/calibration.md, which docs/calibration.md includes, is what the command its
    first line names (a line of make docs-numbers) writes again, line for line."""
    import re
    import shlex
    from pathlib import Path

    from benchmark.commands import calibrate

    root = Path(__file__).resolve().parents[1]
    shared = root.parent / "shared" / "data"
    if not (shared / "real_logs").is_dir() or not (shared / "real_graphs").is_dir():
        pytest.skip("the shared real logs or the real pose graphs (roomseg data fetch real_graphs) are absent")
    published = root / "results" / "published" / "calibration.md"
    assert '--8<-- "results/published/calibration.md"' in (root / "docs" / "calibration.md").read_text(encoding="utf-8")
    want = published.read_text(encoding="utf-8").splitlines()
    command = re.fullmatch(r"Written by `python -m benchmark\.commands\.calibrate (.*)`\.", want[0]).group(1)
    assert f"-m benchmark.commands.calibrate {command}\n" in (root / "Makefile").read_text(encoding="utf-8")
    args = shlex.split(command)
    out = tmp_path / "calibration.md"
    args[args.index("--out") + 1] = str(out)
    monkeypatch.chdir(root)
    monkeypatch.setenv("ROOMSEG_SHARED_DATA", str(shared))
    assert calibrate.main(args) == 0
    capsys.readouterr()
    assert out.read_text(encoding="utf-8").splitlines()[1:] == want[1:]
