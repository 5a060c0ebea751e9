"""The SLAM front end: the correlative scan matcher (against a slow plain-Python reference that
shares no code with it), laser odometry, and loop closures proposed from the robot's estimate and
accepted on the match (fooled by two identical rooms)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from benchmark.conditions.front_end import WRONG_XY, FrontEndSettings, run_front_end
from benchmark.conditions.odometry import increments, move_sigmas, wrap
from benchmark.conditions.pose_graph import move_edge, relative
from benchmark.conditions.scan_matching import EPS, SMALL, LikelihoodGrid, match
from envs.maps.gridmap import GridMap

# --------------------------------------------------------------------------- hand-made scans


def _room_points(spacing: float = 0.03) -> np.ndarray:
    """World points on the walls of an L-shaped room with a pillar (no symmetry)."""
    corners = [(0, 0), (5, 0), (5, 2), (3, 2), (3, 4), (0, 4), (0, 0)]
    pts = []
    for (x0, y0), (x1, y1) in zip(corners[:-1], corners[1:]):
        n = int(math.hypot(x1 - x0, y1 - y0) / spacing)
        t = np.arange(n) / n
        pts.append(np.column_stack([x0 + t * (x1 - x0), y0 + t * (y1 - y0)]))
    a = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    pts.append(np.column_stack([1.2 + 0.2 * np.cos(a), 1.0 + 0.2 * np.sin(a)]))
    return np.vstack(pts)


def _in_frame(world: np.ndarray, pose) -> np.ndarray:
    c, s = math.cos(pose[2]), math.sin(pose[2])
    d = world - np.asarray(pose[:2])
    return np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]])


def test_matcher_recovers_a_known_offset_within_a_cell_and_a_step():
    world = _room_points()
    pose_a = np.array([1.5, 1.5, 0.3])
    truth = np.array([0.23, -0.11, math.radians(3.7)])  # b's pose in a's frame
    c, s = math.cos(pose_a[2]), math.sin(pose_a[2])
    pose_b = np.array([pose_a[0] + c * truth[0] - s * truth[1], pose_a[1] + s * truth[0] + c * truth[1],
                       pose_a[2] + truth[2]])
    ref = LikelihoodGrid(_in_frame(world[::2], pose_a), 0.05, 0.05)
    pts_b = _in_frame(world[1::2], pose_b)  # other samples of the same walls
    m, _ = match(ref, pts_b, np.zeros(3), 0.4, math.radians(8.0), math.radians(0.25))
    # tolerance: one grid cell (0.05 m) per axis and one heading step (0.25 deg)
    assert abs(m.best[0] - truth[0]) <= 0.05 and abs(m.best[1] - truth[1]) <= 0.05
    assert abs(m.best[2] - truth[2]) <= math.radians(0.25) + 1e-12
    assert m.score > 0.8
    # the weighted mean stays as close, and the covariance is a covariance
    assert np.hypot(*(m.mean[:2] - truth[:2])) <= 0.05 and abs(m.mean[2] - truth[2]) <= math.radians(0.25)
    assert np.all(np.linalg.eigvalsh(m.cov) >= -1e-15)
    # a far search centre that does not reach the truth scores poorly
    far, _ = match(ref, pts_b, np.array([1.5, 1.0, 0.0]), 0.2, math.radians(2.0), math.radians(0.25))
    assert far.score < 0.5 * m.score


# --------------------------------------------------------------------------- the slow reference


def _reference_grid(points, res, sigma):
    """(x0, y0, log-likelihood rows) by the definition, in plain Python: each cell's centre, its
    nearest point within 3 sigma, log(eps + (1 - eps) exp(-d^2 / 2 sigma^2))."""
    margin = 3.0 * sigma + res
    xs = [p[0] for p in points]
    ys = [p[1] for p in points]
    x0, y0 = min(xs) - margin, min(ys) - margin
    w = max(int(math.ceil((max(xs) + margin - x0) / res)), 1)
    h = max(int(math.ceil((max(ys) + margin - y0) / res)), 1)
    rows = []
    for r in range(h):
        row = []
        for c in range(w):
            cx, cy = x0 + (c + 0.5) * res, y0 + (r + 0.5) * res
            best = 0.0
            for px, py in points:
                d2 = (cx - px) ** 2 + (cy - py) ** 2
                if d2 <= 9.0 * sigma * sigma:
                    best = max(best, math.exp(-d2 / (2.0 * sigma * sigma)))
            row.append(math.log(EPS + (1.0 - EPS) * best))
        rows.append(row)
    return x0, y0, rows


def _reference_search(points_a, points_b, centre, kx, kt, res, sigma, step):
    """Every pose of the window scored by the definition: {(k, i, j): L}."""
    x0, y0, rows = _reference_grid(points_a, res, sigma)
    h, w = len(rows), len(rows[0])
    scores = {}
    for k in range(2 * kt + 1):
        th = centre[2] + (k - kt) * step
        ct, st = math.cos(th), math.sin(th)
        cells = [(math.floor((st * px + ct * py + centre[1] - y0) / res),
                  math.floor((ct * px - st * py + centre[0] - x0) / res)) for px, py in points_b]
        for i in range(2 * kx + 1):
            for j in range(2 * kx + 1):
                total = 0.0
                for r, c in cells:
                    r, c = r + j - kx, c + i - kx
                    total += rows[r][c] if 0 <= r < h and 0 <= c < w else math.log(EPS)
                scores[(k, i, j)] = total
    return rows, scores


def test_compiled_matcher_matches_the_slow_reference():
    world = _room_points(0.15)
    rng = np.random.default_rng(3)
    pose_a, pose_b = np.array([1.4, 1.2, 0.2]), np.array([1.55, 1.1, 0.25])
    pts_a = _in_frame(world, pose_a) + rng.normal(0, 0.01, (len(world), 2))
    pts_b = _in_frame(world[rng.permutation(len(world))[:45]], pose_b)
    res, sigma, step, centre = 0.05, 0.05, math.radians(0.5), np.array([0.1, -0.05, 0.03])
    kx, kt = 4, 5
    ref_rows, ref_scores = _reference_search([tuple(p) for p in pts_a], [tuple(p) for p in pts_b], centre,
                                             kx, kt, res, sigma, step)
    grid = LikelihoodGrid(pts_a, res, sigma)
    np.testing.assert_allclose(grid.grid, np.array(ref_rows), rtol=0, atol=1e-12)
    full, surface = match(grid, pts_b, centre, kx * res, kt * step, step, exhaustive=True)
    want = np.empty_like(surface)
    for (k, i, j), v in ref_scores.items():
        want[k, i, j] = v
    np.testing.assert_allclose(surface, want, rtol=1e-12, atol=1e-9)  # the same scores, every pose
    k, i, j = np.unravel_index(int(np.argmax(want)), want.shape)  # first (lowest k, i, j) of the best
    best = np.array([centre[0] + (i - kx) * res, centre[1] + (j - kx) * res, centre[2] + (k - kt) * step])
    bound, partial = match(grid, pts_b, centre, kx * res, kt * step, step)
    for m in (full, bound):
        np.testing.assert_allclose(m.best, best, atol=1e-12)  # the same best pose
        assert m.loglik == pytest.approx(want[k, i, j], rel=1e-12)
    # branch and bound scored fewer poses, each as the reference does
    seen = np.isfinite(partial)
    assert bound.evaluated == seen.sum() < surface.size
    np.testing.assert_allclose(partial[seen], want[seen], rtol=1e-12, atol=1e-9)


def test_small_window_scored_pose_by_pose_matches_the_slow_reference():
    # a window of at most SMALL translations a side takes the padded flat grid (no bound); a centre far
    # enough off that some of b's points leave the grid at some shifts checks that they read log(EPS)
    world = _room_points(0.15)
    rng = np.random.default_rng(5)
    pts_a = _in_frame(world, np.array([1.4, 1.2, 0.2])) + rng.normal(0, 0.01, (len(world), 2))
    pts_b = _in_frame(world[rng.permutation(len(world))[:45]], np.array([1.5, 1.15, 0.22]))
    grid = LikelihoodGrid(pts_a, 0.05, 0.05)
    step = math.radians(0.5)
    for centre, (kx, kt) in ((np.array([0.1, -0.05, 0.03]), (2, 4)), (np.array([1.2, -0.9, 0.3]), (3, 2))):
        _, ref_scores = _reference_search([tuple(p) for p in pts_a], [tuple(p) for p in pts_b], centre, kx, kt,
                                          0.05, 0.05, step)
        m, surface = match(grid, pts_b, centre, kx * 0.05, kt * step, step)
        assert 2 * kx + 1 <= SMALL and m.evaluated == surface.size == len(ref_scores)
        want = np.empty_like(surface)
        for (k, i, j), v in ref_scores.items():
            want[k, i, j] = v
        np.testing.assert_allclose(surface, want, rtol=1e-12, atol=1e-9)
        k, i, j = np.unravel_index(int(np.argmax(want)), want.shape)
        np.testing.assert_allclose(m.best, [centre[0] + (i - kx) * 0.05, centre[1] + (j - kx) * 0.05,
                                            centre[2] + (k - kt) * step], atol=1e-12)
    c, s = math.cos(centre[2]), math.sin(centre[2])
    x = c * pts_b[:, 0] - s * pts_b[:, 1] + centre[0]
    y = s * pts_b[:, 0] + c * pts_b[:, 1] + centre[1]
    h, w = grid.grid.shape
    off = (x < grid.x0) | (x >= grid.x0 + w * 0.05) | (y < grid.y0) | (y >= grid.y0 + h * 0.05)
    assert 0 < off.sum() < len(pts_b)  # the second window puts some of b's points off the grid


# --------------------------------------------------------------------------- two identical rooms


def _two_rooms(res: float = 0.05) -> GridMap:
    """Two identical 4 x 4 m rooms side by side (x 0..4 and 5..9 m, z 2..6 m), each with a door in
    its bottom wall onto a corridor (z 0..1.5 m) running under both; a cupboard and a chest in each."""
    w, h = int(10 / res), int(7 / res)
    walk = np.zeros((h, w), bool)
    grid0 = GridMap(walk, res, (-0.5, 6.5))

    def box(x0, x1, z0, z1, value):
        r0, c0 = grid0.world_to_cell(x0, z1)
        r1, c1 = grid0.world_to_cell(x1, z0)
        walk[int(r0):int(r1), int(c0):int(c1)] = value

    for x in (0.0, 5.0):
        box(x, x + 4.0, 2.0, 6.0, True)             # the room
        box(x + 1.5, x + 2.3, 1.5, 2.0, True)       # its door
        box(x + 3.0, x + 4.0, 5.2, 6.0, False)      # a cupboard in its corner
        box(x + 0.0, x + 0.6, 2.0, 2.8, False)      # a chest by the door
    box(0.0, 9.0, 0.0, 1.5, True)                   # the corridor
    return GridMap(walk, res, (-0.5, 6.5))


def _path(points, step=0.25):
    """(M, 2) points every ``step`` metres along a polyline."""
    out = [np.asarray(points[0], float)]
    for a, b in zip(points[:-1], points[1:]):
        a, b = np.asarray(a, float), np.asarray(b, float)
        n = max(int(round(np.hypot(*(b - a)) / step)), 1)
        out.extend(a + (b - a) * t for t in np.arange(1, n + 1) / n)
    return np.array(out)


def _states(xy):
    """SE(2) states along a path, heading along the direction of travel."""
    d = np.diff(xy, axis=0)
    phi = np.arctan2(d[:, 1], d[:, 0])
    return np.column_stack([xy, np.concatenate([phi, phi[-1:]])])


def _kidnapped_between_rooms(grid: GridMap):
    """A robot that drives a loop through room A and back to the corridor, is carried 5 m along the
    corridor (its wheels report no move; its heading is unchanged), and drives the same loop through
    room B; its moves as wheel edges (tiny noise)."""
    route = [(1.0, 0.7), (1.9, 0.7), (1.9, 4.5), (2.5, 4.8), (2.5, 3.0), (1.9, 2.6), (1.9, 4.5), (2.5, 4.8),
             (2.5, 3.0), (1.9, 2.6), (1.9, 0.7), (0.6, 0.7), (1.0, 0.7)]
    a = _path(route)
    carried = _path([(1.0, 0.7), (6.0, 0.7)])[1:-1]
    b = _path([(x + 5.0, z) for x, z in route])
    xy = np.vstack([a, carried, b])
    states = _states(xy)
    moves = increments(states)
    alphas = (1e-5, 1e-5, 1e-5, 1e-6)
    is_carried = np.zeros(len(moves), bool)
    is_carried[len(a) - 1:len(a) + len(carried)] = True
    reported = moves.copy()
    reported[is_carried] = 0.0
    z, info = move_edge(reported, move_sigmas(reported, alphas), 1e-3)
    travelled = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))])
    return states, z, info, travelled, len(a), len(a) + len(carried)


def test_identical_rooms_fool_the_front_end_into_a_wrong_closure():
    grid = _two_rooms()
    states, z, info, travelled, end_a, start_b = _kidnapped_between_rooms(grid)
    assert grid.walkable[tuple(np.array(grid.world_to_cell(states[:, 0], states[:, 1])))].all()
    st = FrontEndSettings(closure_min_travel=3.0, closure_every=0.5)
    fe = run_front_end(~grid.walkable, grid, states, z, info, travelled, st)
    in_b = fe.closures[:, 1] >= start_b
    # room B's nodes were closed onto room A's: the robot thinks it is back where it was
    fooled = fe.wrong & in_b & (fe.closures[:, 0] < end_a)
    assert fooled.sum() >= 1
    truth = relative(states, fe.closures[fooled, 0], fe.closures[fooled, 1])
    assert (np.hypot(*truth[:, :2].T) > 4.0).all()  # ~5 m apart in truth
    assert (np.hypot(*fe.closure_z[fooled, :2].T) < WRONG_XY + 1.5).all()
    # room A's own revisits are right
    assert (~fe.wrong[~in_b]).sum() >= 1


# --------------------------------------------------------------------------- laser odometry


def test_laser_odometry_measures_heading_the_wheels_get_wrong():
    grid = _two_rooms()
    loop = [(1.9, 2.2), (1.9, 4.5), (2.5, 4.8), (2.5, 3.0), (1.9, 2.6)]
    states = _states(_path(loop))
    moves = increments(states)
    alphas = (2e-2, 5e-3, 5e-3, 1e-3)  # poor wheels
    reported = moves - move_sigmas(moves, alphas) * np.random.default_rng(0).standard_normal(moves.shape)
    z, info = move_edge(reported, move_sigmas(reported, alphas), 1e-3)
    travelled = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(states[:, :2], axis=0).T))])
    st = FrontEndSettings(closure_radius=0.0)
    fe = run_front_end(~grid.walkable, grid, states, z, info, travelled, st)
    wheels = run_front_end(~grid.walkable, grid, states, z, info, travelled,
                           FrontEndSettings(closure_radius=0.0, scan_matching=False))
    assert fe.laser.all() and not wheels.laser.any()
    true_turn = moves[:, 0] + moves[:, 2]
    err_laser = np.abs(wrap(fe.z[:, 2] - true_turn))
    err_wheel = np.abs(wrap(wheels.z[:, 2] - true_turn))
    assert err_laser.mean() < 0.25 * err_wheel.mean()  # measured: 0.2 vs 1.7 degrees a move
    # the heading the robot chains: within 2 degrees all round the loop; the wheels' drifts to ~10
    drift_laser = np.abs(wrap(fe.dead[:, 2] - states[:, 2])).max()
    assert np.degrees(drift_laser) < 2.0 and drift_laser < 0.25 * np.abs(wrap(wheels.dead[:, 2] - states[:, 2])).max()


def test_bad_front_end_settings_are_one_line():
    from benchmark.conditions.slam import OdometrySlam

    with pytest.raises(ValueError, match=r"^pose_error.closure_min_score = 1.5: expected a mean likelihood in \[0, 1\]$"):
        OdometrySlam(closure_min_score=1.5)
    with pytest.raises(ValueError, match=r"^pose_error.step_yaw = 0: expected degrees, 0 < step_yaw <= 10$"):
        OdometrySlam(step_yaw=0)
    with pytest.raises(ValueError, match=r"^pose_error: unknown setting\(s\) \['wrong_closures'\]"):
        OdometrySlam(wrong_closures=2)


@pytest.mark.slow
@pytest.mark.shared_data
def test_scan_matching_holds_heading_far_better_than_the_wheels_on_a_shared_house(procthor_file):
    from benchmark.conditions.slam import OdometrySlam
    from benchmark.viewpoints import Autotrace
    from envs.datasets.house_files import load_houses
    from envs.maps.scene import rasterise_house

    scene = rasterise_house(next(iter(load_houses(procthor_file, 0, 1))))
    poses = Autotrace().generate(scene)
    slam_3 = dict(alpha1=2e-4, alpha2=1e-4, alpha3=2e-4, alpha4=5e-5, views_at="final")

    def heading_error(scan_matching: bool) -> tuple[float, float]:
        est = OdometrySlam(**slam_3, scan_matching=scan_matching).estimate(scene.grid, poses, "0", 0.5)
        chained = np.abs((est.odometry[:, 2] - est.true[:, 2] + 180.0) % 360.0 - 180.0).mean()
        final = np.abs((est.estimate[:, 2] - est.true[:, 2] + 180.0) % 360.0 - 180.0).mean()
        return chained, final

    laser, wheels = heading_error(True), heading_error(False)
    # the heading the robot chains, and the solved one: the scans measure rotation, the wheels drift
    assert laser[0] < 0.5 * wheels[0]
    assert laser[1] < 0.3 * wheels[1] and laser[1] < 1.5


# --------------------------------------------------------------------------- keyframes


def _loop_with_turns():
    """A loop in room A every 0.25 m with a turn in place (a view's headings) at two corners; the
    wheels' moves with little noise."""
    states = _states(_path([(1.9, 2.2), (1.9, 4.5), (2.5, 4.8), (2.5, 3.0), (1.9, 2.6)]))
    spins = []
    for k, s in enumerate(states):
        spins.append(s)
        if k in (9, 20):  # stand and turn a quarter round and back, as at a viewpoint
            spins += [s + [0, 0, math.pi / 4], s + [0, 0, math.pi / 2], s + [0, 0, math.pi / 4]]
    states = np.array(spins)
    states[:, 2] = wrap(states[:, 2])
    moves = increments(states)
    alphas = (2e-3, 1e-3, 1e-3, 1e-4)
    reported = moves - move_sigmas(moves, alphas) * np.random.default_rng(1).standard_normal(moves.shape)
    z, info = move_edge(reported, move_sigmas(reported, alphas), 1e-3)
    travelled = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(states[:, :2], axis=0).T))])
    return states, z, info, travelled


