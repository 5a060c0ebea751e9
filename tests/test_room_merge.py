"""The minimum room area of the geometric segmenters (issue #30 item 2): a room under
``min_room_area`` merges into the neighbour sharing the longest border, smallest first.
Hand-made maps with answers worked out by hand, and random maps against a slow reference
that shares no code with :func:`benchmark.segmenters.common.merge_small_rooms`."""

from __future__ import annotations

import numpy as np
import pytest

from benchmark.segmenters.common import merge_small_rooms
from benchmark.segmenters.distance import DistanceTransform
from benchmark.segmenters.morphological import Morphological
from benchmark.segmenters.voronoi import Voronoi
from envs.maps.gridmap import GridMap


def _same_partition(a: np.ndarray, b: np.ndarray) -> bool:
    """Equal up to renumbering (and equal -1 cells)."""
    if not np.array_equal(a < 0, b < 0):
        return False
    m = a >= 0
    pairs = set(zip(a[m].tolist(), b[m].tolist()))
    return len(pairs) == len({p[0] for p in pairs}) == len({p[1] for p in pairs})


def test_longest_border_wins_and_ids_are_renumbered():
    # room 1 (2 x 2 = 4 px) borders room 0 on 2 pixel pairs and room 2 on 4 pixel pairs
    inst = np.array([[0, 0, 0, 0, 0, 0],
                     [0, 0, 1, 1, 2, 2],
                     [3, 3, 1, 1, 2, 2],
                     [3, 3, 2, 2, 2, 2]])
    walk = np.ones(inst.shape, bool)
    # 1 (4 px) and 3 (4 px) are under 5 px; 1 goes first (equal size, lower id): borders
    # 1-0: (0,2)-(1,2), (0,3)-(1,3) = 2; 1-2: (1,3)-(1,4), (2,3)-(2,4), (2,2)-(3,2), (2,3)-(3,3) = 4;
    # 1-3: (2,1)-(2,2) = 1 -> into 2 (now 12 px). Then 3: borders 3-0: (1,0)-(2,0), (1,1)-(2,1) = 2;
    # 3-2 (with 1 inside): (2,1)-(2,2), (3,1)-(3,2) = 2: a tie -> the larger neighbour, 2 (12 px > 6)
    out = merge_small_rooms(inst, walk, 5)
    want = np.array([[0, 0, 0, 0, 0, 0],
                     [0, 0, 1, 1, 1, 1],
                     [1, 1, 1, 1, 1, 1],
                     [1, 1, 1, 1, 1, 1]])
    assert np.array_equal(out, want) and out.dtype == np.int32
    # nothing under the limit: unchanged (renumbered to 0..K-1 in the old ids' order)
    assert np.array_equal(merge_small_rooms(inst * 2 + 7, walk, 4), inst)
    # sparse ids (ranked by sorting, not counting) merge the same way
    assert np.array_equal(merge_small_rooms(inst * 10**12 + 5, walk, 5), want)
    assert np.array_equal(merge_small_rooms(inst, walk, 0), inst)


def test_islands_stay_and_cells_off_the_walkable_mask_are_dropped():
    inst = np.array([[0, 0, -1, 1],
                     [0, 0, -1, -1],
                     [0, 0, -1, 2]])
    walk = inst >= 0
    walk[0, 3] = False  # room 1's only cell is not walkable: dropped
    out = merge_small_rooms(inst, walk, 3)
    # room 2 (1 px) has no neighbouring room (a -1 column between): it stays
    assert out.tolist() == [[0, 0, -1, -1], [0, 0, -1, -1], [0, 0, -1, 1]]


def test_a_chain_of_small_rooms_merges_smallest_first():
    # a row: 10 px big room | 1 px | 2 px | 10 px big room; limit 4 px
    inst = np.array([[0] * 10 + [1] + [2, 2] + [3] * 10])
    out = merge_small_rooms(inst, np.ones(inst.shape, bool), 4)
    # 1 (1 px) borders 0 and 2 with one pair each: a tie -> the larger, 0 (10 px); then 2 (2 px)
    # borders 0 (now 11 px) and 3 (10 px) with one pair each -> 0 again
    assert out.tolist() == [[0] * 13 + [1] * 10]


