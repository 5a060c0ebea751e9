"""The OpenCV distance transform against SciPy's, the reference (no code shared)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

import envs.maps.distance as distance
from envs.maps.distance import distance_px


def _masks():
    rng = np.random.default_rng(0)
    for t in range(200):
        h, w = (int(v) for v in rng.integers(1, 260, 2))
        m = rng.random((h, w)) < rng.uniform(0.3, 0.9999)
        if t % 3 == 0:  # rooms rather than noise: large clear areas
            m = ndimage.binary_opening(m, iterations=3) | (rng.random((h, w)) < 0.95)
        if (~m).any():
            yield m
    yield np.pad(np.ones((300, 420), bool), 1)  # one open room, distances up to 150 px


def test_distance_px_equals_scipy_bit_for_bit(monkeypatch):
    masks = list(_masks())
    masks += [m[::-1, ::2] for m in masks[:20] if (~m[::-1, ::2]).any()]  # views that are not contiguous
    want = [ndimage.distance_transform_edt(m) for m in masks]

    def refuse(*a, **k):
        raise AssertionError("SciPy called for a mask the OpenCV path handles")

    monkeypatch.setattr(distance.ndimage, "distance_transform_edt", refuse)
    for m, w in zip(masks, want):
        assert np.array_equal(distance_px(m), w)
    assert len(masks) > 150


def test_distance_px_on_shared_houses(procthor_file):
    from envs.datasets.house_files import load_houses
    from envs.maps.scene import rasterise_house

    for house in load_houses(procthor_file, 0, 6):
        walk = rasterise_house(house, resolution=0.05).grid.walkable
        for m in (walk, np.pad(walk, 1), ~walk):
            assert np.array_equal(distance_px(m), ndimage.distance_transform_edt(m))


@pytest.mark.parametrize("mask", [np.ones((4, 6), bool), np.zeros((3, 3), bool), np.ones((0, 5), bool),
                                  np.r_[np.ones(2600, bool), False][None], np.arange(1800 * 1800).reshape(1800, 1800) > 0])
def test_distance_px_edge_cases_are_scipys(mask):
    """No False cell, none True, empty, and distances beyond the exact range (up to 2,600 px: SciPy)."""
    assert np.array_equal(distance_px(mask), ndimage.distance_transform_edt(mask))
