"""Image headers that declare huge sizes (issue #24 item 5): every reader of maps, ground truth,
label / index PNGs and external predictions checks the declared size against the map-size
limit before decoding, and says so in one line naming the file, the size and the limit.

The crafted files are a few dozen bytes (a PGM or PNG header declaring 100000 x 100000 pixels
and no pixel data): nothing is ever allocated for them."""

from __future__ import annotations

import json
import struct
import subprocess
import sys
import zlib
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from benchmark.commands.segment import main as segment_main
from envs.datasets.maps import MapsEnv
from envs.maps.ground_truth import read_ground_truth
from envs.maps.images import image_size, read_image
from envs.maps.label_png import read_instance_png, read_label_png
from envs.maps.ros import occupancy_png, read_npy_map, read_ros_map
from envs.maps.scene import MAX_MAP_PIXELS
from envs.maps.segmentation_io import read_index_png

ROOT = Path(__file__).resolve().parents[1]
HUGE = 100_000


def png_header(path: Path, w: int = HUGE, h: int = HUGE, colour_type: int = 0) -> Path:
    """A PNG with a valid IHDR declaring w x h (8-bit, grey or RGB) and no image data."""
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    ihdr = struct.pack(">IIBBBBB", w, h, 8, colour_type, 0, 0, 0)
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IEND", b""))
    return path


def pgm_header(path: Path, w: int = HUGE, h: int = HUGE) -> Path:
    """A binary PGM (P5) header declaring w x h, followed by 16 bytes."""
    path.write_bytes(f"P5\n{w} {h}\n255\n".encode() + bytes(16))
    return path


def _one_line_about(e: BaseException, path: Path, limit: int = MAX_MAP_PIXELS) -> str:
    msg = str(e)
    assert "\n" not in msg, msg
    assert str(path) in msg and f"{HUGE} x {HUGE}" in msg and f"limit of {limit} pixels" in msg, msg
    assert "decompression bomb" not in msg.lower(), msg  # never Pillow's own message
    return msg


def test_the_crafted_headers_are_tiny_and_declare_the_size(tmp_path):
    png, pgm = png_header(tmp_path / "big.png"), pgm_header(tmp_path / "big.pgm")
    assert png.stat().st_size < 100 and pgm.stat().st_size < 100
    # what Pillow would say itself: its decompression-bomb error, a message naming no file
    with pytest.raises(Image.DecompressionBombError):
        Image.open(png)
    for p in (png, pgm):
        with pytest.raises(ValueError) as e:
            image_size(p, "the map image")
        _one_line_about(e.value, p)
    # a smaller limit counts too, and a file under it is read
    small = tmp_path / "small.png"
    Image.fromarray(np.zeros((30, 40), np.uint8)).save(small)
    assert image_size(small, max_pixels=1200) == (40, 30)
    with pytest.raises(ValueError, match=r"40 x 30 = 1200 pixels, over the map-size limit of 1199"):
        read_image(small, max_pixels=1199)


@pytest.mark.parametrize("kind", ["png", "pgm"])
def test_every_reader_refuses_the_header_before_decoding(tmp_path, kind):
    big = png_header(tmp_path / "big.png") if kind == "png" else pgm_header(tmp_path / "big.pgm")
    readers = {
        "occupancy_png": lambda: occupancy_png(big, 0.05),
        "read_ground_truth instance": lambda: read_ground_truth(big, "instance", resolution=0.05),
        "read_ground_truth rooms_white": lambda: read_ground_truth(big, "rooms_white", resolution=0.05),
        "read_ground_truth label": lambda: read_ground_truth(big, "label", classes=["a", "b"], resolution=0.05),
        "read_instance_png": lambda: read_instance_png(big),
        "read_index_png": lambda: read_index_png(big),
    }
    for name, read in readers.items():
        with pytest.raises(ValueError) as e:
            read()
        assert _one_line_about(e.value, big), name
    # a label PNG with its sidecar
    big.with_suffix(".json").write_text(json.dumps({"classes": ["a"], "colors": [[1, 2, 3]],
                                                    "unlabelled_color": [9, 9, 9], "background_color": [0, 0, 0]}))
    with pytest.raises(ValueError) as e:
        read_label_png(big)
    _one_line_about(e.value, big)