def test_keyframes_every_half_metre_and_the_nodes_between_matched_on_the_keyframes_grid():
    grid = _two_rooms()
    states, z, info, travelled = _loop_with_turns()
    every = run_front_end(~grid.walkable, grid, states, z, info, travelled,
                          FrontEndSettings(closure_radius=0.0, keyframe_xy=0.0, keyframe_yaw=0.0))
    kf = run_front_end(~grid.walkable, grid, states, z, info, travelled, FrontEndSettings(closure_radius=0.0))
    assert every.keyframes.all()  # 0 and 0: every node, the first pass's front end
    # 0.5 m between keyframes on a route with a node every 0.25 m: about every other node; the turns
    # in place make none (a 360 degree scan sees the same room turned)
    assert kf.keyframes[0] and kf.keyframes.sum() <= 0.6 * len(states)
    spun = np.flatnonzero(np.abs(np.diff(states[:, 2])) > 0.5) + 1
    assert not kf.keyframes[spun].all()
    # every node between keyframes is still measured by the laser, on the keyframe's grid
    assert kf.laser.all() and every.laser.all()
    for fe in (every, kf):
        assert np.degrees(np.abs(wrap(fe.dead[:, 2] - states[:, 2])).max()) < 2.0
    # a turn of 20 degrees makes a keyframe when asked
    turned = run_front_end(~grid.walkable, grid, states, z, info, travelled,
                           FrontEndSettings(closure_radius=0.0, keyframe_yaw=20.0))
    assert turned.keyframes[spun].all() and turned.keyframes.sum() > kf.keyframes.sum()


