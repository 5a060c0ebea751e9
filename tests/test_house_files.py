"""House inputs: every file layout, bad input failing alone, the room-type mapping, the map
size limit, and the prior loader on prior's real classes."""

from __future__ import annotations

import gzip
import json
import tracemalloc

import numpy as np
import pytest

from envs.datasets.house_files import (
    iter_house_records,
    load_houses,
    load_prior_houses,
    prior_records,
    prior_splits,
    read_house_records,
)
from envs.datasets.procthor import ProcTHOREnv
from envs.maps.scene import MAX_MAP_PIXELS, RASTER_BYTES_PER_PIXEL, rasterise_house
from envs.world.classes import PAPER_CLASSES, ROOM_TYPE_TO_CLASS, room_type_mapping
from envs.world.house import House, HouseError


def room_house(room_type: str = "Kitchen", size: tuple[float, float] = (4.0, 3.0), hid: str | None = None) -> dict:
    """One rectangular room of ``size`` metres (x by z) at the origin, no walls or objects."""
    x, z = size
    h = {"rooms": [{"id": "room|1", "roomType": room_type, "floorPolygon": [
        {"x": 0, "y": 0, "z": 0}, {"x": x, "y": 0, "z": 0}, {"x": x, "y": 0, "z": z}, {"x": 0, "y": 0, "z": z}]}],
        "walls": [], "doors": [], "objects": []}
    if hid is not None:
        h["id"] = hid
    return h


def ids(path, **kw) -> list[str]:
    return [r.id for r in iter_house_records(path, **kw)]


# ---- layouts


def test_every_layout_reads_with_its_ids(tmp_path):
    h = room_house()
    (tmp_path / "one.json").write_text(json.dumps(h))
    (tmp_path / "own.json").write_text(json.dumps(room_house(hid="house-A")))
    (tmp_path / "list.json").write_text(json.dumps([h, h, room_house(hid="x")]))
    with gzip.open(tmp_path / "list.json.gz", "wt") as f:
        json.dump([h, h], f)
    with gzip.open(tmp_path / "one.json.gz", "wt") as f:
        json.dump(h, f)
    (tmp_path / "lines.jsonl").write_text(json.dumps(h) + "\n\n" + json.dumps(h) + "\n")
    with gzip.open(tmp_path / "lines.jsonl.gz", "wt") as f:
        f.write("\n".join(json.dumps(h) for _ in range(3)))
    assert ids(tmp_path / "one.json") == ["one"]
    assert ids(tmp_path / "own.json") == ["house-A"]
    assert ids(tmp_path / "list.json") == ["list-00000", "list-00001", "x"]
    assert ids(tmp_path / "list.json.gz") == ["list-00000", "list-00001"]
    assert ids(tmp_path / "one.json.gz") == ["one"]
    # the blank line keeps its number: the second house is on line 3 (index 2)
    assert ids(tmp_path / "lines.jsonl") == ["lines-00000", "lines-00002"]
    assert ids(tmp_path / "lines.jsonl.gz") == ["lines-00000", "lines-00001", "lines-00002"]
    got = load_houses(tmp_path / "lines.jsonl.gz", start=1, stop=3)
    assert [x.id for x in got] == ["lines-00001", "lines-00002"]
    assert got[0].data == h


def test_folder_of_house_files_sorted_ids_from_house_or_stem(tmp_path):
    d = tmp_path / "houses"
    d.mkdir()
    (d / "b.json").write_text(json.dumps(room_house("Bedroom")))
    with gzip.open(d / "a.json.gz", "wt") as f:
        json.dump(room_house("Kitchen"), f)
    (d / "c.json").write_text(json.dumps(room_house("Bathroom", hid="my-house")))
    (d / "notes.txt").write_text("not a house")
    (d / "sub").mkdir()
    recs = read_house_records(d)
    assert [r.id for r in recs] == ["a", "b", "my-house"]
    assert [r.data["rooms"][0]["roomType"] for r in recs] == ["Kitchen", "Bedroom", "Bathroom"]
    assert [r.source for r in recs] == [str(d / "a.json.gz"), str(d / "b.json"), str(d / "c.json")]
    env = ProcTHOREnv(path=str(d), resolution=0.1)
    assert env.house_ids() == ["a", "b", "my-house"]
    assert env.scene("b").semantic.max() == PAPER_CLASSES.index("bedroom")