def _reference(inst: np.ndarray, walk: np.ndarray, min_px: float) -> np.ndarray:
    """Pixel loops and plain dicts: the rule as stated, nothing shared with the fast code."""
    lab = [[int(inst[r][c]) if walk[r][c] and inst[r][c] >= 0 else -1 for c in range(inst.shape[1])]
           for r in range(inst.shape[0])]
    h, w = inst.shape
    while True:
        size: dict[int, int] = {}
        for r in range(h):
            for c in range(w):
                if lab[r][c] >= 0:
                    size[lab[r][c]] = size.get(lab[r][c], 0) + 1
        border: dict[int, dict[int, int]] = {k: {} for k in size}
        for r in range(h):
            for c in range(w):
                for dr, dc in ((0, 1), (1, 0)):
                    rr, cc = r + dr, c + dc
                    if rr < h and cc < w and lab[r][c] >= 0 and lab[rr][cc] >= 0 and lab[r][c] != lab[rr][cc]:
                        a, b = lab[r][c], lab[rr][cc]
                        border[a][b] = border[a].get(b, 0) + 1
                        border[b][a] = border[b].get(a, 0) + 1
        small = sorted((size[k], k) for k in size if size[k] < min_px and border[k])
        if not small:
            break
        i = small[0][1]
        best = sorted(border[i].items(), key=lambda kv: (-kv[1], -size[kv[0]], kv[0]))[0][0]
        for r in range(h):
            for c in range(w):
                if lab[r][c] == i:
                    lab[r][c] = best
    return np.array(lab)


@pytest.mark.parametrize("seed", range(12))
def test_random_maps_agree_with_the_slow_reference(seed):
    rng = np.random.default_rng(seed)
    h, w = rng.integers(6, 16, size=2)
    # blocky random rooms: a coarse random grid upsampled, with some walls and random ids
    coarse = rng.integers(0, 9, size=(h // 2 + 1, w // 2 + 1))
    inst = np.kron(coarse, np.ones((2, 2), np.int64))[:h, :w]
    inst[rng.random(inst.shape) < 0.08] = rng.integers(9, 20)  # specks of other rooms
    walk = rng.random(inst.shape) > 0.1
    for min_px in (0, 3, 6, 15):
        fast = merge_small_rooms(inst, walk, min_px)
        assert _same_partition(fast, _reference(inst, walk, min_px)), (seed, min_px)


def test_every_geometric_segmenter_merges_the_fragments_of_clutter():
    """Two 3 x 3 m rooms joined by a 1 m door; below the first, an alcove of 0.8 x 0.7 m
    (0.56 m^2 = 224 px, plus 6 px of its 0.3 m opening) that each segmenter makes a room of its
    own without a minimum room area (distance and morphological with seeds from 0.1 m^2)."""
    walk = np.zeros((80, 126), bool)
    walk[2:62, 2:62] = True
    walk[2:62, 64:124] = True
    walk[22:42, 62:64] = True  # the door, 20 px = 1 m
    walk[64:78, 10:26] = True  # the alcove, 14 x 16 px
    walk[62:64, 15:21] = True  # its opening through the wall, 6 px = 0.3 m
    grid = GridMap(walk, 0.05, (0.0, 4.0))
    for seg_cls, kw in ((DistanceTransform, {"min_seed_area": 0.1}), (Morphological, {"min_seed_area": 0.1}),
                        (Voronoi, {})):
        loose = seg_cls(min_room_area=0, **kw)(grid)
        assert 230 in np.bincount(loose[loose >= 0]).tolist(), seg_cls.__name__  # the alcove alone
        rooms = seg_cls(**kw)(grid)  # default min_room_area 1.0 m^2 = 400 px
        assert np.bincount(rooms[rooms >= 0]).min() >= 400, seg_cls.__name__
        # merging only ever joins whole rooms of the unmerged result
        assert _same_partition(merge_small_rooms(loose, walk, 400), rooms), seg_cls.__name__
    # the Voronoi cuts at the door and at the alcove's opening: three parts, then two rooms
    # (the alcove's one border is with the first room)
    rooms = Voronoi()(grid)
    assert rooms.max() + 1 == 2 and len(np.unique(rooms[64:78, 10:26])) == 1
    assert rooms[70, 18] == rooms[30, 30] != rooms[30, 100]


def test_parts_per_threshold_equals_labelling_each_threshold():
    """The distance segmenter's one-sweep count (union-find from the highest threshold down)
    against the map labelled at every threshold (scipy's label, 4-connected), on random free
    space, with distances that equal thresholds exactly and seed sizes of 1 cell and more."""
    from scipy import ndimage

    FOUR = ndimage.generate_binary_structure(2, 1)  # SciPy's cross
    from benchmark.segmenters.distance import parts_per_threshold

    rng = np.random.default_rng(3)
    for k in range(40):
        h, w = (int(x) for x in rng.integers(1, 60, 2))
        free = rng.random((h, w)) < rng.uniform(0.3, 0.95)
        if k % 2:
            dist = ndimage.distance_transform_edt(free) * 0.05
            thresholds = np.arange(0.0, max(dist.max(), 0.05), 0.05)
        else:  # whole numbers: many distances equal a threshold
            dist = np.where(free, rng.integers(0, 6, (h, w)), 0).astype(float)
            thresholds = np.arange(0.0, 6.0, 1.0)
        lo = float(rng.choice([0.5, 1.0, 3.0, 7.5]))
        want = [int((np.bincount(ndimage.label(dist > t, FOUR)[0].ravel())[1:] >= lo).sum()) for t in thresholds]
        assert parts_per_threshold(dist, thresholds, lo).tolist() == want
