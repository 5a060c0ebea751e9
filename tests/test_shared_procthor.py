"""Rasterisation of the 150 shared ProcTHOR houses."""

import networkx as nx
import numpy as np
import pytest
import shapely
from scipy import ndimage

from envs.world.house import floor_polygon


def _door_graph(house, room_ids):
    g = nx.Graph()
    g.add_nodes_from(room_ids)
    for d in house.data.get("doors", []):
        if d["room0"] != d["room1"] and d["room0"] in g and d["room1"] in g:
            g.add_edge(d["room0"], d["room1"])
    return g


@pytest.mark.slow
def test_all_houses_load_and_rasterise(shared_houses, shared_scenes):
    assert len(shared_houses) == 150
    for s in shared_scenes:
        assert s.grid.resolution == 0.05
        assert s.instances.shape == s.grid.shape
        assert set(np.unique(s.instances)) == {-1, *range(len(s.room_ids))}, s.house_id
        assert np.array_equal(s.instances >= 0, s.grid.walkable)


def _expected_free_geometry(house, scene, wall_thickness=0.1, max_object_base=0.5):
    """Free floor as exact geometry (shapely), independent of the raster code: floor
    polygons minus wall bands (door openings cut out) minus blocking furniture boxes."""
    half = wall_thickness / 2
    res = scene.grid.resolution
    walls = {}
    for w in house.data["walls"]:
        pts = [(p["x"], p["z"]) for p in w["polygon"] if p["y"] == min(q["y"] for q in w["polygon"])]
        walls[w["id"]] = (np.array(pts[0], float), np.array(pts[-1], float))
    drawn = {w["id"] for w in house.data["walls"] if not w.get("empty")}  # "empty": an open-plan opening
    bands = shapely.union_all([shapely.LineString([a, b]).buffer(half) for k, (a, b) in walls.items() if k in drawn])
    holes = []
    for d in house.data["doors"]:
        t0, t1 = sorted((d["holePolygon"][0]["x"], d["holePolygon"][-1]["x"]))
        for key in ("wall0", "wall1"):
            if d.get(key) in walls:
                a, b = walls[d[key]]
                u = (b - a) / np.linalg.norm(b - a)
                n = np.array([u[1], -u[0]]) * (half + 1.5 * res)
                p0, p1 = a + u * t0, a + u * t1
                holes.append(shapely.Polygon([p0 - n, p1 - n, p1 + n, p0 + n]))
    walls_geom = bands.difference(shapely.union_all(holes)) if holes else bands
    furniture = shapely.union_all([shapely.Polygon(o.corners()) for o in scene.objects if o.base < max_object_base])
    return walls_geom, furniture


def test_room_area_matches_polygon_minus_walls_and_furniture(shared_houses, shared_scenes):
    """Each room's rasterised walkable area is, within 3 % of the room's area, its polygon area
    minus the wall band and the furniture footprints computed as exact geometry."""
    worst = 0.0
    for h, s in zip(shared_houses, shared_scenes):
        px = s.grid.resolution ** 2
        walls_geom, furniture = _expected_free_geometry(h, s)
        for i, room in enumerate(h.rooms):
            poly = shapely.Polygon(floor_polygon(room))
            expected = poly.difference(walls_geom).difference(furniture).area
            got = (s.instances == i).sum() * px
            assert abs((s.rooms == i).sum() * px - poly.area) / poly.area < 0.03, (s.house_id, room["id"])
            err = abs(got - expected) / poly.area
            worst = max(worst, err)
            assert err < 0.03, (s.house_id, room["id"], got, expected)
    print(f"worst relative area error: {worst:.4f}")


def test_rooms_reachable_through_doors(shared_houses, shared_scenes):
    """Rooms the house's door graph connects are connected on the walkable mask.

    Houses whose own door graph is disconnected (a room reachable only through an exterior
    door) are reported, not failed: that is the data, not the rasteriser.
    """
    disconnected_by_data = []
    for h, s in zip(shared_houses, shared_scenes):
        lab, _ = ndimage.label(s.grid.walkable)
        g = _door_graph(h, s.room_ids)
        if nx.number_connected_components(g) > 1:
            disconnected_by_data.append(h.id)
        for comp in nx.connected_components(g):
            idx = [s.room_ids.index(r) for r in comp]
            # every room of a door-connected group lies in one walkable component
            comps = set()
            for i in idx:
                vals, counts = np.unique(lab[s.instances == i], return_counts=True)
                comps.add(int(vals[np.argmax(counts)]))
            assert len(comps) == 1, (h.id, sorted(comp))
    print(f"{len(disconnected_by_data)} houses have rooms reachable only through exterior doors: "
          f"{disconnected_by_data[:5]} ...")
    assert len(disconnected_by_data) < len(shared_houses)


def test_env_reads_the_shared_file_exactly_and_maps_fit_the_size_limit(procthor_file, shared_scenes):
    """ProcTHOREnv keeps each house dict exactly as the file's line parses (cache keys hash
    it), with ids unchanged; the largest shared map is far under the default max_map_pixels."""
    import gzip
    import json

    from envs.datasets.procthor import ProcTHOREnv
    from envs.maps.scene import MAX_MAP_PIXELS

    env = ProcTHOREnv(path=str(procthor_file))
    with gzip.open(procthor_file, "rt") as f:
        lines = [json.loads(line) for line in f]
    assert env.house_ids() == [f"procthor-10k-uniform-hard-val-{i:05d}" for i in range(150)]
    assert all(env.house(hid).data == d for hid, d in zip(env.house_ids(), lines))
    largest = max(s.grid.walkable.size for s in shared_scenes)
    print(f"largest shared map: {largest} pixels at 0.05 m/px; limit {MAX_MAP_PIXELS}")
    assert largest < MAX_MAP_PIXELS / 10
