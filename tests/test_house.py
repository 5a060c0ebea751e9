import gzip
import json

import numpy as np
import pytest

from envs.datasets.house_files import iter_house_file, load_houses
from envs.maps.scene import rasterise_house
from envs.world.house import House, HouseError, validate_house


def square_house():
    """One 4 x 3 m kitchen, no walls or objects."""
    return {
        "rooms": [{"id": "room|1", "roomType": "Kitchen", "floorPolygon": [
            {"x": 0, "y": 0, "z": 0}, {"x": 4, "y": 0, "z": 0}, {"x": 4, "y": 0, "z": 3}, {"x": 0, "y": 0, "z": 3}]}],
        "walls": [], "doors": [], "objects": [],
    }


@pytest.mark.parametrize("mutate,field", [
    (lambda h: h.pop("rooms"), "rooms"),
    (lambda h: h.__setitem__("rooms", []), "rooms"),
    (lambda h: h["rooms"][0].pop("floorPolygon"), "rooms[room|1].floorPolygon"),
    (lambda h: h["rooms"][0].__setitem__("floorPolygon", h["rooms"][0]["floorPolygon"][:2]), "rooms[room|1].floorPolygon"),
    (lambda h: h["rooms"][0].__setitem__("floorPolygon", [{"x": 0, "y": 0, "z": 0}, {"x": 1, "y": 0, "z": 1}, {"x": 2, "y": 0, "z": 2}]), "rooms[room|1].floorPolygon"),
    (lambda h: h["rooms"][0]["floorPolygon"][1].__setitem__("x", float("nan")), "rooms[room|1].floorPolygon[1]"),
    (lambda h: h["rooms"][0]["floorPolygon"][2].__setitem__("z", float("inf")), "rooms[room|1].floorPolygon[2]"),
    (lambda h: h["rooms"][0].__setitem__("roomType", "Garage"), "rooms[room|1].roomType"),
    (lambda h: h["objects"].append({"id": "o1", "assetId": "Chair_1", "position": {"x": "a", "z": 1}}), "objects[o1].position"),
    (lambda h: h.__setitem__("doors", [3]), "doors[0]"),
    (lambda h: h.__setitem__("walls", {"w": 1}), "walls"),
    (lambda h: h["rooms"][0].__setitem__("roomType", ["Kitchen"]), "rooms[room|1].roomType"),
])
def test_malformed_house_names_house_and_field(mutate, field):
    h = square_house()
    mutate(h)
    with pytest.raises(HouseError) as e:
        validate_house(h, "house-7")
    assert e.value.house_id == "house-7"
    assert e.value.field == field
    assert "house-7" in str(e.value) and field in str(e.value)


def test_file_formats_round_trip(tmp_path):
    h = square_house()
    (tmp_path / "one.json").write_text(json.dumps(h))
    (tmp_path / "many.jsonl").write_text("\n".join(json.dumps(h) for _ in range(3)))
    with gzip.open(tmp_path / "many.jsonl.gz", "wt") as f:
        f.write("\n".join(json.dumps(h) for _ in range(4)))
    assert [x.id for x in iter_house_file(tmp_path / "one.json")] == ["one"]
    assert len(load_houses(tmp_path / "many.jsonl")) == 3
    got = load_houses(tmp_path / "many.jsonl.gz", start=1, stop=3)
    assert [x.id for x in got] == ["many-00001", "many-00002"]
    (tmp_path / "x.txt").write_text("{}")
    with pytest.raises(ValueError, match="expected .json"):
        list(iter_house_file(tmp_path / "x.txt"))


def test_bad_house_in_file_is_named(tmp_path):
    bad = square_house()
    bad["rooms"][0]["roomType"] = "Attic"
    (tmp_path / "h.jsonl").write_text(json.dumps(square_house()) + "\n" + json.dumps(bad))
    with pytest.raises(HouseError, match="'h-00001'.*roomType"):
        load_houses(tmp_path / "h.jsonl")


def test_square_room_rasterises_exactly():
    scene = rasterise_house(House("sq", square_house()), resolution=0.1, wall_thickness=0.0, margin=0.2)
    # 4 x 3 m at 0.1 m/px = 40 x 30 = 1200 pixel centres inside
    assert scene.grid.walkable.sum() == 1200
    assert scene.instances.max() == 0 and scene.semantic.max() == 5  # kitchen
    assert scene.grid.shape == (34, 44)


