"""The metrics beside the paper's (matched, room-averaged, PQ, ipa-style, count error, class
IoU) on hand-made maps with every answer worked out by hand in the comments, the rules for
areas and rooms in pieces, and the fast paths against slow references that share no code."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from benchmark.metrics import (
    METRIC_COLUMNS,
    MetricParams,
    area_px,
    score_instances,
    score_semantic,
    segments,
)

P0 = MetricParams(min_segment_m2=0)
R = 1.0  # metres per pixel: areas in m² are pixel counts


def two_rooms():
    """4 x 8 px: room 0 (class 1) columns 0-3, room 1 (class 2) columns 4-7; 16 px each."""
    gt = np.zeros((4, 8), np.int32)
    gt[:, 4:] = 1
    return gt, np.array([1, 2])


def check(s: dict, want: dict) -> None:
    for k, v in want.items():
        assert s[k] == pytest.approx(v), k


def test_every_row_has_every_column():
    gt, cls = two_rooms()
    assert set(METRIC_COLUMNS) <= set(score_semantic(np.where(gt == 0, 1, 2), gt, cls, P0, resolution=R))
    assert set(METRIC_COLUMNS) <= set(score_instances(gt, gt, P0, resolution=R))


def test_perfect():
    gt, cls = two_rooms()
    s = score_semantic(np.where(gt == 0, 1, 2), gt, cls, P0, resolution=R)
    check(s, dict.fromkeys(("iou", "precision", "recall", "matched_iou", "matched_precision", "matched_recall",
                            "room_iou", "room_recall", "pq", "sq", "rq", "pq_semantic", "ipa_recall",
                            "ipa_precision", "accuracy", "class_iou"), 1.0))
    assert s["count_error"] == 0


def test_shifted_boundary():
    gt, cls = two_rooms()
    pred = np.full(gt.shape, 2)
    pred[:, :3] = 1
    s = score_semantic(pred, gt, cls, P0, resolution=R)
    # A1 = columns 0-2 (12 px, all in room 0); A2 = columns 3-7 (20 px: 4 in room 0, 16 in room 1)
    # IoU: A1-R0 12/16 = .75, A2-R0 4/32, A2-R1 16/20 = .8
    # Hungarian: A1-R0, A2-R1 -> (.75 + .8) / (2 + 2 - 2); P (12/12 + 16/20) / 2; R (12/16 + 16/16) / 2
    # PQ: both pairs > .5: SQ .775, RQ 1; classes agree; ipa R (.75 + 1) / 2, ipa P (1 + .8) / 2
    # class IoU: class 1 12/16, class 2 16/20
    check(s, {"matched_iou": 0.775, "matched_precision": 0.9, "matched_recall": 0.875, "room_iou": 0.775,
              "room_recall": 0.875, "pq": 0.775, "sq": 0.775, "rq": 1.0, "pq_semantic": 0.775,
              "ipa_recall": 0.875, "ipa_precision": 0.9, "count_error": 0, "class_iou": 0.775})


def test_two_rooms_merged():
    gt, cls = two_rooms()
    s = score_semantic(np.full(gt.shape, 1), gt, cls, P0, resolution=R)
    # one 32-px segment A: IoU .5 with each room. Paper: .5 / .5 / 1 (rewards the merge).
    # Hungarian: A with one room: .5 / (1 + 2 - 1) = .25; P (16/32) / 1; R (16/16) / 2
    # rooms: each IoU .5, recall 1. PQ: .5 is not > .5 -> no match, PQ = SQ = RQ = 0
    # ipa: R 1, P 16/32; count 1 - 2; class IoU: class 1 16/32, class 2 0 -> .25
    check(s, {"iou": 0.5, "precision": 0.5, "recall": 1.0, "matched_iou": 0.25, "matched_precision": 0.5,
              "matched_recall": 0.5, "room_iou": 0.5, "room_recall": 1.0, "pq": 0.0, "sq": 0.0, "rq": 0.0,
              "pq_semantic": 0.0, "ipa_recall": 1.0, "ipa_precision": 0.5, "count_error": -1, "class_iou": 0.25})


def test_one_room_split():
    gt, cls = two_rooms()
    pred = np.where(gt == 0, 1, 2)
    pred[:2, 4:] = 0  # room 1 in two halves of 8 px: class 0 on top, class 2 below
    s = score_semantic(pred, gt, cls, P0, resolution=R)
    # A0 = room 0 (IoU 1); A1, A2 = halves of room 1 (IoU 8/16 each, precision 1)
    # Hungarian: A0-R0 and one half-R1: (1 + .5) / (3 + 2 - 2); P (1 + 1) / 3; R (1 + .5) / 2
    # rooms: R0 1, R1 .5. PQ: one match (A0-R0, IoU 1), FP 2, FN 1: 1 / (1 + 1 + .5)
    # ipa: R (1 + .5) / 2, P 1. class IoU: class 0 0/8, class 1 1, class 2 8/16 -> 1.5 / 3
    check(s, {"matched_iou": 0.5, "matched_precision": 2 / 3, "matched_recall": 0.75, "room_iou": 0.75,
              "room_recall": 0.75, "pq": 0.4, "sq": 1.0, "rq": 0.4, "pq_semantic": 0.4, "ipa_recall": 0.75,
              "ipa_precision": 1.0, "count_error": 1, "class_iou": 0.5})


def test_empty_prediction():
    gt, cls = two_rooms()
    s = score_semantic(np.full(gt.shape, -1), gt, cls, P0, resolution=R)
    check(s, {k: 0.0 for k in ("iou", "precision", "recall", "matched_iou", "matched_precision", "matched_recall",
                               "room_iou", "room_recall", "pq", "sq", "rq", "pq_semantic", "ipa_recall",
                               "ipa_precision", "accuracy", "class_iou")})
    assert s["count_error"] == -2 and s["n_pred_segments"] == 0


def test_segment_touching_no_room():
    gt = np.full((4, 10), -1, np.int32)
    gt[:, :4], gt[:, 4:8] = 0, 1  # columns 8-9 are not walkable
    pred = gt.copy()
    pred[:, 8:] = 2  # an 8-px segment outside every room
    s = score_instances(pred, gt, P0, resolution=R)
    # paper: (1 + 1 + 0) / 3 each. Hungarian: two exact pairs, the third segment unmatched:
    # 2 / (3 + 2 - 2), P 2 / 3, R 2 / 2. PQ: TP 2, FP 1: 2 / (2 + .5). ipa P (1 + 1 + 0) / 3
    check(s, {"iou": 2 / 3, "precision": 2 / 3, "recall": 2 / 3, "matched_iou": 2 / 3, "matched_precision": 2 / 3,
              "matched_recall": 1.0, "room_iou": 1.0, "room_recall": 1.0, "pq": 0.8, "sq": 1.0, "rq": 0.8,
              "ipa_recall": 1.0, "ipa_precision": 2 / 3, "count_error": 1})
    assert np.isnan(s["accuracy"]) and np.isnan(s["pq_semantic"]) and np.isnan(s["class_iou"])


def test_semantic_pq_needs_the_room_class():
    gt, cls = two_rooms()
    pred = np.where(gt == 0, 1, 0)  # right geometry, room 1 labelled class 0 instead of 2
    s = score_semantic(pred, gt, cls, P0, resolution=R)
    # PQ 1 (geometry exact); semantic: one true match, FP 1, FN 1 -> 1 / (1 + .5 + .5)
    assert s["pq"] == 1.0 and s["pq_semantic"] == pytest.approx(0.5)


def test_ground_truth_rooms_in_pieces():
    """A room in two pieces scored against itself: 100 with the ids rule; the paper's connected
    reading splits it (the 99.05 of the SeLRoS maps)."""
    gt = np.array([[0, 0, 0, 1, 1, 1, 0, 0, 0, 0]], np.int32)  # room 0: 3 + 4 px, room 1: 3 px
    s = score_instances(gt, gt, P0, resolution=R)
    assert all(s[k] == 1.0 for k in ("iou", "precision", "recall", "matched_iou", "room_iou", "pq", "ipa_recall",
                                     "ipa_precision")) and s["count_error"] == 0
    c = score_instances(gt, gt, MetricParams(min_segment_m2=0, instances="connected"), resolution=R)
    # pieces of 3 and 4 px against the 7-px room: IoU 3/7 and 4/7; room 1 exact
    assert c["iou"] == pytest.approx((3 / 7 + 1 + 4 / 7) / 3) and c["n_pred_segments"] == 3


def test_small_rooms_and_segments_left_out_alike():
    gt = np.zeros((4, 8), np.int32)
    gt[0, 7] = 1  # a 1-px room
    params = MetricParams(min_segment_m2=2)
    s = score_instances(gt, gt, params, resolution=R)
    assert s["n_gt_segments"] == 1 and s["n_pred_segments"] == 1 and s["count_error"] == 0
    assert s["matched_iou"] == 1.0 and s["pq"] == 1.0 and s["room_iou"] == 1.0
    # 0.125 m² at 0.5 m/px = .5 px -> 1 px: the 1-px room counts again, and matches itself
    assert score_instances(gt, gt, MetricParams(min_segment_m2=0.125), resolution=0.5)["n_gt_segments"] == 2


def test_area_in_pixels():
    assert area_px(0.125, 0.05) == 50  # today's 50 px on the runner's 0.05 m/px maps, exactly
    assert area_px(0.125, 0.02) == 313  # 312.5 px
    assert area_px(0.2, 0.02) == 500 and area_px(0.2, 0.05) == 80
    assert MetricParams().min_segment_px(0.05) == 50 and MetricParams().min_colour_px(0.02) == 500
    with pytest.raises(ValueError, match="resolution"):
        area_px(0.1, 0)
    with pytest.raises(ValueError, match="min_segment_m2"):
        MetricParams(min_segment_m2=-1)
    with pytest.raises(ValueError, match="rrggbb"):
        MetricParams(not_room_colours=["#12345"])
    assert MetricParams(not_room_colours=["#FFFFFF", [0, 0, 0]]).not_room_colours == ("#ffffff", "#000000")


# ------------------------------------------------------------ fast paths vs slow references


def _flood_reference(labels: np.ndarray, connectivity: int) -> np.ndarray:
    """Breadth-first flood fill in pure Python; ids by value, then by raster order of the
    region's first pixel."""
    h, w = labels.shape
    comp = -np.ones((h, w), int)
    steps = [(0, 1), (1, 0), (0, -1), (-1, 0)] + ([(1, 1), (1, -1), (-1, 1), (-1, -1)] if connectivity == 8 else [])
    regions = []  # (value, first pixel index, region id)
    for r0 in range(h):
        for c0 in range(w):
            if labels[r0, c0] < 0 or comp[r0, c0] >= 0:
                continue
            rid = len(regions)
            regions.append((labels[r0, c0], r0 * w + c0, rid))
            comp[r0, c0] = rid
            queue = [(r0, c0)]
            while queue:
                r, c = queue.pop()
                for dr, dc in steps:
                    rr, cc = r + dr, c + dc
                    if 0 <= rr < h and 0 <= cc < w and comp[rr, cc] < 0 and labels[rr, cc] == labels[r0, c0]:
                        comp[rr, cc] = rid
                        queue.append((rr, cc))
    order = {rid: k for k, (_, _, rid) in enumerate(sorted(regions))}
    return np.vectorize(lambda v: order[v] if v >= 0 else -1)(comp) if regions else comp


