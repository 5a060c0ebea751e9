"""Occupancy-map statistics (issue 37, item 5) on hand-made maps with known answers, the command
on any map, and the calibration table beside the real laser maps."""

from __future__ import annotations

import math

import numpy as np
import pytest

from envs.maps.map_stats import (
    clutter,
    map_stats,
    occupancy_from_grey,
    speckle_per_m2,
    unknown_inside,
    wall_straightness,
    wall_thickness,
)

RES = 0.05


def _room(wall: int = 1) -> np.ndarray:
    """Unknown outside; a 60 x 80 cell box whose border ``wall`` cells are occupied, free inside."""
    occ = np.full((80, 100), -1, np.int8)
    occ[10:70, 10:90] = 100
    occ[10 + wall:70 - wall, 10 + wall:90 - wall] = 0
    return occ


def test_wall_thickness_is_the_walls_cells():
    assert wall_thickness(_room(1), RES) == pytest.approx(0.05)
    assert wall_thickness(_room(3), RES) == pytest.approx(0.15, rel=0.1)
    assert math.isnan(wall_thickness(np.zeros((5, 5), np.int8), RES))


def test_speckle_and_clutter_count_the_dots():
    occ = _room(1)
    dots = [(20, 20), (30, 40), (40, 60), (50, 30), (60, 80)]
    for r, c in dots:
        occ[r, c] = 100
    occ[25:28, 70:73] = -1  # a 3 x 3 unknown blob: 9 cells, more than a speck (4 cells at 0.05 m)
    free_m2 = (occ == 0).sum() * RES ** 2
    assert speckle_per_m2(occ, RES) == pytest.approx(5 / free_m2)
    n, median = clutter(occ, RES)
    assert n == pytest.approx(5 / free_m2) and median == pytest.approx(RES ** 2)
    occ[25:28, 70:73] = 100  # now an occupied 0.15 m box: clutter, not a speck (9 cells)
    n, _ = clutter(occ, RES)
    assert n == pytest.approx(6 / ((occ == 0).sum() * RES ** 2))
    assert speckle_per_m2(occ, RES) == pytest.approx(5 / ((occ == 0).sum() * RES ** 2))


def test_unknown_inside_is_the_unseen_share_of_the_outline():
    occ = _room(1)
    assert unknown_inside(occ, RES) == 0.0
    occ[30:40, 30:40] = -1
    assert unknown_inside(occ, RES) == pytest.approx(100 / (60 * 80))


def test_straight_walls_are_straight_and_a_ragged_one_is_not():
    assert wall_straightness(_room(1), RES) > 0.99
    rng = np.random.default_rng(0)
    occ = np.zeros((80, 100), np.int8)
    r = 40
    for c in range(5, 95):  # a random walk: a wall that never runs straight for 1 m
        r = int(np.clip(r + rng.integers(-2, 3), 5, 75))
        occ[r, c] = 100
    assert wall_straightness(occ, RES) < 0.5


def test_grey_thresholds_and_bad_input_are_one_line():
    grey = np.array([[254, 205, 0], [255, 230, 127]], np.uint8)
    np.testing.assert_array_equal(occupancy_from_grey(grey, 250, 50), [[0, -1, 100], [0, -1, -1]])
    np.testing.assert_array_equal(occupancy_from_grey(grey, 240, 200), [[0, -1, 100], [0, -1, 100]])
    with pytest.raises(ValueError, match="expected occupied_max < free_min"):
        occupancy_from_grey(grey, 50, 250)
    with pytest.raises(ValueError, match="occupancy must be"):
        map_stats(np.full((3, 3), 7, np.int8), RES)
    with pytest.raises(ValueError, match="resolution = 0"):
        map_stats(_room(), 0)


def test_command_measures_a_ros_map_and_refuses_nothing_to_do(tmp_path, capsys):
    from benchmark.commands.map_stats import main
    from envs.maps.ros import write_ros_map

    occ = _room(1)
    image = np.where(occ == 0, 254, np.where(occ == 100, 0, 205)).astype(np.uint8)  # trinary map_server PGM
    write_ros_map(tmp_path / "m.yaml", image, RES)
    assert main([str(tmp_path / "m.yaml")]) == 0
    out = capsys.readouterr().out
    row = [line for line in out.splitlines() if "m.yaml" in line][0].split("|")
    assert float(row[3]) == pytest.approx(0.05)  # wall_thickness_m
    assert main([]) == 2
    assert capsys.readouterr().err.strip().count("\n") == 0


@pytest.mark.slow
@pytest.mark.shared_data
def test_calibration_table_puts_real_and_simulated_maps_side_by_side(procthor_file, capsys, tmp_path):
    from benchmark.commands.map_stats import main

    real = procthor_file.parents[1] / "real_maps"
    if not real.is_dir():
        pytest.skip(f"real maps not found at {real}")
    logs = procthor_file.parents[1] / "real_logs"
    if not logs.is_dir():
        pytest.skip(f"real logs not found at {logs}")
    fig = tmp_path / "cal.png"
    assert main(["--calibrate", "--n", "1", "--real-dir", str(real), "--real-logs-dir", str(logs), "--figure",
                 str(fig)]) == 0
    lines = capsys.readouterr().out.splitlines()
    names = [line.split("|")[1].strip() for line in lines if line.startswith("| ") and "map" not in line[:8]]
    assert {"intel_map.png", "lab_c_scan.png", "scan_0", "scan_5", "slam_1", "slam_5"} <= set(names)
    # the raw maps of the four corrected CARMEN logs, beside the cleaned ones
    assert {"intel-corrected (raw)", "aces-corrected (raw)", "csail-corrected (raw)",
            "freiburg-079-corrected (raw)"} <= set(names)
    assert fig.read_bytes()[:4] == b"\x89PNG"