def test_folder_bad_file_fails_alone_and_empty_folder_is_an_error(tmp_path):
    d = tmp_path / "houses"
    d.mkdir()
    (d / "a.json").write_text(json.dumps(room_house()))
    (d / "b.json").write_text('{"rooms": [')
    (d / "c.json").write_text(json.dumps([room_house(), room_house()]))
    env = ProcTHOREnv(path=str(d), resolution=0.1)
    assert env.house_ids() == ["a", "b", "c"]
    env.scene("a")
    with pytest.raises(HouseError, match=r"'b'.*b\.json: not valid JSON"):
        env.scene("b")
    with pytest.raises(HouseError, match="one house .* per file in a folder, got a list of 2"):
        env.scene("c")
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(ValueError, match=r"empty holds no \.json or \.json\.gz house files"):
        read_house_records(empty)


def test_split_dictionary_layout(tmp_path):
    path = tmp_path / "splits.json"
    path.write_text(json.dumps({"train": [room_house("Kitchen"), room_house("Bedroom")],
                                "val": [room_house("Bathroom")]}))
    assert ids(path, split="train") == ["splits-train-00000", "splits-train-00001"]
    recs = read_house_records(path, split="val")
    assert [r.id for r in recs] == ["splits-val-00000"]
    assert recs[0].data["rooms"][0]["roomType"] == "Bathroom"
    with pytest.raises(ValueError, match=r"holds the splits \['train', 'val'\]; choose one with split"):
        read_house_records(path)
    with pytest.raises(ValueError, match=r"no split 'test'; splits with houses: \['train', 'val'\]"):
        read_house_records(path, split="test")
    env = ProcTHOREnv(path=str(path), split="val", resolution=0.1)
    assert env.house_ids() == ["splits-val-00000"]
    assert env.scene("splits-val-00000").semantic.max() == PAPER_CLASSES.index("bathroom")
    # prior-style items stored as JSON strings read the same
    path2 = tmp_path / "strings.json.gz"
    with gzip.open(path2, "wt") as f:
        json.dump({"train": [json.dumps(room_house())]}, f)
    assert read_house_records(path2, split="train")[0].data == room_house()


def test_the_split_errors_list_only_splits_that_hold_houses(tmp_path):
    from prior import Dataset, DatasetDict

    path = tmp_path / "splits.json"
    path.write_text(json.dumps({"train": [], "val": [room_house("Bathroom")], "test": []}))
    with pytest.raises(ValueError, match=r"holds the splits \['val'\]; choose one with split"):
        read_house_records(path)
    with pytest.raises(ValueError, match=r"an empty split 'train'; splits with houses: \['val'\]"):
        read_house_records(path, split="train")
    with pytest.raises(ValueError, match=r"no split 'dev'; splits with houses: \['val'\]"):
        read_house_records(path, split="dev")
    path.write_text(json.dumps({"train": [], "val": []}))
    with pytest.raises(ValueError, match=r"every split \(\['train', 'val'\]\) is empty"):
        read_house_records(path, split="val")
    # prior's dataset dict: an empty test split is not offered
    ds = DatasetDict(train=Dataset([room_house()], "procthor-10k", "train"), test=Dataset([], "procthor-10k", "test"))
    assert prior_splits(ds) == ["train"]
    with pytest.raises(ValueError, match=r"split 'test' holds no houses; splits with houses: \['train'\]"):
        prior_records(ds, "procthor-10k", "test")
    with pytest.raises(ValueError, match=r"no split 'val'; splits with houses: \['train'\]"):
        prior_records(ds, "procthor-10k", "val")


