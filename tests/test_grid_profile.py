"""The sweep profile (``benchmark.commands.maintainer.grid_profile``): a hand-made sweep of three
jobs with known stage seconds gives the sums, shares and time outside houses they imply."""

from __future__ import annotations

import json

import pytest

from benchmark.commands.maintainer import grid_profile


def _job(root, name, dataset, family, wall, rows):
    d = root / name
    d.mkdir(parents=True)
    (d / "summary.json").write_text(json.dumps({"wall_time_s": wall}))
    (d / "job.json").write_text(json.dumps({"key": name, "settings": {"env.name": dataset, "robot.corruption": family}}))
    (d / "metrics.csv").write_text("house_id\n")
    (d / "resolved_config.yaml").write_text("run: {}\n")
    cols = sorted({k for r in rows for k in r})
    lines = [",".join(cols)] + [",".join(str(r.get(c, "")) for c in cols) for r in rows]
    (d / "timings.csv").write_text("\n".join(lines) + "\n")


def test_sums_shares_and_time_outside_houses(tmp_path, capsys):
    _job(tmp_path, "a", "procthor", "scan", 10.0,
         [{"house_id": "h0", "cached": False, "house_s": 3.0, "t_map": 2.0, "t_score": 1.0},
          {"house_id": "h1", "cached": False, "house_s": 4.0, "t_map": 3.0, "t_score": 1.0}])
    _job(tmp_path, "b", "procthor", "scan", 2.0,  # a second method on the same maps: read from the cache
         [{"house_id": "h0", "cached": True, "house_s": 0.5, "t_map": "", "t_score": ""},
          {"house_id": "h1", "cached": False, "house_s": 1.0, "t_map": "", "t_score": 0.5}])
    _job(tmp_path, "c", "synthetic", "clean", 8.0,
         [{"house_id": "s0", "cached": False, "house_s": 6.0, "t_score": 6.0}])
    (tmp_path / "unfinished").mkdir()  # rows but no summary.json yet: not counted
    (tmp_path / "unfinished" / "metrics.csv").write_text("house_id\n")
    table = grid_profile.profile(grid_profile.job_rows(tmp_path)).set_index(["dataset", "family"])
    scan = table.loc[("procthor", "scan")]
    assert (scan["jobs"], scan["houses computed"], scan["houses cached"]) == (2, 3, 1)
    assert scan["job s"] == pytest.approx(12.0) and scan["share %"] == pytest.approx(60.0)
    assert scan["map s"] == pytest.approx(5.0) and scan["score s"] == pytest.approx(2.5)
    assert scan["outside houses s"] == pytest.approx((10 - 7) + (2 - 1.5))
    assert scan["in houses, untimed s"] == pytest.approx((7 - 5 - 2) + (1.0 - 0.5))  # the cached house counts no time
    assert table.loc[("synthetic", "all"), "share %"] == pytest.approx(40.0)
    assert list(table.columns).index("map s") < list(table.columns).index("score s")  # pipeline order
    assert grid_profile.main([str(tmp_path), "--out", str(tmp_path / "p.md")]) == 0
    assert "| procthor  | scan" in (tmp_path / "p.md").read_text()


def test_a_folder_without_jobs_is_one_line(tmp_path, capsys):
    assert grid_profile.main([str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(tmp_path) in err[0] and "no finished job" in err[0]


def test_a_malformed_summary_is_one_line_naming_it(tmp_path, capsys):
    _job(tmp_path, "a", "procthor", "scan", 1.0, [{"house_id": "h0", "cached": False, "house_s": 1.0}])
    (tmp_path / "a" / "summary.json").write_text("{not json")
    assert grid_profile.main([str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(tmp_path / "a" / "summary.json") in err[0] and "malformed JSON" in err[0]


def test_a_timed_profile_is_headed_by_the_commands_time_and_houses(tmp_path, capsys):
    sweep = tmp_path / "sweep"
    _job(sweep, "a", "procthor", "scan", 10.0,
         [{"house_id": "h0", "cached": False, "house_s": 3.0, "t_map": 2.0},
          {"house_id": "h1", "cached": True, "house_s": 0.1, "t_map": ""}])
    _job(sweep, "b", "synthetic", "clean", 8.0, [{"house_id": f"s{i}", "cached": False, "house_s": 1.0} for i in range(3)])
    (tmp_path / "time.txt").write_text("Command exited with non-zero status 0\n905.37 1248000\n")
    (tmp_path / "compile.txt").write_text("21.6 300000\n")
    out = tmp_path / "t.md"
    assert grid_profile.main([str(sweep), "--time", str(tmp_path / "time.txt"), "--compile-time",
                              str(tmp_path / "compile.txt"), "--command", "make robustness ROBUST_HOUSES=3",
                              "--out", str(out)]) == 0
    head = out.read_text().split("\n\n")[1]
    assert head.startswith("Measured with `/usr/bin/time` on ")
    assert "`make robustness ROBUST_HOUSES=3` took **905 s wall (15.1 min), 1219 MB peak RSS**" in head
    assert "2 jobs; houses per dataset: procthor 2, synthetic 3;" in head and "took 22 s)" in head
    (tmp_path / "bad.txt").write_text("no time here\n")
    assert grid_profile.main([str(sweep), "--time", str(tmp_path / "bad.txt")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "bad.txt" in err[0] and "GNU time" in err[0]


def test_the_rerun_on_the_filled_cache_gives_the_jobs_fixed_cost(tmp_path, capsys):
    sweep = tmp_path / "sweep"
    for name in ("a", "b", "c", "d"):
        _job(sweep, name, "procthor", "scan", 10.0, [{"house_id": "h0", "cached": False, "house_s": 3.0, "t_map": 2.0}])
    (tmp_path / "time.txt").write_text("905.37 1248000\n")
    (tmp_path / "rerun.txt").write_text("Command exited with non-zero status 0\n50.2 400000 1.5 0.5\n")
    out = tmp_path / "t.md"
    assert grid_profile.main([str(sweep), "--time", str(tmp_path / "time.txt"), "--rerun-time",
                              str(tmp_path / "rerun.txt"), "--out", str(out)]) == 0
    paragraphs = out.read_text().split("\n\n")
    assert paragraphs[1].startswith("Measured with `/usr/bin/time`")
    assert paragraphs[2].startswith("Run again at once on the cache it filled")
    assert "what its 4 jobs cost" in paragraphs[2] and "took 50 s wall and 2 CPU-s: about 0.50 CPU-s a job." in paragraphs[2]
    (tmp_path / "short.txt").write_text("50.2 400000\n")  # '%e %M' only: no CPU seconds
    assert grid_profile.main([str(sweep), "--time", str(tmp_path / "time.txt"), "--rerun-time",
                              str(tmp_path / "short.txt")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "short.txt" in err[0] and "%e %M %U %S" in err[0]
