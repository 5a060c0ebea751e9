"""The SeLRoS release: ground-truth maps load, SeLRoS and VRF outputs score over all 30 maps."""

import numpy as np

from benchmark.baselines.external import score_directory, summary_table
from benchmark.baselines.selros import selros_rows
from benchmark.metrics import MetricParams
from envs.maps.label_png import read_instance_png

#: Room counts checked by eye on the ground-truth PNGs (viewed side by side: one flat colour
#: region per room, thin blended edges ignored).
VISUAL_ROOM_COUNTS = {"01": 4, "05": 5, "09": 5, "12": 3, "22": 6, "25": 7, "27": 9}


def test_ground_truth_maps_load_with_visual_room_counts(selros_dir):
    counts = {}
    for i in range(1, 31):
        inst = read_instance_png(selros_dir / "ground_truth" / f"{i:02d}_ground_truth.png")
        assert inst.dtype == np.int32 and inst.min() == -1
        k = int(inst.max()) + 1
        assert set(np.unique(inst)) == set(range(-1, k))
        counts[f"{i:02d}"] = k
        assert 2 <= k <= 10
    for mid, n in VISUAL_ROOM_COUNTS.items():
        assert counts[mid] == n, (mid, counts[mid])


def test_anti_aliased_colours_are_not_rooms(selros_dir):
    path = selros_dir / "ground_truth" / "01_ground_truth.png"
    kept = read_instance_png(path, assign="neighbour")
    dropped = read_instance_png(path, assign="drop")
    every = read_instance_png(path, min_pixels=1)
    assert kept.max() == dropped.max() == 3 and every.max() > 20
    # neighbour assignment labels every non-black pixel; drop leaves the blends unlabelled
    assert (kept >= 0).sum() == (every >= 0).sum() > (dropped >= 0).sum()


def test_selros_and_vrf_tables_over_30_maps(selros_dir):
    df = selros_rows(selros_dir, MetricParams())
    assert len(df) == 60 and (df["status"] == "ok").all()
    table = summary_table(df)
    print(table.to_markdown(index=False))
    means = df.groupby("method")["iou"].mean()
    assert 0.2 < means["VRF"] < means["SeLRoS"] < 0.95
    assert (df["precision"] > 0).all()


def test_missing_prediction_is_listed_not_dropped(selros_dir, tmp_path):
    import shutil

    for i in (1, 2):
        shutil.copy(selros_dir / "selros" / f"{i:02d}_output.png", tmp_path / f"{i:02d}_output.png")
    df = score_directory(selros_dir / "ground_truth", "{id}_ground_truth.png", tmp_path, "{id}_output.png", "x")
    assert len(df) == 30
    assert (df["status"] == "ok").sum() == 2
    failed = df[df["status"] == "failed"]
    assert "03_output.png" in failed.loc[failed["house_id"] == "03", "error"].item()
