"""``roomseg-segment`` end to end on the hand-made example building (a ROS map with a
non-zero origin, poses in the ROS frame, a label per view): labels land on their rooms, the
rooms GeoJSON re-rasterised independently equals the label PNG, the ROS segmentation map
reads back onto the same grid, and bad input is one line naming the file and the field."""

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import shapely
from PIL import Image
from shapely.geometry import shape

from benchmark.commands.segment import main
from benchmark.commands.segment_example import HEADINGS_DEG, SPOTS, write_example
from envs.maps.label_png import read_label_png
from envs.maps.ros import read_ros_map
from envs.maps.segmentation_io import (
    index_image,
    mask_polygon,
    read_index_png,
    rooms_geojson,
    value_counts,
    write_index_png,
)
from envs.world.classes import PAPER_CLASSES

REPO = Path(__file__).resolve().parents[1]


def _run(args, capsys):
    code = main([str(a) for a in args])
    cap = capsys.readouterr()
    return code, cap.out, cap.err


@pytest.fixture(scope="module")
def example(tmp_path_factory):
    """The 3 x 2 building (walls everywhere), segmented once from its labels with scores."""
    d = tmp_path_factory.mktemp("seg")
    ex = write_example(d / "in", open_plan=False)
    out = d / "out"
    code = main([f"map={ex.map_yaml}", f"poses={ex.poses}", "frame=ros", f"labels={ex.labels}",
                 f"gt={ex.gt}", "gt_format=label", f"out={out}"])
    return ex, out, code


def _centres_ros(ex):
    """World (= ROS) x, y of every pixel centre, computed from the YAML's origin."""
    h, w = ex.grid.shape
    res = ex.grid.resolution
    ox, oy, _ = ex.ros_origin
    cols, rows = np.meshgrid(np.arange(w), np.arange(h))
    return ox + (cols + 0.5) * res, oy + (h - rows - 0.5) * res


@pytest.mark.slow
def test_labels_land_on_their_rooms(example):
    ex, out, code = example
    assert code == 0
    labels = read_index_png(out / "labels.png")
    summary = json.loads((out / "summary.json").read_text())
    classes = summary["classes"]
    # the file's six distinct names, sorted (the open-label-set rule)
    assert classes == sorted(PAPER_CLASSES[k] for k in ex.room_classes)
    assert summary["n_views"] == 6 * len(SPOTS) * len(HEADINGS_DEG) and summary["n_off_map"] == 0
    assert summary["n_views_used"] == summary["n_views"]
    # not walkable -> 255 in the PNG (-1 here), walkable -> a class
    assert (labels[~ex.grid.walkable] == -1).all() and (labels[ex.grid.walkable] >= 0).all()
    for k, c in enumerate(ex.room_classes):
        room = ex.rooms == k
        right = np.mean(labels[room] == classes.index(PAPER_CLASSES[c]))
        assert right >= 0.95, (k, right)
    # every view's own cell carries its label
    import pandas as pd

    p = pd.read_csv(ex.poses)
    lab = pd.read_csv(ex.labels)
    r, c = ex.grid.world_to_cell(p["x"].to_numpy(), p["y"].to_numpy())
    assert [classes[v] for v in labels[r, c]] == lab["label"].tolist()
    scores = json.loads((out / "scores.json").read_text())
    assert scores["scored_as"] == "semantic" and scores["accuracy"] >= 0.95 and scores["n_gt_segments"] == 6


@pytest.mark.slow
def test_every_output_is_written_and_consistent(example):
    ex, out, code = example
    assert code == 0
    summary = json.loads((out / "summary.json").read_text())
    names = sorted(p.name for p in out.iterdir())
    assert names == sorted(summary["files"])
    for f in ("labels.png", "segments.png", "labels_color.png", "labels_color_legend.png", "labels_color.json",
              "overview.png", "segmentation.yaml", "segmentation.png", "rooms.geojson", "scores.json",
              "summary.json", "config.yaml"):
        assert f in names, f
    labels = read_index_png(out / "labels.png")
    assert np.asarray(Image.open(out / "labels.png")).dtype == np.uint8
    colour, colour_classes = read_label_png(out / "labels_color.png")
    assert colour_classes == summary["classes"] and (colour == labels).all()
    # no temporary folder left beside the output
    assert [p.name for p in out.parent.iterdir() if p.name.startswith(".")] == []


