"""The method as one object (benchmark/method.py): its chain, its view transforms, its cache
hook, and the same map from the harness and from ``roomseg-segment`` for the same inputs."""

from __future__ import annotations

import json

import numpy as np
import pytest

from benchmark.config import build_method, compose_job
from benchmark.method import Classified, Context, Lazy, Method, OnMapRule, Views
from envs.maps.gridmap import GridMap
from envs.render.observation import Observation

CLASSES = ("a", "b")


class _Clf:
    """Class 0 for views left of x = 2.5 m, class 1 right of it."""

    classes = CLASSES

    def __init__(self):
        self.calls = 0

    def predict_proba(self, obs):
        self.calls += 1
        x = np.array([o.pose[0] for o in obs])
        return np.stack([(x < 2.5).astype(float), (x >= 2.5).astype(float)], axis=1)


def _left_right(grid, poses, proba):
    """An aggregator by hand: every walkable cell takes the class of the nearest view in x."""
    _, cols = np.nonzero(np.ones(grid.shape, bool))
    x = grid.origin[0] + (np.arange(grid.shape[1]) + 0.5) * grid.resolution
    nearest = np.abs(x[:, None] - poses[None, :, 0]).argmin(axis=1)
    lab = proba.argmax(axis=1)[nearest]
    return np.where(grid.walkable, lab[None, :], -1)


def _grid() -> GridMap:
    walk = np.ones((10, 50), bool)
    walk[:, 0] = False
    return GridMap(walk, 0.1, (0.0, 1.0))  # z runs down the rows from 1.0 m


def _views(xs):
    return [Observation(pose=(float(x), 0.55, 0.0), meta={"id": f"v{k}"}) for k, x in enumerate(xs)]


def test_run_is_the_three_steps_and_never_labels_off_the_map():
    grid = _grid()
    res = Method(_Clf(), _left_right).run(_views([0.5, 1.0, 4.0]), grid)
    assert res.proba.tolist() == [[1, 0], [1, 0], [0, 1]]
    x = (np.arange(50) + 0.5) * 0.1
    # the hand aggregator's answer: class 0 up to the midpoint between 1.0 and 4.0 m
    want = np.where(x < 2.5, 0, 1)
    assert (res.raw[:, 1:] == want[None, 1:]).all()
    assert (res.labels[:, 0] == -1).all()  # not walkable: unlabelled, whatever the stage says
    assert res.labels.dtype == np.int32


def test_refused_views_are_left_out_and_the_house_is_stamped():
    obs = _views([0.5, 4.0, 3.0])
    obs[1].meta["refused"] = True
    clf = _Clf()
    c = Method(clf, _left_right).classify(obs, Context(house_id="h7"))
    assert c.n_refused == 1 and len(c.poses) == 2
    assert all(o.meta["house_id"] == "h7" for o in c.observations)
    with pytest.raises(ValueError, match="house 'h7': every one of 1 views was refused"):
        Method(clf, _left_right).classify([obs[1]], Context(house_id="h7"))


def test_lazy_stages_are_built_once_and_only_when_needed():
    built = []

    def factory():
        built.append(1)
        return _Clf()

    m = Method(Lazy(factory), _left_right)

    class Cached:
        def classified(self, compute):  # served without calling compute: no classifier built
            return Classified(np.array([[0.5, 0.55, 0.0], [4.0, 0.55, 0.0]]), np.array([[1.0, 0.0], [0.0, 1.0]]))

        def aggregated(self, grid, views, compute):
            return compute()

    res = m.run(lambda: pytest.fail("observations read although cached"), _grid(), cache=Cached())
    assert built == [] and res.raw[5, 40] == 1
    assert m.classifier is m.classifier
    assert built == [1]


def test_transforms_run_in_order_and_record_their_columns():
    def shift(views, ctx):
        return Views(views.poses + [1.0, 0, 0], views.proba, views.true_poses, views.ids), {"shift_m": 1.0}

    res = Method(_Clf(), _left_right, transforms=[shift]).run(_views([0.5, 1.0]), _grid())
    assert res.info == {"shift_m": 1.0}
    assert res.poses[:, 0].tolist() == [1.5, 2.0]
    assert res.classified.poses[:, 0].tolist() == [0.5, 1.0]  # where the camera was


