"""The SeLRoS release: ground-truth maps load; the SeLRoS and VRF presets score all 30 maps;
the acceptance of the robust metrics (ground truth vs itself = 100 on every metric, one room
below both methods on PQ and matched IoU, no white slivers among the segments); the free space
given to the geometric baselines equals the other methods' and the ground truth's."""

import shutil

import numpy as np
import pandas as pd
import pytest
from hydra.utils import instantiate

from benchmark.baselines.external import ExternalMethod, summary_table
from benchmark.baselines.selros import read_free_space
from benchmark.commands.selros import compose_score
from benchmark.metrics import MetricParams
from envs.maps.label_png import read_instance_png

#: Room counts checked by eye on the ground-truth PNGs (viewed side by side: one flat colour
#: region per room, thin blended edges ignored).
VISUAL_ROOM_COUNTS = {"01": 4, "05": 5, "09": 5, "12": 3, "22": 6, "25": 7, "27": 9}

ROOM_SCORES = ("iou", "precision", "recall", "matched_iou", "matched_precision", "matched_recall", "room_iou",
               "room_recall", "pq", "sq", "rq", "ipa_recall", "ipa_precision")


def test_ground_truth_maps_load_with_visual_room_counts(selros_dir):
    counts = {}
    for i in range(1, 31):
        inst = read_instance_png(selros_dir / "ground_truth" / f"{i:02d}_ground_truth.png",
                                 not_room=["#ffffff"])
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


def _preset(name: str, selros_dir) -> ExternalMethod:
    cfg = compose_score([f"external={name}", f"paths.selros_dir={selros_dir}"])
    return instantiate(cfg.external)


@pytest.mark.slow
def test_acceptance_on_the_30_maps(selros_dir):
    params = MetricParams()
    df = pd.concat([_preset("selros", selros_dir).score(params, sanity=True),
                    _preset("vrf", selros_dir).score(params)], ignore_index=True)
    assert len(df) == 30 * 5 and (df["status"] == "ok").all()
    print(summary_table(df).to_markdown(index=False))
    gt = df[df["method"] == "gt_geometry"]
    for k in ROOM_SCORES:
        assert (gt[k] == 1.0).all(), k
    assert (gt["count_error"] == 0).all()
    means = df.groupby("method")[["pq", "matched_iou", "iou"]].mean()
    for k in ("pq", "matched_iou"):
        assert means.loc["one_room", k] < means.loc["VRF", k] < means.loc["SeLRoS", k], k
    # the paper's IoU does not see it: one room (39.5) is within 12 points of VRF
    assert means.loc["one_room", "iou"] > means.loc["VRF", "iou"] - 0.12
    # white slivers: with white read as a colour it becomes one more "room" on every map where
    # it reaches the 0.2 m² colour threshold; by default it is unassigned and no segment
    as_colour = _preset("selros", selros_dir).score(MetricParams(not_room_colours=["#000000"]))
    ours = df[df["method"] == "SeLRoS"].set_index("house_id")
    theirs = as_colour.set_index("house_id")
    extra = theirs["n_pred_segments"] - ours["n_pred_segments"]
    assert ((extra == 1) == (ours["pred_unassigned_px"] >= 500)).all()
    assert (extra >= 1).sum() >= 10 and (ours["pred_unassigned_px"] > 0).all()


def test_free_space_is_the_same_in_all_three(selros_dir):
    """VRF's and SeLRoS's free space are identical; the ground truth's equals them on 29 maps
    and has 74 more pixels on map 25 (measured)."""
    differ = {}
    for i in range(1, 31):
        gt = read_free_space(selros_dir / "ground_truth" / f"{i:02d}_ground_truth.png")
        vrf = read_free_space(selros_dir / "vrf" / f"{i:02d}_segmented.png")
        assert (read_free_space(selros_dir / "selros" / f"{i:02d}_output.png") == vrf).all(), i
        assert not (vrf & ~gt).any(), i
        if (gt != vrf).any():
            differ[i] = int((gt & ~vrf).sum())
    assert differ == {25: 74}


def test_missing_prediction_is_listed_not_dropped(selros_dir, tmp_path):
    for i in (1, 2):
        shutil.copy(selros_dir / "selros" / f"{i:02d}_output.png", tmp_path / f"{i:02d}_output.png")
    m = ExternalMethod("x", 0.02, str(selros_dir / "ground_truth"), pred_dir=str(tmp_path),
                       pred_pattern="{id}_output.png")
    df = m.score(MetricParams())
    assert len(df) == 30
    assert (df["status"] == "ok").sum() == 2
    failed = df[df["status"] == "failed"]
    assert "03_output.png" in failed.loc[failed["house_id"] == "03", "error"].item()
