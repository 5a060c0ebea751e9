"""The calibration page (issue 59 items 5-6): the SLAM levels' odometry residuals measured as the
real graphs' are, and the figure of a real raw map beside the levels' maps."""

from __future__ import annotations

import gzip
import json
import math

import numpy as np
import pytest

from benchmark.conditions.calibration import (
    chain_edge_errors,
    odometry_edge_residuals,
    residual_summary,
)


def test_chain_residuals_of_a_hand_made_graph():
    """Five nodes, four odometry edges with known residuals at the solved poses: 0, 0.1 m (a move
    measured 0.9 m for 1 m), 0.573 deg (a turn measured 0.01 rad short) and 0.2 m on an edge whose
    earlier node faces +y (the residual is taken in the edge's frame, so its size does not depend
    on the heading)."""
    states = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [2, 1, math.pi / 2], [2, 2.2, math.pi / 2]], float)
    # node 3 seen from node 2 is (0, 1, pi/2), node 4 from node 3 (1.2, 0, 0)
    z = np.array([[1, 0, 0], [0.9, 0, 0], [0, 1, math.pi / 2 - 0.01], [1, 0, 0]], float)
    e = chain_edge_errors(states, z)
    np.testing.assert_allclose(np.hypot(e[:, 0], e[:, 1]), [0, 0.1, 0, 0.2], atol=1e-12)
    np.testing.assert_allclose(np.abs(e[:, 2]), [0, 0, 0.01, 0], atol=1e-12)
    r = residual_summary(e, z)
    assert r["edges"] == 4
    assert r["trans_mean_m"] == pytest.approx(0.075) and r["trans_median_m"] == pytest.approx(0.05)
    assert r["trans_std_m"] == pytest.approx(np.std([0, 0.1, 0, 0.2]))
    assert r["rot_mean_deg"] == pytest.approx(math.degrees(0.01) / 4)
    assert r["rot_median_deg"] == pytest.approx(0.0, abs=1e-12)
    assert r["move_m"] == pytest.approx((1 + 0.9 + 1 + 1) / 4)
    assert r["turn_deg"] == pytest.approx(math.degrees(math.pi / 2 - 0.01) / 4)
    with pytest.raises(ValueError, match=r"^3 odometry edges over 5 nodes: expected one edge"):
        chain_edge_errors(states, z[:3])


def test_the_level_residual_is_the_real_graphs_quantity(tmp_path):
    """The same poses and edges as a TORO file and as a chain: the real graphs' residual (odometry
    edges of the file, closures apart) and a level's (its chain) are the same numbers."""
    from envs.logs.g2o import read_toro

    states = np.array([[0, 0, 0], [1, 0, 0.1], [2.1, 0.3, 0.05]], float)
    z = np.array([[1, 0.05, 0.12], [1.0, 0.2, -0.1]], float)
    info = "1 0 1 1 0 0"
    path = tmp_path / "g.graph"
    path.write_text("VERTEX2 0 0 0 0\nVERTEX2 1 1 0 0\nVERTEX2 2 2 0 0\n"
                    + "".join(f"EDGE2 {i} {i + 1} {a} {b} {c} {info}\n" for i, (a, b, c) in enumerate(z))
                    + f"EDGE2 0 2 2 0 0.5 {info}\n")
    real = odometry_edge_residuals(read_toro(path), states)
    level = residual_summary(chain_edge_errors(states, z), z)
    assert real.pop("closures") == 1
    assert real == pytest.approx(level)
    assert level["trans_mean_m"] > 0.01 and level["rot_mean_deg"] > 1


def test_a_slam_estimate_exposes_the_odometry_edges_its_back_end_got():
    """OdometrySlam's estimate keeps the front end's fused odometry edges: chained from the start
    they are its dead reckoning; at the solved estimate their residuals are what the closures pull
    (some, small); a clean estimate has none."""
    from benchmark.conditions.odometry import to_se2
    from benchmark.conditions.slam import OdometrySlam
    from tests.maps import pose_at, two_rooms_scene

    scene = two_rooms_scene()
    ring = [(8, 45), (8, 70), (30, 70), (30, 45)]
    poses = np.array([pose_at(scene.grid, r, c, 90.0 * k) for _ in range(3) for k, (r, c) in enumerate(ring)])
    every = dict(keyframe_xy=0.0, keyframe_yaw=0.0)
    est = OdometrySlam(alpha1=0.01, alpha2=0.01, alpha3=0.01, alpha4=0.001, closure_min_travel=2.0,
                       **every).estimate(scene.grid, poses, "h")
    z = est.odometry_edges
    assert z.shape == (len(est.true) - 1, 3) and len(est.closures) > 0
    dead = to_se2(est.odometry)
    np.testing.assert_allclose(chain_edge_errors(dead, z), 0.0, atol=1e-9)
    r = residual_summary(chain_edge_errors(to_se2(est.estimate), z), z)
    assert 0 < r["trans_mean_m"] < 0.1 and 0 < r["rot_mean_deg"] < 5
    assert OdometrySlam().estimate(scene.grid, poses, "h").odometry_edges is None


