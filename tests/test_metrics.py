"""Metrics on hand-made maps with answers computed by hand, and against a slow reference."""

import numpy as np
import pytest

from benchmark.metrics import (
    MetricParams,
    describe,
    resample_nearest,
    score_instances,
    score_semantic,
    segments,
)

P0 = MetricParams(min_segment_m2=0)


def two_rooms():
    """A 4 x 8 map: room 0 (class 1) in columns 0-3, room 1 (class 2) in columns 4-7."""
    gt = np.zeros((4, 8), np.int32)
    gt[:, 4:] = 1
    return gt, np.array([1, 2])


def test_perfect_prediction():
    gt, cls = two_rooms()
    pred = np.where(gt == 0, 1, 2)
    s = score_semantic(pred, gt, cls, P0, resolution=1.0)
    assert (s["iou"], s["precision"], s["recall"], s["accuracy"]) == (1.0, 1.0, 1.0, 1.0)
    assert s["n_pred_segments"] == 2 and s["n_gt_segments"] == 2


def test_shifted_boundary():
    gt, cls = two_rooms()
    pred = np.full(gt.shape, 2)
    pred[:, :3] = 1  # boundary one column too far left
    s = score_semantic(pred, gt, cls, P0, resolution=1.0)
    # A1 = 12 px inside room 0 (16 px): IoU 12/16, P 1, R 12/16
    # A2 = 20 px, overlaps room 1 (16) by 16: IoU 16/20, P 16/20, R 1
    assert s["iou"] == pytest.approx((12 / 16 + 16 / 20) / 2)
    assert s["precision"] == pytest.approx((1 + 16 / 20) / 2)
    assert s["recall"] == pytest.approx((12 / 16 + 1) / 2)
    assert s["accuracy"] == pytest.approx(28 / 32)


def test_merged_rooms():
    gt, cls = two_rooms()
    pred = np.full(gt.shape, 1)
    s = score_semantic(pred, gt, cls, P0, resolution=1.0)
    # one segment of 32 px; best match room 0 (IoU 16/32, tie broken to the lower id)
    assert s["n_pred_segments"] == 1
    assert (s["iou"], s["precision"], s["recall"]) == (0.5, 0.5, 1.0)
    assert s["accuracy"] == 0.5


def test_split_room():
    gt, cls = two_rooms()
    pred = np.where(gt == 0, 1, 2)
    pred[:2, 4:] = 0  # room 1 split into two label regions (class 0 and class 2)
    s = score_semantic(pred, gt, cls, P0, resolution=1.0)
    # segments: room 0 exact (1,1,1); two halves of room 1, each IoU 8/16, P 1, R 8/16
    assert s["n_pred_segments"] == 3
    assert s["iou"] == pytest.approx((1 + 0.5 + 0.5) / 3)
    assert s["precision"] == pytest.approx(1.0)
    assert s["recall"] == pytest.approx((1 + 0.5 + 0.5) / 3)
    assert s["accuracy"] == pytest.approx(24 / 32)


def test_empty_prediction():
    gt, cls = two_rooms()
    s = score_semantic(np.full(gt.shape, -1), gt, cls, P0, resolution=1.0)
    assert (s["iou"], s["precision"], s["recall"], s["accuracy"], s["n_pred_segments"]) == (0, 0, 0, 0, 0)


def test_min_segment_and_connectivity():
    gt, cls = two_rooms()
    pred = np.where(gt == 0, 1, 2)
    pred[0, 0] = 2  # a 1-px island of class 2 in room 0
    assert score_semantic(pred, gt, cls, MetricParams(min_segment_m2=0), resolution=1.0)["n_pred_segments"] == 3
    assert score_semantic(pred, gt, cls, MetricParams(min_segment_m2=2), resolution=1.0)["n_pred_segments"] == 2
    diag = np.full((3, 3), -1)
    diag[0, 0] = diag[1, 1] = 0
    g = np.zeros((3, 3), np.int32)
    assert score_instances(diag, g, MetricParams(connectivity=4, min_segment_m2=0, instances="connected"), resolution=1.0)["n_pred_segments"] == 2
    assert score_instances(diag, g, MetricParams(connectivity=8, min_segment_m2=0, instances="connected"), resolution=1.0)["n_pred_segments"] == 1


def test_overlap_matching_differs_from_iou():
    gt = np.zeros((1, 10), np.int32)
    gt[0, 6:] = 1  # room 0: 6 px, room 1: 4 px
    pred = np.full((1, 10), -1)
    pred[0, 3:10] = 0  # 7 px: overlap 3 with room 0 (IoU 3/10), 4 with room 1 (IoU 4/7)
    a = score_instances(pred, gt, MetricParams(match="iou", min_segment_m2=0), resolution=1.0)
    b = score_instances(pred, gt, MetricParams(match="overlap", min_segment_m2=0), resolution=1.0)
    assert a["iou"] == pytest.approx(4 / 7) and b["iou"] == pytest.approx(4 / 7)
    pred[0, 0:10] = 0  # 10 px: overlap 6 with room 0 (IoU .6), 4 with room 1 (IoU .4)
    assert score_instances(pred, gt, MetricParams(match="overlap", min_segment_m2=0), resolution=1.0)["recall"] == 1.0
    assert np.isnan(a["accuracy"])


def _reference(pred_seg, gt, min_px, match):
    """One segment at a time, with Python sets: the obviously correct version."""
    ious, ps, rs = [], [], []
    for s in range(pred_seg.max() + 1):
        a = set(zip(*np.nonzero(pred_seg == s)))
        if len(a) < max(min_px, 1):
            continue
        best = None
        for g in range(gt.max() + 1):
            b = set(zip(*np.nonzero(gt == g)))
            inter = len(a & b)
            key = inter / len(a | b) if match == "iou" else inter
            if best is None or key > best[0]:
                best = (key, inter, len(a | b), len(b))
        _, inter, uni, nb = best
        ious.append(inter / uni)
        ps.append(inter / len(a))
        rs.append(inter / nb)
    return (np.mean(ious), np.mean(ps), np.mean(rs)) if ious else (0.0, 0.0, 0.0)