@pytest.mark.parametrize("seed", range(6))
def test_segments_equal_flood_fill(seed):
    rng = np.random.default_rng(seed)
    labels = np.kron(rng.integers(-1, 3, (7, 9)), np.ones((2, 2), int))
    labels[rng.random(labels.shape) < 0.08] = -1
    for conn in (4, 8):
        assert segments(labels, conn).tolist() == _flood_reference(labels, conn).tolist()



@pytest.mark.parametrize("seed", range(3))
def test_segments_equal_flood_fill_winding_regions(seed):
    """Combs and U shapes whose provisional regions meet late (union-find merges chains of
    them), several values, both connectivities; 64-bit values beyond int32 order correctly."""
    rng = np.random.default_rng(seed)
    labels = np.full((40, 50), -1, np.int64)
    labels[:, ::2] = rng.integers(0, 2, 25)  # columns of a value ...
    labels[::7, :] = rng.integers(0, 2, (6, 1))  # ... joined by rows
    labels[rng.random(labels.shape) < 0.05] = -1
    labels[labels == 1] = 2**40
    for conn in (4, 8):
        got = segments(labels, conn)
        assert got.dtype == np.int32 and got.tolist() == _flood_reference(labels, conn).tolist()


def _brute_matched_iou(seg: np.ndarray, gt: np.ndarray) -> float:
    """Every one-to-one assignment tried; unmatched (or zero-overlap) items count 0."""
    S, G = range(seg.max() + 1), range(gt.max() + 1)
    iou = {(s, g): np.sum((seg == s) & (gt == g)) / np.sum((seg == s) | (gt == g)) for s in S for g in G}
    best = 0.0, 0
    small, big = (S, G) if len(S) <= len(G) else (G, S)
    for perm in itertools.permutations(big, len(small)):
        pairs = [(a, b) if len(S) <= len(G) else (b, a) for a, b in zip(small, perm)]
        tot, k = sum(iou[p] for p in pairs), sum(iou[p] > 0 for p in pairs)
        if tot > best[0] + 1e-12:
            best = tot, k
    return best[0] / (len(S) + len(G) - best[1])


