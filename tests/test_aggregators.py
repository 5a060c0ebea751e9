import numpy as np
import pytest
from maps import pose_at, two_rooms_grid

from benchmark.aggregators.euclidean_knn import EuclideanKNN
from benchmark.aggregators.graph_knn import GraphKNN
from benchmark.aggregators.reference import (
    euclidean_knn_reference,
    graph_knn_reference,
    vision_cone_reference,
    vision_cone_votes_reference,
)
from benchmark.aggregators.vision_cone import VisionCone
from envs.maps.gridmap import GridMap


def random_case(seed, n=None, c=4):
    """A random map (obstacle share and size vary with the seed) with n random walkable views."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(6, 25)) if n is None else n
    walk = rng.random((int(rng.integers(20, 36)), int(rng.integers(25, 45)))) > rng.uniform(0.1, 0.4)
    walk[::7, :] = True  # corridors keep most of it connected
    grid = GridMap(walk, 0.05, (0.0, 1.5))
    rr, cc = np.nonzero(walk)
    pick = rng.choice(len(rr), n, replace=False)
    poses = np.array([pose_at(grid, rr[i], cc[i], rng.uniform(0, 360)) for i in pick])
    proba = rng.dirichlet(np.ones(c), n)
    # duplicated positions and equal labels make ties on purpose
    poses[1, :2] = poses[0, :2]
    proba[2] = proba[3]
    return grid, poses, proba


@pytest.mark.parametrize("kind", ["graph_knn", "euclidean_knn"])
def test_neighbours_kept_for_the_next_classifier_give_the_reference_labels(kind, monkeypatch):
    """The neighbour tables kept per process (kept_neighbours): a second aggregation of the same
    views on the same map with other probabilities reads the kept table and still equals the
    reference; a map with one cell changed, or views with one moved, makes its own; a table larger
    than the memo's budget is not kept."""
    from benchmark.aggregators import common

    monkeypatch.setattr(common, "_NEIGHBOURS", common.ByteLRU())
    made = []
    for name in ("knn_neighbours", "euclidean_neighbours"):
        module = __import__(f"benchmark.aggregators.{kind}", fromlist=[name])
        if hasattr(module, name):
            real = getattr(module, name)
            monkeypatch.setattr(module, name, lambda *a, real=real, **k: made.append(1) or real(*a, **k))

    def labels(grid, poses, proba, k=3):
        agg = GraphKNN(k=k) if kind == "graph_knn" else EuclideanKNN(k=k)
        return agg(grid, poses, proba)

    def reference(grid, poses, proba, k=3):
        return (graph_knn_reference(grid, poses, proba, k, 4, "majority") if kind == "graph_knn"
                else euclidean_knn_reference(grid, poses, proba, k, "majority"))

    grid, poses, proba = random_case(3, n=14)
    assert np.array_equal(labels(grid, poses, proba), reference(grid, poses, proba)) and len(made) == 1
    other = np.random.default_rng(9).dirichlet(np.ones(4), len(poses))
    assert not np.array_equal(reference(grid, poses, other), reference(grid, poses, proba))
    assert np.array_equal(labels(grid, poses, other), reference(grid, poses, other)) and len(made) == 1  # kept
    walk = grid.walkable.copy()
    rr, cc = np.nonzero(walk)
    walk[rr[-1], cc[-1]] = False  # one walkable cell fewer (no view on it)
    changed = GridMap(walk, grid.resolution, grid.origin)
    assert np.array_equal(labels(changed, poses, other), reference(changed, poses, other)) and len(made) == 2
    moved = poses.copy()
    moved[5, :2] = poses[6, :2]
    assert np.array_equal(labels(grid, moved, other), reference(grid, moved, other)) and len(made) == 3
    assert np.array_equal(labels(grid, poses, other, k=2), reference(grid, poses, other, k=2)) and len(made) == 4
    assert len(common._NEIGHBOURS) == 4
    monkeypatch.setattr(common, "NEIGHBOURS_MEMO_BYTES", 16)
    labels(grid, poses, other, k=1)
    assert len(common._NEIGHBOURS) == 0 and len(made) == 5  # over the budget: nothing kept, the rest let go


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("conn", [4, 8])
@pytest.mark.parametrize("k", [1, 3, 5])
@pytest.mark.parametrize("weighting", ["majority", "probability"])
def test_graph_knn_equals_one_bfs_per_viewpoint(seed, conn, k, weighting):
    grid, poses, proba = random_case(seed)
    fast = GraphKNN(k=k, connectivity=conn, weighting=weighting)(grid, poses, proba)
    ref = graph_knn_reference(grid, poses, proba, k, conn, weighting)
    assert np.array_equal(fast, ref)


