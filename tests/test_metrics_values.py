"""The one reader of metrics files refuses a share outside [0, 1] (issue #24): one line naming
the file, the line, the column and the value; counts are not shares; missing values pass
where a column may lack them. Through the reader and through ``tables``."""

from __future__ import annotations

import json

import pandas as pd
import pytest

from benchmark.commands.tables import main as tables_main
from benchmark.harness.store import read_metrics
from benchmark.metrics import METRIC_COLUMNS

HEAD = "house_id,status,iou,precision,recall,accuracy,count_error,n_views,iou_kitchen,view_accuracy_seen,pq\n"
GOOD = "h1,ok,0.5,0.9,0.4,0.6,-3,120,0.2,1.0,0.0\n"


def _file(tmp_path, *lines: str, job: bool = True):
    f = tmp_path / "metrics.csv"
    f.write_text(HEAD + "".join(lines))
    if job:  # a runner job's folder
        (tmp_path / "summary.json").write_text(json.dumps({"n_houses": len(lines)}))
    return f


@pytest.mark.parametrize("column,value", [("iou", "7.5"), ("precision", "-0.01"), ("accuracy", "inf"),
                                          ("iou_kitchen", "1.0000001"), ("view_accuracy_seen", "-inf"),
                                          ("pq", "2")])
def test_a_share_outside_0_1_is_refused_naming_file_line_column_value(tmp_path, column, value):
    cols = HEAD.strip().split(",")
    bad = GOOD.strip().split(",")
    bad[cols.index(column)] = value
    f = _file(tmp_path, GOOD, ",".join(["h2", *bad[1:]]) + "\n")
    with pytest.raises(ValueError) as e:
        read_metrics(f)
    msg = str(e.value)
    assert "\n" not in msg
    assert msg == f"{f}: line 3 (house h2), column {column!r}: {float(value)} is outside [0, 1]; expected a fraction in [0, 1]"


def test_text_in_a_share_column_and_a_missing_iou_in_an_ok_row_are_refused(tmp_path):
    f = _file(tmp_path, GOOD.replace("0.9", "high"))
    with pytest.raises(ValueError, match=r"metrics.csv: line 2 \(house h1\), column 'precision': high is not a number"):
        read_metrics(f)
    f = _file(tmp_path, GOOD.replace("ok,0.5,", "ok,,"))
    with pytest.raises(ValueError, match=r"line 2 \(house h1\), column 'iou': missing in a row with status ok"):
        read_metrics(f)


def test_counts_missing_values_and_failed_rows_pass(tmp_path):
    rows = [GOOD,
            "h2,ok,0.0,1.0,0.0,,12,0,,,\n",  # shares at the bounds, accuracy/per-class/view/pq missing
            "h3,failed,,,,,,,,,\n"]  # a failed house has no metrics
    df = read_metrics(_file(tmp_path, *rows))
    assert df["count_error"].tolist()[:2] == [-3, 12] and df["n_views"].tolist()[:2] == [120, 0]
    # a per-map table of the baselines (no summary.json) is checked the same way
    (tmp_path / "summary.json").unlink()
    with pytest.raises(ValueError, match="column 'iou': 7.5 is outside"):
        read_metrics(_file(tmp_path, GOOD.replace("0.5", "7.5"), job=False))


def test_which_columns_are_shares():
    from benchmark.harness.store import fraction_columns

    robot = ["coverage_area", "coverage_rooms", "label_noise_share", "map_free_iou", "map_missed_share"]
    cols = fraction_columns([*METRIC_COLUMNS, "iou_kitchen", "view_accuracy", "view_accuracy_seen", "oracle_accuracy",
                             *robot, "house_id", "t_score", "n_refused", "score_key", "severity",
                             "pose_error_mean_m", "yaw_error_mean_deg"])
    assert "count_error" not in cols and not any(c.startswith("n_") for c in cols)
    assert {"iou", "precision", "recall", "matched_iou", "matched_precision", "matched_recall", "room_iou",
            "room_recall", "pq", "sq", "rq", "pq_semantic", "ipa_recall", "ipa_precision", "accuracy", "class_iou",
            "iou_kitchen", "view_accuracy", "view_accuracy_seen", "oracle_accuracy", *robot} == set(cols)


def test_tables_refuses_a_hand_edited_iou_with_one_line_and_exit_2(tmp_path, capsys):
    job = tmp_path / "runs" / "x"
    job.mkdir(parents=True)
    pd.DataFrame({"house_id": ["h0", "h1"], "dataset": "synthetic", "classifier": "oracle", "aggregator": "graph_knn",
                  "postprocess": "default", "segmenter": "", "status": "ok", "error": "", "iou": [0.5, 7.5],
                  "accuracy": [0.5, 0.5]}).to_csv(job / "metrics.csv", index=False)
    code = tables_main([str(tmp_path / "runs"), "--table", "table4"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert err[-1] == f"error: {job / 'metrics.csv'}: line 3 (house h1), column 'iou': 7.5 is outside [0, 1]; " \
                      "expected a fraction in [0, 1]"