@pytest.mark.slow
def test_rooms_geojson_rerasterised_equals_the_label_png(example):
    ex, out, code = example
    assert code == 0
    gj = json.loads((out / "rooms.geojson").read_text())
    labels = read_index_png(out / "labels.png")
    segs = read_index_png(out / "segments.png")
    classes = json.loads((out / "summary.json").read_text())["classes"]
    x, y = _centres_ros(ex)
    drawn_cls = np.full(labels.shape, -1)
    drawn_seg = np.full(labels.shape, -1)
    hits = np.zeros(labels.shape, int)
    res = ex.grid.resolution
    for f in gj["features"]:
        inside = shapely.contains_xy(shape(f["geometry"]), x, y)
        hits += inside
        drawn_cls[inside] = classes.index(f["properties"]["class"])
        drawn_seg[inside] = f["properties"]["segment"]
        assert f["properties"]["area_m2"] == pytest.approx(inside.sum() * res * res)
        assert shape(f["geometry"]).area == pytest.approx(inside.sum() * res * res)
    labelled = labels >= 0
    agree = np.mean(drawn_cls[labelled] == labels[labelled])
    assert agree >= 0.99  # the acceptance threshold; the polygons are exact pixel outlines:
    assert agree == 1.0 and (drawn_seg == segs).all() and hits.max() == 1 and (hits[~labelled] == 0).all()


@pytest.mark.slow
def test_ros_segmentation_reads_back_on_the_same_grid(example):
    ex, out, code = example
    assert code == 0
    back = read_ros_map(out / "segmentation.yaml")
    src = read_ros_map(ex.map_yaml)
    assert back.mode == "raw" and back.origin == src.origin == (-3.25, 1.5, 0.0)
    assert back.grid.shape == src.grid.shape and back.grid.resolution == src.grid.resolution
    assert back.grid.origin == src.grid.origin
    # raw cells: the class index, unknown (-1) where there is none
    assert (back.occupancy.astype(int) == read_index_png(out / "labels.png")).all()


def test_index_png_and_polygons_by_hand(tmp_path):
    from envs.maps.gridmap import GridMap

    v = np.array([[-1, 0, 0], [1, 1, -1]])
    img, marker = index_image(v)
    assert marker == 255 and img.dtype == np.uint8 and img.tolist() == [[255, 0, 0], [1, 1, 255]]
    big = np.array([[300, -1]])
    img16, m16 = index_image(big)
    assert m16 == 65535 and img16.dtype == np.uint16 and img16.tolist() == [[300, 65535]]
    write_index_png(tmp_path / "a.png", big)
    assert read_index_png(tmp_path / "a.png").tolist() == [[300, -1]]
    # an L of three pixels: outline (0,0)-(2,0)-(2,1)-(1,1)-(1,2)-(0,2), area 3
    m = np.array([[1, 1], [1, 0]], bool)
    g = mask_polygon(m)
    assert g.area == 3 and shapely.equals(g, shapely.Polygon([(0, 0), (2, 0), (2, 1), (1, 1), (1, 2), (0, 2)]))
    # a ring of 8 pixels around a hole: area 8, the hole is the centre pixel
    ring = np.ones((3, 3), bool)
    ring[1, 1] = False
    g = mask_polygon(ring)
    assert g.area == 8 and len(g.interiors) == 1 and shapely.Polygon(g.interiors[0]).area == 1
    # world coordinates: 0.5 m pixels, top-left corner at (10, 20): pixel (0, 1) spans x 10.5..11, z 19.5..20
    seg = np.array([[-1, 0], [-1, -1]])
    gj = rooms_geojson(seg, GridMap(seg >= 0, 0.5, (10.0, 20.0)), ["kitchen"])
    f = gj["features"][0]
    assert f["properties"] == {"segment": 0, "class": "kitchen", "area_m2": 0.25, "pixels": 1}
    ext = shape(f["geometry"]).exterior
    assert sorted(map(tuple, np.asarray(ext.coords)[:-1])) == [(10.5, 19.5), (10.5, 20.0), (11.0, 19.5), (11.0, 20.0)]
    assert ext.is_ccw