@pytest.mark.parametrize("seed", range(6))
def test_matched_iou_and_pq_equal_brute_force(seed):
    rng = np.random.default_rng(seed)
    gt = np.kron(rng.integers(0, 4, (4, 4)), np.ones((3, 3), int)).astype(np.int32)
    gt = np.unique(gt, return_inverse=True)[1].reshape(gt.shape).astype(np.int32)
    seg = np.kron(rng.integers(0, 5, (4, 3)), np.ones((3, 4), int))
    seg = np.unique(seg, return_inverse=True)[1].reshape(seg.shape)
    s = score_instances(seg, gt, P0, resolution=R)
    assert s["matched_iou"] == pytest.approx(_brute_matched_iou(seg, gt))
    tp = [np.sum((seg == a) & (gt == b)) / np.sum((seg == a) | (gt == b))
          for a in range(seg.max() + 1) for b in range(gt.max() + 1)]
    tp = [v for v in tp if v > 0.5]
    n, m = seg.max() + 1, gt.max() + 1
    assert s["pq"] == pytest.approx(sum(tp) / (len(tp) + (n - len(tp)) / 2 + (m - len(tp)) / 2))


@pytest.mark.parametrize("seed", range(4))
def test_room_side_scores_equal_a_loop_over_rooms(seed):
    rng = np.random.default_rng(10 + seed)
    gt = np.kron(rng.integers(0, 5, (4, 4)), np.ones((3, 3), int)).astype(np.int32)
    gt = np.unique(gt, return_inverse=True)[1].reshape(gt.shape).astype(np.int32)
    seg = np.kron(rng.integers(-1, 4, (6, 4)), np.ones((2, 3), int))
    s = score_instances(seg, gt, P0, resolution=R)
    room_iou, room_rec, ipa_rec = [], [], []
    for b in range(gt.max() + 1):
        B = gt == b
        best_iou, best_rec, best_ov = 0.0, 0.0, 0.0
        for a in np.unique(seg[seg >= 0]):
            A = seg == a
            iou = np.sum(A & B) / np.sum(A | B)
            if iou > best_iou:
                best_iou, best_rec = iou, np.sum(A & B) / np.sum(B)
            best_ov = max(best_ov, np.sum(A & B) / np.sum(B))
        room_iou.append(best_iou)
        room_rec.append(best_rec)
        ipa_rec.append(best_ov)
    ipa_prec = [max(np.sum((seg == a) & (gt == b)) for b in range(gt.max() + 1)) / np.sum(seg == a)
                for a in np.unique(seg[seg >= 0])]
    assert s["room_iou"] == pytest.approx(np.mean(room_iou)) and s["room_recall"] == pytest.approx(np.mean(room_rec))
    assert s["ipa_recall"] == pytest.approx(np.mean(ipa_rec)) and s["ipa_precision"] == pytest.approx(np.mean(ipa_prec))