def test_loop_closures_only_between_keyframes():
    grid = _two_rooms()
    states, z, info, travelled, end_a, start_b = _kidnapped_between_rooms(grid)
    st = FrontEndSettings(closure_min_travel=3.0, closure_every=0.5)
    fe = run_front_end(~grid.walkable, grid, states, z, info, travelled, st)
    assert len(fe.closures) and fe.keyframes[fe.closures].all()
    assert not fe.keyframes.all()


def test_bad_keyframe_settings_are_one_line():
    from benchmark.conditions.slam import OdometrySlam

    with pytest.raises(ValueError, match=r"^pose_error.keyframe_xy = -0.1: expected metres >= 0$"):
        OdometrySlam(keyframe_xy=-0.1)
    with pytest.raises(ValueError, match=r"^pose_error.keyframe_yaw = 200: expected degrees in \[0, 180\]$"):
        OdometrySlam(keyframe_yaw=200)


# --------------------------------------------------------------------------- the scene's obstacles


def test_the_front_end_scans_the_obstacles_it_is_given():
    """OdometrySlam.estimate scans what the harness hands it (the mapping stage's scan plane: legs,
    closed doors); without them, the route grid's non-walkable cells. The memo keeps them apart."""
    from benchmark.conditions.slam import OdometrySlam

    grid = _two_rooms()
    views = np.array([[1.9, 2.4, 0.0], [1.9, 4.4, 0.0], [2.5, 3.2, 90.0], [1.0, 0.7, 0.0], [6.9, 3.0, 0.0]])
    slam = OdometrySlam(alpha1=2e-3, alpha2=1e-3, alpha3=1e-3, alpha4=1e-4, views_at="final")
    plain = slam.estimate(grid, views, "h", 0.5)
    assert slam.estimate(grid, views, "h", 0.5, ~grid.walkable) is not plain
    np.testing.assert_array_equal(slam.estimate(grid, views, "h", 0.5, ~grid.walkable).estimate, plain.estimate)
    legs = ~grid.walkable
    for x, zz in ((1.3, 3.3), (1.3, 3.9), (3.0, 3.3), (3.0, 3.9), (6.3, 3.3), (7.0, 4.0)):  # table legs
        r, c = grid.world_to_cell(x, zz)
        legs[int(r), int(c)] = True
    seen = slam.estimate(grid, views, "h", 0.5, legs)
    assert slam.known(grid, views, "h", 0.5, legs) is seen and slam.known(grid, views, "h", 0.5) is plain
    assert not np.array_equal(seen.estimate, plain.estimate)  # other scans, another estimate
    with pytest.raises(ValueError, match=r"^slam obstacles have shape \(3, 3\): expected the grid's"):
        OdometrySlam(alpha1=1e-3).estimate(grid, views, "h2", 0.5, np.zeros((3, 3), bool))