def two_rooms(door=True, chair=False):
    """Kitchen (0..4 x 0..3) and bedroom (4..8 x 0..3) sharing the wall x=4, door 1 m wide."""
    h = {
        "rooms": [
            {"id": "room|1", "roomType": "Kitchen", "floorPolygon": [
                {"x": 0, "y": 0, "z": 0}, {"x": 4, "y": 0, "z": 0}, {"x": 4, "y": 0, "z": 3}, {"x": 0, "y": 0, "z": 3}]},
            {"id": "room|2", "roomType": "Bedroom", "floorPolygon": [
                {"x": 4, "y": 0, "z": 0}, {"x": 8, "y": 0, "z": 0}, {"x": 8, "y": 0, "z": 3}, {"x": 4, "y": 0, "z": 3}]},
        ],
        "walls": [
            {"id": "wall|1|4.00|0.00|4.00|3.00", "roomId": "room|1", "polygon": [
                {"x": 4, "y": 0, "z": 0}, {"x": 4, "y": 0, "z": 3}, {"x": 4, "y": 2.5, "z": 0}, {"x": 4, "y": 2.5, "z": 3}]},
            {"id": "wall|2|4.00|0.00|4.00|3.00", "roomId": "room|2", "polygon": [
                {"x": 4, "y": 0, "z": 0}, {"x": 4, "y": 0, "z": 3}, {"x": 4, "y": 2.5, "z": 0}, {"x": 4, "y": 2.5, "z": 3}]},
        ],
        "doors": [], "objects": [],
    }
    if door:
        h["doors"].append({"id": "door|1|2", "room0": "room|1", "room1": "room|2",
                           "wall0": "wall|1|4.00|0.00|4.00|3.00", "wall1": "wall|2|4.00|0.00|4.00|3.00",
                           "holePolygon": [{"x": 1.0, "y": 0, "z": 0}, {"x": 2.0, "y": 2.0, "z": 0}]})
    if chair:
        h["objects"].append({"id": "c", "assetId": "NoSuchChair_99", "position": {"x": 2, "y": 0.45, "z": 1.5},
                             "rotation": {"x": 0, "y": 45, "z": 0}})
    return h


def test_door_connects_rooms_and_wall_separates_them():
    from scipy import ndimage

    s = rasterise_house(House("two", two_rooms(door=True)), resolution=0.05)
    lab, n = ndimage.label(s.grid.walkable)
    assert n == 1
    s2 = rasterise_house(House("two", two_rooms(door=False)), resolution=0.05)
    lab, n = ndimage.label(s2.grid.walkable)
    assert n == 2
    # the opening lies where the hole is: z in [1, 2] (metres from the wall's first point z=0)
    col = int(s.grid.world_to_cell(4.0, 0)[1])
    rows = np.nonzero(s.grid.walkable[:, col])[0]
    _, z = s.grid.pixel_to_world(rows, col)
    assert z.min() > 0.9 and z.max() < 2.1


def test_an_empty_wall_is_an_open_plan_not_a_wall():
    """ProcTHOR marks a wall fully opened between two rooms ``empty`` (its open plans): it is
    not drawn, so the rooms are one walkable area, split only by the ground truth."""
    from scipy import ndimage

    h = two_rooms(door=False)
    for w in h["walls"]:
        w["empty"] = True
    s = rasterise_house(House("two", h), resolution=0.05)
    assert ndimage.label(s.grid.walkable)[1] == 1 and not s.walls.any()
    floor = s.rooms >= 0
    assert (s.grid.walkable == floor).all()  # nothing but the floor's edge is lost
    assert set(np.unique(s.instances[s.grid.walkable])) == {0, 1}


def test_unknown_asset_uses_type_default_and_rotation():
    s = rasterise_house(House("two", two_rooms(chair=True)), resolution=0.02, wall_thickness=0.0)
    s0 = rasterise_house(House("two", two_rooms()), resolution=0.02, wall_thickness=0.0)
    removed = s0.grid.walkable.sum() - s.grid.walkable.sum()
    # unknown "NoSuchChair" -> generic default footprint 0.5 x 0.5 m = 625 px at 0.02 m/px
    assert s.objects[0].known_asset is False
    assert removed == pytest.approx(0.25 / 0.02**2, rel=0.05)