@pytest.mark.parametrize("seed", range(8))
@pytest.mark.parametrize("k", [1, 4])
@pytest.mark.parametrize("weighting", ["majority", "probability"])
def test_euclidean_knn_equals_sorting_every_view(seed, k, weighting):
    grid, poses, proba = random_case(seed)
    if seed % 2:  # views on a lattice: many equal distances, ties at the K-th place included
        rr, cc = np.nonzero(grid.walkable)
        on = (rr % 4 == 0) & (cc % 4 == 0)
        poses = np.array([pose_at(grid, r, c, 0) for r, c in zip(rr[on], cc[on])])
        proba = np.random.default_rng(seed).dirichlet(np.ones(4), len(poses))
    fast = EuclideanKNN(k=k, weighting=weighting)(grid, poses, proba)
    assert np.array_equal(fast, euclidean_knn_reference(grid, poses, proba, k, weighting))


@pytest.mark.parametrize("seed", range(5))
@pytest.mark.parametrize("vote", ["label", "probability"])
@pytest.mark.parametrize("density", [1.0, 2.0])
def test_vision_cone_equals_per_ray_loop(seed, vote, density):
    grid, poses, proba = random_case(seed)
    kw = dict(fov=90.0, max_range_m=0.8, blocked_ray_m=0.1, window=3, vote=vote, ray_density=density)
    assert np.array_equal(VisionCone(**kw)(grid, poses, proba), vision_cone_reference(grid, poses, proba, **kw))


@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize("fov, density, paths", [(360.0, 1.0, True), (90.0, 0.4, True), (120.0, 1.0, False)])
@pytest.mark.parametrize("vote", ["label", "probability"])
def test_vision_cone_equals_per_ray_loop_beyond_neighbouring_ends(seed, fov, density, paths, vote, monkeypatch):
    """A whole turn (the last ray's end next to the first's), sparse rays (ends 2-3 px apart: no
    difference list, each ray walked whole) and no path tables at all (over the budget: each ray
    walks its own line), with either vote: the same cells as the per-ray reference."""
    import benchmark.aggregators.vision_cone as vc

    if not paths:
        monkeypatch.setattr(vc, "PATH_CACHE_BYTES", 0)
    grid, poses, proba = random_case(seed)
    kw = dict(fov=fov, max_range_m=1.2, blocked_ray_m=0.1, window=1, ray_density=density, vote=vote)
    assert np.array_equal(VisionCone(**kw)(grid, poses, proba), vision_cone_reference(grid, poses, proba, **kw))
    assert (vc.ray_paths(24.0, vc.PATH_CACHE_BYTES)[0] > 0) == paths


