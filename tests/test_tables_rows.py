"""What one table cell holds (issues #24, #26, #30): each (configuration, house) once, the
newest job's row; never two settings; a line when cells hold different house sets; the
segment count error beside the area-weighted ipa metrics.

Real runs (generated houses through the runner, the sweep of the issue with run.limit 2 then
3) and hand-made job folders whose means are known."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pandas as pd
import pytest

from benchmark.commands.tables import main as tables_main
from benchmark.reports.tables import ROBUST_METRICS, TABLES, load_rows, render


def _row(house: str, iou: float, **fixed) -> dict:
    base = {"house_id": house, "dataset": "synthetic", "env": "synthetic", "viewpoints": "autotrace",
            "classifier": "oracle", "aggregator": "graph_knn", "postprocess": "default", "segmenter": "",
            "status": "ok", "error": "", "iou": iou, "accuracy": iou}
    base.update(fixed)
    return base


def _job(folder: Path, settings: dict, rows: list[dict], finished: str | None = None, run: str = "x") -> Path:
    """A finished runner job made by hand: metrics.csv, summary.json (with ``finished_at``
    when given), resolved_config.yaml and job.json holding ``settings``."""
    folder.mkdir(parents=True)
    pd.DataFrame(rows).to_csv(folder / "metrics.csv", index=False)
    summary = {"n_houses": len(rows), **({"finished_at": finished} if finished else {})}
    (folder / "summary.json").write_text(json.dumps(summary))
    (folder / "resolved_config.yaml").write_text(f"run:\n  name: {run}\n")
    (folder / "job.json").write_text(json.dumps({"key": folder.name, "settings": settings}))
    return folder


def _tables(args: list[str], capsys) -> tuple[int, str, str]:
    code = tables_main([str(a) for a in args])
    cap = capsys.readouterr()
    return code, cap.out, cap.err


def _csv(folder: Path, name: str) -> pd.DataFrame:
    return pd.read_csv(folder / f"{name}.csv")


# ---------------------------------------------------------------- each (configuration, house) once
@pytest.mark.slow
def test_two_sweeps_with_different_limits_count_each_house_once(tmp_path, capsys):
    """The issue's reproduction through the runner: a sweep of two aggregators with
    run.limit=2, then the same with run.limit=3 into the same run; the second jobs move to
    ``~<key>`` siblings. Table IV must say 3 houses per cell, with the means of those 3."""
    from benchmark.config import compose_job
    from benchmark.harness.runner import run

    res = tmp_path / "R"
    fast = ["env=synthetic", "classifier=oracle", "env.resolution=0.1", "viewpoints.spacing=1.0",
            "run.progress=false", f"run.results_dir={res}", "run.name=x"]
    folders = {}
    for limit in (2, 3):
        for agg in ("graph_knn", "vision_cone"):
            cfg, choices = compose_job([*fast, f"aggregator={agg}", f"run.limit={limit}"])
            df = run(cfg, res / "runs" / "x" / f"aggregator={agg}", choices)
            folders[(limit, agg)] = (Path(df.attrs["job_dir"]), df)
    assert folders[(3, "graph_knn")][0].name.startswith("aggregator=graph_knn~")  # the sibling of the issue
    code, out, err = _tables([res / "runs" / "x", "--table", "table4", "--out", tmp_path / "t"], capsys)
    assert code == 0, err
    assert "3 houses per cell" in out and "5 houses" not in out
    t4 = _csv(tmp_path / "t", "table4").set_index("aggregator")
    for agg in ("graph_knn", "vision_cone"):
        newest = folders[(3, agg)][1]
        assert t4.loc[agg, "n"] == 3
        assert t4.loc[agg, "iou_mean"] == pytest.approx(newest["iou"].mean())
    lines = [ln for ln in err.splitlines() if "set aside" in ln]
    assert len(lines) == 1  # one line: how many, and from which folders
    assert "set aside 4 older row(s)" in lines[0]
    for agg in ("graph_knn", "vision_cone"):
        assert str(folders[(2, agg)][0]) in lines[0]


def test_the_newest_job_wins_by_its_finish_time_not_its_folder_name(tmp_path, capsys):
    runs = tmp_path / "runs"
    same = {"aggregator.k": 5, "classifier.accuracy": 0.8, "houses": "2 houses: h0 .. h1", "run.limit": 2}
    # "b" sorts after "a" but finished first: its rows are the older ones
    _job(runs / "x" / "b", same, [_row("h0", 0.1), _row("h1", 0.3)], finished="2026-01-01T10:00:00+00:00")
    _job(runs / "x" / "a", {**same, "houses": "3 houses: h0 .. h2", "run.limit": 3},
         [_row("h0", 0.5), _row("h1", 0.7), _row("h2", 0.9)], finished="2026-01-02T10:00:00+00:00")
    code, out, err = _tables([runs / "x", "--table", "table4", "--out", tmp_path / "t"], capsys)
    assert code == 0, err
    t4 = _csv(tmp_path / "t", "table4")
    assert t4["n"].tolist() == [3] and t4["iou_mean"].tolist() == pytest.approx([0.7])
    aside = [ln for ln in err.splitlines() if "set aside" in ln]
    assert len(aside) == 1 and "set aside 2 older row(s)" in aside[0] and str(runs / "x" / "b") in aside[0]


def test_without_a_finish_time_the_summary_file_time_decides(tmp_path):
    runs = tmp_path / "runs"
    old = _job(runs / "x" / "new-name", {"aggregator.k": 5}, [_row("h0", 0.2)])
    new = _job(runs / "x" / "old-name", {"aggregator.k": 5}, [_row("h0", 0.6)])
    os.utime(old / "summary.json", (1_000_000_000, 1_000_000_000))
    os.utime(new / "summary.json", (2_000_000_000, 2_000_000_000))
    df = load_rows([runs])
    assert df["iou"].tolist() == [0.6]
    assert "set aside 1 older row(s)" in df.attrs["set_aside"] and str(old) in df.attrs["set_aside"]


def test_a_file_holding_a_house_twice_for_one_configuration_is_refused(tmp_path, capsys):
    runs = tmp_path / "runs"
    f = runs / "x" / "metrics.csv"
    f.parent.mkdir(parents=True)
    pd.DataFrame([_row("h0", 0.2), _row("h1", 0.4), _row("h0", 0.6)]).to_csv(f, index=False)
    code, _, err = _tables([runs, "--table", "table4"], capsys)
    assert code == 2
    assert err.strip().splitlines()[-1] == (f"error: {f}: house h0 is on lines 2 and 4 with the same configuration; "
                                            f"expected one row per house and configuration")


# ---------------------------------------------------------------- a cell never mixes settings
def test_different_settings_become_separate_rows_labelled_by_what_differs(tmp_path, capsys):
    runs = tmp_path / "runs"
    _job(runs / "x" / "k3", {"aggregator.k": 3, "env.maps": "/m/*.yaml"}, [_row("h0", 0.2), _row("h1", 0.4)])
    _job(runs / "x" / "k5", {"aggregator.k": 5, "env.maps": "/m/*.yaml"}, [_row("h0", 0.6), _row("h1", 0.8)])
    code, out, err = _tables([runs / "x", "--table", "table4", "--table", "table3", "--out", tmp_path / "t"], capsys)
    assert code == 0, err
    t4 = _csv(tmp_path / "t", "table4").set_index("settings")
    assert t4["iou_mean"].to_dict() == pytest.approx({"aggregator.k=3": 0.3, "aggregator.k=5": 0.7})
    assert t4["n"].tolist() == [2, 2]
    table = [ln for ln in out.splitlines() if ln.startswith("| oracle")]
    assert len(table) == 2 and "aggregator.k=3" in table[0] and "30.00 [20.00, 40.00]" in table[0]
    assert "kept apart, labelled by aggregator.k" in out
    # Table III pools classifiers and aggregators on purpose: one cell of 4 maps
    t3 = _csv(tmp_path / "t", "table3")
    assert "settings" not in t3 and t3["n"].tolist() == [4] and t3["iou_mean"].tolist() == pytest.approx([0.5])


def test_two_map_folders_over_the_same_map_ids_are_not_averaged(tmp_path):
    """env=maps with two env.maps patterns over the same map ids: not duplicates of one
    another (their configurations differ), and not one cell."""
    runs = tmp_path / "runs"
    rows = lambda v: [_row("office_a", v, dataset="maps", env="maps"), _row("office_b", v, dataset="maps", env="maps")]  # noqa: E731
    _job(runs / "x" / "a", {"env.maps": "/robot1/*.yaml", "aggregator.k": 5}, rows(0.2))
    _job(runs / "x" / "b", {"env.maps": "/robot2/*.yaml", "aggregator.k": 5}, rows(0.6))
    df = load_rows([runs])
    assert len(df) == 4 and df.attrs["set_aside"] == ""
    text = render([runs], ["table4"], tmp_path / "t")
    t4 = _csv(tmp_path / "t", "table4").set_index("settings")
    assert t4["iou_mean"].to_dict() == pytest.approx({"env.maps=/robot1/*.yaml": 0.2, "env.maps=/robot2/*.yaml": 0.6})
    assert "env.maps=/robot1/*.yaml" in text


def test_rows_without_their_job_settings_are_told_apart_by_their_names(tmp_path):
    """Per-map tables (no job.json): a renderer that differs inside a cell splits it."""
    f = tmp_path / "t.csv"
    pd.DataFrame([_row("h0", 0.2, renderer="floorplan"), _row("h0", 0.6, renderer="ai2thor")]).to_csv(f, index=False)
    render([f], ["table4"], tmp_path / "t")
    t4 = _csv(tmp_path / "t", "table4").set_index("settings")
    assert t4["iou_mean"].to_dict() == pytest.approx({"renderer=floorplan": 0.2, "renderer=ai2thor": 0.6})


def test_cells_over_different_house_sets_say_so_in_one_line(tmp_path):
    runs = tmp_path / "runs"
    _job(runs / "x" / "knn", {"aggregator._target_": "knn"}, [_row("h0", 0.2), _row("h1", 0.4)])
    _job(runs / "x" / "cone", {"aggregator._target_": "cone"}, [_row("h0", 0.6, aggregator="vision_cone")])
    text = render([runs], ["table4"])
    notes = [ln for ln in text.splitlines() if "different house sets" in ln]
    assert len(notes) == 1 and "2 houses in all, 1 in every cell" in notes[0] and "h1" in notes[0]
    # the same houses everywhere: no such line
    (runs / "x" / "knn").rename(tmp_path / "aside")
    _job(runs / "x" / "knn", {"aggregator._target_": "knn"}, [_row("h0", 0.2)])
    assert "different house sets" not in render([runs], ["table4"])


def test_datasets_are_not_compared_house_for_house(tmp_path):
    """Table IV puts datasets side by side: their houses differ by nature, and that is no
    reason for the house-set line."""
    f = tmp_path / "t.csv"
    pd.DataFrame([_row("s0", 0.2), _row("p0", 0.4, dataset="procthor")]).to_csv(f, index=False)
    assert "different house sets" not in render([f], ["table4"])


# ---------------------------------------------------------------- segment count beside ipa metrics
def test_every_table_with_ipa_metrics_shows_the_count_error_next_to_them():
    from benchmark.baselines.external import summary_table

    shown = 0
    for name, spec in TABLES.items():
        ipa = [i for i, m in enumerate(spec.metrics) if m.startswith("ipa_")]
        if ipa:
            shown += 1
            assert "count_error" in spec.metrics, name
            assert spec.metrics.index("count_error") == max(ipa) + 1, name  # right after them
    assert shown >= 2 and "count_error" in ROBUST_METRICS
    rows = pd.DataFrame([{"method": "m", "house_id": "h", "status": "ok", "iou": 0.5, "precision": 0.5, "recall": 0.5,
                          "matched_iou": 0.5, "pq": 0.5, "room_iou": 0.5, "ipa_recall": 0.5, "ipa_precision": 0.5,
                          "n_pred_segments": 3, "count_error": -1}])
    cols = list(summary_table(rows).columns)
    # the baselines' summary: ipa R, ipa P, then the segment count and segments - rooms
    assert cols.index("count_error") - cols.index("ipa_precision") == 2 and cols[cols.index("count_error") - 1] == "segments"


@pytest.mark.slow
def test_a_robustness_sweep_keeps_each_severity_in_its_own_row(tmp_path, capsys):
    """Issue #26: the clean run and a corrupted one of the same method, through the runner,
    were one cell of Table IV (its columns do not name the corruption); now one row each,
    labelled by corruption and severity, with each run's own mean."""
    from benchmark.config import compose_job
    from benchmark.harness.runner import run

    res = tmp_path / "R"
    means = {}
    for corruption in ("clean", "pose_2"):
        cfg, choices = compose_job(["env=synthetic", "classifier=oracle", "env.resolution=0.1", "viewpoints.spacing=1.0",
                                    "run.progress=false", f"run.results_dir={res}", "run.name=c", "run.limit=2",
                                    f"corruption={corruption}"])
        df = run(cfg, res / "runs" / "c" / corruption, choices)
        means[corruption] = df["iou"].mean()
    assert means["clean"] != pytest.approx(means["pose_2"])
    code, out, err = _tables([res / "runs" / "c", "--table", "table4", "--out", tmp_path / "t"], capsys)
    assert code == 0, err
    t4 = _csv(tmp_path / "t", "table4").set_index("settings")
    assert t4["iou_mean"].to_dict() == pytest.approx({"corruption=clean, severity=0": means["clean"],
                                                      "corruption=pose, severity=2": means["pose_2"]})
    assert t4["n"].tolist() == [2, 2] and "2 houses per cell" in out


