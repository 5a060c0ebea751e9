"""The robot-conditions commands: the figure and the coverage table run end to end."""

import pytest

from benchmark.commands import draw_robot_map, robot_coverage


def test_draw_robot_map(procthor_file, tmp_path, capsys):
    out = tmp_path / "robot_map.png"
    assert draw_robot_map.main(["--houses", str(procthor_file), "--house", "4", "--budget", "8",
                                "--out", str(out)]) == 0
    assert out.exists() and out.stat().st_size > 10_000
    assert "frontier exploration, 8 m budget" in capsys.readouterr().out


def test_draw_robot_map_bad_house(procthor_file, tmp_path, capsys):
    assert draw_robot_map.main(["--houses", str(procthor_file), "--house", "100000", "--out",
                                str(tmp_path / "x.png")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--house 100000" in err
    assert not (tmp_path / "x.png").exists()


def test_robot_coverage_generated_houses(capsys):
    assert robot_coverage.main(["--synthetic", "--n", "1", "--budgets", "5"]) == 0
    out = capsys.readouterr().out
    for name in ("autotrace", "frontier 5 m", "random walk 5 m", "coverage_area", "walkable_free", "pose_error_mean_m"):
        assert name in out


@pytest.mark.parametrize("args", [["--n", "0"], ["--budgets", "0"]])
def test_robot_coverage_bad_input(args, capsys):
    assert robot_coverage.main(["--synthetic", *args]) == 2
    assert capsys.readouterr().err.count("\n") == 1
