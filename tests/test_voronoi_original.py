"""The Voronoi segmentation's ``original`` rule (issue 60 item 4): ipa_room_segmentation's
critical-point rule and merging passes re-implemented (``benchmark/segmenters/voronoi_original.py``),
on hand-made graphs, cells and maps with known answers; the option's bad value refused in one line;
and, where ``.ipa-env`` holds the authors' build, the rule against their own output."""

from __future__ import annotations

import numpy as np
import pytest
from omegaconf import OmegaConf

from benchmark.config import compose_job
from benchmark.harness.checks import ConfigError
from benchmark.harness.typed import check_typed
from benchmark.segmenters import voronoi_original as original
from benchmark.segmenters.voronoi import Voronoi, prune_spurs
from envs.maps.gridmap import GridMap
from tests.test_ipa import NEEDS_BUILD
from tests.test_ipa_ports import (
    two_rooms,  # two 4 x 4 m rooms at 0.05 m/px, a 0.8 m door (columns 82-83, rows 34-49)
)

# ---------------------------------------------------------------- the critical-point rule


def test_each_stretch_of_the_graph_gives_its_lowest_clearance_point():
    """A straight graph of 30 pixels, clearance 10 but 4 at column 12; reach 50 pixels²: a
    search from a pixel of clearance 10 stops once it has counted more than 50 // 10 = 5 pixels,
    so the stretches are columns 0-6, 7-13, 14-20, 21-27, 28-29, each giving its lowest pixel
    (the first in raster order on a tie): the narrowing at 12 is the second stretch's point."""
    graph = np.zeros((5, 30), bool)
    graph[2] = True
    clearance = np.full(graph.shape, 10, np.int64)
    clearance[2, 12] = 4
    pts = original.critical_points(graph, clearance, reach_px2=50, max_steps=150)
    assert pts.tolist() == [[2, 0], [2, 12], [2, 14], [2, 21], [2, 28]]
    # a search also stops after max_steps steps: one step takes one pixel on each side of a line
    pts = original.critical_points(graph, clearance, reach_px2=50, max_steps=2)
    assert pts.tolist() == [[2, 0], [2, 3], [2, 6], [2, 9], [2, 12], [2, 15], [2, 18], [2, 21], [2, 24], [2, 27]]


def test_of_two_close_critical_points_the_one_whose_line_turns_more_stays():
    """Points 2 pixels apart with clearance 10 (closer than 0.5 x 10): the 170-degree line stays,
    the 90-degree one goes; on equal angles the shorter line stays; far apart, both stay."""
    pts = np.array([[10, 10], [10, 12], [40, 40]])
    clearance = np.array([10, 10, 10])
    keep = original.keep_lines(pts, clearance, np.array([90.0, 170.0, 90.0]), np.array([20.0, 20.0, 20.0]), 0.5)
    assert keep.tolist() == [False, True, True]
    keep = original.keep_lines(pts, clearance, np.array([170.0, 170.0, 90.0]), np.array([30.0, 20.0, 20.0]), 0.5)
    assert keep.tolist() == [False, True, True]
    keep = original.keep_lines(pts, clearance, np.array([90.0, 170.0, 90.0]), np.array([20.0, 20.0, 20.0]), 0.1)
    assert keep.all()


def test_a_critical_line_ends_on_both_sides_of_a_door():
    """The point in a 16-pixel door (rows 34-49 free between walls): its nearest border pixel is
    on one jamb, the second on the other (farther than the first and more than the clearance
    from it), and the line across the door is nearly straight."""
    grid = two_rooms()
    clear = original.rounded_clearance(grid.walkable)
    ok, b1, b2, angle, length = original.critical_lines(np.array([[41, 82]]), clear,
                                                        original.border_pixels(grid.walkable))
    assert ok[0] and b1[0].tolist() == [34, 82] and b2[0][0] == 49
    assert angle[0] > 170 and 14 <= length[0] <= 17


# ---------------------------------------------------------------- the merging passes


