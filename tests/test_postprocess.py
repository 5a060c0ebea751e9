"""Post-processing: known answers on hand-made maps, each step against a slow reference,
the guarantees on shared ProcTHOR houses, bad input."""

import numpy as np
import pytest
from scipy import ndimage

from benchmark.postprocess import (
    NoPostProcess,
    PostProcess,
    apply_background,
    check_labels,
    fill_unlabelled,
    label_orphan_components,
    mode_filter,
    noisy_ground_truth,
    regularise,
    remove_small_components,
    rescale,
)
from envs.maps.gridmap import GridMap

EIGHT = np.ones((3, 3), bool)


def clean_two_rooms(res=0.1):
    """30 x 50 px map, a walkable rectangle split into class 1 (left) and 4 (right)."""
    walk = np.zeros((30, 50), bool)
    walk[2:28, 2:48] = True
    lab = np.full(walk.shape, -1, np.int32)
    lab[2:28, 2:25] = 1
    lab[2:28, 25:48] = 4
    return GridMap(walk, res, (0.0, 3.0)), lab


# ---------------------------------------------------------------- slow references


def mode_filter_ref(labels, walkable, n_classes, window, iterations):
    lab = np.where(walkable, labels, -1).astype(np.int32)
    h, w = lab.shape
    r = window // 2
    for _ in range(iterations):
        new = lab.copy()
        for i in range(h):
            for j in range(w):
                if lab[i, j] < 0:
                    continue
                votes = [0] * n_classes
                for a in range(max(i - r, 0), min(i + r + 1, h)):
                    for b in range(max(j - r, 0), min(j + r + 1, w)):
                        if lab[a, b] >= 0:
                            votes[lab[a, b]] += 1
                top = max(votes)
                new[i, j] = lab[i, j] if votes[lab[i, j]] == top else votes.index(top)
        lab = new
    return lab


def fill_ref(labels, walkable, n_classes):
    lab = np.where(walkable, labels, -1).astype(np.int32)
    h, w = lab.shape
    while True:
        new = lab.copy()
        for i in range(h):
            for j in range(w):
                if not walkable[i, j] or lab[i, j] >= 0:
                    continue
                votes = [0] * n_classes
                for a in range(max(i - 1, 0), min(i + 2, h)):
                    for b in range(max(j - 1, 0), min(j + 2, w)):
                        if lab[a, b] >= 0:
                            votes[lab[a, b]] += 1
                if max(votes) > 0:
                    new[i, j] = votes.index(max(votes))
        if np.array_equal(new, lab):
            return lab
        lab = new


def remove_small_ref(labels, min_px, structure):
    out = labels.copy()
    for k in np.unique(labels[labels >= 0]):
        comp, n = ndimage.label(labels == k, structure=structure)
        for c in range(1, n + 1):
            if (comp == c).sum() < min_px:
                out[comp == c] = -1
    return out


def random_map(seed, shape=(17, 23), n_classes=4, p_unlab=0.15, p_wall=0.15):
    rng = np.random.default_rng(seed)
    walk = rng.random(shape) > p_wall
    lab = rng.integers(0, n_classes, shape).astype(np.int32)
    lab[rng.random(shape) < p_unlab] = -1
    lab[~walk] = -1
    return lab, walk


@pytest.mark.parametrize("seed", range(6))
def test_steps_match_slow_references(seed):
    lab, walk = random_map(seed)
    for window, iters in [(3, 1), (3, 3), (5, 2)]:
        assert np.array_equal(mode_filter(lab, walk, 4, window, iters), mode_filter_ref(lab, walk, 4, window, iters))
    assert np.array_equal(fill_unlabelled(lab, walk, 4), fill_ref(lab, walk, 4))
    sparse, _ = random_map(seed, p_unlab=0.7, p_wall=0.3)
    assert np.array_equal(fill_unlabelled(sparse, walk, 4), fill_ref(sparse, walk, 4))
    # a few seeds in a large map: many passes, fronts meeting, pockets left unreachable
    few, big_walk = random_map(seed, shape=(41, 57), p_unlab=0.985, p_wall=0.25)
    got = fill_unlabelled(few, big_walk, 4)
    assert np.array_equal(got, fill_ref(few, big_walk, 4))
    assert (got[big_walk] >= 0).any() and (got[~big_walk] == -1).all()
    for min_px in (2, 4):
        assert np.array_equal(remove_small_components(lab, min_px), remove_small_ref(lab, min_px, None))
        assert np.array_equal(remove_small_components(lab, min_px, connectivity=8),
                              remove_small_ref(lab, min_px, EIGHT))


