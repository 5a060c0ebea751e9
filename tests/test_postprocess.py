import numpy as np
import pytest

from benchmark.postprocess import (
    NoPostProcess,
    PostProcess,
    fill_unlabelled,
    mode_filter,
    regularise,
    remove_small_components,
    rescale,
)
from envs.gridmap import GridMap


def clean_two_rooms(res=0.1):
    walk = np.zeros((30, 50), bool)
    walk[2:28, 2:48] = True
    lab = np.full(walk.shape, -1, np.int32)
    lab[2:28, 2:25] = 1
    lab[2:28, 25:48] = 4
    return GridMap(walk, res, (0.0, 3.0)), lab


def test_salt_and_pepper_is_restored():
    grid, clean = clean_two_rooms()
    rng = np.random.default_rng(0)
    noisy = clean.copy()
    flip = grid.walkable & (rng.random(grid.shape) < 0.15)
    noisy[flip] = rng.choice([0, 2, 3, 5, 6, -1], flip.sum())
    out = PostProcess(min_area=0.5, dp_tolerance=0.1)(noisy, grid)
    assert np.array_equal(out, clean)


def test_island_removed_and_hole_filled():
    grid, clean = clean_two_rooms()
    lab = clean.copy()
    lab[10, 10] = 6  # one-pixel island
    lab[15:18, 30:33] = -1  # a hole
    assert np.array_equal(PostProcess()(lab, grid), clean)


def test_walkable_mask_respected_and_idempotent():
    grid, clean = clean_two_rooms()
    walk = grid.walkable.copy()
    walk[10:14, 10:14] = False  # furniture
    g = GridMap(walk, 0.1, (0.0, 3.0))
    lab = np.where(walk, clean, -1)
    out = PostProcess()(lab, g)
    assert (out[~walk] == -1).all() and (out[walk] >= 0).all()
    assert np.array_equal(PostProcess()(out, g), out)
    assert np.array_equal(out, lab)


def test_result_on_the_input_grid_at_finer_resolution():
    walk = np.zeros((60, 100), bool)
    walk[4:56, 4:96] = True
    lab = np.where(walk, 2, -1).astype(np.int32)
    lab[4:56, 50:96] = 3
    g = GridMap(walk, 0.05, (0.0, 3.0))
    out = PostProcess(target_resolution=0.1)(lab, g)
    assert out.shape == lab.shape and (out[walk] >= 0).all() and (out[~walk] == -1).all()
    assert np.mean(out[walk] == lab[walk]) > 0.97


def test_each_step_alone():
    lab = np.array([[0, 0, 0], [0, 1, 0], [0, 0, 0]], np.int32)
    walk = np.ones((3, 3), bool)
    assert (mode_filter(lab, walk, 2, window=3, iterations=1) == 0).all()
    assert remove_small_components(lab, 2).tolist() == [[0, 0, 0], [0, -1, 0], [0, 0, 0]]
    holes = np.array([[2, -1, 2], [-1, -1, -1], [2, -1, 2]], np.int32)
    assert (fill_unlabelled(holes, walk, 3) == 2).all()
    sep = walk.copy()
    sep[:, 1] = False
    part = np.array([[1, -1, -1], [-1, -1, -1], [-1, -1, -1]], np.int32)
    # unreachable pixels (right column, cut off by the wall) stay unlabelled
    assert fill_unlabelled(part, sep, 2)[:, 2].tolist() == [-1, -1, -1]
    big, small = rescale(np.arange(4).reshape(2, 2), np.ones((2, 2), bool), 0.1, 0.05)
    assert big.shape == (4, 4) and small.all()
    staircase = np.full((20, 20), -1, np.int32)
    for i in range(20):
        staircase[i, : i + 1] = 0
    staircase[staircase < 0] = 1
    reg = regularise(staircase, np.ones((20, 20), bool), 2, tolerance_px=1.5)
    assert (reg >= 0).all() and np.mean(reg == staircase) > 0.9


def test_bad_input():
    grid, clean = clean_two_rooms()
    with pytest.raises(ValueError, match="shape"):
        PostProcess()(clean[:5], grid)
    with pytest.raises(ValueError, match="all-background"):
        PostProcess()(np.full((4, 4), -1), GridMap(np.zeros((4, 4), bool), 0.1, (0, 0)))
    with pytest.raises(ValueError, match="unknown label value"):
        PostProcess(classes=["a", "b"])(np.where(grid.walkable, 5, -1), grid)
    out = NoPostProcess()(np.where(grid.walkable, 1, 3), grid)
    assert (out[~grid.walkable] == -1).all()
