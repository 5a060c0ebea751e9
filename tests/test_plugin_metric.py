"""Metrics of your own (``metrics.extra``): the extension point of :mod:`benchmark.metrics`.

Hand-made maps with answers worked out by hand: two 4 x 2 px rooms side by side at
0.5 m/px. The callables here are written for the test (the documented example, a boundary F1,
is run through ``roomseg-bench`` in ``tests/test_plugin_examples.py``)."""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest
from hydra.utils import instantiate
from omegaconf import OmegaConf

from benchmark.metrics import MetricParams, describe, score_instances, score_semantic

RES = 0.5  # metres per pixel
GT = np.array([[0, 0, 1, 1],
               [0, 0, 1, 1],
               [-1, -1, -1, -1]])
GT_CLASSES = [2, 5]  # room 0 a bedroom, room 1 a kitchen (indices into a 7-class list)


class Seen:
    """Records what it was called with; returns an area (m², as a count of whole m²) and a share."""

    def __init__(self):
        self.calls = []

    def __call__(self, pred, gt_instances, gt_classes, resolution):
        self.calls.append((pred.copy(), gt_instances.copy(), None if gt_classes is None else list(gt_classes),
                           resolution, pred.flags.writeable, gt_instances.flags.writeable))
        labelled = int((pred >= 0).sum())
        return {"labelled_m2": int(labelled * resolution**2), "labelled_share": labelled / int((gt_instances >= 0).sum())}


def unlabelled_share(pred, gt_instances, gt_classes, resolution, *, name="unlabelled"):
    """A function metric (configured with ``_partial_: true``)."""
    walk = gt_instances >= 0
    return {name: float(np.mean(pred[walk] < 0))}


def test_extra_columns_join_the_semantic_and_the_instance_scores():
    seen = Seen()
    params = MetricParams(extra=(seen, functools.partial(unlabelled_share, name="unlabelled")))
    pred = np.array([[2, 2, 5, -1],
                     [2, 2, 5, -1],
                     [-1, -1, -1, -1]])
    out = score_semantic(pred, GT, GT_CLASSES, params, resolution=RES)
    # 6 of 8 walkable pixels labelled: 6 x 0.25 m² = 1.5 m² -> int 1; share 0.75; unlabelled 2 / 8
    assert out["labelled_m2"] == 1 and isinstance(out["labelled_m2"], int)
    assert out["labelled_share"] == 0.75 and out["unlabelled"] == 0.25
    assert out["iou"] > 0  # the built-in metrics are still there
    p, g, classes, res, pw, gw = seen.calls[-1]
    assert (p == pred).all() and (g == GT).all() and classes == GT_CLASSES and res == RES
    assert not pw and not gw  # handed over read-only

    inst = np.where(GT >= 0, 7, -1)  # one segment over both rooms
    out = score_instances(inst, GT, params, resolution=RES)
    assert out["labelled_m2"] == 2 and out["labelled_share"] == 1.0 and out["unlabelled"] == 0.0
    assert seen.calls[-1][2] is None  # instance maps: no classes
    assert out["count_error"] == -1


def test_without_extra_metrics_the_row_is_unchanged():
    pred = np.array([[2, 2, 5, 5], [2, 2, 5, 5], [-1, -1, -1, -1]])
    plain = score_semantic(pred, GT, GT_CLASSES, MetricParams(), resolution=RES)
    assert "labelled_share" not in plain and plain["iou"] == 1.0 and plain["accuracy"] == 1.0
    assert "extra metrics" not in describe(MetricParams())


def test_a_metric_cannot_change_the_map_it_scores():
    def vandal(pred, gt_instances, gt_classes, resolution):
        pred[0, 0] = 99
        return {}

    pred = np.array([[2, 2, 5, 5], [2, 2, 5, 5], [-1, -1, -1, -1]])
    with pytest.raises(ValueError, match="read-only"):
        score_semantic(pred, GT, GT_CLASSES, MetricParams(extra=(vandal,)), resolution=RES)
    assert pred[0, 0] == 2


def _returning(value):
    def metric(pred, gt_instances, gt_classes, resolution):
        return value
    return metric


@pytest.mark.parametrize(("result", "message"), [
    ([0.5], "returned list, expected a dict"),
    ({"Boundary": 0.5}, "'Boundary' is not lower_snake_case"),
    ({"iou": 0.5}, "column 'iou' is already a column"),
    ({"house_id": 0.5}, "column 'house_id' is already a column"),
    ({"iou_kitchen": 0.5}, "column 'iou_kitchen' is already a column"),
    ({"t_metric": 0.5}, "column 't_metric' is already a column"),
    ({"share": 1.5}, r"share=1.5, expected a share in \[0, 1\]"),
    ({"share": -0.1}, r"share=-0.1, expected a share in \[0, 1\]"),
    ({"count": -3}, r"count=-3, expected a count \(int >= 0\)"),
    ({"flag": True}, "flag=True, expected a share"),
    ({"text": "high"}, "text='high', expected a share"),
])
def test_bad_results_are_one_line_naming_metric_column_and_value(result, message):
    pred = np.array([[2, 2, 5, 5], [2, 2, 5, 5], [-1, -1, -1, -1]])
    with pytest.raises(ValueError, match=message) as e:
        score_semantic(pred, GT, GT_CLASSES, MetricParams(extra=(_returning(result),)), resolution=RES)
    assert "metric test_plugin_metric._returning.<locals>.metric" in str(e.value)
    assert "\n" not in str(e.value)


def test_nan_and_numpy_scalars_are_accepted():
    pred = np.array([[2, 2, 5, 5], [2, 2, 5, 5], [-1, -1, -1, -1]])
    out = score_semantic(pred, GT, GT_CLASSES, MetricParams(
        extra=(_returning({"undefined": float("nan"), "n": np.int64(3), "s": np.float32(0.25)}),)), resolution=RES)
    assert math.isnan(out["undefined"]) and out["n"] == 3 and type(out["n"]) is int and out["s"] == 0.25


def test_two_metrics_may_not_write_one_column():
    pred = np.array([[2, 2, 5, 5], [2, 2, 5, 5], [-1, -1, -1, -1]])
    twice = (_returning({"same": 0.1}), _returning({"same": 0.2}))
    with pytest.raises(ValueError, match="column 'same' is already a column"):
        score_semantic(pred, GT, GT_CLASSES, MetricParams(extra=twice), resolution=RES)


def test_extra_from_the_config_group():
    """``conf/metrics/default.yaml`` holds ``extra: []``; entries are instantiated by Hydra, a
    class (instance callable) or a function with ``_partial_: true``."""
    cfg = OmegaConf.load("conf/metrics/default.yaml")
    assert instantiate(cfg).extra == ()
    cfg.extra = [{"_target_": "test_plugin_metric.unlabelled_share", "_partial_": True, "name": "left_out"}]
    params = instantiate(cfg)
    pred = np.array([[2, 2, -1, -1], [2, 2, -1, -1], [-1, -1, -1, -1]])
    assert score_semantic(pred, GT, GT_CLASSES, params, resolution=RES)["left_out"] == 0.5
    assert describe(params).endswith("; extra metrics: test_plugin_metric.unlabelled_share")
    with pytest.raises(ValueError, match=r"metrics.extra\[0\] is 'x', expected a callable"):
        MetricParams(extra=["x"])
    with pytest.raises(ValueError, match="metrics.extra must be a list"):
        MetricParams(extra="x")
