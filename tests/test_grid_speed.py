"""The robustness grid's work done once (issue 58, item 7): what a sweep asked for again in every
job of a condition is made once per house and process, and is what making it afresh gives."""

import numpy as np
import pytest

from envs.maps import scan as scan_module
from envs.maps.gridmap import GridMap
from envs.maps.scan import ScanSettings, scan_plane
from envs.maps.scene import ObjectFootprint, Scene


def _scene(chair_x: float = 1.02) -> Scene:
    """A 3 x 2 m room (0.1 m cells) inside a wall band, a door in its east wall, a chair (on legs),
    a cabinet standing on the floor and a shelf above the scan plane."""
    h, w = 24, 34
    rooms = np.full((h, w), -1, np.int32)
    rooms[2:22, 2:32] = 0
    walls = np.zeros((h, w), bool)
    walls[1, 1:33] = walls[22, 1:33] = True
    walls[1:23, 1] = walls[1:23, 32] = True
    walls[10:13, 32] = False  # the door's opening, on the floor
    rooms[10:13, 32] = 0
    walkable = (rooms >= 0) & ~walls
    grid = GridMap(walkable, 0.1, (0.0, 2.4))
    objects = [ObjectFootprint("Chair|1", "chair", "Chair", (chair_x, 1.03), 0.0, (0.45, 0.9, 0.45), 0.0, 0.9),
               ObjectFootprint("Cabinet|1", "cabinet", "Cabinet", (2.52, 1.47), 0.0, (0.3, 1.0, 0.2), 0.0, 1.0),
               ObjectFootprint("Shelf|1", "shelf", "Shelf", (1.72, 0.63), 0.0, (0.4, 0.3, 0.3), 0.6, 0.9)]
    return Scene("h", grid, rooms, np.where(walkable, 0, -1).astype(np.int32), np.array([0]), ["r0"],
                 walls=walls, objects=objects, doors={"door|0|1": np.array([[10, 32], [11, 32], [12, 32]])})