@pytest.mark.slow
def test_a_geometric_segmenter_on_the_map(tmp_path, capsys):
    ex = write_example(tmp_path / "in", open_plan=False)
    code, outp, err = _run([f"map={ex.map_yaml}", "segmenter=distance", f"gt={ex.gt}", "gt_format=label",
                            f"out={tmp_path / 'o'}"], capsys)
    assert code == 0, err
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert s["mode"] == "geometry" and not (tmp_path / "o" / "labels.png").exists()
    segs = read_index_png(tmp_path / "o" / "segments.png")
    assert s["n_segments"] == segs.max() + 1 == 6
    # each room is one segment
    for k in range(6):
        ids, n = np.unique(segs[ex.rooms == k], return_counts=True)
        assert n.max() / n.sum() >= 0.95
    gj = json.loads((tmp_path / "o" / "rooms.geojson").read_text())
    assert {f["properties"]["class"] for f in gj["features"]} == {None}
    sc = json.loads((tmp_path / "o" / "scores.json").read_text())
    assert sc["scored_as"] == "instances" and sc["iou"] > 0.9
    assert read_ros_map(tmp_path / "o" / "segmentation.yaml").occupancy.max() == 5


@pytest.mark.slow
def test_an_image_map_gives_the_same_labels_as_the_ros_map(example, tmp_path, capsys):
    ex, out, _ = example
    png = tmp_path / "map.png"
    Image.open(ex.map_yaml.with_name("map.pgm")).save(png)
    code, _, err = _run([f"map={png}", "resolution=0.05", "origin=[-3.25,1.5]", "free_thresh=0.196",
                         f"poses={ex.poses}", "frame=ros", f"labels={ex.labels}", "figure=false",
                         f"out={tmp_path / 'o'}"], capsys)
    assert code == 0, err
    assert (read_index_png(tmp_path / "o" / "labels.png") == read_index_png(out / "labels.png")).all()
    assert read_ros_map(tmp_path / "o" / "segmentation.yaml").origin == (-3.25, 1.5, 0.0)


@pytest.mark.slow
def test_output_folder_is_never_overwritten_by_accident(example, tmp_path, capsys):
    ex, out, _ = example
    before = (out / "summary.json").read_text()
    code, _, err = _run([f"map={ex.map_yaml}", "segmenter=distance", f"out={out}"], capsys)
    assert code == 2 and "exists and is not empty" in err and "overwrite=true" in err
    assert (out / "summary.json").read_text() == before
    o = tmp_path / "o"
    assert _run([f"map={ex.map_yaml}", "segmenter=distance", "figure=false", f"out={o}"], capsys)[0] == 0
    code, _, err = _run([f"map={ex.map_yaml}", "segmenter=morphological", "figure=false", "overwrite=true",
                         f"out={o}"], capsys)
    assert code == 0, err
    assert json.loads((o / "summary.json").read_text())["segmenter"].endswith("Morphological")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["o"]


# ---------------------------------------------------------------- bad input: one line, file and field


def _one_line(err):
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("error: ")
    return lines[0]


@pytest.fixture()
def inputs(tmp_path):
    return write_example(tmp_path / "in", open_plan=False)


def test_label_name_not_in_the_class_list(inputs, tmp_path, capsys):
    code, _, err = _run([f"map={inputs.map_yaml}", f"poses={inputs.poses}", "frame=ros", f"labels={inputs.labels}",
                         "classes=[balcony,bathroom,bedroom]", f"out={tmp_path / 'o'}"], capsys)
    line = _one_line(err)
    assert code == 2 and str(inputs.labels) in line and "column 'label'" in line
    assert "['corridor', 'dining_room', 'kitchen']" in line
    assert not (tmp_path / "o").exists()


