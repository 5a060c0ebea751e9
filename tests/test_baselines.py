"""Baselines: external-output scoring on hand-made maps with known scores, the SeLRoS release,
geometric segmenters on hand-made maps (known answer) and on the shared maps, and matching
maps to houses (FFT placement checked against a brute-force search)."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from PIL import Image

from benchmark.baselines.external import (
    ExternalMethod,
    Pair,
    onto_grid,
    pairs_by_pattern,
    pairs_from_manifest,
    score_directory,
    score_pairs,
    summary_table,
)
from benchmark.metrics import MetricParams, score_instances
from benchmark.segmenters.distance import DistanceTransform
from benchmark.segmenters.morphological import Morphological
from benchmark.segmenters.voronoi import Voronoi
from envs.maps.gridmap import GridMap

RED, GREEN, BLUE, YELLOW = (200, 30, 30), (30, 200, 30), (30, 30, 200), (220, 220, 0)


def _png(path, ids: np.ndarray, colours) -> None:
    rgb = np.zeros(ids.shape + (3,), np.uint8)
    for i, c in enumerate(colours):
        rgb[ids == i] = c
    Image.fromarray(rgb).save(path)


def two_rooms_gt() -> np.ndarray:
    """40 x 60 px: room 0 = columns 0-29, room 1 = columns 30-59 (1200 px each)."""
    gt = np.zeros((40, 60), np.int32)
    gt[:, 30:] = 1
    return gt


def known_prediction() -> np.ndarray:
    """Segment 0 = columns 0-19 (800 px, inside room 0); segment 1 = columns 20-59 (1600 px).

    By hand: segment 0 -> room 0: IoU 800/1200, precision 1, recall 800/1200;
    segment 1 -> room 1 (IoU 1200/1600 beats 400/2400): IoU 3/4, precision 3/4, recall 1.
    Means: IoU 17/24, precision 7/8, recall 5/6."""
    pred = np.zeros((40, 60), np.int32)
    pred[:, 20:] = 1
    return pred


KNOWN = {"iou": 17 / 24, "precision": 7 / 8, "recall": 5 / 6}


@pytest.fixture
def handmade(tmp_path):
    """gt/: maps a, b, c; pred/: a (known scores), b (perfect), z (no ground truth); c missing."""
    gt_dir, pred_dir = tmp_path / "gt", tmp_path / "pred"
    gt_dir.mkdir()
    pred_dir.mkdir()
    for mid in "abc":
        _png(gt_dir / f"{mid}_gt.png", two_rooms_gt(), [RED, GREEN])
    _png(pred_dir / "a_out.png", known_prediction(), [BLUE, YELLOW])
    _png(pred_dir / "b_out.png", two_rooms_gt(), [YELLOW, RED])  # colours need not match
    _png(pred_dir / "z_out.png", two_rooms_gt(), [YELLOW, RED])
    return gt_dir, pred_dir


def test_external_scores_on_handmade_maps(handmade):
    gt_dir, pred_dir = handmade
    df = score_directory(gt_dir, "{id}_gt.png", pred_dir, "{id}_out.png", "X", MetricParams(min_segment_m2=0),
                         resolution=0.05)
    assert list(df["house_id"]) == ["a", "b", "c"]
    a, b, c = (df.iloc[i] for i in range(3))
    for k, v in KNOWN.items():
        assert a[k] == pytest.approx(v)
        assert b[k] == pytest.approx(1.0)
    assert a["n_pred_segments"] == 2 and a["n_gt_segments"] == 2 and np.isnan(a["accuracy"])
    assert c["status"] == "failed" and "c_out.png" in c["error"] and np.isnan(c["iou"])
    assert df.attrs["unpaired"] == [str(pred_dir / "z_out.png")]
    table = summary_table(df).iloc[0]
    assert table["maps"] == 2 and table["failed"] == 1
    # two maps: the mean, and the bootstrap interval of a mean of two is [lower, higher]
    assert table["iou"] == f"{100 * (17 / 24 + 1) / 2:.2f} [{100 * 17 / 24:.2f}, 100.00]"


def test_manifest_label_png_and_resolution(handmade, tmp_path):
    from envs.maps.label_png import write_label_png

    gt_dir, pred_dir = handmade
    # a label PNG: segments are connected regions of one class -> same scores as the instance map
    write_label_png(tmp_path / "a_labels.png", known_prediction(), ["kitchen", "bedroom"], legend=False)
    # half the resolution (0.1 m/px vs 0.05): 20 x 30 px scaled x2 onto the ground-truth grid
    _png(tmp_path / "a_coarse.png", known_prediction()[::2, ::2], [BLUE, YELLOW])
    (tmp_path / "m.csv").write_text(f"id,ground_truth,prediction\na,{gt_dir / 'a_gt.png'},a_labels.png\n"
                                    f"c,{gt_dir / 'c_gt.png'},\n")
    pairs = pairs_from_manifest(tmp_path / "m.csv")
    assert pairs == [Pair("a", gt_dir / "a_gt.png", tmp_path / "a_labels.png"), Pair("c", gt_dir / "c_gt.png", None)]
    params = MetricParams(min_segment_m2=0)
    df = score_pairs(pairs, "L", params, pred_format="label", resolution=0.05)
    assert df.iloc[0]["iou"] == pytest.approx(KNOWN["iou"]) and df.iloc[1]["status"] == "failed"
    # 200-px rooms at 0.1 m/px = 2 m², above the 0.2 m² colour threshold (20 px there)
    coarse = score_pairs([Pair("a", gt_dir / "a_gt.png", tmp_path / "a_coarse.png")], "C", params,
                         resolution=0.05, pred_resolution=0.1)
    assert coarse.iloc[0]["iou"] == pytest.approx(KNOWN["iou"])
    # scaling about the top-left corner: a 0.1 m/px map half as wide covers the left half only
    half = onto_grid(np.zeros((20, 15), np.int32), (40, 60), 0.05, 0.1)
    assert (half[:, :30] == 0).all() and (half[:, 30:] == -1).all()
    with pytest.raises(ValueError, match="columns"):
        (tmp_path / "bad.csv").write_text("id,gt\na,b\n")
        pairs_from_manifest(tmp_path / "bad.csv")
    with pytest.raises(ValueError, match="format"):
        score_pairs(pairs, "L", params, pred_format="jpeg", resolution=0.05)
    with pytest.raises(ValueError, match="resolution"):
        score_pairs(pairs, "L", params, resolution=None)
    with pytest.raises(FileNotFoundError, match="prediction folder"):
        pairs_by_pattern(gt_dir, "{id}_gt.png", tmp_path / "nowhere", "{id}.png")
    with pytest.raises(ValueError, match="{id}"):
        pairs_by_pattern(gt_dir, "gt.png", pred_dir, "{id}.png")


def _score_app(overrides: list[str]) -> int:
    """The score app's body on a config composed like ``python -m ...baselines_score``."""
    from benchmark.commands.baselines_score import run
    from benchmark.commands.selros import compose_score

    out = [o for o in overrides if o.startswith("out=")]
    cfg = compose_score([o for o in overrides if not o.startswith("out=")])
    return run(cfg, Path(out[0][4:]) if out else None)