def test_split_only_for_split_dictionaries_and_unknown_inputs(tmp_path):
    (tmp_path / "h.jsonl").write_text(json.dumps(room_house()))
    with pytest.raises(ValueError, match="split 'val' given, but only a split dictionary"):
        read_house_records(tmp_path / "h.jsonl", split="val")
    with pytest.raises(FileNotFoundError, match="house file not found"):
        read_house_records(tmp_path / "nope.jsonl")
    (tmp_path / "x.txt").write_text("{}")
    with pytest.raises(ValueError, match=r"expected \.json, \.json\.gz, \.jsonl, \.jsonl\.gz or a folder"):
        read_house_records(tmp_path / "x.txt")
    (tmp_path / "empty.jsonl").write_text("\n\n")
    with pytest.raises(ValueError, match="empty.jsonl holds no houses"):
        read_house_records(tmp_path / "empty.jsonl")
    (tmp_path / "broken.json").write_text('[{"rooms": []},\n {"rooms": ')
    with pytest.raises(ValueError, match=r"broken\.json: not valid JSON: .*line 2, column"):
        read_house_records(tmp_path / "broken.json")


# ---- bad input fails alone


def test_invalid_json_line_fails_that_house_only(tmp_path):
    path = tmp_path / "h.jsonl"
    lines = [json.dumps(room_house("Kitchen")), '{"rooms": [ oops', json.dumps(room_house("Bedroom"))]
    path.write_text("\n".join(lines) + "\n")
    env = ProcTHOREnv(path=str(path), resolution=0.1)
    assert env.house_ids() == ["h-00000", "h:line2", "h-00002"]
    assert env.scene("h-00000").semantic.max() == PAPER_CLASSES.index("kitchen")
    assert env.scene("h-00002").semantic.max() == PAPER_CLASSES.index("bedroom")
    with pytest.raises(HouseError) as e:
        env.scene("h:line2")
    msg = str(e.value)
    assert e.value.house_id == "h:line2" and f"{path} line 2" in msg and "not valid JSON" in msg
    assert "\n" not in msg
    with pytest.raises(HouseError, match="h:line2"):
        env.house("h:line2")
    # the strict loaders raise the same error
    with pytest.raises(HouseError, match=r"h\.jsonl line 2: not valid JSON"):
        load_houses(path)


def test_house_data_is_the_exact_parsed_dict(tmp_path):
    h = room_house()
    h["metadata"] = {"note": "kept as read", "n": 1.5}
    path = tmp_path / "h.jsonl"
    path.write_text(json.dumps(h) + "\n")
    env = ProcTHOREnv(path=str(path))
    data = env.house("h-00000").data
    assert data == h
    assert env.house("h-00000").data is data


def test_duplicate_house_ids_name_both_places(tmp_path):
    path = tmp_path / "h.jsonl"
    path.write_text("\n".join(json.dumps(room_house(hid=i)) for i in ("a", "b", "a")) + "\n")
    with pytest.raises(ValueError) as e:
        ProcTHOREnv(path=str(path))
    msg = str(e.value)
    assert "house id 'a' appears twice" in msg and f"{path} line 1" in msg and f"{path} line 3" in msg
    d = tmp_path / "folder"
    d.mkdir()
    (d / "x.json").write_text(json.dumps(room_house(hid="same")))
    (d / "y.json").write_text(json.dumps(room_house(hid="same")))
    with pytest.raises(ValueError, match=f"'same' appears twice: {d / 'x.json'} and {d / 'y.json'}"):
        read_house_records(d)
    (tmp_path / "list.json").write_text(json.dumps([room_house(hid="q"), room_house(hid="q")]))
    with pytest.raises(ValueError, match=r"'q' appears twice: .*list\.json \[0\] and .*list\.json \[1\]"):
        load_houses(tmp_path / "list.json")