def test_each_row_configuration_and_method_name_are_those_written_out_row_by_row(tmp_path):
    """``load_rows`` writes the settings' JSON once per file and names each distinct row once;
    every row's ``_config`` must still be ``json.dumps({"settings": ..., "row": ...})`` of that
    row and its ``method`` :func:`method_label` of that row. Rows that differ only by 1 / 1.0,
    0.0 / -0.0, NaN, a number / its text, and segmenter, explicit-method and oracle rows."""
    import json

    import numpy as np

    from benchmark.harness.store import read_metrics
    from benchmark.reports.tables import ROW_KEYS_LAST, ROW_NAMES, job_configuration, method_label

    runs = tmp_path / "runs"
    oracle = [_row(f"h{i}", 0.1 * i, classifier="oracle", oracle_accuracy=acc, severity=sev, label=lab)
              for i, (acc, sev, lab) in enumerate([(0.8, 1, "a"), (0.8, 1, "a"), (0.9, 2, "1"), (np.nan, 2, "1.0"),
                                                   (0.0, 3, "b"), (-0.0, 3, "b")])]
    for r in oracle:  # no empty name (NaN) in these rows: rows equal but for 0.0 / -0.0 must not share
        r.pop("segmenter")
    _job(runs / "x" / "oracle", {"classifier._target_": "oracle", "nested": [1, {"b": None, "a": 2.5}],
                                 "houses": "6 houses"}, oracle)
    floats = [_row(f"h{i}", 0.5, severity=s, postprocess=p) for i, (s, p) in enumerate([(1.0, "none"), (2.0, "default"),
                                                                                         (1.0, "default")])]
    _job(runs / "x" / "floats", {"aggregator._target_": "knn"}, floats)
    seg = [_row(f"h{i}", 0.3, segmenter=s, classifier="", aggregator="") for i, s in enumerate(["voronoi", "grid"])]
    _job(runs / "x" / "seg", {"segmenter._target_": "v", "classifier.x": 1}, seg)
    named = [_row(f"h{i}", 0.4, method=m) for i, m in enumerate(["ROSE2", "", "SeLRoS"])]
    (runs / "maps").mkdir(parents=True)
    pd.DataFrame(named).to_csv(runs / "maps" / "per_map.csv", index=False)  # no job: its score_key counts

    got = load_rows([runs, runs / "maps" / "per_map.csv"])
    want_config, want_method = [], []
    for f in sorted({*got["source"]}):
        df = read_metrics(f)
        settings = {}
        if Path(f).name == "metrics.csv":
            settings = job_configuration(json.loads((Path(f).parent / "job.json").read_text())["settings"])
        cols = [c for c in (*ROW_NAMES, *ROW_KEYS_LAST) if c in df and not (settings and c == "score_key")]
        for _, r in df.iterrows():
            plain = {c: (None if isinstance(r[c], float) and np.isnan(r[c]) else
                         r[c].item() if isinstance(r[c], np.generic) else r[c]) for c in cols}
            want_config.append(json.dumps({"settings": settings, "row": plain}, sort_keys=True, default=str))
        for c in ("classifier", "aggregator", "postprocess", "segmenter"):
            df[c] = df[c].astype("string").fillna("").astype(str) if c in df else ""
        want_method += df.apply(method_label, axis=1).tolist()
    order = got.sort_values(["source", "_line"])
    assert order["_config"].tolist() == want_config
    assert order["method"].tolist() == want_method
    assert len(set(want_config)) == 13 and {"ROSE2", "SeLRoS", "voronoi", "grid", "oracle@0.8+graph_knn +post",
                                            "oracle@0.9+graph_knn +post", "oracle@0+graph_knn +post",
                                            "oracle@-0+graph_knn +post"} <= set(want_method)