@pytest.mark.parametrize("seed", range(4))
def test_steps_match_slow_references_with_classes_absent_and_large_ids(seed):
    """Classes that label no pixel (class 0 among them, and the highest) and fractional area
    bounds; the small-region step labels every class's regions at once."""
    rng = np.random.default_rng(100 + seed)
    lab, walk = random_map(seed, shape=(29, 31), n_classes=3)
    present = np.array([1, 4, 5]) if seed % 2 else np.array([2, 3, 6])
    lab = np.where(lab >= 0, present[np.clip(lab, 0, 2)], -1).astype(np.int32)
    lab[rng.random(lab.shape) < 0.1] = -1
    for window, iters in [(3, 1), (5, 3)]:
        assert np.array_equal(mode_filter(lab, walk, 7, window, iters), mode_filter_ref(lab, walk, 7, window, iters))
    nothing = np.full(lab.shape, -1, np.int32)
    assert np.array_equal(mode_filter(nothing, walk, 7, 3, 2), nothing)
    for min_px in (2.5, 5, 12.0):
        for conn, structure in ((4, None), (8, EIGHT)):
            assert np.array_equal(remove_small_components(lab, min_px, conn), remove_small_ref(lab, min_px, structure))
    assert np.array_equal(remove_small_components(nothing, 3), nothing)


def _mode_pass_per_class(lab, n_classes, window):
    """The mode pass as it was, one OpenCV box filter per class (written out: shares no code)."""
    import cv2

    best = np.zeros(lab.shape, np.int32)
    top = own = None
    for k in range(n_classes):
        is_k = lab == k
        summed = cv2.boxFilter(is_k.astype(np.float32), -1, (window, window), normalize=False,
                               borderType=cv2.BORDER_CONSTANT)
        if top is None:
            top, own = summed, np.zeros(lab.shape, np.float32)
        else:
            best[summed > top] = k
            np.maximum(top, summed, out=top)
        own[is_k] = summed[is_k]
    keep = (lab >= 0) & (own >= top)
    best[keep] = lab[keep]
    return best


@pytest.mark.parametrize("seed", range(5))
def test_mode_pass_equals_one_box_filter_per_class(seed):
    """The running-sum mode pass against the per-class box filters it replaced, on maps from 1 x 1
    to 150 x 170 px (thinner than the window too), windows 1 to 9, sparse and dense labels, and
    labels at n_classes (outside the classes: they count nothing and keep their label only
    where nothing is counted); unlabelled pixels are not voted on (mode_filter keeps them)."""
    from benchmark.postprocess import _mode_pass

    rng = np.random.default_rng(seed)
    shapes = [(1, 1), (1, 9), (9, 1), (2, 3), (37, 41), (150, 170)]
    for h, w in shapes:
        for window in (1, 3, 5, 9):
            for n_classes in (1, 3, 7):
                lab = rng.integers(-1, n_classes + (1 if seed % 2 else 0), (h, w)).astype(np.int32)
                lab[rng.random((h, w)) < (0.9 if seed == 4 else 0.2)] = -1
                got = _mode_pass(lab, n_classes, window)
                assert got.dtype == np.int32 and (got[lab < 0] == -1).all()  # unlabelled: not voted on
                want = _mode_pass_per_class(lab, n_classes, window)
                assert np.array_equal(got[lab >= 0], want[lab >= 0]), (h, w, window, n_classes)


# ---------------------------------------------------------------- whole pipeline, known answers