def test_map_size_limit_fails_before_allocating():
    # 4000 x 3000 m room (a 4 x 3 m room scaled x1000); 0.25 m margin each side; at 0.25 m/px:
    # (4000.5 / 0.25) x (3000.5 / 0.25) = 16002 x 12002 = 192 056 004 pixels
    house = House("huge", room_house(size=(4000.0, 3000.0)))
    tracemalloc.start()
    try:
        with pytest.raises(HouseError) as e:
            rasterise_house(house, resolution=0.25)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    msg = str(e.value)
    assert e.value.house_id == "huge" and e.value.field == "map size"
    assert "extent 4000.50 x 3000.50 m" in msg and "16002 x 12002 = 192056004 pixels" in msg
    assert f"max_map_pixels={MAX_MAP_PIXELS}" in msg
    assert peak < 5e6, peak  # nothing map-sized was allocated


def test_map_size_limit_is_inclusive_and_settable():
    # 4 x 3 m at 0.25 m/px with 0.25 m margin: 4.5 / 0.25 = 18 by 3.5 / 0.25 = 14 -> 252 pixels
    house = House("sq", room_house())
    assert rasterise_house(house, resolution=0.25, max_map_pixels=252).grid.shape == (14, 18)
    with pytest.raises(HouseError, match="18 x 14 = 252 pixels, over the limit max_map_pixels=251"):
        rasterise_house(house, resolution=0.25, max_map_pixels=251)
    assert rasterise_house(house, resolution=0.25, max_map_pixels=None).grid.shape == (14, 18)
    for bad in (0, -5, 1.5, "many", True):
        with pytest.raises(ValueError, match="env.max_map_pixels must be a positive number of pixels or null"):
            ProcTHOREnv(path="unused.jsonl", max_map_pixels=bad)


def test_env_house_over_the_size_limit_fails_alone(tmp_path):
    path = tmp_path / "h.jsonl"
    path.write_text(json.dumps(room_house()) + "\n" + json.dumps(room_house(size=(40.0, 30.0))) + "\n")
    env = ProcTHOREnv(path=str(path), resolution=0.25, max_map_pixels=1000)
    assert env.scene("h-00000").grid.walkable.size == 252
    with pytest.raises(HouseError, match=r"'h-00001': map size: extent 40\.50 x 30\.50 m .* 162 x 122 = 19764 "
                                         r"pixels, over the limit max_map_pixels=1000"):
        env.scene("h-00001")


def test_bytes_per_pixel_bound_holds():
    """The documented cost per pixel bounds the traced peak of a map-filling room with a
    diagonal wall (each window spans the whole map), so MAX_MAP_PIXELS fits in 2 GB."""
    h = room_house(size=(20.0, 20.0))
    h["walls"] = [{"id": "w", "polygon": [{"x": 0, "y": 0, "z": 0}, {"x": 20, "y": 0, "z": 20},
                                          {"x": 0, "y": 2, "z": 0}, {"x": 20, "y": 2, "z": 20}]}]
    rasterise_house(House("warm", room_house()), resolution=0.5)  # imports and caches outside the trace
    tracemalloc.start()
    try:
        scene = rasterise_house(House("big", h), resolution=0.05)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    n = scene.grid.walkable.size
    assert n == 410 * 410
    assert 40 < peak / n <= RASTER_BYTES_PER_PIXEL
    assert MAX_MAP_PIXELS * RASTER_BYTES_PER_PIXEL <= 2_000_000_000


# ---- room types


def test_hallway_house_loads_as_corridor(tmp_path):
    path = tmp_path / "h.jsonl"
    path.write_text(json.dumps(room_house("Hallway")) + "\n")
    env = ProcTHOREnv(path=str(path), resolution=0.1)
    scene = env.scene("h-00000")
    assert list(scene.instance_classes) == [PAPER_CLASSES.index("corridor")]
    assert set(np.unique(scene.semantic)) == {-1, PAPER_CLASSES.index("corridor")}