def test_ray_paths_are_the_digital_lines_to_their_ends():
    """Every kept path, put back at a camera, is the cell list of trace_ray to that end; and
    each difference list names exactly the indices where two neighbouring paths differ, then
    those where the path goes on beyond its neighbour's end (some neighbours are shorter)."""
    from envs.maps.ray_paths import ray_paths
    from envs.maps.rays import trace_ray

    k, slot, pm, geo, plen, dstart, dj = ray_paths(9.5)
    free = np.zeros((41, 41), bool)
    cells = {}
    for er, ec in np.argwhere(slot >= 0) - k:
        s = slot[er + k, ec + k]
        j = np.arange(plen[s])
        got = np.stack([20 + geo[s, 0] * j + geo[s, 2] * pm[s, j], 20 + geo[s, 1] * j + geo[s, 3] * pm[s, j]], 1)
        br, bc = np.zeros(41, np.int32), np.zeros(41, np.int32)
        n, _, _ = trace_ray(free, 20, 20, 20 + er, 20 + ec, br, bc)
        assert np.array_equal(got, np.stack([br[:n], bc[:n]], 1))
        cells[(er, ec)] = got
    assert len(cells) > 100
    tails = 0
    for (er, ec), a in cells.items():
        for q in range(9):
            b = cells.get((er + q // 3 - 1, ec + q % 3 - 1))
            if q == 4 or b is None:
                continue
            m = min(len(a), len(b))
            # where they differ, then where this path goes on beyond the other's end
            want = np.concatenate([np.nonzero((a[:m] != b[:m]).any(1))[0], np.arange(m, len(a))])
            s = slot[er + k, ec + k]
            got = dj[2 * dstart[s, q]:2 * dstart[s, q + 1]].reshape(-1, 2)
            assert np.array_equal(got[:, 0], want)
            # each with this path's minor coordinate there (relative to the camera at (20, 20))
            assert np.array_equal(got[:, 1], (a[want, 1] if geo[s, 2] == 0 else a[want, 0]) - 20)
            tails += len(a) > len(b)
    assert tails > 100


def test_the_cone_refuses_path_tables_of_a_shorter_range(monkeypatch):
    """The kernel reads a ray's path from the tables without a bounds test (its end lies within
    ceil(range) px of the camera): tables of a shorter range are refused, not read beyond."""
    import benchmark.aggregators.vision_cone as vc
    from envs.maps.ray_paths import _no_paths

    grid, poses, proba = random_case(0)
    cone = VisionCone(max_range_m=1.2)
    want = cone.votes(grid, poses, proba).copy()
    shorter = vc.ray_paths(3.0, vc.PATH_CACHE_BYTES)
    monkeypatch.setattr(vc, "ray_paths", lambda max_range, budget: shorter)
    with pytest.raises(ValueError, match="shorter range"):
        cone.votes(grid, poses, proba)
    monkeypatch.setattr(vc, "ray_paths", lambda max_range, budget: _no_paths())  # none: every ray walked
    assert np.array_equal(cone.votes(grid, poses, proba), want)


def test_knn_splits_at_the_geodesic_midpoint_not_across_the_wall():
    grid = two_rooms_grid(door=(2, 6))  # door at the top
    # view A in the left room near the wall's bottom, view B in the right room far away
    poses = np.array([pose_at(grid, 34, 34, 0), pose_at(grid, 4, 70, 0)])
    proba = np.eye(3)[[0, 1]]
    lab = GraphKNN(k=1)(grid, poses, proba)
    eu = EuclideanKNN(k=1)(grid, poses, proba)
    # the cell just right of the wall at the bottom is Euclidean-close to A but geodesically to B
    assert eu[34, 41] == 0 and lab[34, 41] == 1
    assert (lab[2:38, 2:38][grid.walkable[2:38, 2:38]] == 0).all()
    # along the path, the boundary is where the geodesic distances are equal
    assert lab[3, 50] == 1 and lab[30, 20] == 0


def test_cone_labels_the_room_it_looks_into_knn_where_it_stands():
    grid = two_rooms_grid(door=(16, 24))
    left = pose_at(grid, 20, 30, 90)  # in the left room, looking right through the door
    right = pose_at(grid, 20, 60, 90)  # in the right room, looking away (right)
    poses = np.array([left, right])
    proba = np.eye(2)[[1, 0]]
    cone = VisionCone(fov=30, max_range_m=2.0, window=1)(grid, poses, proba)
    knn = GraphKNN(k=1)(grid, poses, proba)
    # (20, 50) in the right room: seen only by the left view -> its label; geodesically nearer
    # to the right view (10 steps vs 20) -> KNN gives the right view's label
    assert cone[20, 50] == 1 and knn[20, 50] == 0
    assert knn[20, 30] == 1
    assert cone[5, 5] == -1  # no view looked at the top-left corner


def test_view_facing_a_wall_is_dropped():
    grid = two_rooms_grid()
    poses = np.array([pose_at(grid, 30, 36, 90)])  # 2 px from the wall, facing it
    cone = VisionCone(blocked_ray_m=0.3)
    assert (cone(grid, poses, np.eye(2)[[1]]) == -1).all() and cone.last_used == 0


@pytest.mark.parametrize("agg", [GraphKNN(k=2), VisionCone(max_range_m=1.0), EuclideanKNN(k=2)])
def test_views_off_the_map_are_dropped_and_counted(agg, caplog):
    grid, poses, proba = random_case(3)
    r, c = np.nonzero(~grid.walkable)
    bad = np.array([[-3.0, 0.0, 0.0], pose_at(grid, r[0], c[0], 0)])  # off the map; on an obstacle
    both = agg(grid, np.vstack([bad, poses]), np.vstack([np.eye(4)[[0, 1]], proba]))
    assert "2 of" in caplog.text and "dropped" in caplog.text
    assert np.array_equal(both, agg(grid, poses, proba))


@pytest.mark.parametrize("agg", [GraphKNN(k=2), VisionCone(), EuclideanKNN(k=2)])
def test_bad_inputs(agg):
    grid = two_rooms_grid()
    good = np.array([pose_at(grid, 10, 10, 0), pose_at(grid, 12, 12, 0)])
    with pytest.raises(ValueError, match="no viewpoints"):
        agg(grid, np.zeros((0, 3)), np.zeros((0, 3)))
    with pytest.raises(ValueError, match="off the walkable map"):
        agg(grid, np.array([[99.0, 99.0, 0.0], [-5.0, 0.0, 0.0]]), np.eye(3)[:2])
    with pytest.raises(ValueError, match="probability matrix"):
        agg(grid, good, np.eye(3))
    if not isinstance(agg, VisionCone):
        with pytest.raises(ValueError, match="larger than"):
            type(agg)(k=5)(grid, good, np.eye(3)[:2])


@pytest.mark.parametrize("weighting", ["majority", "probability"])
@pytest.mark.parametrize("seed", range(4))
def test_numba_vote_equals_numpy_reference(weighting, seed):
    """The aggregators' numba vote against the references' NumPy vote, with many ties (few
    classes, probabilities on a coarse grid) and cells with fewer than K or no neighbours."""
    from benchmark.aggregators.common import vote_neighbours
    from benchmark.aggregators.reference import vote_reference

    rng = np.random.default_rng(seed)
    n_views, m, k, c = 40, 3000, 7, 4
    proba = rng.integers(0, 4, size=(n_views, c)).astype(float) / 4
    nbr = rng.integers(0, n_views, size=(m, k))
    short = rng.integers(0, k + 1, size=m)  # neighbours kept per cell (0: none); the rest -1
    nbr[np.arange(k)[None, :] >= short[:, None]] = -1
    got, want = vote_neighbours(nbr, proba, weighting), vote_reference(nbr, proba, weighting)
    assert got.dtype == np.int32 and (got[short == 0] == -1).all()
    np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize("k", [1, 4, 5, 8])
def test_euclidean_neighbours_with_lattice_ties(k):
    """Views on a lattice (and two on one cell): most cells have several views at the same
    distance; the row-pruned kernel keeps the (distance, index) order of a full sort."""
    from benchmark.aggregators.euclidean_knn import euclidean_neighbours

    rr, cc = np.mgrid[2:40:4, 3:50:4]
    rows, cols = rr.ravel()[::-1].copy(), cc.ravel()[::-1].copy()  # index order unlike row order
    rows[5], cols[5] = rows[9], cols[9]
    cells = np.argwhere(np.ones((42, 53), bool))
    d2 = (cells[:, None, 0] - rows[None]) ** 2 + (cells[:, None, 1] - cols[None]) ** 2
    ids = np.broadcast_to(np.arange(len(rows)), d2.shape)
    want = np.take_along_axis(ids, np.lexsort((ids, d2), axis=1)[:, :k], 1)
    np.testing.assert_array_equal(euclidean_neighbours(rows, cols, cells, k), want)


@pytest.mark.parametrize("seed", range(6))
def test_euclidean_neighbours_of_cells_in_any_order_with_views_in_clusters(seed):
    """Cells given in no particular order (some far from every view, some in tiles of their own)
    and views in tight clusters: a cell's K-th view can lie far on the other side of its tile's
    centre; the tiled kernel keeps the (distance, index) order of a full sort of every view."""
    from benchmark.aggregators.euclidean_knn import euclidean_neighbours

    rng = np.random.default_rng(seed)
    centres = rng.integers(0, 90, size=(rng.integers(1, 5), 2))
    which = rng.integers(0, len(centres), rng.integers(3, 40))
    spots = centres[which] + rng.integers(-2, 3, size=(len(which), 2))
    rows, cols = spots[:, 0].copy(), spots[:, 1].copy()
    cells = np.argwhere(rng.random((97, 91)) < 0.4)
    cells = cells[rng.permutation(len(cells))]
    for k in sorted({1, 2, min(5, len(rows)), len(rows)}):
        d2 = (cells[:, None, 0] - rows[None]) ** 2 + (cells[:, None, 1] - cols[None]) ** 2
        ids = np.broadcast_to(np.arange(len(rows)), d2.shape)
        want = np.take_along_axis(ids, np.lexsort((ids, d2), axis=1)[:, :k], 1)
        np.testing.assert_array_equal(euclidean_neighbours(rows, cols, cells, k), want)
    assert euclidean_neighbours(rows, cols, np.zeros((0, 2), np.int64), 1).shape == (0, 1)


@pytest.mark.parametrize("k", [1, 3, 5, 9])
def test_euclidean_neighbours_of_views_turning_in_place(k):
    """Views in runs on one cell (1 to 8 a place, as views turning in place), places revisited
    later in the route and places in one row: the kernel's places keep the (distance, index)
    order of a full sort of every view."""
    from benchmark.aggregators.euclidean_knn import euclidean_neighbours, view_places

    rng = np.random.default_rng(5)
    spots = rng.integers(0, 30, size=(12, 2))
    spots[3] = [spots[2, 0], spots[2, 1] + 7]  # two places in one row
    route = np.concatenate([rng.integers(0, 12, 25), [2, 2, 2]])  # places visited again
    which = np.repeat(route, rng.integers(1, 9, len(route)))
    rows, cols = spots[which, 0].copy(), spots[which, 1].copy()
    cells = np.argwhere(np.ones((32, 32), bool))
    d2 = (cells[:, None, 0] - rows[None]) ** 2 + (cells[:, None, 1] - cols[None]) ** 2
    ids = np.broadcast_to(np.arange(len(rows)), d2.shape)
    want = np.take_along_axis(ids, np.lexsort((ids, d2), axis=1)[:, :k], 1)
    np.testing.assert_array_equal(euclidean_neighbours(rows, cols, cells, k), want)
    prow, pcol, starts, members = view_places(rows.astype(np.int64), cols.astype(np.int64))
    assert len(prow) == len(np.unique(spots[route], axis=0)) and (np.diff(prow) >= 0).all()
    for p in range(len(prow)):  # each place: its views, in index order
        on = members[starts[p]:starts[p + 1]]
        assert (np.diff(on) > 0).all() and (rows[on] == prow[p]).all() and (cols[on] == pcol[p]).all()
    assert sorted(members) == list(range(len(rows)))


@pytest.mark.slow
@pytest.mark.shared_data
@pytest.mark.parametrize("vote", ["label", "probability"])
def test_vision_cone_equals_per_ray_loop_on_a_shared_house_at_default_settings(shared_houses, vote):
    """A real ProcTHOR house at 0.05 m/px, the default 10 m cone (315 rays a view, furniture
    and walls blocking them at every distance): the kernel's shared-path walk votes for
    exactly the cells the per-ray reference walks."""
    from benchmark.viewpoints import Autotrace
    from envs.maps.scene import rasterise_house

    scene = rasterise_house(shared_houses[0], resolution=0.05)
    poses = Autotrace().generate(scene)[::12]
    proba = np.random.default_rng(1).dirichlet(np.ones(len(scene.classes)), len(poses))
    cone = VisionCone(vote=vote)
    got, want = cone(scene.grid, poses, proba), vision_cone_reference(scene.grid, poses, proba, vote=vote)
    assert cone.last_used > 5 and (got >= 0).sum() > 1000
    assert np.array_equal(got, want)


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("window", [1, 3, 5])
@pytest.mark.parametrize("n_classes", [1, 2, 7])
def test_window_mode_one_class_at_a_time_equals_the_stacked_argmax(seed, window, n_classes):
    """Small integer votes (ties everywhere, cells with none) and fractional ones: the running
    best equals the argmax over all classes' window sums, ties to the lower class."""
    from benchmark.aggregators.reference import window_mode_reference
    from benchmark.aggregators.vision_cone import window_mode

    rng = np.random.default_rng(seed)
    counts = rng.integers(0, 3, (n_classes, 23, 31)).astype(np.float32) * (rng.random((n_classes, 23, 31)) < 0.3)
    if seed % 2:
        counts = counts * rng.random(counts.shape).astype(np.float32)
    walkable = rng.random((23, 31)) < 0.8
    got = window_mode(counts, walkable, window)
    assert got.dtype == np.int32 and (got == -1).any() and (got >= 0).any()
    want = window_mode_reference(counts, walkable, window)
    assert np.array_equal(got, want)
    for band in (1, 2, 5, 22):  # bands of rows, windows reaching across their edges: the same
        assert np.array_equal(window_mode(counts, walkable, window, band_rows=band), want)
    if seed % 2 == 0:  # whole votes as the cone counts them (uint8, uint16): the same
        assert np.array_equal(window_mode(counts.astype(np.uint16), walkable, window, band_rows=7), want)
        assert np.array_equal(window_mode(counts.astype(np.uint8), walkable, window, band_rows=7), want)


def test_vote_bound_counts_the_views_in_the_tiles_around_a_cell():
    """max_votes_per_cell on known layouts (tiles of 10 px): views in the 3 x 3 tiles around
    any one tile add up, views three tiles apart do not; no views, no votes."""
    from benchmark.aggregators.vision_cone import max_votes_per_cell

    def bound(*groups):
        rows = np.concatenate([np.full(n, r) for n, r, _ in groups])
        cols = np.concatenate([np.full(n, c) for n, _, c in groups])
        return max_votes_per_cell((100, 120), rows, cols, 10)

    assert bound((3, 0, 0), (5, 95, 115)) == 5
    assert bound((3, 0, 0), (4, 15, 15)) == 7  # neighbouring tiles (0, 0) and (1, 1)
    assert bound((3, 0, 0), (4, 25, 5)) == 7  # tiles (0, 0) and (2, 0): tile (1, 0) touches both
    assert bound((3, 0, 0), (4, 35, 5)) == 4  # tiles (0, 0) and (3, 0): no tile touches both
    assert bound((3, 9, 9), (4, 10, 10), (2, 99, 119)) == 7
    assert max_votes_per_cell((100, 120), np.zeros(0, int), np.zeros(0, int), 10) == 0


@pytest.mark.parametrize("seed", range(4))
def test_cone_votes_equal_the_reference_in_the_smallest_type(seed):
    """The cone's whole votes are the per-ray reference's counts, in uint8 (few views near any
    cell), and no cell gets more votes than the bound the type was chosen by."""
    from benchmark.aggregators.vision_cone import max_votes_per_cell, reach_px

    grid, poses, proba = random_case(seed)
    kw = dict(fov=120.0, max_range_m=0.8, blocked_ray_m=0.1)
    cone = VisionCone(**kw)
    got, want = cone.votes(grid, poses, proba), vision_cone_votes_reference(grid, poses, proba, **kw)
    assert got.dtype == np.uint8 and want.max() >= 2 and np.array_equal(got, want)
    r, c = grid.world_to_cell(poses[:, 0], poses[:, 1])
    assert want.sum(0).max() <= max_votes_per_cell(grid.shape, r, c, reach_px(0.8 / grid.resolution))


@pytest.mark.parametrize(("n", "dtype"), [(255, np.uint8), (256, np.uint16), (65_535, np.uint16), (65_536, np.uint32)])
def test_cone_votes_widen_where_a_cell_can_get_more_votes(n, dtype):
    """n copies of one view: every cell it sees gets exactly n votes (n times the reference's
    one view), in the narrowest type that holds n, including past 255 and 65,535."""
    grid, poses, proba = random_case(0)
    kw = dict(fov=90.0, max_range_m=0.8, blocked_ray_m=0.0)
    one = vision_cone_votes_reference(grid, poses[:1], proba[:1], **kw)
    got = VisionCone(**kw).votes(grid, np.repeat(poses[:1], n, 0), np.repeat(proba[:1], n, 0))
    assert got.dtype == dtype and one.sum() > 10 and np.array_equal(got, one * n)