def test_off_map_rule_errors_names_the_view_or_drops():
    grid = _grid()
    obs = _views([0.5, 0.05, 4.0])  # x = 0.05 m is column 0: not walkable
    with pytest.raises(ValueError, match="1 of 3 poses are off the walkable map, first view v1"):
        Method(_Clf(), _left_right, transforms=[OnMapRule("error", "p.csv", "m.yaml", "ros")]).run(obs, grid)
    res = Method(_Clf(), _left_right, transforms=[OnMapRule("drop")]).run(obs, grid)
    assert res.info == {"n_off_map": 1} and len(res.poses) == 2 and res.views.ids == ["v0", "v2"]
    with pytest.raises(ValueError, match="none of the 1 poses"):
        Method(_Clf(), _left_right, transforms=[OnMapRule("drop")]).run(_views([0.05]), grid)
    with pytest.raises(ValueError, match="off_map='keep'"):
        OnMapRule("keep")


def test_build_method_adds_only_the_conditions_that_change_anything():
    clean, _ = compose_job(["corruption=clean"])
    assert build_method(clean).transforms == []
    noisy, _ = compose_job(["corruption=realistic_3"])
    kinds = [type(t).__name__ for t in build_method(noisy).transforms]
    assert kinds == ["PoseErrorTransform", "LabelNoiseTransform"]


@pytest.mark.slow
@pytest.mark.parametrize("aggregator", ["vision_cone", "graph_knn"])
def test_harness_and_roomseg_segment_give_the_same_map(tmp_path, aggregator):
    """One generated house through the harness (oracle classifier, post-processing), then its
    map, the harness's poses and class probabilities given to ``roomseg-segment`` as files:
    the two label maps are equal cell for cell, because both run the one Method."""
    from benchmark.commands.segment import main as segment
    from benchmark.harness.cache import load_npz
    from benchmark.harness.runner import build_pipeline
    from envs.maps.ros import write_grid_ros
    from envs.maps.segmentation_io import read_index_png

    cfg, choices = compose_job(["env=synthetic", "classifier=oracle", f"aggregator={aggregator}",
                                "postprocess=default", f"run.results_dir={tmp_path / 'r'}", "run.progress=false"])
    pipe = build_pipeline(cfg, choices)
    hid = pipe.env.house_ids()[0]
    row = pipe.run_house(hid)
    assert row["status"] == "ok", row.get("error")
    maps = load_npz(pipe.entry("maps", hid))
    scene = pipe.scene(hid)
    classes = list(scene.classes)
    yaml = write_grid_ros(tmp_path / "in" / "map.yaml", scene.grid)
    poses, proba = maps["poses"], np.asarray(maps["proba"], np.float64)
    lines = ["id,x,z,yaw," + ",".join(classes)]
    for k, (p, q) in enumerate(zip(poses, proba)):
        lines.append(f"v{k}," + ",".join(repr(float(v)) for v in (*p, *q)))
    (tmp_path / "in" / "views.csv").write_text("\n".join(lines) + "\n")
    out = tmp_path / "out"
    code = segment([f"map={yaml}", f"poses={tmp_path / 'in' / 'views.csv'}", "frame=sim",
                    f"labels={tmp_path / 'in' / 'views.csv'}", f"aggregator={aggregator}", "postprocess=default",
                    "reachable=all", f"out={out}"])
    assert code == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["classes"] == classes and summary["n_views"] == len(poses)
    got = read_index_png(out / "labels.png").astype(np.int64)
    got[got == 255] = -1
    want = maps["post"].astype(np.int64)
    assert got.shape == want.shape
    assert (got == want).all(), f"{int((got != want).sum())} cells differ"
    assert (want >= 0).sum() > 0.9 * scene.grid.walkable.sum()  # a real map, not an empty one


def test_a_lazy_view_transform_stage_is_built_once():
    from benchmark.method import PoseErrorTransform

    built = []

    class Shift:
        def __call__(self, poses, grid, hid):
            return poses + [0.1, 0, 0], {"pose_error_mean_m": 0.1}

    def factory():
        built.append(1)
        return Shift()

    m = Method(_Clf(), _left_right, transforms=[PoseErrorTransform(Lazy(factory))])
    for _ in range(3):
        m.run(_views([0.5, 4.0]), _grid())
    assert built == [1]
