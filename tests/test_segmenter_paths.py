"""The geometric segmenters' fast paths against the code they replaced (written out here):
the morphological erosion by OpenCV and its seeds numbered at once, the distance transforms by
:func:`envs.maps.distance.distance_px`, the parts labelled by
:func:`envs.maps.components.components`, and the distance sweep's cells sorted on 16-bit keys.
Same rooms, cell for cell, on the shared ProcTHOR maps, on the same maps with holes and specks
(clutter), and on cut-outs whose free space runs off the map's edge."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from benchmark.segmenters import voronoi as voronoi_mod
from benchmark.segmenters.common import check_area_limits, finish_rooms
from benchmark.segmenters.distance import DistanceTransform, parts_per_threshold
from benchmark.segmenters.morphological import Morphological
from benchmark.segmenters.voronoi import Voronoi
from envs.maps.gridmap import GridMap

FOUR = ndimage.generate_binary_structure(2, 1)  # SciPy's cross: the labelling the segmenters had


def _morphological_reference(seg: Morphological, grid: GridMap) -> np.ndarray:
    """The erosion loop before: SciPy's binary erosion, one seed at a time."""
    lo, hi = check_area_limits(grid, seg.min_seed_area, seg.max_area)
    work = grid.walkable.copy()
    prev, _ = ndimage.label(work, FOUR)
    seeds = np.zeros(grid.shape, np.int32)
    k = 0
    while work.any():
        lab, n = ndimage.label(work, FOUR)
        parent = np.zeros(n + 1, np.int64)
        parent[lab.ravel()] = prev.ravel()
        sizes = np.bincount(lab.ravel(), minlength=n + 1)
        big = np.nonzero(sizes[1:] >= lo)[0] + 1
        siblings = np.bincount(parent[big], minlength=prev.max() + 1)
        nxt = ndimage.binary_erosion(work, np.ones((3, 3), bool))
        alive = np.bincount(lab[nxt], minlength=n + 1) > 0
        for i in range(1, n + 1):
            broke_off = siblings[parent[i]] >= 2 or not alive[i]
            if broke_off and lo <= sizes[i] <= hi:
                k += 1
                part = lab == i
                seeds[part] = k
                nxt &= ~part
        prev, work = lab, nxt
    return finish_rooms(seeds, grid, seg.min_room_area)


def _parts_reference(dist, thresholds, min_pixels):
    """The part counts by labelling the map once per threshold."""
    return np.array([int((np.bincount(ndimage.label(dist > t, FOUR)[0].ravel())[1:] >= min_pixels).sum())
                     for t in thresholds])