def test_score_app_without_preset_lists_missing(handmade, tmp_path, capsys):
    gt_dir, pred_dir = handmade
    out = tmp_path / "out"
    args = ["external=rose2", f"external.gt_dir={gt_dir}", f"external.pred_dir={pred_dir}",
            "external.gt_pattern='{id}_gt.png'", "external.pred_pattern='{id}_out.png'", "external.method=Hand",
            "external.resolution=0.05", "metrics.min_segment_m2=0", f"out={out}"]
    assert _score_app(args) == 1  # c has no prediction
    df = pd.read_csv(out / "metrics.csv")
    assert len(df) == 3 + 3 * 3  # + one_room, gt_geometry, grid on each ground truth
    assert df.loc[(df["house_id"] == "a") & (df["method"] == "Hand"), "iou"].item() == pytest.approx(KNOWN["iou"])
    # one_room on two equal rooms: IoU 1/2 (paper), matched 1/2 / (1 + 2 - 1), PQ 0
    one = df[(df["method"] == "one_room")].iloc[0]
    assert (one["iou"], one["matched_iou"], one["pq"]) == (0.5, 0.25, 0.0)
    assert (df.loc[df["method"] == "gt_geometry", "pq"] == 1.0).all()
    # the reader's counts: two colours became rooms, nothing anti-aliased or unassigned
    a = df[(df["house_id"] == "a") & (df["method"] == "Hand")].iloc[0]
    assert (a["pred_rooms"], a["gt_rooms"], a["pred_antialias_px"], a["pred_unassigned_px"]) == (2, 2, 0, 0)
    text = (out / "table5.md").read_text()
    assert "Failed or missing maps (1)" in text and "c_out.png" in text and "z_out.png" in text
    assert "c_out.png" in capsys.readouterr().out
    assert _score_app(["external=rose2", "external.pred_dir=null"]) == 2  # no prediction folder: one line
    assert "pred_dir" in capsys.readouterr().err


