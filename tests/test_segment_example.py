"""The example building drawn by bands of rows (``segment_example.example_rows``, the map
writer ``envs.maps.ros.write_ros_map_rows``): the same arrays as the whole-map drawing it
replaced, kept here as the reference, and the same file bytes as before."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

from benchmark.commands.segment_example import (
    DOOR_M,
    FREE,
    MARGIN_M,
    UNKNOWN,
    WALL,
    WALL_M,
    example_map,
    example_rows,
    write_example,
    write_example_inputs,
)
from envs.maps.frames import ros_origin_to_grid_origin
from envs.maps.ros import write_ros_map, write_ros_map_rows


def _example_map_reference(nx, ny, room_m, resolution, ros_origin, open_plan):
    """The whole-map drawing (map-sized float64 coordinate grids) that ``example_map`` used
    before it went by bands: (image (H, W) uint8, rooms (H, W) int32)."""
    w_m, h_m = nx * room_m + 2 * MARGIN_M, ny * room_m + 2 * MARGIN_M
    W, H = int(round(w_m / resolution)), int(round(h_m / resolution))
    x0, z0 = ros_origin_to_grid_origin(ros_origin, H, resolution)
    bx, by = ros_origin[0] + MARGIN_M, ros_origin[1] + MARGIN_M
    U, V = np.meshgrid(x0 + (np.arange(W) + 0.5) * resolution - bx, z0 - (np.arange(H) + 0.5) * resolution - by)
    inside = (U > 0) & (U < nx * room_m) & (V > 0) & (V < ny * room_m)
    wall_u = np.abs(U - np.round(U / room_m) * room_m) < WALL_M / 2
    wall_v = np.abs(V - np.round(V / room_m) * room_m) < WALL_M / 2
    ku, kv = np.round(U / room_m), np.round(V / room_m)
    mid_u = np.abs((V % room_m) - room_m / 2) < DOOR_M / 2
    mid_v = np.abs((U % room_m) - room_m / 2) < DOOR_M / 2
    door_u = wall_u & mid_u & (ku > 0) & (ku < nx) & ~wall_v
    door_v = wall_v & mid_v & (kv > 0) & (kv < ny) & ~wall_u
    wall = inside & ((wall_u & ~door_u) | (wall_v & ~door_v))
    if open_plan and nx >= 2:
        wall &= ~(wall_u & (ku == nx - 1) & (V > (ny - 1) * room_m + WALL_M / 2) & (V < ny * room_m - WALL_M / 2))
    building = (U > -WALL_M / 2) & (U < nx * room_m + WALL_M / 2) & (V > -WALL_M / 2) & (V < ny * room_m + WALL_M / 2)
    free = inside & ~wall
    img = np.full((H, W), UNKNOWN, np.uint8)
    img[free] = FREE
    img[wall | (building & ~inside)] = WALL
    ci = np.where(door_u, np.clip(ku - 1, 0, nx - 1), np.clip(np.floor(U / room_m), 0, nx - 1)).astype(np.int64)
    cj = np.where(door_v, np.clip(kv - 1, 0, ny - 1), np.clip(np.floor(V / room_m), 0, ny - 1)).astype(np.int64)
    return img, np.where(free, ci + nx * cj, -1).astype(np.int32)


CASES = [
    (3, 2, 4.0, 0.05, (-3.25, 1.5), True),
    (3, 2, 4.0, 0.05, (-3.25, 1.5), False),
    (4, 4, 10.0, 0.05, (-3.25, 1.5), True),
    (5, 3, 4.95, 0.07, (1.234, -7.5), True),
    (1, 1, 4.0, 0.05, (0.0, 0.0), True),
]


@pytest.mark.parametrize("case", CASES)
def test_bands_draw_the_reference_building(case):
    """Put together, the bands are the whole-map reference's image and rooms, for any band
    height (one row, an odd 7, more than the map)."""
    ref_img, ref_rooms = _example_map_reference(*case)
    img, rooms, *_ = example_map(*case)
    assert np.array_equal(img, ref_img) and np.array_equal(rooms, ref_rooms)
    for rows in (1, 7, 10_000):
        bands = list(example_rows(*case, rows=rows))
        assert max(len(b[0]) for b in bands) <= rows
        assert np.array_equal(np.concatenate([b[0] for b in bands]), ref_img)
        assert np.array_equal(np.concatenate([b[1] for b in bands]), ref_rooms)
    assert {int(v) for v in np.unique(img)} == {FREE, WALL, UNKNOWN}
    assert (rooms >= 0).sum() == (img == FREE).sum()


def test_example_files_are_the_bytes_written_before(tmp_path):
    """The default example's files, digests taken from the whole-map writer before the
    change (PIL's PGM of the whole image)."""
    ex = write_example(tmp_path / "in")
    digest = {p.name: hashlib.sha256(p.read_bytes()).hexdigest()
              for p in (ex.map_yaml, ex.map_yaml.with_suffix(".pgm"), ex.poses, ex.labels, ex.gt)}
    assert digest == {
        "map.yaml": "929e014139ea68f1feb993a53fec81c3c11ca54541e975b0fc54a5c766558b4e",
        "map.pgm": "b462cd360cd7689173ea62d3d84100ebaf114808f657f89d0bb54c0f542cc7de",
        "poses.csv": "f346c0ccb6f56c008aa03f1e9ffaab39cd42eb0a888e4892c91a15218ea5bb51",
        "labels.csv": "80cb813173e5f51b69894c043f0702dad25669f2686ce683566e3b4f0e9896b5",
        "gt.png": "3b7516d4196ea37d63f7467b4c80bc5bae54fd06f862bc85cd43b4f93a1245ca",
    }


def test_inputs_alone_are_the_example_files(tmp_path):
    """write_example_inputs (no map-sized answers) writes the bytes write_example writes."""
    ex = write_example(tmp_path / "a", 4, 3, room_m=5.0)
    ins = write_example_inputs(tmp_path / "b", 4, 3, room_m=5.0)
    assert ins.shape == ex.grid.shape and ins.views == 4 * 3 * 16
    for name in ("map.yaml", "map.pgm", "poses.csv", "labels.csv"):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes()
    assert not (tmp_path / "b" / "gt.png").exists()


def test_map_by_bands_is_pils_whole_map(tmp_path):
    """write_ros_map_rows writes the bytes of write_ros_map (PIL's PGM writer), for bands of
    any height."""
    img = np.random.default_rng(3).integers(0, 256, (37, 23), dtype=np.uint8)
    write_ros_map(tmp_path / "whole" / "m.yaml", img, 0.05, (1.0, -2.0, 0.0))
    want = {n: (tmp_path / "whole" / n).read_bytes() for n in ("m.yaml", "m.pgm")}
    for rows in (1, 5, 37):
        d = tmp_path / f"rows{rows}"
        write_ros_map_rows(d / "m.yaml", img.shape, (img[r:r + rows] for r in range(0, 37, rows)), 0.05,
                           (1.0, -2.0, 0.0))
        assert {n: (d / n).read_bytes() for n in ("m.yaml", "m.pgm")} == want


@pytest.mark.parametrize(("bands", "message"), [
    (lambda img: [img[:10]], "bands hold 10 rows; expected 37"),
    (lambda img: [img, img[:1]], "bands hold more than the 37 rows"),
    (lambda img: [img[:, :5]], "band of shape (37, 5) dtype uint8 at row 0; expected (rows, 23) uint8"),
    (lambda img: [img.astype(np.int16)], "dtype int16 at row 0"),
])
def test_bad_bands_leave_no_map(tmp_path, bands, message):
    img = np.zeros((37, 23), np.uint8)
    with pytest.raises(ValueError, match=message.replace("(", r"\(").replace(")", r"\)")):
        write_ros_map_rows(tmp_path / "m.yaml", img.shape, bands(img), 0.05)
    assert list(tmp_path.iterdir()) == []


def test_command_without_gt_writes_the_inputs_alone(tmp_path, capsys):
    """``segment_example --no-gt``: the map, poses and labels write_example writes, no gt.png,
    and the command that segments them without gt=."""
    from benchmark.commands.segment_example import main

    assert main([str(tmp_path / "a"), "--no-gt", "--rooms", "4x3"]) == 0
    out = capsys.readouterr().out
    assert "(340 x 260 px, 0.05 m/px, 12 rooms)" in out and "(192 views)" in out and "gt=" not in out
    write_example(tmp_path / "b", 4, 3)
    assert sorted(p.name for p in (tmp_path / "a").iterdir()) == ["labels.csv", "map.pgm", "map.yaml", "poses.csv"]
    for name in ("map.yaml", "map.pgm", "poses.csv", "labels.csv"):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes()
