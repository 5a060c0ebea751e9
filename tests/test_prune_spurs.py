"""The Voronoi segmenters' spur pruning (benchmark.segmenters.voronoi.prune_spurs, compiled)
against a plain Python reference written here (the loop as it ran before it was compiled, a list
as its stack): the same skeleton, pixel for pixel, on the shared ProcTHOR houses (the narrowing
rule's skeleton and clearance at three room limits), on the authors' Voronoi graph (no exception
kept) and on random blobs."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage
from skimage.morphology import skeletonize

from benchmark.segmenters import voronoi_original as original
from benchmark.segmenters.voronoi import prune_spurs
from envs.maps.distance import distance_px


def prune_reference(skel: np.ndarray, clearance: np.ndarray, room: float) -> np.ndarray:
    s = np.asarray(skel, bool).copy()
    h, w = s.shape
    count = np.zeros((h, w), int)
    for r, c in zip(*np.nonzero(s)):
        count[r, c] = sum(1 for dr in (-1, 0, 1) for dc in (-1, 0, 1)
                          if (dr or dc) and 0 <= r + dr < h and 0 <= c + dc < w and s[r + dr, c + dc])
    node = s & (count > 2)
    stack = [(r, c) for r in range(h) for c in range(w) if s[r, c] and count[r, c] <= 1 and not node[r, c]]
    while stack:
        r, c = stack.pop()
        if not s[r, c] or count[r, c] > 1:
            continue
        around = [(rr, cc) for rr in range(r - 1, r + 2) for cc in range(c - 1, c + 2)
                  if 0 <= rr < h and 0 <= cc < w and (rr, cc) != (r, c) and s[rr, cc]]
        if around and clearance[r, c] >= clearance[around[0]] and clearance[r, c] > room:
            continue
        s[r, c] = False
        for rr, cc in around:
            count[rr, cc] -= 1
            if count[rr, cc] <= 1 and not node[rr, cc]:
                stack.append((rr, cc))
    return s


@pytest.mark.parametrize("room_m", [0.3, 0.6, 1.5])
def test_pruning_equals_the_reference_on_the_shared_houses(shared_scenes, room_m):
    changed = 0
    for scene in shared_scenes[:12]:
        walk = scene.grid.walkable
        dist = distance_px(np.pad(walk, 1))[1:-1, 1:-1]
        skel = skeletonize(walk) & (dist > 1)
        room = room_m / scene.grid.resolution
        got = prune_spurs(skel, dist, room)
        assert np.array_equal(got, prune_reference(skel, dist, room)), scene.house_id
        changed += int((got != skel).sum())
    assert changed > 1000  # spurs were pruned: the comparison is not between two copies of the input


def test_pruning_the_authors_graph_equals_the_reference(shared_scenes):
    for scene in shared_scenes[:6]:
        walk = original.resample(scene.grid.walkable, scene.grid.resolution, 0.05)
        graph = original.voronoi_graph(walk)
        got = prune_spurs(graph, np.zeros(walk.shape), np.inf)
        assert np.array_equal(got, prune_reference(graph, np.zeros(walk.shape), np.inf))
        assert got.sum() < graph.sum()


def test_pruning_random_blobs_equals_the_reference():
    rng = np.random.default_rng(7)
    for _ in range(40):
        walk = ndimage.binary_opening(rng.random((60, 70)) < 0.62)
        dist = distance_px(walk)
        skel = skeletonize(walk)
        clearance = dist + rng.integers(0, 3, walk.shape) * 0.5  # ties and near-ties between neighbours
        for room in (0.0, 2.0, np.inf):
            assert np.array_equal(prune_spurs(skel, clearance, room), prune_reference(skel, clearance, room))