def test_rows_read_on_forked_processes_are_the_rows_read_here(tmp_path, monkeypatch):
    """Many files are read on forked processes (runs of consecutive files): the same frame as
    reading them one after the other here (columns in their order of first appearance, a column
    only some jobs have, an older job's row set aside), and a bad file is named the same way."""
    import benchmark.reports.tables as tables

    runs = tmp_path / "runs"
    for j in range(9):
        extra = {"only_some": 0.5 * j} if j % 4 == 1 else {}
        _job(runs / "x" / f"j{j}", {"aggregator.k": j % 3}, [_row(f"h{i}", 0.1 * (i + j) % 1, **extra) for i in range(3)],
             finished=f"2026-01-01T10:00:0{j}+00:00")
    monkeypatch.setenv("ROOMSEG_JOBS", "3")
    monkeypatch.setattr(tables, "FILES_PER_PROCESS", 10**9)
    here = load_rows([runs])
    monkeypatch.setattr(tables, "FILES_PER_PROCESS", 2)
    forked = load_rows([runs])
    pd.testing.assert_frame_equal(forked, here, check_exact=True)
    assert forked.attrs == here.attrs and here.attrs["set_aside"]
    assert "only_some" in forked.columns
    (runs / "x" / "j7" / "metrics.csv").write_text("house_id,iou\nh0,not a number\n", encoding="utf-8")
    with pytest.raises(ValueError) as forked_error:
        load_rows([runs])
    monkeypatch.setattr(tables, "FILES_PER_PROCESS", 10**9)
    with pytest.raises(ValueError) as here_error:
        load_rows([runs])
    assert str(forked_error.value) == str(here_error.value) and "j7" in str(here_error.value)