def _plain_plane(scene: Scene, settings: ScanSettings, wall: float) -> np.ndarray:
    """The plane written out cell by cell (the objects stand unrotated): outside the floor, the
    wall band, every footprint whose box spans the plane with a cell centre inside it (a legged
    one's four leg squares in its corners instead, and the cells of the legs' centres), the doors
    the seeded draw closes."""
    import zlib

    assert 0 < settings.height < wall
    g = scene.grid
    h, w = g.shape
    ox, oz = g.origin
    res = g.resolution
    out = np.zeros((h, w), bool)
    for r in range(h):
        for c in range(w):
            x, z = ox + (c + 0.5) * res, oz - (r + 0.5) * res
            hit = bool(scene.rooms[r, c] < 0 or scene.walls[r, c])
            for o in scene.objects:
                if not o.base < settings.height < o.top:
                    continue
                if settings.legs and o.object_type in scan_module.LEGGED_TYPES:
                    half = settings.leg_size / 2
                    for sx in (-1, 1):
                        for sz in (-1, 1):
                            lx = o.center[0] + sx * max(o.size[0] / 2 - half, 0.0)
                            lz = o.center[1] + sz * max(o.size[2] / 2 - half, 0.0)
                            in_leg = abs(x - lx) <= half and abs(z - lz) <= half
                            hit |= in_leg or (r, c) == (int((oz - lz) // res), int((lx - ox) // res))
                else:
                    hit |= abs(x - o.center[0]) <= o.size[0] / 2 and abs(z - o.center[1]) <= o.size[2] / 2
            out[r, c] = hit
    for door_id, cells in scene.doors.items():
        u = np.random.default_rng([int(settings.seed), 3, zlib.crc32(door_id.encode())]).random()
        if u < settings.door_closed:
            out[cells[:, 0], cells[:, 1]] = True
    return out


@pytest.mark.parametrize("legs, door_closed", [(False, 0.0), (True, 0.0), (False, 1.0), (True, 1.0)])
def test_the_kept_scan_plane_is_the_plane_made_afresh(legs, door_closed):
    scene = _scene()
    settings = ScanSettings(height=0.25, legs=legs, leg_size=0.12, door_closed=door_closed)
    ref = _plain_plane(scene, settings, 2.5)
    first = scan_plane(scene, settings, 2.5)
    again = scan_plane(scene, settings, 2.5)  # from the memo
    assert np.array_equal(first, ref) and np.array_equal(again, ref)
    assert ref[10:13, 32].all() == (door_closed == 1.0)


def test_a_kept_plane_is_neither_shared_with_the_caller_nor_served_to_another_scene_or_setting():
    scene = _scene()
    settings = ScanSettings(height=0.25, legs=False, door_closed=0.0)
    mine = scan_plane(scene, settings, 2.5)
    assert mine.flags.writeable  # the numba kernels get the plain (writable) array type they were compiled for
    mine[:] = True  # the caller's copy: writing it changes no later answer
    assert np.array_equal(scan_plane(scene, settings, 2.5), _plain_plane(scene, settings, 2.5))
    legs = ScanSettings(height=0.25, legs=True, leg_size=0.12, door_closed=0.0)
    assert np.array_equal(scan_plane(scene, legs, 2.5), _plain_plane(scene, legs, 2.5))
    assert not np.array_equal(_plain_plane(scene, legs, 2.5), _plain_plane(scene, settings, 2.5))
    moved = _scene(chair_x=2.02)  # another scene of the same house id: its own plane
    assert np.array_equal(scan_plane(moved, settings, 2.5), _plain_plane(moved, settings, 2.5))
    assert not np.array_equal(_plain_plane(moved, settings, 2.5), _plain_plane(scene, settings, 2.5))
    scene.objects = moved.objects  # a layer set anew: the plane made again
    assert np.array_equal(scan_plane(scene, settings, 2.5), _plain_plane(moved, settings, 2.5))
    with pytest.raises(ValueError, match="scan height"):
        scan_plane(scene, settings, 0.2)


def test_a_slam_conditions_scan_plane_is_rasterised_once_per_house_across_its_jobs(tmp_path, monkeypatch):
    """Before: the map, the estimate and every method job's route each rasterised the house's
    scan plane again (2 jobs x 2 houses: 8 and more)."""
    from benchmark.config import compose_job
    from benchmark.harness.runner import run

    made = []
    original = scan_module.scan_obstacles

    def counted(scene, *a, **kw):
        made.append(scene.house_id)
        return original(scene, *a, **kw)

    monkeypatch.setattr(scan_module, "scan_obstacles", counted)
    monkeypatch.setattr(scan_module, "_SCAN_PLANES", scan_module.ByteLRU())
    rows = []
    for aggregator in ("vision_cone", "euclidean_knn"):
        cfg, ch = compose_job(["env=synthetic", "env.resolution=0.1", "env.n_houses=2", "classifier=oracle",
                               f"aggregator={aggregator}", "run.progress=false", f"run.results_dir={tmp_path / 'R'}",
                               "corruption=slam_2", "run.workers=1"])
        rows.append(run(cfg, tmp_path / "R" / "jobs" / aggregator, ch))
    assert all((df["status"] == "ok").all() and len(df) == 2 for df in rows)
    assert sorted(made) == sorted(rows[0]["house_id"])  # once per house, for both jobs


def test_the_byte_lru_keeps_what_a_plain_list_that_sums_its_sizes_keeps():
    """:class:`envs.memo.ByteLRU` keeps its held bytes as they change (a put was a pass over every
    value kept: thousands a sweep); the same keys, values and order as a list summed each time."""
    from envs.memo import ByteLRU

    rng = np.random.default_rng(7)
    lru, ref = ByteLRU(), []  # ref: [key, value, nbytes], least recently used first
    for step in range(3000):
        key = int(rng.integers(0, 40))
        if rng.random() < 0.3:
            got = lru.get(key)
            hit = [e for e in ref if e[0] == key]
            if hit:
                ref.remove(hit[0])
                ref.append(hit[0])
            assert got == (hit[0][1] if hit else None)
            continue
        nbytes, limit = int(rng.integers(0, 300)), float(rng.choice([0, 500, 2000, 5000]))
        ref = [e for e in ref if e[0] != key] + [[key, step, nbytes]]
        while ref and sum(e[2] for e in ref) > limit:
            ref.pop(0)
        lru.put(key, step, nbytes, limit)
        assert list(lru) == [e[0] for e in ref] and list(lru.values()) == [e[1] for e in ref]
    assert len(lru) == len(ref)


def test_the_view_transforms_have_their_own_timing_column(tmp_path):
    """The pose error and label noise a method's views go through were time in a house no stage
    timed (the grid profile's largest block); timings.csv names them ``t_transform``, and the
    clean robot, whose views go through none, has no such column."""
    import pandas as pd

    from benchmark.config import compose_job
    from benchmark.harness.runner import run

    def timings(corruption: str) -> pd.DataFrame:
        cfg, ch = compose_job(["env=synthetic", "env.resolution=0.1", "env.n_houses=2", "classifier=oracle",
                               "aggregator=vision_cone", "run.progress=false", f"run.results_dir={tmp_path / 'R'}",
                               f"corruption={corruption}", "run.workers=1"])
        df = run(cfg, tmp_path / "R" / "jobs" / corruption, ch)
        assert (df["status"] == "ok").all() and "t_transform" not in df  # a timing, not a metric
        return pd.read_csv(tmp_path / "R" / "jobs" / corruption / "timings.csv")

    noisy = timings("realistic_2")  # pose error on the SLAM estimate, label noise
    assert noisy["t_transform"].notna().all() and (noisy["t_transform"] >= 0).all()
    assert (noisy["t_transform"] + noisy["t_slam"] <= noisy["house_s"]).all()  # the estimate is not counted twice
    assert "t_transform" not in timings("clean")


def test_a_pipelines_kept_entry_paths_are_the_stores(tmp_path):
    """:meth:`Pipeline.entry` keeps each house's entry paths (a house's stages asked the store
    for them again and again: tens of microseconds a time); what it keeps is what the store gives."""
    from benchmark.config import compose_job
    from benchmark.harness.runner import build_pipeline
    from benchmark.harness.store import CacheStore

    cfg, ch = compose_job(["env=synthetic", "env.n_houses=2", "classifier=oracle", "aggregator=vision_cone",
                           f"run.results_dir={tmp_path / 'R'}", "corruption=realistic_2"])
    pipe = build_pipeline(cfg, ch)
    for _ in range(2):  # made, then kept
        for hid in ("synthetic-s000000", "synthetic-s000001"):
            for kind in CacheStore.KINDS:
                want = CacheStore(tmp_path / "R" / "cache").entry(kind, pipe.keys, pipe.contents(hid), hid)
                assert pipe.entry(kind, hid) == want
    assert pipe.entry("score", "synthetic-s000000") != pipe.entry("score", "synthetic-s000001")
    pipe.cache_dir = tmp_path / "other"  # another cache: other paths
    assert pipe.entry("score", "synthetic-s000000").is_relative_to(tmp_path / "other")