def test_where_a_level_falls_against_the_real_graphs():
    from benchmark.commands.calibrate import placement

    graphs = [{"graph": "Intel", "trans_mean_m": 0.019, "rot_mean_deg": 0.34},
              {"graph": "CSAIL", "trans_mean_m": 0.005, "rot_mean_deg": 0.027}]
    levels = [{"level": "slam_1", "trans_mean_m": 0.001, "rot_mean_deg": 0.1},
              {"level": "slam_5", "trans_mean_m": 0.03, "rot_mean_deg": 0.34}]
    assert placement(graphs, levels).splitlines() == [
        "- `slam_1`: translation below CSAIL, rotation between CSAIL and Intel",
        "- `slam_5`: translation above Intel, rotation between CSAIL and Intel"]


def test_the_levels_residual_table_has_the_real_graphs_columns():
    from benchmark.commands.calibrate import front_end_tables

    row = {"edges": 10, "closures": 2, "move_m": 0.4, "turn_deg": 5.0, "trans_mean_m": 0.01, "trans_std_m": 0.002,
           "trans_median_m": 0.009, "rot_mean_deg": 0.2, "rot_std_deg": 0.1, "rot_median_deg": 0.15}
    text = front_end_tables([{"graph": "Intel", **row}], [], [{"level": "slam_1", **row}])
    heads = [line for line in text.splitlines() if line.startswith("| graph") or line.startswith("| level")]
    assert len(heads) == 2
    cols = [[c.strip() for c in h.strip("|").split("|")] for h in heads]
    assert cols[0][1:] == cols[1][1:] and cols[0][0] == "graph" and cols[1][0] == "level"
    assert "- `slam_1`: translation above Intel, rotation above Intel" in text  # equal: not below


def test_densest_window():
    from benchmark.commands.calibrate import densest_window

    known = np.zeros((20, 30), bool)
    known[12:18, 3:9] = True  # a 6 x 6 block
    known[0, 29] = True
    assert densest_window(known, (6, 6)) == (12, 3)
    assert densest_window(known, (50, 50)) == (0, 0)  # larger than the map: the whole map


def _box_log(path, n=40):
    """A CARMEN log of FLASER scans (180 beams over 180 degrees) in a 6 x 5 m box, exact ranges,
    the robot driving a loop inside it."""
    angles = np.deg2rad(np.arange(-90, 90))
    lines = []
    for k in range(n):
        t = 2 * math.pi * k / n
        x, y, th = 1.5 * math.cos(t), 1.0 * math.sin(t), t + math.pi / 2
        a = th + angles
        c, s = np.cos(a), np.sin(a)
        with np.errstate(divide="ignore"):
            tx = np.where(c > 0, (3 - x) / c, np.where(c < 0, (-3 - x) / c, np.inf))
            ty = np.where(s > 0, (2.5 - y) / s, np.where(s < 0, (-2.5 - y) / s, np.inf))
        r = np.minimum(tx, ty)
        lines.append("FLASER 180 " + " ".join(f"{v:.3f}" for v in r)
                     + f" {x:.4f} {y:.4f} {th:.5f} {x:.4f} {y:.4f} {th:.5f} {k}.0 host {k}.0\n")
    with gzip.open(path, "wt") as f:
        f.write("".join(lines))


@pytest.mark.slow
def test_calibrate_figure_writes_a_png(tmp_path, monkeypatch, capsys):
    """``calibrate --figure PATH`` draws a PNG (a real log's raw map beside a house's maps at
    scan_1/3/5 and slam_1/3/5) on a data root of four small logs and one house; without the log,
    one line and exit 2."""
    from benchmark.commands import calibrate
    from envs.datasets.synthetic import generate_house

    logs = tmp_path / "data" / "real_logs"
    logs.mkdir(parents=True)
    _box_log(logs / calibrate.LOGS["Intel"])
    for file in calibrate.LOGS.values():
        if not (logs / file).exists():
            (logs / file).write_bytes((logs / calibrate.LOGS["Intel"]).read_bytes())
    (tmp_path / "data" / "procthor").mkdir()
    with gzip.open(tmp_path / "data" / "procthor" / "procthor-10k-uniform-hard-val.jsonl.gz", "wt") as f:
        f.write(json.dumps(generate_house(4).data) + "\n")
    monkeypatch.setenv("ROOMSEG_SHARED_DATA", str(tmp_path / "data"))
    out = tmp_path / "fig" / "maps.png"
    out.parent.mkdir()
    assert calibrate.main(["--houses", "0", "--figure", str(out)]) == 0
    capsys.readouterr()
    data = out.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and 5_000 < len(data) < 300_000
    from PIL import Image

    w, h = Image.open(out).size
    assert w > h > 0  # two rows of four panels

    (logs / calibrate.LOGS["Intel"]).unlink()
    with pytest.raises(FileNotFoundError, match="real log not found"):
        calibrate.maps_figure(logs / calibrate.LOGS["Intel"], tmp_path / "x.png")
    assert not (tmp_path / "x.png").exists()