def test_through_a_ros_yaml_and_a_npy_header(tmp_path):
    pgm_header(tmp_path / "big.pgm")
    y = tmp_path / "big.yaml"
    y.write_text("image: big.pgm\nresolution: 0.05\norigin: [0, 0, 0]\nnegate: 0\n")
    with pytest.raises(ValueError) as e:
        read_ros_map(y)
    msg = _one_line_about(e.value, tmp_path / "big.pgm")
    assert str(y) in msg  # says which YAML named the image
    # env.max_map_pixels raises the limit for one environment; a header over it is still refused
    with pytest.raises(ValueError) as e:
        read_ros_map(y, max_pixels=10 * MAX_MAP_PIXELS)
    _one_line_about(e.value, tmp_path / "big.pgm", 10 * MAX_MAP_PIXELS)
    # a .npy map whose header declares the same size (no data behind it)
    buf = tmp_path / "big.npy"
    with buf.open("wb") as f:
        np.lib.format.write_array_header_1_0(f, {"descr": "|b1", "fortran_order": False, "shape": (HUGE, HUGE)})
    with pytest.raises(ValueError) as e:
        read_npy_map(buf)
    _one_line_about(e.value, buf)


def test_roomseg_segment_exits_2_with_one_line(tmp_path, capsys):
    big_png, big_pgm = png_header(tmp_path / "big.png"), pgm_header(tmp_path / "big.pgm")
    (tmp_path / "big.yaml").write_text("image: big.pgm\nresolution: 0.05\norigin: [0, 0, 0]\nnegate: 0\n")
    for args, named in [([f"map={big_png}", "resolution=0.05"], big_png),
                        ([f"map={tmp_path / 'big.yaml'}"], big_pgm)]:
        code = segment_main([*args, "segmenter=distance", f"out={tmp_path / 'o'}"])
        err = capsys.readouterr().err.strip().splitlines()
        assert code == 2 and len(err) == 1 and err[0].startswith("error: ValueError: "), err
        _one_line_about(err[0], named)
    # a ground truth with a huge header, on a good map
    Image.fromarray(np.full((20, 20), 254, np.uint8)).save(tmp_path / "ok.png")
    code = segment_main([f"map={tmp_path / 'ok.png'}", "resolution=0.05", "segmenter=distance",
                         f"gt={big_png}", "gt_format=rooms_white", "figure=false", f"out={tmp_path / 'o2'}"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1
    _one_line_about(err[0], big_png)
    assert not (tmp_path / "o").exists() and not (tmp_path / "o2").exists()


@pytest.mark.slow
def test_the_module_as_a_command(tmp_path):
    big = png_header(tmp_path / "big.png")
    r = subprocess.run([sys.executable, "-m", "benchmark.commands.segment", f"map={big}", "resolution=0.05",
                        "segmenter=distance", f"out={tmp_path / 'o'}"], cwd=ROOT, capture_output=True, text=True,
                       timeout=300, env={"PYTHONPATH": str(ROOT), "PATH": ""})
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1, r.stderr
    _one_line_about(lines[0], big)


def test_in_a_sweep_of_env_maps_that_map_fails_alone(tmp_path):
    from hydra import compose, initialize_config_dir

    from benchmark.harness.runner import CONF_DIR, run

    folder = tmp_path / "maps"
    folder.mkdir()
    img = np.zeros((44, 64), np.uint8)
    img[2:42, 2:62] = 255
    Image.fromarray(img).save(folder / "good.png")
    Image.fromarray(img).save(folder / "good_gt.png")
    png_header(folder / "huge.png")
    Image.fromarray(img).save(folder / "huge_gt.png")
    env = MapsEnv(str(folder), maps="{id}.png", image_resolution=0.05, gt_format="rooms_white")
    assert env.house_ids() == ["good", "huge"]
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        cfg = compose("config", overrides=["env=maps", f"env.dir={folder}", "env.maps='{id}.png'",
                                           "env.image_resolution=0.05", "env.gt_format=rooms_white",
                                           "segmenter=distance", "run.allow_failures=true", "run.progress=false",
                                           f"run.results_dir={tmp_path / 'res'}"], return_hydra_config=True)
    choices = {k: str(v) for k, v in cfg.hydra.runtime.choices.items() if not k.startswith("hydra")}
    df = run(cfg, tmp_path / "out", choices).set_index("house_id")
    assert df.loc["good", "status"] == "ok" and df.loc["good", "n_gt_segments"] == 1
    assert df.loc["huge", "status"] == "failed"
    _one_line_about(df.loc["huge", "error"], folder / "huge.png")