def test_white_is_unassigned_and_counted(tmp_path):
    gt = two_rooms_gt()
    _png(tmp_path / "a_gt.png", gt, [RED, GREEN])
    pred = gt.copy()
    pred[0, :] = 2  # a 60-px white line along the top edge
    _png(tmp_path / "a_out.png", pred, [BLUE, YELLOW, (255, 255, 255)])
    m = ExternalMethod("W", 0.05, str(tmp_path), "{id}_gt.png", str(tmp_path), "{id}_out.png")
    row = m.score(MetricParams(min_segment_m2=0, min_colour_m2=0.1)).iloc[0]  # 0.1 m² = 40 px
    # white is no room: 2 segments of 39 x 30 px, each inside its room: precision 1, recall 39/40
    assert (row["pred_rooms"], row["pred_unassigned_px"], row["n_pred_segments"]) == (2, 60, 2)
    assert row["precision"] == 1.0 and row["recall"] == pytest.approx(39 / 40)
    row = m.score(MetricParams(min_segment_m2=0, min_colour_m2=0.1, not_room_colours=["#000000"])).iloc[0]
    assert (row["pred_rooms"], row["n_pred_segments"]) == (3, 3)  # white read as a room
    row = m.score(MetricParams(min_segment_m2=0, min_colour_m2=0.2, not_room_colours=["#000000"])).iloc[0]
    # 0.2 m² = 80 px: the 60 white pixels are anti-aliasing and join the room below them
    assert (row["pred_rooms"], row["pred_antialias_px"], row["iou"]) == (2, 60, 1.0)


def test_presets_are_hydra_configs_over_30_maps(selros_dir, tmp_path):
    from hydra.utils import instantiate

    from benchmark.commands.selros import compose_score

    for preset, method in (("selros", "SeLRoS"), ("vrf", "VRF")):
        cfg = compose_score([f"external={preset}", f"paths.selros_dir={selros_dir}"])
        assert cfg.external._target_ == "benchmark.baselines.external.ExternalMethod"
        m = instantiate(cfg.external)
        assert m.method == method and m.resolution == 0.02
        assert [p.map_id for p in m.pairs()] == [f"{i:02d}" for i in range(1, 31)]