def test_room_type_setting_adds_overrides_and_removes(tmp_path):
    path = tmp_path / "h.jsonl"
    path.write_text("\n".join(json.dumps(room_house(t)) for t in ("Garage", "Hallway", "Kitchen")) + "\n")
    env = ProcTHOREnv(path=str(path), resolution=0.1)
    with pytest.raises(HouseError) as e:
        env.scene("h-00000")
    assert "unknown room type 'Garage'" in str(e.value) and "env.room_types" in str(e.value)
    assert env.scene("h-00002").instance_classes.tolist() == [PAPER_CLASSES.index("kitchen")]

    env = ProcTHOREnv(path=str(path), resolution=0.1,
                      room_types={"Garage": "living_room", "Hallway": None, "Kitchen": "dining_room"})
    assert env.scene("h-00000").instance_classes.tolist() == [PAPER_CLASSES.index("living_room")]
    with pytest.raises(HouseError, match="unknown room type 'Hallway'"):
        env.scene("h-00001")
    assert env.scene("h-00002").instance_classes.tolist() == [PAPER_CLASSES.index("dining_room")]


def test_room_type_mapped_to_a_class_not_in_the_list_fails_that_house(tmp_path):
    path = tmp_path / "h.jsonl"
    path.write_text(json.dumps(room_house("Kitchen")) + "\n" + json.dumps(room_house("Hallway")) + "\n")
    env = ProcTHOREnv(path=str(path), resolution=0.1, classes=["bathroom", "bedroom", "kitchen", "living_room"])
    assert env.scene("h-00000").instance_classes.tolist() == [2]
    with pytest.raises(HouseError, match="'Hallway' maps to class 'corridor', which is not in classes .*env.room_types"):
        env.scene("h-00001")


def test_room_type_mapping_defaults_and_bad_values():
    assert ROOM_TYPE_TO_CLASS["Hallway"] == "corridor" and ROOM_TYPE_TO_CLASS["Corridor"] == "corridor"
    assert {ROOM_TYPE_TO_CLASS[t] for t in ("Kitchen", "LivingRoom", "Bedroom", "Bathroom")} == {
        "kitchen", "living_room", "bedroom", "bathroom"}
    assert set(ROOM_TYPE_TO_CLASS.values()) == set(PAPER_CLASSES)
    assert room_type_mapping({"Office": "bedroom"})["Office"] == "bedroom"
    assert "Office" not in ROOM_TYPE_TO_CLASS  # the defaults are not modified
    with pytest.raises(ValueError, match=r"env.room_types.Office: expected a class name or null, got 3"):
        room_type_mapping({"Office": 3})


def test_room_types_from_the_hydra_config(tmp_path):
    from hydra import compose, initialize_config_dir
    from hydra.utils import instantiate

    from benchmark.harness.runner import CONF_DIR

    path = tmp_path / "h.jsonl"
    path.write_text(json.dumps(room_house("Office")) + "\n" + json.dumps(room_house("Kitchen")) + "\n")
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        cfg = compose("config", overrides=["env=procthor", f"env.path={path}", "env.resolution=0.1",
                                           "env.room_types={Office: bedroom, Kitchen: null}"])
    env = instantiate(cfg.env)
    assert env.scene("h-00000").instance_classes.tolist() == [PAPER_CLASSES.index("bedroom")]
    with pytest.raises(HouseError, match="unknown room type 'Kitchen'"):
        env.scene("h-00001")
    assert cfg.env.max_map_pixels == MAX_MAP_PIXELS and cfg.env.split is None


# ---- prior


def _prior_dataset_dict():
    from prior import Dataset, DatasetDict, LazyJsonDataset

    train = LazyJsonDataset([json.dumps(room_house(t)) for t in ("Kitchen", "Bedroom", "Hallway")],
                            "procthor-10k", "train")
    val = Dataset([room_house("Bathroom"), room_house("LivingRoom")], "procthor-10k", "val")
    return DatasetDict(train=train, val=val)