@pytest.fixture(scope="module")
def maps(shared_scenes):
    """Shared house maps as they are, with clutter, and cut out so that free space meets the edge."""
    rng = np.random.default_rng(7)
    out = []
    for scene in shared_scenes[:12]:
        g = scene.grid
        out.append(g)
        walk = g.walkable & (rng.random(g.shape) > 0.03)  # specks of clutter
        walk[rng.random(g.shape) > 0.997] = False
        out.append(GridMap(walk, g.resolution, g.origin))
        h, w = g.shape
        cut = g.walkable[h // 4:, w // 5:w - w // 6]  # free space runs off three edges
        if cut.any():
            out.append(GridMap(np.ascontiguousarray(cut), g.resolution, g.origin))
    return out


def test_morphological_equals_the_erosion_loop(maps):
    seg = Morphological()
    edge = 0
    for g in maps:
        assert np.array_equal(seg(g), _morphological_reference(seg, g))
        edge += bool(g.walkable[0].any() or g.walkable[-1].any() or g.walkable[:, 0].any() or g.walkable[:, -1].any())
    assert edge >= 10  # the map's edge erodes as an obstacle on these
    # by hand: a strip 2 cells wide vanishes in one step with a seed's size (it is a seed, the
    # first), then two rooms joined by a door split apart
    walk = np.zeros((90, 240), bool)
    walk[2:4, 5:215] = True
    walk[20:80, 10:70] = walk[20:80, 90:150] = True
    walk[48:52, 70:90] = True
    hand = GridMap(walk, 0.05, (0.0, 0.0))
    assert np.array_equal(seg(hand), _morphological_reference(seg, hand))
    assert len(np.unique(seg(hand))) == 4  # the strip, two rooms, and -1
    # smaller seeds (more of them break off) on a few maps
    small = Morphological(min_seed_area=0.2, max_area=20.0)
    for g in maps[:9]:
        assert np.array_equal(small(g), _morphological_reference(small, g))


def _distance_reference(seg: DistanceTransform, grid: GridMap) -> np.ndarray:
    """The distance segmenter before: SciPy's transform, the part counts by labelling."""
    lo, _ = check_area_limits(grid, seg.min_seed_area, seg.max_area)
    edt = ndimage.distance_transform_edt(grid.walkable)
    dist = edt * grid.resolution
    thresholds = np.arange(0.0, dist.max(), max(seg.step, grid.resolution))
    t = thresholds[int(np.argmax(_parts_reference(dist, thresholds, lo)))]
    lab, n = ndimage.label(dist > t, FOUR)
    keep = np.nonzero(np.bincount(lab.ravel())[1:] >= lo)[0] + 1
    number = np.zeros(n + 1, np.int32)
    number[keep] = np.arange(1, len(keep) + 1)
    return finish_rooms(number[lab], grid, seg.min_room_area, edt)


def _critical_points_reference(seg: Voronoi, grid: GridMap) -> np.ndarray:
    """Voronoi's critical points before: SciPy's transform of the map padded with obstacles and
    SciPy's labelling (the fast path's distance_px and components are what is checked; the
    skeleton's spur pruning is the algorithm's own step, tested in tests/test_ipa_ports.py)."""
    from skimage.morphology import skeletonize

    from benchmark.segmenters.voronoi import prune_spurs

    walk = grid.walkable
    dist = ndimage.distance_transform_edt(np.pad(walk, 1))[1:-1, 1:-1]
    skel = prune_spurs(skeletonize(walk) & (dist > 1), dist, seg.max_door / 2 / grid.resolution)
    nbrs = ndimage.convolve(skel.astype(np.uint8), np.ones((3, 3), np.uint8), mode="constant") - 1
    win = max(int(round(seg.window / grid.resolution)), 1) * 2 + 1
    local_min = ndimage.minimum_filter(np.where(skel, dist, np.inf), size=win, mode="constant", cval=np.inf)
    local_max = ndimage.maximum_filter(np.where(skel, dist, 0), size=win * 2 + 1)
    cand = (skel & (nbrs == 2) & (dist <= local_min) & (dist * grid.resolution <= seg.max_door / 2)
            & (local_max >= dist * seg.widening))
    lab, n = ndimage.label(cand, np.ones((3, 3), bool))
    pts = []
    for sl, i in zip(ndimage.find_objects(lab), range(1, n + 1)):
        rr, cc = np.nonzero(lab[sl] == i)
        j = np.argmin(dist[sl][rr, cc])
        r, c = rr[j] + sl[0].start, cc[j] + sl[1].start
        pts.append((r, c, dist[r, c]))
    return np.array(pts, dtype=float).reshape(-1, 3)


def test_distance_and_voronoi_equal_their_scipy_versions(maps, monkeypatch):
    dist_seg, vor = DistanceTransform(), Voronoi()
    points = 0
    for g in maps:
        assert np.array_equal(dist_seg(g), _distance_reference(dist_seg, g))
        pts = vor.critical_points(g)
        assert np.array_equal(pts, _critical_points_reference(vor, g))
        points += len(pts)
    assert points > 50
    # the critical lines' obstacle pixels (the feature transform without its distances)
    fast = [(vor(g), vor.critical_lines(g)) for g in maps]
    real = ndimage.distance_transform_edt

    def with_distances(a, return_distances=True, return_indices=False):
        out = real(a, return_indices=return_indices)
        return out if return_distances or not return_indices else out[1]
    monkeypatch.setattr(voronoi_mod.ndimage, "distance_transform_edt", with_distances)
    for g, (v, cl) in zip(maps, fast):
        assert cl == vor.critical_lines(g)
        assert np.array_equal(v, vor(g))


@pytest.mark.parametrize("step", [0.05, 0.2])
def test_parts_per_threshold_equals_labelling_each_threshold(maps, step):
    for g in maps[::2]:
        dist = ndimage.distance_transform_edt(g.walkable) * g.resolution
        thresholds = np.arange(0.0, dist.max(), step)
        for lo in (1.0, 40.0, 200.0):
            assert np.array_equal(parts_per_threshold(dist, thresholds, lo), _parts_reference(dist, thresholds, lo))


def test_dense_ids_are_unique_inverse():
    from envs.maps.ids import dense_ids

    rng = np.random.default_rng(3)
    cases = [rng.integers(0, 12, 500), rng.integers(0, 12, 500).astype(np.int32),  # a segmentation's ids
             rng.choice([3, 90, 4000], 300),  # gaps (counted: below 2 N + 1024)
             rng.choice([5, 10**9, 2**40], 300),  # far apart: sorted
             rng.integers(-5, 5, 200),  # negative values: sorted
             np.array([7]), np.zeros(0, np.int64)]
    for v in cases:
        ranks, n = dense_ids(v)
        ids, inverse = np.unique(v, return_inverse=True)
        assert ranks.dtype == np.int64 and n == len(ids)
        assert np.array_equal(ranks, inverse.ravel())
    with pytest.raises(ValueError, match="integer"):
        dense_ids(np.array([0.5, 1.0]))


def test_grid_and_instance_scores_keep_their_ids(shared_scenes):
    """The grid's squares and score_instances' segments as np.unique numbered them."""
    from benchmark.metrics import MetricParams, score_instances
    from benchmark.segmenters.sanity import Grid

    for scene in shared_scenes[:6]:
        g = scene.grid
        walk = g.walkable
        rows = np.floor(np.arange(g.shape[0]) * g.resolution / 3.0).astype(np.int64)
        cols = np.floor(np.arange(g.shape[1]) * g.resolution / 3.0).astype(np.int64)
        cell = rows[:, None] * (int(cols.max()) + 1) + cols[None, :]
        want = np.full(g.shape, -1, np.int32)
        want[walk] = np.unique(cell[walk], return_inverse=True)[1].ravel()
        got = Grid(3.0)(g)
        assert np.array_equal(got, want)
        # ids with gaps score as the same segments renumbered
        sparse = np.where(got >= 0, got * 37 + 5, -1)
        params = MetricParams(instances="ids")
        a = score_instances(sparse, scene.instances, params, resolution=g.resolution)
        b = score_instances(got, scene.instances, params, resolution=g.resolution)
        assert a == pytest.approx(b, nan_ok=True)