def test_room_type_checked_against_mapping_and_classes():
    h = square_house()
    h["rooms"][0]["roomType"] = "Hallway"
    validate_house(h, "h")  # default mapping: Hallway -> corridor
    with pytest.raises(HouseError, match="'Hallway' maps to class 'corridor', which is not in classes"):
        validate_house(h, "h", classes=["kitchen", "bedroom"])
    with pytest.raises(HouseError, match="unknown room type 'Hallway': map it to a class in env.room_types"):
        validate_house(h, "h", room_types={"Kitchen": "kitchen"})
    scene = rasterise_house(House("h", h), resolution=0.1, classes=["corridor", "kitchen"])
    assert scene.instance_classes.tolist() == [0]


def _check_rooms_layer(houses):
    for house in houses:
        full = rasterise_house(house, resolution=0.1)
        rooms = rasterise_house(house, resolution=0.1, layers="rooms")
        assert rooms.grid.shape == full.grid.shape and rooms.grid.origin == full.grid.origin
        np.testing.assert_array_equal(rooms.rooms, full.rooms)
        np.testing.assert_array_equal(rooms.instance_classes, full.instance_classes)
        assert rooms.objects == full.objects and rooms.room_ids == full.room_ids
        assert rooms.walls is None and rooms.object_map is None
        np.testing.assert_array_equal(rooms.grid.walkable, full.rooms >= 0)


def test_rooms_layer_is_the_full_rasterisation_cut_down():
    """``layers="rooms"`` (the objects classifier's training) gives the same room raster,
    room classes and objects as the full rasterisation, on the same grid."""
    from envs.datasets.synthetic import generate_house

    houses = [generate_house(s) for s in range(100000, 100012)]
    _check_rooms_layer(houses)
    with pytest.raises(ValueError, match="layers must be 'all' or 'rooms'"):
        rasterise_house(houses[0], layers="walls")


@pytest.mark.shared_data
def test_rooms_layer_on_the_shared_houses(shared_houses):
    _check_rooms_layer(shared_houses[:40])


def _in_closed_polygon(px: float, pz: float, poly) -> bool:
    """Exact (rational arithmetic) test: point inside the polygon or on one of its edges."""
    from fractions import Fraction as F

    x, z = F(px), F(pz)
    pts = [(F(a), F(b)) for a, b in poly]
    inside = False
    for (x0, z0), (x1, z1) in zip(pts, pts[1:] + pts[:1]):
        if (x1 - x0) * (z - z0) == (z1 - z0) * (x - x0) and min(x0, x1) <= x <= max(x0, x1) \
                and min(z0, z1) <= z <= max(z0, z1):
            return True  # on this edge
        if (z0 > z) != (z1 > z) and x < x0 + (z - z0) * (x1 - x0) / (z1 - z0):
            inside = not inside  # the ray towards +x crosses this edge
    return inside


def _reference_rooms(scene, house):
    """The room raster from its definition: each pixel centre takes the first room whose floor
    polygon holds it (inside or on an edge), -1 for none."""
    from envs.maps.scene import floor_polygon

    h, w = scene.grid.shape
    xs, _ = scene.grid.pixel_to_world(np.zeros(w), np.arange(w))
    _, zs = scene.grid.pixel_to_world(np.arange(h), np.zeros(h))
    out = np.full((h, w), -1, np.int32)
    for i, room in enumerate(house.data["rooms"]):
        poly = floor_polygon(room, house.id)
        (x0, z0), (x1, z1) = np.min(poly, 0), np.max(poly, 0)
        for r in np.nonzero((zs >= z0) & (zs <= z1))[0]:
            for c in np.nonzero((xs >= x0) & (xs <= x1))[0]:
                if out[r, c] < 0 and _in_closed_polygon(float(xs[c]), float(zs[r]), poly):
                    out[r, c] = i
    return out