def test_prior_splits_found_on_the_real_dataset_dict():
    ds = _prior_dataset_dict()
    # prior's DatasetDict has __getitem__ only: iteration (and `in`) falls back to ds[0]
    assert not hasattr(ds, "keys") and not hasattr(ds, "__contains__") and not hasattr(ds, "__iter__")
    with pytest.raises(KeyError, match="0"):
        list(ds)
    assert prior_splits(ds) == ["train", "val"]
    assert prior_splits({"a": [room_house()], "b": []}) == ["a"]  # only splits that hold houses


def test_prior_loader_with_the_real_prior_classes(monkeypatch):
    import prior

    ds = _prior_dataset_dict()
    calls = []
    monkeypatch.setattr(prior, "load_dataset", lambda name, **kw: calls.append((name, kw)) or ds)
    houses = load_prior_houses("procthor-10k", "train", 1, 3)
    assert calls == [("procthor-10k", {})]
    assert [h.id for h in houses] == ["procthor-10k-train-00001", "procthor-10k-train-00002"]
    assert [h.data["rooms"][0]["roomType"] for h in houses] == ["Bedroom", "Hallway"]
    assert len(load_prior_houses("procthor-10k", "val", 0, None)) == 2
    with pytest.raises(ValueError, match=r"procthor-10k has no split 'test'; splits with houses: \['train', 'val'\]"):
        load_prior_houses("procthor-10k", "test")

    env = ProcTHOREnv(path=None, stop=100, resolution=0.1)  # split null -> train, as the paper's config
    assert env.house_ids() == [f"procthor-10k-train-{i:05d}" for i in range(3)]
    assert env.scene("procthor-10k-train-00002").instance_classes.tolist() == [PAPER_CLASSES.index("corridor")]
    env = ProcTHOREnv(path=None, split="val", stop=1)
    assert env.house_ids() == ["procthor-10k-val-00000"]


def test_prior_house_that_does_not_parse_fails_alone():
    from prior import DatasetDict, LazyJsonDataset

    ds = DatasetDict(train=LazyJsonDataset([json.dumps(room_house()), "{broken", json.dumps(room_house())],
                                           "procthor-10k", "train"))
    recs = prior_records(ds, "procthor-10k", "train")
    assert [r.error is None for r in recs] == [True, False, True]
    with pytest.raises(HouseError, match=r"prior procthor-10k \[train\]\[1\]: not valid JSON"):
        recs[1].house()


@pytest.mark.slow
def test_run_with_an_invalid_json_line_has_one_failed_row(tmp_path, procthor_file):
    from hydra import compose, initialize_config_dir

    from benchmark.harness.runner import CONF_DIR, run

    with gzip.open(procthor_file, "rt") as f:
        lines = [next(f).strip() for _ in range(3)]
    lines[1] = lines[1][: len(lines[1]) // 2]  # cut mid-house: not valid JSON
    houses = tmp_path / "houses.jsonl"
    houses.write_text("\n".join(lines) + "\n")
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        cfg = compose("config", overrides=[
            "env=procthor_shared", f"env.path={houses}", "classifier=oracle", "env.resolution=0.1",
            "viewpoints.spacing=1.0", f"run.results_dir={tmp_path / 'results'}", "run.progress=false",
        ], return_hydra_config=True)
    choices = {k: str(v) for k, v in cfg.hydra.runtime.choices.items() if not k.startswith("hydra")}
    df = run(cfg, tmp_path / "out", choices)
    assert df["house_id"].tolist() == ["houses-00000", "houses:line2", "houses-00002"]
    assert df["status"].tolist() == ["ok", "failed", "ok"]
    assert f"{houses} line 2" in df.loc[1, "error"] and "not valid JSON" in df.loc[1, "error"]


def test_shared_file_ids_unchanged(procthor_file):
    recs = read_house_records(procthor_file, 148)
    assert [r.id for r in recs] == ["procthor-10k-uniform-hard-val-00148", "procthor-10k-uniform-hard-val-00149"]
    assert all(r.error is None and r.source.endswith(f"line {149 + i}") for i, r in enumerate(recs))
