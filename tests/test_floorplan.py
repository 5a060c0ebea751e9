import numpy as np
import pytest
from maps import pose_at, two_rooms_scene

from envs.maps.scene import ObjectFootprint
from envs.render.floorplan import FloorplanRenderer, occluders, view_from


def _with_objects(scene):
    objs = [ObjectFootprint("bed", "Bed_1", "Bed", (0, 0), 0, (1, .5, 1), 0.0, 0.5, ("Pillow",)),
            ObjectFootprint("fridge", "Fridge_1", "Fridge", (0, 0), 0, (1, 2, 1), 0.0, 1.8)]
    omap = np.full(scene.grid.shape, -1, np.int32)
    omap[18:22, 60:64] = 0   # low bed in the right room
    omap[18:22, 66:70] = 1   # tall fridge behind it
    omap[5:8, 60:63] = 1
    scene.objects, scene.object_map = objs, omap
    return scene


def test_camera_facing_wall_sees_nothing_behind_it():
    s = two_rooms_scene()
    obs = FloorplanRenderer(fov=30, max_range=3.0).render(None, s, np.array([pose_at(s.grid, 32, 20, 90)]))
    # looking right from row 32 with a 30-degree cone: the wall is hit at rows 27-36, the door
    # (rows 18-21) is outside the cone, so only the left room is visible
    assert obs[0].visible_classes.tolist() == [0, 0, 0, 0, 0, 1, 0]


def test_view_through_door_sees_the_next_room_and_objects():
    s = _with_objects(two_rooms_scene())
    r = FloorplanRenderer(fov=20, max_range=3.0, occluder_height=1.2)
    o = r.render(None, s, np.array([pose_at(s.grid, 20, 30, 90)]))[0]
    assert o.visible_classes[2] > 0.5  # most of what it sees is the bedroom beyond the door
    types = dict(o.objects)
    assert "Bed" in types and "Pillow" in types and "Fridge" in types
    assert types["Pillow"] == types["Bed"]
    # rays stop at the tall fridge: nothing beyond column 66 on those rows
    v = view_from(s, occluders(s, 1.2), pose_at(s.grid, 20, 30, 90), 20, 60)
    assert not ((v.cols > 66) & (v.rows >= 18) & (v.rows < 22)).any()


def test_batch_render_equals_per_pose_view():
    s = _with_objects(two_rooms_scene())
    rng = np.random.default_rng(0)
    rr, cc = np.nonzero(s.grid.walkable)
    pick = rng.choice(len(rr), 25, replace=False)
    poses = np.array([pose_at(s.grid, rr[i], cc[i], rng.uniform(0, 360)) for i in pick])
    obs = FloorplanRenderer(fov=90, max_range=2.0).render(None, s, poses)
    block = occluders(s, 1.2)
    for p, o in zip(poses, obs):
        v = view_from(s, block, p, 90, 2.0 / s.grid.resolution)
        cls = np.append(s.instance_classes, -1)[s.rooms[v.rows, v.cols]]
        cls = cls[cls >= 0]
        assert np.allclose(np.bincount(cls, minlength=7) / max(len(cls), 1), o.visible_classes)
        assert sorted({s.objects[k].object_type for k in v.object_rays}) == sorted(
            {t for t, _ in o.objects} - {"Pillow"})


