"""Pose files with absurd values (issue #24): ``theta=1e308`` used to print four NumPy warnings
and an error naming neither the file nor the column. Every non-finite, non-numeric or
absurd value in every column of every frame is now one line naming the file, the column
and the pose, with no warning."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from envs.maps.gridmap import GridMap
from envs.maps.pose_files import FRAME_COLUMNS, read_poses

GRID = GridMap(np.ones((20, 30), bool), 0.1, (-1.0, 2.0))
GOOD = {"x": 0.5, "y": 1.0, "z": 1.0, "theta": 0.3, "yaw": 45.0, "row": 3, "col": 4}
BAD = [float("inf"), float("-inf"), float("nan"), 1e308, -1e308, "abc"]


def _write(path, frame, column, value):
    cols = FRAME_COLUMNS[frame]
    rows = [{c: GOOD[c] for c in cols}, {c: (value if c == column else GOOD[c]) for c in cols}]
    if path.suffix == ".json":
        path.write_text(json.dumps(rows))
    else:
        path.write_text(",".join(cols) + "\n" + "".join(",".join(str(r[c]) for c in cols) + "\n" for r in rows))
    return path


@pytest.mark.parametrize("suffix", [".csv", ".json"])
@pytest.mark.parametrize("frame", sorted(FRAME_COLUMNS))
def test_every_bad_value_in_every_column_is_one_line_naming_file_column_pose(tmp_path, frame, suffix):
    for column in FRAME_COLUMNS[frame]:
        for value in BAD:
            f = _write(tmp_path / f"p{suffix}", frame, column, value)
            with warnings.catch_warnings():
                warnings.simplefilter("error")  # a NumPy RuntimeWarning would fail here
                with pytest.raises(ValueError) as e:
                    read_poses(f, frame, GRID)
            msg = str(e.value)
            assert "\n" not in msg and msg.startswith(f"{f}: "), msg
            assert f"column {column!r} at pose index 1" in msg, msg
            if suffix == ".csv":
                assert "(line 3)" in msg
            if isinstance(value, str):
                assert "non-numeric value 'abc'" in msg
            elif np.isfinite(value):
                from envs.maps.pose_files import LIMITS

                assert f"value {value:g}" in msg and f"|{column}| <= {LIMITS[column][0]:g} {LIMITS[column][1]}" in msg
            else:
                assert "non-finite value" in msg


def test_large_but_possible_values_are_read(tmp_path):
    """An unwrapped odometry heading of 1000 rad and a pose 100 km away are kept."""
    f = tmp_path / "p.csv"
    f.write_text("x,y,theta\n100000.0,-5.0,1000.0\n")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        p = read_poses(f, "ros")
    assert p[0, 0] == 100000.0 and p[0, 1] == -5.0
    assert p[0, 2] == pytest.approx((90.0 - np.rad2deg(1000.0)) % 360.0)


def test_the_segment_command_says_it_in_one_line(tmp_path, capsys):
    """``roomseg-segment`` with theta=1e308 on the example building: exit 2, one stderr line
    naming the file and the column, no warning."""
    from benchmark.commands.segment import main
    from benchmark.commands.segment_example import write_example

    ex = write_example(tmp_path / "in", open_plan=False)
    lines = ex.poses.read_text().splitlines()
    head = lines[0].split(",")
    cells = lines[2].split(",")
    cells[head.index("theta")] = "1e308"
    lines[2] = ",".join(cells)
    ex.poses.write_text("\n".join(lines) + "\n")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        code = main([f"map={ex.map_yaml}", f"poses={ex.poses}", "frame=ros", f"labels={ex.labels}", "figure=false",
                     f"out={tmp_path / 'o'}"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1, err
    assert str(ex.poses) in err[0] and "'theta'" in err[0] and "1e+308" in err[0] and "pose index 1" in err[0]
