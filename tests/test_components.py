"""OpenCV's labelling of connected parts against SciPy's, the reference (no code shared):
the same part numbers, cell for cell, with either connectivity and any number of OpenCV threads."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from scipy import ndimage

from envs.maps.components import components

CROSS = ndimage.generate_binary_structure(2, 1)
SQUARE = np.ones((3, 3), bool)


def _masks():
    rng = np.random.default_rng(0)
    for t in range(300):
        big = t % 50 == 0
        h, w = (int(v) for v in rng.integers(1, 1400 if big else 90, 2))
        m = rng.random((h, w)) < rng.uniform(0.05, 0.95)
        if t % 2:  # blobs and corridors rather than noise
            m = cv2.dilate(m.view(np.uint8), np.ones((3, 3), np.uint8)).view(bool) & (rng.random((h, w)) < 0.9)
        yield m
    yield np.zeros((7, 5), bool)
    yield np.ones((6, 9), bool)
    yield np.eye(12, dtype=bool)  # diagonal cells: 12 parts in 4-connectivity, 1 in 8
    yield np.eye(12, dtype=bool)[:, ::-1]


@pytest.fixture
def threads():
    before = cv2.getNumThreads()
    yield
    cv2.setNumThreads(before)


@pytest.mark.parametrize("n_threads", [1, 4])
def test_components_number_parts_as_scipy(n_threads, threads):
    cv2.setNumThreads(n_threads)  # OpenCV's parallel labelling (bands of rows) numbers them the same
    masks = list(_masks())
    masks += [m[::-1, ::2] for m in masks[:20]]  # views that are not contiguous
    want = {c: [ndimage.label(m, CROSS if c == 4 else SQUARE) for m in masks] for c in (4, 8)}
    for c in (4, 8):
        for m, (lab, n) in zip(masks, want[c]):
            got, k = components(m, c)
            assert k == n and got.dtype == np.int32 and np.array_equal(got, lab), (c, m.shape)
    assert components(np.eye(12, dtype=bool), 4)[1] == 12 and components(np.eye(12, dtype=bool), 8)[1] == 1


def test_components_of_values_empty_masks_and_bad_input():
    m = np.array([[0, 2, 2, 0], [0, 0, 0, 7], [5, 0, 0, 7]])  # nonzero is True, whatever its value
    lab, n = components(m)
    assert n == 3 and np.array_equal(lab, [[0, 1, 1, 0], [0, 0, 0, 2], [3, 0, 0, 2]])
    for c in (4, 8):
        lab, n = components(np.zeros((0, 4), bool), c)  # empty: no part
        want, k = ndimage.label(np.zeros((0, 4), bool), CROSS if c == 4 else SQUARE)
        assert n == k == 0 and lab.shape == want.shape and lab.dtype == np.int32
    with pytest.raises(ValueError, match=r"2-D \(H, W\) mask, got shape \(5,\)"):
        components(np.ones(5, bool))
    with pytest.raises(ValueError, match="connectivity must be 4 or 8, got 6"):
        components(np.ones((3, 3), bool), 6)


def test_components_on_shared_maps(shared_scenes):
    """The free space of shared ProcTHOR houses and its erosions, as the morphological segmenter labels them."""
    for scene in shared_scenes[:8]:
        work = scene.grid.walkable.copy()
        while work.any():
            for c in (4, 8):
                lab, n = components(work, c)
                want, k = ndimage.label(work, CROSS if c == 4 else SQUARE)
                assert n == k and np.array_equal(lab, want)
            work = ndimage.binary_erosion(work, iterations=3)
