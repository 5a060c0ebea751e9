"""The synthetic house generator over 500 seeds."""

import json
from collections import Counter

import numpy as np
import pytest
from scipy import ndimage

from envs.datasets.synthetic import SyntheticEnv, generate_house, house_id_for, seed_from_house_id
from envs.maps.scene import ObjectFootprint, rasterise_house
from envs.world.house import validate_house

SEEDS = range(500)


@pytest.fixture(scope="module")
def houses():
    return [generate_house(s) for s in SEEDS]


def _footprint(obj):
    from envs.world.assets import asset_info

    a = asset_info(obj["assetId"])
    return ObjectFootprint(obj["id"], obj["assetId"], a.object_type, (obj["position"]["x"], obj["position"]["z"]),
                           obj["rotation"]["y"], a.size, 0.0, a.size[1])


@pytest.mark.slow
def test_valid_and_deterministic(houses):
    for h in houses:
        validate_house(h.data, h.id)
        assert seed_from_house_id(h.id) == int(h.data["metadata"]["seed"])
    for s in (0, 17, 499):
        a = json.dumps(generate_house(s).data, sort_keys=True)
        assert a == json.dumps(houses[s].data, sort_keys=True)
    assert json.dumps(houses[1].data, sort_keys=True) != json.dumps(houses[2].data, sort_keys=True)
    assert house_id_for(42) == "synthetic-s000042"
    with pytest.raises(ValueError, match="synthetic house id"):
        seed_from_house_id("procthor-1")


@pytest.mark.slow
def test_every_room_reachable(houses):
    for h in houses:
        s = rasterise_house(h, resolution=0.1)
        lab, _ = ndimage.label(s.grid.walkable)
        comps = {int(np.bincount(lab[s.instances == i]).argmax()) for i in range(len(s.room_ids))}
        assert len(comps) == 1 and 0 not in comps, h.id


def test_furniture_does_not_overlap_objects_or_door_swings(houses):
    for h in houses[:200]:
        fps = [_footprint(o) for o in h.data["objects"]]
        boxes = []
        for f in fps:
            c = f.corners()
            boxes.append((c[:, 0].min(), c[:, 0].max(), c[:, 1].min(), c[:, 1].max()))
        for i in range(len(boxes)):
            for j in range(i + 1, len(boxes)):
                a, b = boxes[i], boxes[j]
                overlap = a[0] < b[1] - 1e-6 and b[0] < a[1] - 1e-6 and a[2] < b[3] - 1e-6 and b[2] < a[3] - 1e-6
                assert not overlap, (h.id, fps[i].id, fps[j].id)
        walls = {w["id"]: w["polygon"] for w in h.data["walls"]}
        for d in h.data["doors"]:
            p = walls[d["wall0"]]
            x0, z0, x1, z1 = p[0]["x"], p[0]["z"], p[1]["x"], p[1]["z"]
            length = np.hypot(x1 - x0, z1 - z0)
            ux, uz = (x1 - x0) / length, (z1 - z0) / length
            t0, t1 = d["holePolygon"][0]["x"], d["holePolygon"][1]["x"]
            # sample the swing area (door width on both sides of the opening)
            ts, ns = np.meshgrid(np.linspace(t0, t1, 7), np.linspace(-0.85, 0.85, 9))
            px, pz = x0 + ux * ts + uz * ns, z0 + uz * ts - ux * ns
            for f in fps:
                assert not f.contains(px, pz).any(), (h.id, d["id"], f.id)


def test_classes_proportions_and_open_plan(houses):
    types = Counter(r["roomType"] for h in houses for r in h.rooms)
    n = len(houses)
    for t in ("Kitchen", "DiningRoom", "LivingRoom", "Corridor"):
        assert types[t] == n
    assert 1.0 <= types["Bedroom"] / n <= 3.0
    assert 0.8 <= types["Bathroom"] / n <= 2.0
    assert 0.6 <= types["Balcony"] / n <= 0.95
    opened = sum(len(h.data["metadata"]["openPlan"]) for h in houses)
    share = opened / (3 * n)
    assert abs(share - 0.5) < 4 * np.sqrt(0.25 / (3 * n))
    closed = [generate_house(s, open_plan_share=0.0) for s in range(30)]
    assert all(not h.data["metadata"]["openPlan"] for h in closed)


def test_open_plan_has_no_wall_between_rooms():
    h = generate_house(3, open_plan_share=1.0)
    s = rasterise_house(h, resolution=0.05)
    kinds = [r["roomType"] for r in h.rooms]
    k, d = kinds.index("Kitchen"), kinds.index("DiningRoom")
    # the kitchen/dining boundary column: walkable cells on both sides touch across it
    kx = max(p["x"] for p in h.rooms[k]["floorPolygon"])
    col = int(s.grid.world_to_cell(kx, 0)[1])
    assert (s.walls[:, col - 1:col + 1] & (s.rooms[:, col - 1:col + 1] >= 0)).sum() < 10
    assert (s.instances[:, col - 2] == k).any() and (s.instances[:, col + 1] == d).any()


def test_env_and_bad_parameters():
    env = SyntheticEnv(n_houses=3, seed_start=10, resolution=0.1)
    assert env.house_ids() == ["synthetic-s000010", "synthetic-s000011", "synthetic-s000012"]
    s = env.scene("synthetic-s000011")
    assert set(s.instance_classes.tolist()) >= {3, 4, 5, 6}
    with pytest.raises(ValueError, match="open_plan_share"):
        generate_house(1, open_plan_share=2.0)
    with pytest.raises(ValueError, match="length"):
        generate_house(1, length=(3.0, 4.0))


def test_env_keeps_its_recent_houses_equal_to_fresh_ones():
    """A run asks for a house's content, then its scene: the house is generated once, and a
    kept house is the house generate_house makes."""
    from envs.datasets.synthetic import (
        RECENT_HOUSES,
        SyntheticEnv,
        generate_house,
        seed_from_house_id,
    )

    env = SyntheticEnv(n_houses=RECENT_HOUSES + 2)
    ids = env.house_ids()
    first = env.house(ids[0])
    assert env.house(ids[0]) is first
    assert first.data == generate_house(seed_from_house_id(ids[0])).data
    for h in ids[1:]:
        env.house(h)
    again = env.house(ids[0])  # dropped (least recently used), generated again: equal, not the same
    assert again is not first and again.data == first.data