def test_salt_and_pepper_is_restored():
    grid, clean = clean_two_rooms()
    rng = np.random.default_rng(0)
    noisy = clean.copy()
    flip = grid.walkable & (rng.random(grid.shape) < 0.15)
    noisy[flip] = rng.choice([0, 2, 3, 5, 6, -1], flip.sum())
    assert (noisy != clean).sum() > 100
    out = PostProcess(min_area=0.5, dp_tolerance=0.1)(noisy, grid)
    assert np.array_equal(out, clean)


def test_salt_and_pepper_restored_at_finer_input_resolution():
    """A 0.05 m/px input is cleaned at 0.1 m/px and comes back on its own 0.05 m/px grid."""
    grid, clean = clean_two_rooms()
    fine = np.repeat(np.repeat(clean, 2, 0), 2, 1)
    g = GridMap(np.repeat(np.repeat(grid.walkable, 2, 0), 2, 1), 0.05, (0.0, 3.0))
    rng = np.random.default_rng(1)
    noisy = fine.copy()
    flip = g.walkable & (rng.random(g.shape) < 0.15)
    noisy[flip] = rng.choice([0, 2, 3, 5, 6, -1], flip.sum())
    out = PostProcess()(noisy, g)
    assert out.shape == g.shape and np.array_equal(out, fine)


def test_one_pixel_island_disappears():
    grid, clean = clean_two_rooms()
    lab = clean.copy()
    lab[10, 10] = 6
    assert np.array_equal(PostProcess()(lab, grid), clean)
    # also without the mode filter: step 4 removes it, step 5 refills it
    assert np.array_equal(PostProcess(iterations=0)(lab, grid), clean)


def test_hole_is_filled_with_surrounding_label():
    grid, clean = clean_two_rooms()
    lab = clean.copy()
    lab[12:20, 30:40] = -1  # 0.8 m^2 unlabelled hole in class 4
    out = PostProcess()(lab, grid)
    assert (out[12:20, 30:40] == 4).all() and np.array_equal(out, clean)


def test_walkable_mask_respected_and_idempotent_on_clean_map():
    grid, clean = clean_two_rooms()
    walk = grid.walkable.copy()
    walk[10:14, 10:14] = False  # furniture
    walk[20:23, 30:33] = False
    g = GridMap(walk, 0.1, (0.0, 3.0))
    lab = np.where(walk, clean, -1)
    out = PostProcess()(lab, g)
    assert np.array_equal(out, lab)
    assert np.array_equal(PostProcess()(out, g), out)
    # labels given on non-walkable pixels are dropped, never invented there
    dirty = np.where(walk, clean, 2)
    out2 = PostProcess()(dirty, g)
    assert (out2[~walk] == -1).all() and np.array_equal(out2, lab)


def test_unreachable_walkable_stays_unlabelled_and_orphan_pocket_kept():
    """A walkable pocket with no input label stays -1; a labelled pocket smaller than
    min_area keeps its (majority) label instead of vanishing."""
    grid, clean = clean_two_rooms()
    walk = grid.walkable.copy()
    walk[:, 36] = False  # wall: columns 37.. form their own component
    walk[5, 40] = walk[6, 40] = False
    lab = np.where(walk, clean, -1)
    lab[:, 37:] = -1  # no label beyond the wall
    out = PostProcess()(lab, GridMap(walk, 0.1, (0.0, 3.0)))
    assert (out[:, 37:] == -1).all() and (out[:, 36] == -1).all()
    assert (out[2:28, 2:25] == 1).all() and (out[2:28, 25:36] == 4).all()
    # a 2 x 2 px (0.04 m^2) walkable pocket of mostly class 3 behind walls
    walk2 = np.zeros((20, 20), bool)
    walk2[2:18, 2:10] = True
    walk2[5:7, 14:16] = True
    lab2 = np.where(walk2, 0, -1).astype(np.int32)
    lab2[5:7, 14:16] = [[3, 3], [3, -1]]
    out2 = PostProcess()(lab2, GridMap(walk2, 0.1, (0, 0)))
    assert (out2[5:7, 14:16] == 3).all() and (out2[2:18, 2:10] == 0).all()


# ---------------------------------------------------------------- each step alone