def test_missing_image(inputs, tmp_path, capsys):
    pics = tmp_path / "pics"
    pics.mkdir()
    Image.fromarray(np.zeros((8, 8, 3), np.uint8)).save(pics / "a.png")
    views = tmp_path / "views.csv"
    views.write_text(f"image,x,y,theta\na.png,-1.25,3.5,0\nb.png,-1.25,3.5,{math.pi}\n")
    code, _, err = _run([f"map={inputs.map_yaml}", f"poses={views}", "frame=ros", f"images={pics}",
                         "classifier=cnn", f"out={tmp_path / 'o'}"], capsys)
    line = _one_line(err)
    assert code == 2 and str(views) in line and "column 'image' row 1" in line and "'b.png'" in line


def test_wrong_pose_columns(inputs, tmp_path, capsys):
    code, _, err = _run([f"map={inputs.map_yaml}", f"poses={inputs.poses}", "frame=sim", f"labels={inputs.labels}",
                         f"out={tmp_path / 'o'}"], capsys)
    line = _one_line(err)
    assert code == 2 and str(inputs.poses) in line and "lacks column(s) ['z', 'yaw']" in line


def test_map_yaml_missing_a_field(inputs, tmp_path, capsys):
    text = inputs.map_yaml.read_text()
    inputs.map_yaml.write_text("\n".join(ln for ln in text.splitlines() if not ln.startswith("resolution")) + "\n")
    code, _, err = _run([f"map={inputs.map_yaml}", "segmenter=distance", f"out={tmp_path / 'o'}"], capsys)
    line = _one_line(err)
    assert code == 2 and str(inputs.map_yaml) in line and "missing field(s) ['resolution']" in line


def test_poses_in_the_wrong_frame_land_off_the_map(inputs, tmp_path, capsys):
    off = tmp_path / "off.csv"
    off.write_text("x,y,theta\n100,100,0\n-1.25,3.5,0\n")
    lab = tmp_path / "lab.csv"
    lab.write_text("label\nkitchen\nbedroom\n")
    code, _, err = _run([f"map={inputs.map_yaml}", f"poses={off}", "frame=ros", f"labels={lab}",
                         f"out={tmp_path / 'o'}"], capsys)
    line = _one_line(err)
    assert code == 2 and str(off) in line and "1 of 2 poses are off the walkable map" in line and "off_map=drop" in line


def test_unknown_option_and_missing_map(tmp_path, capsys):
    code, _, err = _run(["segmenter=distance", f"out={tmp_path / 'o'}"], capsys)
    assert code == 2 and "map" in _one_line(err)
    code, _, err = _run(["map=x.yaml", "segmenter=nonsense", f"out={tmp_path / 'o'}"], capsys)
    assert code == 2 and "nonsense" in _one_line(err)