# --------------------------------------------------------------------------- place recognition


def test_ring_descriptor_finds_the_turn_between_two_scans_of_one_place():
    from benchmark.conditions.front_end import descriptor, ring_distance

    world = _room_points()
    here = np.array([1.5, 1.5, 0.0])
    turned = np.array([1.55, 1.45, math.radians(90.0)])
    a = descriptor(_in_frame(world, here), 10.0)
    b = descriptor(_in_frame(world, turned), 10.0)
    dist, turn = ring_distance(a, b)
    assert abs(math.degrees(turn) - 90.0) <= 6.0 and dist < 0.2  # one 6-degree sector, a few cm of range
    elsewhere = descriptor(_in_frame(world, np.array([4.0, 1.0, 0.0])), 10.0)
    assert ring_distance(a, elsewhere)[0] > 3 * dist


def test_place_recognition_finds_revisits_without_the_estimate_and_is_fooled_by_a_look_alike_room():
    """No closures from the estimate (closure_radius 0): with place recognition on, a keyframe that
    looks compares its descriptor with every earlier keyframe's and a strict match is accepted.
    Room A's own revisits are found right; carried to room B, the robot is re-found in room A, its
    identical twin (wrong: aliasing, what a descriptor also proposes)."""
    grid = _two_rooms()
    states, z, info, travelled, end_a, start_b = _kidnapped_between_rooms(grid)
    st = dict(closure_min_travel=3.0, closure_every=0.5, closure_radius=0.0)
    off = run_front_end(~grid.walkable, grid, states, z, info, travelled, FrontEndSettings(**st))
    on = run_front_end(~grid.walkable, grid, states, z, info, travelled,
                       FrontEndSettings(**st, place_recognition=True))
    assert len(off.closures) == 0 and off.place_tried == 0
    assert on.place.all() and on.place_tried >= len(on.closures) >= 2
    assert on.keyframes[on.closures].all()
    in_a = on.closures[:, 1] < end_a
    assert in_a.sum() >= 1 and not on.wrong[in_a].any()
    fooled = on.wrong & (on.closures[:, 1] >= start_b) & (on.closures[:, 0] < end_a)
    assert fooled.sum() >= 1


