"""External label maps (issue 24): ``external.pred_format=label`` scored each class as one whole
segment (IoU 84.45 where ``roomseg-segment`` gave 61.16 on the same files). A label map is split
into connected segments as the method's own maps are, and scored with accuracy when the ground
truth carries classes too: the same numbers as ``roomseg-segment`` on the same files."""

from __future__ import annotations

import json

import pytest

from benchmark.baselines.external import Pair, score_pairs
from benchmark.commands.segment import main as segment
from benchmark.commands.segment_example import write_example
from benchmark.metrics import MetricParams


@pytest.fixture(scope="module")
def segmented(tmp_path_factory):
    d = tmp_path_factory.mktemp("ext")
    ex = write_example(d / "in", open_plan=True)
    out = d / "out"
    assert segment([f"map={ex.map_yaml}", f"poses={ex.poses}", "frame=ros", f"labels={ex.labels}", f"gt={ex.gt}",
                    "gt_format=label", f"out={out}", "figure=false"]) == 0
    return ex, out


def test_a_label_map_is_scored_as_roomseg_segment_scores_it(segmented):
    ex, out = segmented
    want = json.loads((out / "scores.json").read_text())
    df = score_pairs([Pair("ex", ex.gt, out / "labels_color.png")], "mine", MetricParams(), gt_format="label",
                     pred_format="label", resolution=ex.grid.resolution)
    row = df.iloc[0]
    assert row["status"] == "ok", row["error"]
    for k in ("iou", "precision", "recall", "matched_iou", "pq", "accuracy", "n_pred_segments"):
        assert row[k] == pytest.approx(want[k]), k
    from envs.maps.label_png import read_label_png

    labels, _ = read_label_png(out / "labels_color.png")
    n_classes = len(set(labels[labels >= 0].tolist()))
    assert row["n_pred_segments"] > n_classes  # classes in pieces: not one whole segment per class