@pytest.mark.parametrize("seed", range(8))
def test_fast_equals_reference_on_random_maps(seed):
    from benchmark.metrics import segments

    rng = np.random.default_rng(seed)
    gt = rng.integers(0, 4, (12, 14)).astype(np.int32)
    gt = np.repeat(np.repeat(gt[:6, :7], 2, 0), 2, 1)
    gt[rng.random(gt.shape) < 0.1] = -1
    gt[gt >= 0] = np.unique(gt[gt >= 0], return_inverse=True)[1]
    pred = rng.integers(-1, 3, gt.shape)
    for match in ("iou", "overlap"):
        for min_px in (0, 3):
            params = MetricParams(match=match, min_segment_m2=min_px, connectivity=4, instances="connected")
            got = score_instances(pred, gt, params, resolution=1.0)
            ref = _reference(segments(pred, 4), gt, min_px, match)
            assert (got["iou"], got["precision"], got["recall"]) == pytest.approx(ref)


def test_per_class_iou():
    gt, cls = two_rooms()
    pred = np.full(gt.shape, 2)
    pred[:, :3] = 1
    s = score_semantic(pred, gt, cls, P0, classes=["a", "b", "c"], resolution=1.0)
    assert s["iou_b"] == pytest.approx(12 / 16) and s["iou_c"] == pytest.approx(16 / 20)
    assert np.isnan(s["iou_a"])


def test_bad_inputs():
    gt, cls = two_rooms()
    with pytest.raises(ValueError, match="prediction shape"):
        score_semantic(np.zeros((3, 3)), gt, cls, resolution=1.0)
    with pytest.raises(ValueError, match="no room pixel"):
        score_semantic(np.zeros((4, 8)), np.full((4, 8), -1), cls, resolution=1.0)
    with pytest.raises(ValueError, match="non-empty"):
        score_instances(np.zeros((0, 0)), np.zeros((0, 0)), resolution=1.0)
    with pytest.raises(ValueError, match="outside"):
        score_semantic(np.full((4, 8), 9), gt, cls, classes=["a", "b", "c"], resolution=1.0)
    with pytest.raises(ValueError, match="match"):
        MetricParams(match="dice")


def test_resample_nearest_takes_each_pixel_s_nearest_source_pixel():
    """Pixel (i, j) of an (h, w) resample of an (H, W) map is the source pixel whose cell holds
    its centre, row floor((i + 0.5) H / h) and column floor((j + 0.5) W / w) (a Python loop,
    sharing no code), for every dtype, up and down, to and from one row or column."""
    rng = np.random.default_rng(7)
    for (h0, w0), (h, w) in [((5, 7), (11, 3)), ((1, 9), (4, 4)), ((13, 1), (2, 5)), ((6, 6), (6, 6)),
                             ((37, 29), (74, 58)), ((74, 58), (37, 29)), ((10, 10), (1, 1))]:
        for dtype in (np.int32, np.int16, np.int64, np.bool_, np.float32):
            src = rng.integers(-1, 9, (h0, w0)).astype(dtype)
            want = np.empty((h, w), dtype)
            for i in range(h):
                for j in range(w):
                    want[i, j] = src[min(int((i + 0.5) * h0 / h), h0 - 1), min(int((j + 0.5) * w0 / w), w0 - 1)]
            got = resample_nearest(src, (h, w))
            assert got.dtype == src.dtype and np.array_equal(got, want), (h0, w0, h, w, dtype)
            view = np.asfortranarray(src)[::-1]  # not C-contiguous
            assert np.array_equal(resample_nearest(view, (h, w)), resample_nearest(np.ascontiguousarray(view), (h, w)))


def test_resample_and_describe():
    a = np.arange(4).reshape(2, 2)
    assert resample_nearest(a, (4, 4)).tolist() == [[0, 0, 1, 1], [0, 0, 1, 1], [2, 2, 3, 3], [2, 2, 3, 3]]
    assert resample_nearest(resample_nearest(a, (4, 4)), (2, 2)).tolist() == a.tolist()
    assert "50 px at 0.05 m/px" in describe(MetricParams(), 0.05)
    assert "313 px at 0.02 m/px" in describe(MetricParams(), 0.02) and "500 px" in describe(MetricParams(), 0.02, colours=True)


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("connectivity", [4, 8])
@pytest.mark.parametrize("dtype", [np.int64, np.int32, np.int16])
def test_segments_equal_a_per_value_scipy_labelling(seed, connectivity, dtype):
    """Ids ordered by value, then by the raster position of each region's first pixel: a
    reference labelling each value apart with SciPy, whatever the input's integer type."""
    from scipy import ndimage

    rng = np.random.default_rng(seed)
    labels = rng.integers(-2, 4, (19, 23)).astype(dtype)
    labels[rng.random(labels.shape) < 0.5] = 1  # large regions too
    want = np.full(labels.shape, -1, np.int32)
    nxt = 0
    structure = ndimage.generate_binary_structure(2, 1 if connectivity == 4 else 2)
    for v in np.unique(labels[labels >= 0]):
        comp, n = ndimage.label(labels == v, structure=structure)
        firsts = sorted((int(np.flatnonzero(comp == k)[0]), k) for k in range(1, n + 1))
        for _, k in firsts:
            want[comp == k] = nxt
            nxt += 1
    got = segments(labels, connectivity)
    assert got.dtype == np.int32 and np.array_equal(got, want)