def test_room_raster_equals_exact_point_in_polygon():
    """Pixel centres on edges and corners (binary fractions: the polygons' corners and a point
    of the slanted edge sit exactly on pixel centres), a concave room, a room sharing edges
    with another (the first room wins)."""
    def room(rid, pts):
        return {"id": rid, "roomType": "Kitchen", "floorPolygon": [{"x": x, "y": 0, "z": z} for x, z in pts]}

    data = {"rooms": [room("room|L", [(0, 0), (2, 0), (2, 1), (1, 1), (1, 2), (0, 2)]),
                      room("room|2", [(1, 1), (2, 1), (2, 2), (1, 2)]),
                      room("room|3", [(2, 0), (3, 0.5), (2, 2)])],
            "walls": [], "doors": [], "objects": []}
    house = House("edges", data)
    scene = rasterise_house(house, resolution=0.25, wall_thickness=0.0, margin=0.125)
    ref = _reference_rooms(scene, house)
    assert np.array_equal(scene.rooms, ref)
    at = lambda x, z: scene.rooms[tuple(int(v) for v in scene.grid.world_to_cell(x, z))]  # noqa: E731
    # the L's inner corner and the edge it shares with room 2 go to the L (first room); room
    # 3's slanted edge holds the centre (2.5, 0.25); the centre (2.75, 0.25) lies outside it
    assert (at(1.0, 1.0), at(1.5, 1.0), at(1.75, 1.5), at(2.5, 0.25), at(2.75, 0.25), at(0.0, 0.0)) == (0, 0, 1, 2, -1, 0)


@pytest.mark.shared_data
def test_room_raster_equals_exact_point_in_polygon_on_shared_houses(shared_houses):
    for house in shared_houses[:3]:
        scene = rasterise_house(house, resolution=0.2)
        assert np.array_equal(scene.rooms, _reference_rooms(scene, house))


def test_inside_or_on_rectangles_equal_geos():
    """The rectangle test (coordinates against the sides) gives GEOS's answers: rectangles of
    random and of binary-fraction corners, in every vertex order and both turning senses, on
    points on and near their edges and corners. 4-corner shapes that are not rectangles (a
    spike going back along its own edge, a bow tie, a slanted side) are GEOS's own."""
    import shapely

    from envs.maps.scene import inside_or_on

    rng = np.random.default_rng(3)
    shapes = []
    for k in range(60):
        if k % 2:
            x0, x1 = sorted(rng.integers(-8, 8, 2) / 4.0 + (0, 0.25))
            z0, z1 = sorted(rng.integers(-8, 8, 2) / 4.0 + (0, 0.25))
        else:
            x0, x1 = sorted(rng.uniform(-3, 3, 2))
            z0, z1 = sorted(rng.uniform(-3, 3, 2))
        corners = np.array([(x0, z0), (x1, z0), (x1, z1), (x0, z1)])
        shapes.append(np.roll(corners if k % 4 < 2 else corners[::-1], k % 4, axis=0))
    shapes += [np.array([(0, 0), (1, 0), (0, 0), (0, 1)], float),  # a spike along its own edge
               np.array([(0, 0), (1, 1), (1, 0), (0, 1)], float),  # a bow tie
               np.array([(0, 0), (1, 0), (1.5, 1), (0, 1)], float)]  # a slanted side
    x, z = np.meshgrid(np.arange(-3.5, 3.5, 0.125), np.arange(-3.5, 3.5, 0.125))
    for poly in shapes:
        # the grid, each corner and each corner's neighbours along the axes
        px = np.concatenate([x.ravel(), poly[:, 0], poly[:, 0] + 1e-12, poly[:, 0]])
        pz = np.concatenate([z.ravel(), poly[:, 1], poly[:, 1], poly[:, 1] - 1e-12])
        assert np.array_equal(inside_or_on(poly, px, pz), shapely.intersects_xy(shapely.Polygon(poly), px, pz)), poly


def test_inside_or_on_sends_only_rectangles_past_geos(monkeypatch):
    """Which shapes take the rectangle test: the 4-corner shapes that are not rectangles go to
    GEOS (the spike agrees with its bounding box in GEOS today, and is still GEOS's to decide)."""
    import envs.maps.scene as scene

    calls = []
    real = scene.shapely.intersects_xy
    monkeypatch.setattr(scene.shapely, "intersects_xy", lambda *a: calls.append(1) or real(*a))
    x, z = np.array([0.5]), np.array([0.5])
    for poly, geos in (([(0, 0), (1, 0), (1, 1), (0, 1)], False), ([(0, 1), (1, 1), (1, 0), (0, 0)], False),
                       ([(0, 0), (1, 0), (0, 0), (0, 1)], True), ([(0, 0), (1, 0), (2, 0), (3, 0)], True),
                       ([(0, 0), (1, 1), (1, 0), (0, 1)], True), ([(0, 0), (1, 0), (1.5, 1), (0, 1)], True),
                       ([(0, 0), (1, 0), (1, 1), (0, 1), (0, 0.5)], True)):
        calls.clear()
        scene.inside_or_on(np.array(poly, float), x, z)
        assert bool(calls) == geos, poly