def test_rescale_nearest():
    lab = np.arange(4, dtype=np.int32).reshape(2, 2)
    big, wbig = rescale(lab, np.array([[True, False], [True, True]]), 0.1, 0.05)
    assert big.tolist() == [[0, 0, 1, 1], [0, 0, 1, 1], [2, 2, 3, 3], [2, 2, 3, 3]]
    assert wbig[:2, 2:].sum() == 0 and wbig.sum() == 12
    small, _ = rescale(big, wbig, 0.05, 0.1)
    assert np.array_equal(small, lab)
    odd, _ = rescale(np.zeros((5, 7), np.int32), np.ones((5, 7), bool), 0.05, 0.1)
    assert odd.shape == (2, 4)  # round(2.5) = 2, round(3.5) = 4
    with pytest.raises(ValueError, match="positive"):
        rescale(lab, lab >= 0, 0.0, 0.1)


def test_apply_background():
    walk = np.array([[True, False]])
    assert apply_background(np.array([[2, 3]]), walk).tolist() == [[2, -1]]


def test_mode_filter_known_answers():
    walk = np.ones((3, 3), bool)
    lab = np.array([[0, 0, 0], [0, 1, 0], [0, 0, 0]], np.int32)
    assert (mode_filter(lab, walk, 2, window=3, iterations=1) == 0).all()
    # unlabelled pixels neither vote nor change: the centre 1 sees only two 0s and itself
    lab = np.array([[-1, -1, -1], [0, 1, -1], [0, -1, -1]], np.int32)
    assert mode_filter(lab, walk, 2, 3, 1).tolist() == [[-1, -1, -1], [0, 0, -1], [0, -1, -1]]
    # non-walkable pixels do not vote even when labelled
    lab = np.array([[2, 2, 2], [2, 1, 1], [2, 1, 1]], np.int32)
    w = np.ones((3, 3), bool)
    w[0, :] = w[:, 0] = False
    assert mode_filter(lab, w, 3, 3, 1)[1:, 1:].tolist() == [[1, 1], [1, 1]]
    # a tie keeps the pixel's own label
    lab = np.array([[0, 1]], np.int32)
    assert mode_filter(lab, np.ones((1, 2), bool), 2, 3, 1).tolist() == [[0, 1]]
    with pytest.raises(ValueError, match="odd"):
        mode_filter(lab, np.ones((1, 2), bool), 2, 4, 1)


def test_remove_small_components_known_answer():
    lab = np.array([[0, 0, 0], [0, 1, 0], [0, 0, 2]], np.int32)
    assert remove_small_components(lab, 2).tolist() == [[0, 0, 0], [0, -1, 0], [0, 0, -1]]
    # two diagonal 1s: separate regions with 4-connectivity, one region with 8
    lab = np.array([[1, 0], [0, 1]], np.int32)
    assert remove_small_components(lab, 2).tolist() == [[-1, -1], [-1, -1]]
    assert remove_small_components(lab, 2, connectivity=8).tolist() == [[1, 0], [0, 1]]


def test_fill_unlabelled_known_answers():
    walk = np.ones((3, 3), bool)
    holes = np.array([[2, -1, 2], [-1, -1, -1], [2, -1, 2]], np.int32)
    assert (fill_unlabelled(holes, walk, 3) == 2).all()
    # majority: the hole between three 1s and one 0 becomes 1
    lab = np.array([[1, 1, 1], [-1, -1, -1], [0, -1, -1]], np.int32)
    assert fill_unlabelled(lab, walk, 2)[1].tolist() == [1, 1, 1]
    sep = walk.copy()
    sep[:, 1] = False
    part = np.array([[1, -1, -1], [-1, -1, -1], [-1, -1, -1]], np.int32)
    out = fill_unlabelled(part, sep, 2)
    assert out[:, 0].tolist() == [1, 1, 1] and out[:, 1:].tolist() == [[-1, -1]] * 3


