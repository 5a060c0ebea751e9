"""Geometric baselines on hand-made maps (known answer) and on the shared maps."""

import numpy as np
import pytest

from benchmark.baselines.geometric import DistanceTransform, Morphological, Voronoi
from benchmark.metrics import MetricParams, score_instances
from envs.gridmap import GridMap


def rooms_and_corridor():
    """Two 3 x 3 m rooms left and right of a 1.5 m corridor, each joined to it by a 0.8 m door."""
    walk = np.zeros((64, 154), bool)
    gt = np.full(walk.shape, -1, np.int32)
    walk[2:62, 2:62] = True
    gt[2:62, 2:62] = 0
    walk[2:62, 64:94] = True
    gt[2:62, 64:94] = 1
    walk[2:62, 96:152] = True
    gt[2:62, 96:152] = 2
    walk[24:40, 62:64] = True  # doors, 16 px = 0.8 m
    gt[24:40, 62:64] = 1
    walk[24:40, 94:96] = True
    gt[24:40, 94:96] = 1
    return GridMap(walk, 0.05, (0.0, 64 * 0.05)), gt


@pytest.mark.parametrize("seg", [Morphological(), DistanceTransform(), Voronoi()])
def test_split_at_the_doors(seg):
    grid, gt = rooms_and_corridor()
    inst = seg(grid)
    assert (inst[grid.walkable] >= 0).all() and (inst[~grid.walkable] == -1).all()
    assert inst.max() + 1 == 3
    s = score_instances(inst, gt, MetricParams(min_segment_px=0))
    assert s["iou"] > 0.9 and np.isnan(s["accuracy"])
    for room in range(3):
        vals, counts = np.unique(inst[gt == room], return_counts=True)
        assert counts.max() / counts.sum() > 0.9


def test_bad_input():
    with pytest.raises(ValueError, match="walkable"):
        Morphological()(GridMap(np.zeros((5, 5), bool), 0.05, (0, 0)))
    grid, _ = rooms_and_corridor()
    with pytest.raises(ValueError, match="area limits"):
        DistanceTransform(min_area=5, max_area=1)(grid)


def test_shared_houses_do_not_crash(shared_scenes):
    for scene in shared_scenes[:6]:
        for seg in (Morphological(), DistanceTransform(), Voronoi()):
            inst = seg(scene.grid)
            assert inst.shape == scene.grid.shape and (inst[scene.grid.walkable] >= 0).all()
            s = score_instances(inst, scene.instances)
            assert 0 <= s["iou"] <= 1


def test_match_finds_the_house_behind_a_rotated_map(shared_houses):
    from benchmark.baselines.match import match_maps
    from envs.scene import rasterise_house

    houses = shared_houses[:6]
    target = rasterise_house(houses[4], resolution=0.02).grid.walkable
    maps = {"rotated": np.rot90(np.pad(target, ((7, 0), (0, 13))), 1)}
    (row,) = match_maps(maps, 0.02, houses)
    assert row["best_house"] == houses[4].id
    assert row["iou"] > 0.85 and row["iou"] > row["second_iou"] + 0.1


def test_score_cli_with_preset(selros_dir, tmp_path):
    from benchmark.baselines.__main__ import main

    assert main(["score", "--preset", "vrf", "--out", str(tmp_path)]) == 0
    import pandas as pd

    df = pd.read_csv(tmp_path / "metrics.csv")
    assert len(df) == 30 and set(df["method"]) == {"VRF"}
    assert main(["score", "--preset", "nope"]) == 2
