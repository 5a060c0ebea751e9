"""The plug-in examples of ``docs/plugins.md`` (``examples/plugins/<kind>/``): each on a hand-made
input with an answer worked out by hand, and every command block of the page run through
``roomseg-bench`` from a fresh copy of the repository, with what each run wrote checked."""

from __future__ import annotations

import importlib
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from benchmark.commands import docs
from envs.maps.gridmap import GridMap
from envs.render.observation import Observation

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples" / "plugins"
CLASSES = ("balcony", "bathroom", "bedroom", "corridor", "dining_room", "kitchen", "living_room")


def _example(kind: str, module: str):
    path = str(EXAMPLES / kind)
    if path not in sys.path:
        sys.path.insert(0, path)
    return importlib.import_module(module)


def two_rooms(door_m: float, res: float = 0.05) -> GridMap:
    """Two 4 x 4 m rooms side by side (x), a 0.1 m wall between them with a door ``door_m``
    wide in its middle; origin (0, 4): x grows with columns, z falls with rows."""
    n = int(round(4 / res))
    wall = int(round(0.1 / res))
    walkable = np.zeros((n, 2 * n + wall), bool)
    walkable[:, :n] = True
    walkable[:, n + wall:] = True
    half = int(round(door_m / res / 2))
    walkable[n // 2 - half:n // 2 + half, n:n + wall] = True
    return GridMap(walkable=walkable, resolution=res, origin=(0.0, 4.0))


def test_object_rules_classifier():
    m = _example("classifier", "my_classifier.object_rules")
    clf = m.ObjectRules(CLASSES, {"Toilet": "bathroom", "Bed": "bedroom", "Sofa": "living_room"}, prior=0.01)
    views = [Observation(pose=(0, 0, 0), objects=[("Toilet", 0.2), ("Chair", 0.5)]),
             Observation(pose=(0, 0, 0), objects=[]),
             Observation(pose=(0, 0, 0), objects=[("Bed", 0.1), ("Sofa", 0.3)])]
    p = clf.predict_proba(views)
    assert p.shape == (3, 7) and np.allclose(p.sum(axis=1), 1)
    # view 0: bathroom 0.21, the six others 0.01 each: 0.21 / 0.27
    assert p[0, 1] == pytest.approx(0.21 / 0.27) and p[0, 0] == pytest.approx(0.01 / 0.27)
    assert np.allclose(p[1], 1 / 7)  # nothing known seen: uniform
    assert np.argmax(p[2]) == 6 and p[2, 2] == pytest.approx(0.11 / 0.47)
    with pytest.raises(ValueError, match=r"class\(es\) \['garage'\] not in classes"):
        m.ObjectRules(CLASSES, {"Car": "garage"})
    with pytest.raises(ValueError, match="prior=0"):
        m.ObjectRules(CLASSES, {}, prior=0)


def test_nearest_view_aggregator():
    m = _example("aggregator", "my_aggregator.nearest_view")
    grid = two_rooms(door_m=0.8)
    # a kitchen view in the middle of the left room, a bedroom view in the middle of the right room
    poses = np.array([[2.0, 2.0, 0.0], [6.1, 2.0, 90.0]])
    proba = np.zeros((2, 7))
    proba[0, 5] = proba[1, 2] = 1.0
    labels = m.NearestView(max_distance_m=3.0)(grid, poses, proba)
    rows, cols = np.nonzero(grid.walkable)
    x, z = grid.pixel_to_world(rows, cols)
    d0, d1 = np.hypot(x - 2.0, z - 2.0), np.hypot(x - 6.1, z - 2.0)
    want = np.where(np.minimum(d0, d1) > 3.0, -1, np.where(d0 <= d1, 5, 2))
    ties = np.isclose(d0, d1)
    assert (labels[rows, cols][~ties] == want[~ties]).all()
    assert (labels[~grid.walkable] == -1).all()
    # the corners (2 m x 2 m from a view: 2.83 m) are reached; nothing is beyond 3 m here
    assert (labels[grid.walkable] >= 0).all()
    far = m.NearestView(max_distance_m=1.0)(grid, poses, proba)
    assert far[grid.world_to_cell(0.1, 3.9)] == -1 and far[grid.world_to_cell(2.5, 2.5)] == 5
    with pytest.raises(ValueError, match="max_distance_m=-1"):
        m.NearestView(max_distance_m=-1)
    # its annotation is the config check's range: one line before any work, as for a bundled stage
    from benchmark.harness.typed import ConfigError, check_targets

    with pytest.raises(ConfigError, match=r"^aggregator.max_distance_m=-1: expected metres > 0$"):
        check_targets({"aggregator": {"_target_": "my_aggregator.nearest_view.NearestView", "max_distance_m": -1}})


def test_door_cut_segmenter():
    m = _example("segmenter", "my_segmenter.door_cut")
    grid = two_rooms(door_m=0.8)
    seg = m.DoorCut(door_width_m=1.0, min_area_m2=1.0)(grid)
    n = 80
    left, right = seg[:, :n], seg[:, n + 2:]
    assert (seg[~grid.walkable] == -1).all() and (seg[grid.walkable] >= 0).all()
    assert len(np.unique(left)) == 1 and len(np.unique(right)) == 1 and left[0, 0] != right[0, 0]
    # a door wider than door_width_m stays open: one room
    wide = m.DoorCut(door_width_m=1.0)(two_rooms(door_m=2.0))
    assert set(np.unique(wide)) == {-1, 0}
    with pytest.raises(ValueError, match="door_width_m=0"):
        m.DoorCut(door_width_m=0)


def test_boundary_f1_metric():
    m = _example("metric", "my_metric.boundary")
    gt = np.full((4, 8), -1)
    gt[:, :4], gt[:, 4:] = 0, 1          # two rooms, border between columns 3 and 4
    f1 = m.BoundaryF1(tolerance_m=0.0)
    # the rooms themselves: every border pixel found
    assert f1(gt.copy(), gt, [2, 5], 0.5) == {"boundary_precision": 1.0, "boundary_recall": 1.0, "boundary_f1": 1.0,
                                             "boundary_px": 8}
    # one segment: no predicted border, recall 0, F1 0
    out = f1(np.zeros_like(gt), gt, None, 0.5)
    assert np.isnan(out["boundary_precision"]) and out["boundary_recall"] == 0 and out["boundary_f1"] == 0
    # border shifted one column right (0.5 m): found with a 0.5 m tolerance, not with 0.4 m
    shifted = np.where(np.arange(8) < 5, 0, 1)[None, :].repeat(4, 0)
    # predicted border pixels: columns 4 and 5; gt border: columns 3 and 4
    assert m.BoundaryF1(tolerance_m=0.5)(shifted, gt, None, 0.5)["boundary_f1"] == 1.0
    strict = m.BoundaryF1(tolerance_m=0.4)(shifted, gt, None, 0.5)
    assert strict["boundary_precision"] == 0.5 and strict["boundary_recall"] == 0.5 and strict["boundary_f1"] == 0.5
    # one room predicted as one room
    one = np.zeros((3, 3), int)
    assert m.BoundaryF1()(one, one, None, 0.05)["boundary_f1"] == 1.0


@pytest.mark.slow
def test_every_block_of_the_plugins_page_runs_and_the_plugins_ran(tmp_path, capsys):
    work = tmp_path / "clone"
    rc = docs.run_blocks(ROOT / "docs" / "plugins.md", workdir=work, venv_from=sys.executable)
    out = capsys.readouterr().out
    assert rc == 0, out
    runs = work / "results" / "runs"

    def rows(name: str) -> pd.DataFrame:
        files = sorted((runs / name).rglob("metrics.csv"))
        assert files, f"no metrics.csv under {runs / name}"
        df = pd.concat(pd.read_csv(f) for f in files)
        assert (df["status"] == "ok").all(), df[df["status"] != "ok"]["error"].tolist()
        return df

    assert set(rows("object_rules")["classifier"]) == {"object_rules"}
    assert set(rows("nearest_view")["aggregator"]) == {"nearest_view"}
    assert set(rows("nearest_vs_cone")["aggregator"]) == {"nearest_view", "vision_cone"}
    seg = rows("door_cut")
    assert set(seg["segmenter"]) == {"door_cut", "distance"} and len(seg) == 6
    b = rows("boundary")
    assert len(b) == 9 and (b["boundary_f1"].between(0, 1)).all()
    assert (b.loc[b["segmenter"] == "gt_geometry", "boundary_f1"] == 1.0).all()
    assert (b.loc[b["segmenter"] == "one_room", "boundary_f1"] == 0.0).all()
    assert b["metric_params"].str.endswith("extra metrics: my_metric.boundary.BoundaryF1").all()