def test_regularise_straightens_a_staircase_and_keeps_rectangles():
    n = 24
    walk = np.ones((n, n), bool)
    ii, jj = np.indices((n, n))
    # a jagged diagonal border: exact diagonal plus +-1 px zig-zag
    stair = np.where(jj <= ii + (ii % 4 == 0) - (ii % 4 == 2), 0, 1).astype(np.int32)
    diag = np.where(jj <= ii, 0, 1)
    reg = regularise(stair, walk, 2, tolerance_px=1.5)
    assert (reg >= 0).all()
    assert (reg != diag).sum() < (stair != diag).sum()
    rect = np.zeros((20, 30), np.int32)
    rect[5:15, 8:22] = 1
    assert np.array_equal(regularise(rect, np.ones((20, 30), bool), 2, 1.0), rect)
    # a hole in a label survives (drawn as the hole's own label)
    ring = np.zeros((20, 20), np.int32)
    ring[6:14, 6:14] = 2
    assert np.array_equal(regularise(ring, np.ones((20, 20), bool), 3, 1.0), ring)


def test_regularise_overlap_rule_and_walkable_cut():
    """Labels are drawn largest first: where the simplified polygons overlap, the smaller
    label wins; pixels outside the walkable mask are never labelled."""
    lab = np.zeros((20, 20), np.int32)
    lab[4:16, 4:16] = 1  # class 1 (144 px) inside class 0 (256 px): 0 drawn first
    walk = np.ones((20, 20), bool)
    walk[0, :] = False
    out = regularise(lab, walk, 2, tolerance_px=1.0)
    assert (out[4:16, 4:16] == 1).all() and (out[0] == -1).all() and (out[walk] >= 0).all()


def test_label_orphan_components():
    walk = np.zeros((5, 8), bool)
    walk[:, :3] = True
    walk[1:4, 5:8] = True
    out = np.where(walk, -1, -1)
    out[:, :3] = 0
    ref = np.where(walk, 1, -1)
    ref[1, 5] = 2
    got = label_orphan_components(out, ref, walk, 3)
    assert (got[:, :3] == 0).all() and (got[1:4, 5:8] == 1).all() and (got[~walk] == -1).all()
    # nothing to restore where the input had no label either
    assert np.array_equal(label_orphan_components(out, np.where(walk, -1, -1), walk, 3), out)



def _orphans_reference(out, ref, walk, n_classes):
    """Per 8-connected walkable component (scipy's labelling), in plain Python: no label in
    ``out`` but some in ``ref`` -> the majority of ``ref`` there (ties: lower class)."""
    comp, n = ndimage.label(walk, structure=np.ones((3, 3), bool))
    got = np.where(walk, out, -1).astype(np.int32)
    for k in range(1, n + 1):
        m = comp == k
        if (got[m] >= 0).any():
            continue
        votes = [int(((ref == c) & m).sum()) for c in range(n_classes)]
        if max(votes) > 0:
            got[m] = votes.index(max(votes))
    return got


@pytest.mark.parametrize("seed", range(4))
def test_label_orphan_components_equal_reference(seed):
    rng = np.random.default_rng(seed)
    walk = rng.random((30, 40)) < 0.45  # many small 8-connected pockets
    out = np.where(walk & (rng.random(walk.shape) < 0.3), rng.integers(0, 3, walk.shape), -1)
    ref = np.where(rng.random(walk.shape) < 0.7, rng.integers(0, 3, walk.shape), -1)
    got = label_orphan_components(out, ref, walk, 3)
    assert np.array_equal(got, _orphans_reference(out, ref, walk, 3))
    assert (got != np.where(walk, out, -1)).any()  # some pockets were filled


def test_label_orphan_components_bad_reference():
    walk = np.ones((3, 3), bool)
    with pytest.raises(ValueError, match="n_classes = 2"):
        label_orphan_components(np.full((3, 3), -1), np.full((3, 3), 2), walk, 2)


# ---------------------------------------------------------------- shared houses