def test_cell_statistics_count_each_pixel_around_a_cell_once_by_its_label():
    """Two cells of 3 x 3 side by side in a walled 5 x 8 map: each one's border is the 16 pixels
    around it (wall 13, the other cell 3)."""
    lab = np.zeros((5, 8), np.int64)
    lab[1:4, 1:4], lab[1:4, 4:7] = 1, 2
    stats = original.cell_statistics(lab, 0.05)
    assert stats[1].border == {0: 13, 2: 3} and stats[2].border == {0: 13, 1: 3}
    assert stats[1].neighbours == {2} and stats[1].area == pytest.approx(9 * 0.05 ** 2)


def alcove_cells() -> np.ndarray:
    """A 4 x 4 m room (cell 1) with a 1.2 x 0.8 m alcove (cell 2) on its top side, open along its
    whole width, at 0.05 m/px; 0 the walls."""
    lab = np.zeros((100, 86), np.int64)
    lab[18:98, 2:82] = 1
    lab[2:18, 30:54] = 2
    return lab


def test_the_merging_passes_join_an_alcove_to_its_room_and_keep_two_rooms_apart():
    """The alcove (one neighbouring cell, under ``max_merge_area``, at most 75 % wall) joins the
    room by the first pass; with ``max_merge_area`` below its area it still joins, by the second
    (under 2 m², its border with the room over a fifth of its perimeter). Two rooms of 16 m²
    that touch along a 0.8 m door stay two."""
    for max_merge_area in (12.5, 0.5):
        merged = original.merge_cells(alcove_cells(), 0.05, max_merge_area)
        assert set(np.unique(merged[merged > 0])) == {1}
    lab = np.zeros((84, 166), np.int64)
    lab[2:82, 2:83] = 1
    lab[2:82, 83:164] = 2
    lab[2:34, 82:84] = lab[50:82, 82:84] = 0  # the wall around the door
    assert set(np.unique(original.merge_cells(lab, 0.05, 12.5)[lab > 0])) == {1, 2}


def test_the_cells_ids_are_the_authors_unseeded_colour_draws():
    """glibc's rand() under its default seed starts 1804289383, 846930886, 1681692777: the
    first cells' ids are those draws mod 52224 plus 13056, and a draw a cell already has is
    skipped (the ids stay distinct)."""
    assert original.colour_ids(3) == [v % 52224 + 13056 for v in (1804289383, 846930886, 1681692777)]
    ids = original.colour_ids(500)
    assert len(set(ids)) == 500 and min(ids) >= 13056 and max(ids) <= 65279


# ---------------------------------------------------------------- the segmenter


def test_the_original_rule_parts_two_rooms_at_their_door():
    """On two rooms joined by a door: one of the kept critical lines crosses the door; the cut
    and merged map is the two rooms, each (but for a few pixels by the door) one room."""
    grid = two_rooms()
    walk = grid.walkable
    graph = prune_spurs(original.voronoi_graph(walk), np.zeros(walk.shape), np.inf)
    clear = original.rounded_clearance(walk)
    pts = original.critical_points(graph, clear, 280, 150)
    ok, b1, b2, angle, length = original.critical_lines(pts, clear, original.border_pixels(walk))
    keep = original.keep_lines(pts[ok], clear[pts[ok][:, 0], pts[ok][:, 1]], angle[ok], length[ok], 0.5)
    at_door = [(p, a, b) for p, a, b in zip(pts[ok][keep], b1[ok][keep], b2[ok][keep]) if 34 <= p[0] <= 49
               and 78 <= p[1] <= 86]
    assert any({a[0], b[0]} == {34, 49} for _, a, b in at_door)  # from jamb to jamb
    inst = Voronoi(rule="original", min_room_area=0.0)(grid)
    assert inst.max() + 1 == 2
    for part in (slice(0, 82), slice(84, 166)):
        ids, counts = np.unique(inst[:, part][walk[:, part]], return_counts=True)
        assert counts.max() >= 0.99 * counts.sum()
    left = np.bincount(inst[:, :82][walk[:, :82]]).argmax()
    right = np.bincount(inst[:, 84:][walk[:, 84:]]).argmax()
    assert left != right