@pytest.mark.slow
def test_the_module_runs_as_a_command_with_an_exit_status(tmp_path):
    r = subprocess.run([sys.executable, "-m", "benchmark.commands.segment", f"map={tmp_path / 'none.yaml'}",
                        "segmenter=distance", f"out={tmp_path / 'o'}"], cwd=REPO, capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 2 and r.stderr.strip() == f"error: FileNotFoundError: map YAML not found: {tmp_path / 'none.yaml'}"


@pytest.mark.slow
def test_images_classified_by_a_cnn_through_the_command(inputs, tmp_path, capsys):
    torch = pytest.importorskip("torch")
    pytest.importorskip("torchvision")
    from benchmark.classifiers.cnn import build_resnet
    from benchmark.classifiers.torch_common import save_checkpoint

    torch.manual_seed(0)
    ckpt = tmp_path / "tiny.pt"
    save_checkpoint(ckpt, build_resnet("resnet18", 2, False), ["kitchen", "office"], {"arch": "resnet18"})
    pics = tmp_path / "pics"
    pics.mkdir()
    rows = ["id,image,x,y,theta"]
    rng = np.random.default_rng(0)
    for i, (x, y) in enumerate([(-1.25, 3.5), (2.75, 3.5), (-1.25, 6.5)]):
        Image.fromarray(rng.integers(0, 256, (16, 16, 3), dtype=np.uint8)).save(pics / f"{i}.png")
        rows.append(f"v{i},{i}.png,{x},{y},0")
    views = tmp_path / "views.csv"
    views.write_text("\n".join(rows) + "\n")
    o = tmp_path / "o"
    code, _, err = _run([f"map={inputs.map_yaml}", f"poses={views}", "frame=ros", f"images={pics}",
                         "classifier=cnn", f"classifier.checkpoint={ckpt}", "classifier.arch=resnet18",
                         "classifier.device=cpu", "classifier.image_size=32", "classes=[kitchen,office]",
                         f"out={o}"], capsys)
    assert code == 0, err
    s = json.loads((o / "summary.json").read_text())
    assert s["mode"] == "images" and s["n_views"] == 3 and s["classes"] == ["kitchen", "office"]
    labels = read_index_png(o / "labels.png")
    assert set(np.unique(labels[inputs.grid.walkable]).tolist()) <= {0, 1}


@pytest.mark.parametrize("connectivity", [1, 2])
def test_mask_polygon_is_the_exact_pixel_outline_of_random_shapes(connectivity):
    """Checked against pixel centres with shapely (no shared code with the tracing): every
    4- or 8-connected region of random masks, with holes and corner-touching pixels."""
    from scipy import ndimage

    rng = np.random.default_rng(7)
    rr, cc = np.mgrid[0:13, 0:11]
    n_regions = 0
    for t in range(60):
        m = rng.random((13, 11)) < rng.uniform(0.3, 0.8)
        if t % 3 == 1:
            m = ndimage.binary_opening(m)
        lab, n = ndimage.label(m, ndimage.generate_binary_structure(2, connectivity))
        for k in range(1, n + 1):
            region = lab == k
            g = mask_polygon(region)
            assert g.is_valid and g.area == region.sum()
            assert (shapely.contains_xy(g, cc + 0.5, rr + 0.5) == region).all()
            n_regions += 1
    assert n_regions > 150


def test_a_segment_in_two_pieces_is_one_multipolygon_feature():
    from envs.maps.gridmap import GridMap

    seg = np.array([[0, -1, 0], [-1, -1, -1], [1, 1, -1]])
    gj = rooms_geojson(seg, GridMap(seg >= 0, 1.0, (0.0, 3.0)))
    f0, f1 = gj["features"]
    assert f0["geometry"]["type"] == "MultiPolygon" and shape(f0["geometry"]).area == 2
    assert f0["properties"]["class"] is None and f1["properties"]["area_m2"] == 2.0
    assert shapely.equals(shape(f1["geometry"]), shapely.box(0, 0, 2, 1))


@pytest.mark.slow
def test_labels_matched_by_pose_give_the_same_map_as_by_id(example, tmp_path, capsys):
    """The pose file without ids, the labels file holding shuffled ROS poses: rows pair by
    pose (classifier.match=auto), and the result equals the id-matched run."""
    import pandas as pd

    ex, out, _ = example
    p = pd.read_csv(ex.poses)
    lab = pd.read_csv(ex.labels)
    p[["x", "y", "theta"]].to_csv(tmp_path / "poses.csv", index=False)
    both = p.merge(lab, on="id").drop(columns="id").sample(frac=1.0, random_state=0)
    both.to_csv(tmp_path / "labels.csv", index=False)
    code, _, err = _run([f"map={ex.map_yaml}", f"poses={tmp_path / 'poses.csv'}", "frame=ros",
                         f"labels={tmp_path / 'labels.csv'}", "figure=false", f"out={tmp_path / 'o'}"], capsys)
    assert code == 0, err
    assert (read_index_png(tmp_path / "o" / "labels.png") == read_index_png(out / "labels.png")).all()


# ------------------------------------------------------------------ issue 24 / 29 / 30 small things
def test_unknown_keys_list_the_valid_ones(tmp_path, capsys):
    ex = write_example(tmp_path / "in", open_plan=False)
    code, _, err = _run([f"mapp={ex.map_yaml}", f"out={tmp_path / 'o'}"], capsys)
    assert code == 2 and "valid keys:" in err and " map, " in err and "poses" in err and len(err.splitlines()) == 1
    code, _, err = _run([f"map={ex.map_yaml}", "aggregator.kk=3", f"out={tmp_path / 'o'}"], capsys)
    assert code == 2 and "valid keys of aggregator: fov, max_range_m" in err
    code, _, err = _run([f"map={ex.map_yaml}", "segmenter=distanc", f"out={tmp_path / 'o'}"], capsys)
    assert code == 2 and "segmenter options: distance, " in err
    code, _, err = _run([f"map={ex.map_yaml}", "+foo=3", "segmenter=distance", f"out={tmp_path / 'o'}"], capsys)
    assert code == 2 and "foo: unknown key (with or without +)" in err and "valid keys: " in err
    assert not (tmp_path / "o").exists()


def test_the_summary_line_says_which_pose_frame_it_assumed(example, tmp_path, capsys):
    ex, _, _ = example
    code, out, _ = _run([f"map={ex.map_yaml}", f"poses={ex.poses}", f"labels={ex.labels}", f"out={tmp_path / 'o'}",
                         "figure=false"], capsys)
    assert code == 0 and "poses read as frame=ros (x, y metres, theta radians CCW from +x)" in out


def test_a_label_ground_truth_index_png_uses_the_given_classes(example, tmp_path, capsys):
    """Issue 30 item 4: ``gt_format=label`` with a class-index PNG (no sidecar) and
    ``classes=[...]`` stopped with "needs the class list"."""
    ex, _, _ = example
    gt = tmp_path / "gt_index.png"
    semantic, gt_classes = read_label_png(ex.gt)
    write_index_png(gt, semantic)
    classes = "[" + ",".join(gt_classes) + "]"
    code, _, err = _run([f"map={ex.map_yaml}", "segmenter=distance", f"gt={gt}", "gt_format=label",
                         f"classes={classes}", f"out={tmp_path / 'o'}", "figure=false"], capsys)
    assert code == 0, err
    scores = json.loads((tmp_path / "o" / "scores.json").read_text())
    assert scores["n_gt_segments"] == 6 and scores["iou"] > 0.9


def test_leftovers_of_a_killed_run_are_cleaned_by_the_next(example, tmp_path, capsys):
    """Issue 24 item 9: a killed ``roomseg-segment`` left ``.out.tmp-*`` folders behind."""
    ex, _, _ = example
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True,
                          text=True).stdout.strip()
    import os

    left = [tmp_path / f".o.tmp-{dead}-abc", tmp_path / f".o.old-{dead}-def"]
    alive = tmp_path / f".o.tmp-{os.getppid()}-ghi"  # a writer still running (this test's parent)
    for d in (*left, alive):
        d.mkdir()
        (d / "labels.png").write_bytes(b"half")
    code, _, err = _run([f"map={ex.map_yaml}", "segmenter=distance", f"out={tmp_path / 'o'}", "figure=false"], capsys)
    assert code == 0, err
    assert not any(d.exists() for d in left) and alive.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([alive.name, "o"])


def test_value_counts_by_bands_equal_bincount():
    """Counted a few rows at a time (bands of 1, 3 and more rows than the map): np.bincount of
    the values >= 0 over the whole map, trailing zero counts included."""
    rng = np.random.default_rng(1)
    v = rng.integers(-1, 5, (13, 7)).astype(np.int32)
    want = np.bincount(v[v >= 0], minlength=8)
    for rows in (1, 3, 100):
        got = value_counts(v, 8, band_rows=rows)
        assert got.dtype == np.int64 and got.tolist() == want.tolist()