def test_shared_houses_noisy_ground_truth(procthor_file):
    from envs.datasets.house_files import load_houses
    from envs.maps.scene import rasterise_house

    pp = PostProcess()
    for i, h in enumerate(load_houses(procthor_file, 0, 4)):
        s = rasterise_house(h)
        walk = s.grid.walkable
        noisy = noisy_ground_truth(s.semantic, walk, len(s.classes), 0.2, i)
        out = pp(noisy, s.grid)
        assert out.shape == walk.shape and out.dtype == np.int32
        assert (out[~walk] == -1).all()
        # independent reachability check: every 8-connected walkable component that held
        # an input label is fully labelled
        comp, _ = ndimage.label(walk, structure=EIGHT)
        with_labels = np.unique(comp[noisy >= 0])
        assert (out[np.isin(comp, with_labels) & walk] >= 0).all()
        before, after = np.mean(noisy[walk] == s.semantic[walk]), np.mean(out[walk] == s.semantic[walk])
        assert after > before + 0.1, (h.id, before, after)


# ---------------------------------------------------------------- config, raw output, bad input


def test_configs_instantiate():
    from hydra.utils import instantiate
    from omegaconf import OmegaConf

    for name, cls in [("default", PostProcess), ("none", NoPostProcess)]:
        cfg = OmegaConf.load(f"conf/postprocess/{name}.yaml")
        cfg = OmegaConf.merge({"classes": ["a", "b", "c"]}, {"pp": cfg})
        obj = instantiate(cfg.pp)
        assert isinstance(obj, cls) and obj.n_classes == 3


def test_no_postprocess_only_clears_background():
    grid, clean = clean_two_rooms()
    raw = np.where(grid.walkable, clean, 3)
    raw[10, 10] = 6
    raw[11, 11] = -1
    out = NoPostProcess()(raw, grid)
    assert (out[~grid.walkable] == -1).all()
    assert np.array_equal(out[grid.walkable], raw[grid.walkable])


def test_bad_input():
    grid, clean = clean_two_rooms()
    with pytest.raises(ValueError, match="shape"):
        PostProcess()(clean[:5], grid)
    with pytest.raises(ValueError, match="all-background"):
        PostProcess()(np.full((4, 4), -1), GridMap(np.zeros((4, 4), bool), 0.1, (0, 0)))
    with pytest.raises(ValueError, match="unknown label value"):
        PostProcess(classes=["a", "b"])(np.where(grid.walkable, 5, -1), grid)
    with pytest.raises(ValueError, match="unknown label value"):
        NoPostProcess()(np.where(grid.walkable, -2, -1), grid)
    with pytest.raises(ValueError, match="integer"):
        check_labels(np.full(grid.shape, 0.5), grid.walkable, 7)
    with pytest.raises(ValueError, match="odd"):
        PostProcess(window=4)
    with pytest.raises(ValueError, match="target_resolution"):
        PostProcess(target_resolution=0)
    with pytest.raises(ValueError, match="min_area"):
        PostProcess(min_area=-1)


def test_timing_helpers(procthor_file, tmp_path, capsys):
    from benchmark.commands.maintainer.perf_postprocess import (
        main,
        time_postprocess,
        time_postprocess_job,
    )

    rows = time_postprocess(procthor_file, houses=2, repeat=1)
    assert len(rows) == 2 and all(r["ms"] > 0 and r["agree_after"] > r["agree_before"] for r in rows)
    assert main(["--data", str(procthor_file), "--houses", "1"]) == 0
    assert "post-process median" in capsys.readouterr().out
    with pytest.raises(FileNotFoundError, match="not a finished runner job"):
        time_postprocess_job(tmp_path)


def test_timing_on_a_job_that_ran_part_of_its_environment(tmp_path):
    """``--job`` times the houses the job ran (here 1 of 3), not every house of its env."""
    from hydra import compose, initialize_config_dir

    from benchmark.commands.maintainer.perf_postprocess import time_postprocess_job
    from benchmark.harness.runner import CONF_DIR, run

    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        cfg = compose("config", overrides=["env=synthetic", "env.n_houses=3", "env.resolution=0.1", "run.limit=1",
                                           "classifier=oracle", "postprocess=none", "run.progress=false",
                                           f"run.results_dir={tmp_path / 'r'}"])
    run(cfg, tmp_path / "job", {})
    rows = time_postprocess_job(tmp_path / "job", repeat=1)
    assert [r["house"] for r in rows] == ["synthetic-s000000"] and rows[0]["ms"] > 0