def test_the_harness_hands_the_front_end_the_mapping_stages_scan_plane(tmp_path):
    """Under corruption=slam_3 the robot's scans see what its mapping stage's scan plane holds: with
    furniture as its legs (mapping.legs) the front end matches other scans than with furniture as
    boxes, so the estimate differs (before, it scanned the route grid, the same either way)."""
    from tests.test_robot_conditions import _run

    boxes = _run(tmp_path, "b", "corruption=slam_3", "mapping.legs=false", results="b")
    legs = _run(tmp_path, "l", "corruption=slam_3", "mapping.legs=true", results="l")
    assert (boxes["status"] == "ok").all() and (legs["status"] == "ok").all()
    assert (boxes["ate_rmse_m"] != legs["ate_rmse_m"]).any()


def test_closure_search_gives_the_same_answer_whatever_grids_it_keeps(monkeypatch):
    # the closure search keeps the last KEPT_GRIDS reference grids and makes an evicted one again: keeping one
    # grid (every candidate's made anew), and one grid for every keyframe, give the same closures bit for bit
    from benchmark.conditions import front_end

    grid = _two_rooms()
    states, z, info, travelled, _, _ = _kidnapped_between_rooms(grid)
    st = FrontEndSettings(closure_min_travel=3.0, closure_every=0.5, closure_candidates=3, place_recognition=True)
    made = []
    real = front_end.LikelihoodGrid

    def counted(*args):
        made.append(1)
        return real(*args)

    monkeypatch.setattr(front_end, "LikelihoodGrid", counted)
    answers = {}
    for kept in (1, len(states)):
        monkeypatch.setattr(front_end, "KEPT_GRIDS", kept)
        made.clear()
        fe = run_front_end(~grid.walkable, grid, states, z, info, travelled, st)
        answers[kept] = (len(made), fe)
    (n_one, one), (n_all, every) = answers[1], answers[len(states)]
    assert n_one > n_all and len(every.closures) >= 2  # grids made again, on a route that closes loops
    for name in ("closures", "closure_z", "closure_sqrt_info", "wrong", "place", "dead"):
        np.testing.assert_array_equal(getattr(one, name), getattr(every, name))
    assert (one.candidates, one.place_tried) == (every.candidates, every.place_tried)