@pytest.mark.slow
def test_table5_cli_on_a_partial_copy(selros_dir, tmp_path, capsys):
    """The table5 command on three SeLRoS maps renamed office_*, one VRF output removed: every
    method and sanity row, ids kept whole, the gap listed."""
    from benchmark.commands.baselines import main

    for sub, pattern in (("ground_truth", "{}_ground_truth.png"), ("selros", "{}_output.png"),
                         ("vrf", "{}_segmented.png")):
        (tmp_path / "data" / sub).mkdir(parents=True)
        for mid, new in (("01", "office_a"), ("05", "office_b"), ("22", "office_c")):
            if not (sub == "vrf" and mid == "05"):
                shutil.copy(selros_dir / sub / pattern.format(mid), tmp_path / "data" / sub / pattern.format(new))
    assert main(["table5", "--data", str(tmp_path / "data"), "--out", str(tmp_path / "out"),
                 "--resolution", "0.02", "metrics.connectivity=8"]) == 0
    df = pd.read_csv(tmp_path / "out" / "metrics.csv", dtype={"house_id": str})
    assert set(df["method"]) == {"SeLRoS", "VRF", "morphological", "distance", "voronoi", "one_room",
                                 "gt_geometry", "grid"}
    assert set(df["house_id"]) == {"office_a", "office_b", "office_c"}
    assert len(df) == 24 and (df["status"] != "ok").sum() == 4  # VRF and the geometric rows of office_b
    bad = df.loc[df["status"] != "ok"]
    assert sorted(bad["method"]) == ["VRF", "distance", "morphological", "voronoi"]
    assert (bad["house_id"] == "office_b").all()
    geo = df[df["method"].isin(["morphological", "distance", "voronoi"]) & (df["status"] == "ok")]
    assert geo["accuracy"].isna().all() and geo["iou"].between(0, 1).all()
    assert "office_b_segmented.png" in (tmp_path / "out" / "table5.md").read_text()
    assert "8-connected" in df["metric_params"].iloc[0]
    # table5.html, written with the set: the same table, and per map (all 3: fewer than --page-maps) the
    # ground truth and every method that scored it, drawn as segments
    import base64
    import io
    import re

    from PIL import Image

    from benchmark.baselines.external import read_gt
    from benchmark.metrics import MetricParams
    from benchmark.reports.html_report import INSTANCE_COLORS, PAGE_BORDER_COLOR

    page = (tmp_path / "out" / "table5.html").read_text()
    assert page.count("<tr>") == 1 + 8 + 1 + 4  # the table (header + methods) and the failures (header + 4)
    assert '<td class="num" data-v="100.00">100.00 [100.00, 100.00]</td>' in page  # gt_geometry
    sections = re.findall(r'<section class="house" id="map-([^"]+)">(.*?)</section>', page, re.S)
    assert [m for m, _ in sections] == ["office_a", "office_b", "office_c"]
    captions = dict((m, re.findall(r"<figcaption>([^<]+)</figcaption>", body)) for m, body in sections)
    assert len(captions["office_a"]) == 1 + 8 and captions["office_b"] == ["ground truth", "SeLRoS", "one_room",
                                                                            "gt_geometry", "grid"]
    img = re.search(r'src="data:image/png;base64,([^"]+)"', sections[0][1]).group(1)
    gt_rgb = np.asarray(Image.open(io.BytesIO(base64.b64decode(img))))[..., :3]
    gt, _ = read_gt(tmp_path / "data" / "ground_truth" / "office_a_ground_truth.png", "instance",
                    MetricParams(connectivity=8), 0.02)
    assert ((gt_rgb == 0).all(-1) == (gt < 0)).all()  # black exactly where no room
    colours = {tuple(c) for c in gt_rgb.reshape(-1, 3)} - {(0, 0, 0), PAGE_BORDER_COLOR}
    assert colours <= set(INSTANCE_COLORS) and len(colours) >= 3
    assert main(["table5", "--data", str(tmp_path / "data"), "--bogus"]) == 2
    # an output folder that cannot be made: one line naming it, exit 2
    (tmp_path / "a_file").write_text("")
    capsys.readouterr()
    assert main(["table5", "--data", str(tmp_path / "data"), "--out", str(tmp_path / "a_file" / "out"),
                 "--no-geometric", "--no-sanity"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("error: cannot write") and "a_file" in err


# ---------------------------------------------------------------- geometric segmenters


def rooms_and_corridor(margin: int = 2, scale: int = 1):
    """Two 3 x 3 m rooms left and right of a 1.5 m corridor, each joined to it by a 0.8 m door
    (0.05 m/px, or 0.05 / scale). ``margin`` px of obstacle around the map (0: rooms touch the edge)."""
    walk = np.zeros((60, 150), bool)
    gt = np.full(walk.shape, -1, np.int32)
    walk[:, 0:60] = True
    gt[:, 0:60] = 0
    walk[:, 62:92] = True
    gt[:, 62:92] = 1
    walk[:, 94:150] = True
    gt[:, 94:150] = 2
    walk[22:38, 60:62] = True  # doors, 16 px = 0.8 m, belong to the corridor
    gt[22:38, 60:62] = 1
    walk[22:38, 92:94] = True
    gt[22:38, 92:94] = 1
    walk, gt = np.pad(walk, margin), np.pad(gt, margin, constant_values=-1)
    walk, gt = np.kron(walk, np.ones((scale, scale), bool)), np.kron(gt, np.ones((scale, scale), np.int32))
    return GridMap(walk, 0.05 / scale, (0.0, walk.shape[0] * 0.05 / scale)), gt


SEGMENTERS = [Morphological(), DistanceTransform(), Voronoi()]


@pytest.mark.parametrize("seg", SEGMENTERS, ids=lambda s: type(s).__name__)
@pytest.mark.parametrize("margin,scale", [(2, 1), (0, 1), (2, 2)])
def test_split_at_the_doors(seg, margin, scale):
    grid, gt = rooms_and_corridor(margin, scale)
    inst = seg(grid)
    assert inst.dtype == np.int32
    assert (inst[grid.walkable] >= 0).all() and (inst[~grid.walkable] == -1).all()
    assert inst.max() + 1 == 3
    s = score_instances(inst, gt, MetricParams(min_segment_m2=0), resolution=grid.resolution)
    assert s["iou"] > 0.9 and np.isnan(s["accuracy"])
    for room in range(3):  # each room is (nearly all) one segment, and a different one
        vals, counts = np.unique(inst[gt == room], return_counts=True)
        assert counts.max() / counts.sum() > 0.9
    assert len({np.bincount(inst[gt == r]).argmax() for r in range(3)}) == 3


def test_voronoi_critical_lines_span_the_doors():
    grid, _ = rooms_and_corridor()
    seg = Voronoi()
    pts = seg.critical_points(grid)
    assert len(pts) == 2
    assert sorted(np.round(pts[:, 1]).astype(int).tolist()) in ([62, 94], [62, 95], [63, 94], [63, 95])
    assert (np.abs(pts[:, 0] - 31.5) <= 1).all() and (np.abs(pts[:, 2] - 8.5) <= 1).all()
    for b1, p, b2 in seg.critical_lines(grid):
        # the basis points are the door jambs: obstacle pixels just above and below the door
        assert sorted([b1[0], b2[0]]) == [23, 40] and abs(b1[1] - p[1]) <= 1 and abs(b2[1] - p[1]) <= 1
        assert not grid.walkable[b1] and not grid.walkable[b2]


def test_room_area_limits_are_square_metres():
    """Known answers in square metres (0.05 m/px map; the same at 0.025 m/px)."""
    for scale in (1, 2):
        grid, gt = rooms_and_corridor(scale=scale)
        # min_room_area limits whole rooms: the 4.5 m^2 corridor (with its doors) is below 5 m^2 and
        # merges into a room; DistanceTransform's min_seed_area limits seeds (the free space above a
        # distance threshold): the 0.8 m doors part at thresholds >= 0.4 m, where the room seeds have
        # (3 - 2t)^2 >= 3 m^2 up to t = 0.63 m but the corridor seed has at most
        # (1.5 - 0.8)(3 - 0.8) = 1.54 m^2
        for seg in (Voronoi(min_room_area=5.0), DistanceTransform(min_seed_area=3.0),
                    Morphological(min_room_area=5.0)):
            inst = seg(grid)
            assert inst.max() + 1 == 2, type(seg).__name__
            assert np.bincount(inst[gt == 0]).argmax() != np.bincount(inst[gt == 2]).argmax()
        assert DistanceTransform(min_seed_area=1.5)(grid).max() + 1 == 3
        # no seed can reach 10 m^2: one segment per walkable component
        assert DistanceTransform(min_seed_area=10.0)(grid).max() == 0


def test_bad_input():
    with pytest.raises(ValueError, match="walkable"):
        Morphological()(GridMap(np.zeros((5, 5), bool), 0.05, (0, 0)))
    grid, _ = rooms_and_corridor()
    with pytest.raises(ValueError, match="area limits"):
        DistanceTransform(min_seed_area=5, max_area=1)(grid)
    with pytest.raises(ValueError, match="min_room_area is -1"):
        Voronoi(min_room_area=-1)
    with pytest.raises(ValueError, match="max_door"):
        Voronoi(max_door=0)


@pytest.mark.slow
def test_geometric_on_shared_maps(shared_scenes, selros_dir):
    from envs.maps.label_png import read_instance_png

    maps = [(s.grid, s.instances) for s in shared_scenes[:4]]
    for mid in ("01", "12", "27"):
        gt = read_instance_png(selros_dir / "ground_truth" / f"{mid}_ground_truth.png")
        maps.append((GridMap(gt >= 0, 0.02, (0.0, 0.0)), gt))
    for grid, gt in maps:
        for seg in SEGMENTERS:
            inst = seg(grid)
            assert inst.shape == grid.shape and (inst[grid.walkable] >= 0).all() and (inst[~grid.walkable] == -1).all()
            s = score_instances(inst, gt, resolution=grid.resolution)
            assert 0 < s["iou"] <= 1 and s["n_pred_segments"] >= 1


# ---------------------------------------------------------------- matching maps to houses


def _brute_force_overlap(a: np.ndarray, b: np.ndarray) -> float:
    """Largest IoU of ``b`` over 8 rotations/flips and every shift, by direct counting."""
    best = 0.0
    for t in range(8):
        bb = np.rot90(np.fliplr(b) if t >= 4 else b, t % 4)
        for dr in range(-bb.shape[0] + 1, a.shape[0]):
            for dc in range(-bb.shape[1] + 1, a.shape[1]):
                canvas = np.zeros((a.shape[0] + 2 * bb.shape[0], a.shape[1] + 2 * bb.shape[1]), bool)
                canvas[bb.shape[0] + dr: 2 * bb.shape[0] + dr, bb.shape[1] + dc: 2 * bb.shape[1] + dc] = bb
                placed = canvas[bb.shape[0]: bb.shape[0] + a.shape[0], bb.shape[1]: bb.shape[1] + a.shape[1]]
                inter = np.count_nonzero(placed & a)
                best = max(best, inter / (a.sum() + bb.sum() - inter))
    return best


def test_best_overlap_matches_brute_force():
    from benchmark.baselines.match import best_overlap, downsample_mask

    rng = np.random.default_rng(0)
    for _ in range(4):
        a = rng.random((9, 7)) < 0.5
        b = rng.random((5, 6)) < 0.6
        iou, t, (dr, dc) = best_overlap(a, b)
        assert iou == pytest.approx(_brute_force_overlap(a, b), abs=1e-5)
    # an exact copy, rotated and shifted, is found with IoU 1 and the inverse transform
    a = np.zeros((12, 14), bool)
    a[2:9, 3:7] = True
    a[5:9, 7:12] = True
    iou, t, (dr, dc) = best_overlap(a, np.rot90(a[2:9, 3:12], -1))
    assert iou == pytest.approx(1.0) and (dr, dc) == (2, 3)
    assert downsample_mask(np.kron(a, np.ones((5, 5), bool)), 5).tolist() == a.tolist()


def test_match_finds_the_house_behind_a_rotated_map(shared_houses):
    from benchmark.baselines.match import match_maps
    from envs.maps.scene import rasterise_house

    houses = shared_houses[:6]
    target = rasterise_house(houses[4], resolution=0.02).grid.walkable
    maps = {"rotated": np.rot90(np.pad(target, ((7, 0), (0, 13))), 1)}
    (row,) = match_maps(maps, 0.02, houses)
    assert row["best_house"] == houses[4].id
    assert row["iou"] > 0.85 and row["iou"] > row["second_iou"] + 0.1


def test_carry_house_ground_truth_onto_a_matched_map(shared_houses):
    """A 0.02 m/px map made from a house (turned, flipped, padded) is matched, and the house's
    own 0.1 m/px room instances carried onto it agree with the map's ground truth."""
    from benchmark.baselines.match import carry_to_map, match_maps
    from envs.maps.scene import rasterise_house

    house = shared_houses[7]
    fine = rasterise_house(house, resolution=0.02)

    def as_map(a, pad):
        return np.rot90(np.fliplr(np.pad(a, ((11, 0), (0, 4)), constant_values=pad)), 3)

    walk, gt = as_map(fine.grid.walkable, False), as_map(fine.instances, -1)
    (row,) = match_maps({"m": walk}, 0.02, shared_houses[5:9])
    assert row["best_house"] == house.id and row["matched"]
    coarse = rasterise_house(house, resolution=0.1).instances
    carried = carry_to_map(coarse, row["transform"], row["shift"], walk.shape, 5)
    assert carried.shape == walk.shape
    inside = gt >= 0
    assert np.mean(carried[inside] == gt[inside]) > 0.9
    assert score_instances(np.where(inside, carried, -1), gt, resolution=0.02)["iou"] > 0.85


def test_match_cli_reports_the_house(procthor_file, shared_houses, tmp_path, capsys):
    from benchmark.commands.baselines import main
    from envs.maps.scene import rasterise_house

    scene = rasterise_house(shared_houses[3], resolution=0.02)
    inst = np.rot90(scene.instances, 2)
    rng = np.random.default_rng(1)
    _png(tmp_path / "07_ground_truth.png", inst, [tuple(rng.integers(40, 255, 3)) for _ in range(inst.max() + 1)])
    out = tmp_path / "matches.csv"
    assert main(["match", "--houses", str(procthor_file), "--maps", str(tmp_path), "--limit", "5",
                 "--out", str(out)]) == 0
    df = pd.read_csv(out, dtype={"map": str})
    assert df["map"].tolist() == ["07"] and df["best_house"].item() == shared_houses[3].id
    assert df["matched"].item() and df["iou"].item() > 0.9
    assert "1 of 1 maps matched" in capsys.readouterr().out
    assert main(["match", "--houses", str(procthor_file), "--maps", str(tmp_path / "none")]) == 2


# ---------------------------------------------------------------- sanity rows


def test_sanity_segmenters_by_hand():
    from benchmark.segmenters.sanity import Grid, GroundTruthGeometry, OneRoom

    walk = np.ones((7, 13), bool)
    walk[:, 12] = False  # 3.5 m x 6.5 m at 0.5 m/px, the last column blocked
    grid = GridMap(walk, 0.5, (0.0, 0.0))
    assert (OneRoom()(grid) == np.where(walk, 0, -1)).all()
    # 3 m squares: rows 0-5 | 6 and columns 0-5 | 6-11 (| 12 blocked) -> 4 squares in raster order
    want = np.full(walk.shape, -1)
    want[:6, :6], want[:6, 6:12], want[6:, :6], want[6:, 6:12] = 0, 1, 2, 3
    assert (Grid(3.0)(grid) == want).all()
    with pytest.raises(ValueError, match="size"):
        Grid(0)
    inst = np.where(walk, np.arange(13)[None, :] // 4, -1).astype(np.int32)
    scene = type("Scene", (), {"instances": inst})()
    assert (GroundTruthGeometry()(grid, scene=scene) == inst).all()
    with pytest.raises(ValueError, match="needs the scene"):
        GroundTruthGeometry()(grid)


def test_sanity_rows_through_the_runner(tmp_path):
    """segmenter=gt_geometry gets the scene and scores 100 on every metric; one_room scores the
    biggest room's share on the paper's IoU but 0 PQ on the generated houses."""
    from hydra import compose, initialize_config_dir

    from benchmark.harness.runner import CONF_DIR, run

    rows = {}
    for seg in ("gt_geometry", "one_room"):
        with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
            cfg = compose("config", overrides=[f"segmenter={seg}", "env=synthetic", "run.limit=2",
                                               f"run.results_dir={tmp_path}", "run.progress=false"])
        rows[seg] = run(cfg, tmp_path / seg)
    gt, one = rows["gt_geometry"], rows["one_room"]
    for k in ("iou", "precision", "recall", "matched_iou", "room_iou", "pq", "ipa_recall", "ipa_precision"):
        assert (gt[k] == 1.0).all(), k
    assert (gt["count_error"] == 0).all() and (one["n_pred_segments"] == 1).all()
    assert (one["pq"] == 0).all() and (one["recall"] == 1.0).all() and (one["iou"] < 0.5).all()