def _reference_observation(scene, pose, fov, max_range_m, occluder_height):
    """Slow renderer: Python rays (tests/test_rays.py's reference) over blockers built
    from the scene's fields; visible floor share per class and each object type's share of
    rays (children with their parent)."""
    from test_rays import reference_ray

    from envs.maps.rays import cone_thetas

    g = scene.grid
    h, w = g.shape
    blocked = np.zeros((h, w), bool)
    omap = scene.object_map
    for r in range(h):
        for c in range(w):
            k = omap[r, c]
            blocked[r, c] = (scene.rooms[r, c] < 0 or bool(scene.walls[r, c])
                             or (k >= 0 and scene.objects[k].top >= occluder_height))
    r0, c0 = (int(v) for v in g.world_to_cell(pose[0], pose[1]))
    max_px = max_range_m / g.resolution
    thetas = cone_thetas(pose[2], fov, max_px)
    cells, rays_on = set(), {}
    for th in thetas:
        seen, hit = reference_ray(blocked, r0, c0, float(th), max_px)
        cells.update(seen)
        touched = {int(omap[rc]) for rc in seen + ([hit] if hit else [])} - {-1}
        for k in touched:
            rays_on[k] = rays_on.get(k, 0) + 1
    counts = np.zeros(len(scene.classes))
    for r, c in cells:
        if scene.rooms[r, c] >= 0:
            counts[scene.instance_classes[scene.rooms[r, c]]] += 1
    objects = {}
    for k, n in rays_on.items():
        o = scene.objects[k]
        for t in (o.object_type, *o.children):
            objects[t] = max(objects.get(t, 0.0), n / len(thetas))
    return counts / max(counts.sum(), 1), objects, len(cells)


@pytest.mark.parametrize("fov, max_range, paths", [(90.0, 4.0, True), (360.0, 3.0, True), (120.0, 4.0, False)])
def test_render_equals_slow_reference_on_a_shared_house(procthor_file, fov, max_range, paths, monkeypatch):
    """The renderer's shared-path walk (a whole turn too, whose last ray ends beside its first)
    and its walk of every ray whole (no path tables: over the budget) see the reference's
    cells and objects."""
    import envs.render.floorplan as floorplan
    from benchmark.classifiers.oracle import OracleClassifier
    from benchmark.viewpoints import Autotrace
    from envs.datasets.house_files import load_houses
    from envs.maps.scene import rasterise_house

    if not paths:
        monkeypatch.setattr(floorplan, "PATH_CACHE_BYTES", 0)
    house = load_houses(procthor_file, 80, 81)[0]
    scene = rasterise_house(house, resolution=0.1)
    poses = Autotrace(offset=0.4, spacing=1.0, n_headings=3).generate(scene)[::9][:12]
    assert len(poses) >= 8
    assert (floorplan.ray_paths(max_range / scene.grid.resolution, floorplan.PATH_CACHE_BYTES)[0] > 0) == paths
    obs = FloorplanRenderer(fov=fov, max_range=max_range, occluder_height=1.2).render(house, scene, poses)
    majority = []
    for p, o in zip(poses, obs):
        vis, objects, n_cells = _reference_observation(scene, p, fov, max_range, 1.2)
        assert np.allclose(o.visible_classes, vis)
        assert o.meta["n_visible_cells"] == n_cells
        assert dict(o.objects) == pytest.approx(objects)
        majority.append(int(np.argmax(vis)))
    assert sum(len(o.objects) > 0 for o in obs) >= len(obs) // 2  # the house has furniture in view
    # the oracle at accuracy 1.0 gives the class covering most of the visible floor
    assert OracleClassifier(accuracy=1.0).predict_proba(obs).argmax(1).tolist() == majority

    # cameras standing on a tall object (every ray touches it and stops), in a wall, off the map
    g = scene.grid
    tall = np.array([o.top >= 1.2 for o in scene.objects] + [False])[scene.object_map]
    odd = [np.argwhere(tall)[0], np.argwhere(tall)[-1], np.argwhere(scene.walls)[len(np.argwhere(scene.walls)) // 2]]
    odd_poses = [pose_at(g, int(r), int(c), 30.0 * i) for i, (r, c) in enumerate(odd)]
    odd_poses.append((g.origin[0] - 1.0, g.origin[1] + 1.0, 0.0))
    for p, o in zip(odd_poses, FloorplanRenderer(fov=fov, max_range=max_range, occluder_height=1.2).render(house, scene, odd_poses)):
        vis, objects, n_cells = _reference_observation(scene, p, fov, max_range, 1.2)
        assert np.allclose(o.visible_classes, vis) and o.meta["n_visible_cells"] == n_cells == 0
        assert dict(o.objects) == pytest.approx(objects)
    assert len(objects) == 0 and all(len(o.objects) for o in
                                     FloorplanRenderer(fov=fov, max_range=max_range).render(house, scene, odd_poses[:2]))