def test_the_original_rule_at_the_maps_own_resolution_and_resampled():
    """At 0.025 m/px the rule runs on the map resampled to 0.05 m/px and its rooms come back on
    the map's own grid: two rooms again, every walkable cell labelled."""
    fine = np.repeat(np.repeat(two_rooms().walkable, 2, axis=0), 2, axis=1)
    grid = GridMap(fine, 0.025, (0.0, 0.0))
    inst = Voronoi(rule="original", min_room_area=0.0)(grid)
    assert inst.shape == fine.shape and (inst[fine] >= 0).all() and (inst[~fine] == -1).all()
    assert inst.max() + 1 == 2


def test_the_settings_in_metres_are_the_authors_pixels(monkeypatch):
    """At 0.05 m/px ``reach`` 0.7 m² and ``max_search`` 7.5 m are the authors' 280 pixels² and
    150 steps (0.7 / 0.05² is 279.99... in floating point: counted as 280, in whole pixels²)."""
    seen = {}
    real = original.critical_points

    def spy(graph, clearance, reach_px2, max_steps):
        seen.update(reach=reach_px2, steps=max_steps)
        return real(graph, clearance, reach_px2, max_steps)

    monkeypatch.setattr(original, "critical_points", spy)
    Voronoi(rule="original", min_room_area=0.0)(two_rooms())
    assert seen == {"reach": 280, "steps": 150}


def test_the_rule_is_checked_in_one_line():
    with pytest.raises(ValueError, match=r"segmenter.rule='voronoi': expected narrowing or original"):
        Voronoi(rule="voronoi")
    with pytest.raises(ValueError, match=r"segmenter.work_resolution=0: expected metres per pixel > 0, or null"):
        Voronoi(rule="original", work_resolution=0)
    cfg = OmegaConf.to_container(compose_job(["segmenter=voronoi", "segmenter.rule=bogus"])[0], resolve=True)
    with pytest.raises(ConfigError, match=r"^segmenter.rule='bogus': expected one of 'narrowing', 'original'$"):
        check_typed(cfg)
    check_typed(OmegaConf.to_container(compose_job(["segmenter=voronoi_original"])[0], resolve=True))


@NEEDS_BUILD
def test_the_original_rule_agrees_with_the_authors_build_on_two_rooms():
    """The authors' own Voronoi segmentation (``make ipa-env``) on the same map: the same two
    rooms, cell for cell but for a few by the door."""
    from benchmark.segmenters.ipa import IpaSegmenter

    grid = two_rooms()
    ours = Voronoi(rule="original", min_room_area=0.0)(grid)
    theirs = IpaSegmenter("voronoi")(grid)
    walk = grid.walkable
    assert ours.max() == theirs.max() == 1
    same = (ours[walk] == theirs[walk]).mean()
    assert max(same, 1 - same) > 0.99


@NEEDS_BUILD
def test_the_original_rule_gives_the_authors_rooms_on_a_furnished_generated_house():
    """A generated house (seed 101: furnished, 14 segments from the authors' build): the rule's
    rooms are the original's, the same partition. With sequential ids in place of the authors'
    colour draws, or the neighbourhood as 279 pixels² in place of their 280, it was not."""
    from benchmark.segmenters.ipa import IpaSegmenter
    from envs.datasets.synthetic import SyntheticEnv

    env = SyntheticEnv(n_houses=1, seed_start=101)
    grid = env.scene(env.house_ids()[0]).grid
    ours = Voronoi(rule="original", min_room_area=0.0)(grid)
    theirs = IpaSegmenter("voronoi")(grid)
    walk = theirs >= 0
    assert ours.max() == theirs.max() >= 5
    pairs = np.unique(np.stack([ours[walk], theirs[walk]]), axis=1)
    assert pairs.shape[1] == theirs.max() + 1  # one of ours for each of theirs: the same partition
