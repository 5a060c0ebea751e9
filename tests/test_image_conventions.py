"""Plain image maps read by their convention (issue #30 item 1): ROS map_server's defaults when
no YAML says otherwise, the ``white_only`` preset, explicit thresholds, and one warning line
when many pixels are grey. Every expected value is worked out by hand from p = (255 - v) / 255."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from PIL import Image

from envs.datasets.maps import MapsEnv
from envs.maps.ros import (
    IMAGE_PRESETS,
    grey_pixels_note,
    image_thresholds,
    occupancy_png,
    read_ros_map,
    write_ros_map,
)

#: one row per grey level: 255 white, 254 map_saver free, 250 / 249 either side of the
#: white_only limit, 215 / 211 / 206 / 205 around the ROS free limit (p < 0.196 <=> v >= 206),
#: 200 / 192 light furniture, 178 desks, 90 / 89 either side of the occupied limit (p > 0.65
#: <=> v <= 89), 0 walls
LEVELS = [255, 254, 250, 249, 215, 211, 206, 205, 200, 192, 178, 90, 89, 0]


def _levels_image(tmp_path, name="levels.png"):
    img = np.repeat(np.array(LEVELS, np.uint8)[:, None], 3, axis=1)
    Image.fromarray(img).save(tmp_path / name)
    return tmp_path / name


def _free_levels(grid) -> list[int]:
    return [v for v, free in zip(LEVELS, grid.walkable[:, 0]) if free]


def _quiet(fn, *a, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        return fn(*a, **kw)


def test_plain_image_default_is_ros_map_server_and_grey_furniture_178_is_not_free(tmp_path):
    png = _levels_image(tmp_path)
    g = _quiet(occupancy_png, png, 0.05)
    # ROS defaults: free iff p < 0.196 iff v >= 206 (205: p = 50/255 = 0.19608, not free)
    assert _free_levels(g) == [255, 254, 250, 249, 215, 211, 206]
    # so desks (178) and light furniture below 206 (200, 192) are not free; 211 and 215 are:
    # ROS's default reads them as free, which the warning says (test below)
    assert not g.walkable[LEVELS.index(178)].any() and not g.walkable[LEVELS.index(200)].any()
    # unknown cells (between the thresholds: 90..205) become walkable only with unknown_as=free
    free = _quiet(occupancy_png, png, 0.05, unknown_as="free")
    assert _free_levels(free) == [v for v in LEVELS if v >= 90]


def test_white_only_preset_frees_only_white_and_explicit_thresholds_override(tmp_path):
    png = _levels_image(tmp_path)
    white = _quiet(occupancy_png, png, 0.05, preset="white_only")
    # free iff p < 0.02 iff 255 - v < 5.1 iff v >= 250; everything else occupied, even as unknown_as=free
    assert _free_levels(white) == [255, 254, 250]
    assert _free_levels(_quiet(occupancy_png, png, 0.05, preset="white_only", unknown_as="free")) == [255, 254, 250]
    assert not white.walkable[[LEVELS.index(178), LEVELS.index(211)]].any()  # both furniture greys blocked
    # an explicit threshold reads grey furniture as free: p(178) = 77/255 = 0.302 < 0.35
    g = _quiet(occupancy_png, png, 0.05, free_thresh=0.35)
    assert _free_levels(g) == [v for v in LEVELS if v >= 166]  # 255 - v < 0.35 * 255 = 89.25
    assert g.walkable[LEVELS.index(178)].all() and g.walkable[LEVELS.index(211)].all()
    # the old default (free_thresh 0.25) is still one setting away: v >= 192 (255 - v < 63.75)
    assert _free_levels(_quiet(occupancy_png, png, 0.05, free_thresh=0.25)) == [v for v in LEVELS if v >= 192]
    assert image_thresholds("white_only", occupied_thresh=0.5) == (0.02, 0.5)
    assert IMAGE_PRESETS["ros"] == (0.196, 0.65)


def test_a_yaml_without_thresholds_reads_like_the_plain_image(tmp_path):
    """map_saver's trinary image (254 free, 0 occupied, 205 unknown) and furniture greys."""
    img = np.repeat(np.array(LEVELS, np.uint8)[:, None], 3, axis=1)
    y = write_ros_map(tmp_path / "m.yaml", img, 0.05)
    y.write_text("".join(ln + "\n" for ln in y.read_text().splitlines() if "thresh" not in ln))
    m = read_ros_map(y)
    assert (m.free_thresh, m.occupied_thresh) == (0.196, 0.65)
    png = _levels_image(tmp_path)
    assert np.array_equal(m.grid.walkable, _quiet(occupancy_png, png, 0.05).walkable)
    # map_saver's 205 unknown reads as unknown (-1), 254 free, 0 occupied; 89 occupied, 90 unknown
    occ = dict(zip(LEVELS, m.occupancy[:, 0].tolist()))
    assert (occ[205], occ[254], occ[0], occ[89], occ[90], occ[206]) == (-1, 0, 100, 100, -1, 0)
    assert read_ros_map(y, unknown_as="free").grid.walkable[LEVELS.index(205)].all()
    # the YAML writer's default thresholds are map_saver's too
    assert "free_thresh: 0.196" in write_ros_map(tmp_path / "w.yaml", img, 0.05).read_text()


def test_grey_warning_fires_on_a_grey_heavy_image_and_not_on_a_clean_one(tmp_path):
    # 10 x 10: 30 px white, 10 px walls, 40 px desks (178), 15 px chairs (211), 5 px 205
    img = np.full((10, 10), 255, np.uint8)
    img[0, :] = 0
    img[1:5, :] = 178
    img[5, :] = 211
    img[6, :5] = 211
    img[6, 5:] = 205
    Image.fromarray(img).save(tmp_path / "furnished.png")
    with pytest.warns(UserWarning) as rec:
        occupancy_png(tmp_path / "furnished.png", 0.05)
    assert len(rec) == 1
    msg = str(rec[0].message)
    assert "\n" not in msg and str(tmp_path / "furnished.png") in msg
    # grey: 178, 211, 205 = 60 px of 100; read as free under the ROS default: the 15 px of 211
    assert "60.0 % of the pixels are grey" in msg
    assert "178 (40.0 %), 211 (15.0 %), 205 (5.0 %)" in msg
    assert "15.0 % of the image is grey read as free" in msg and "image_preset=white_only" in msg
    # with an explicit free_thresh 0.35 all 60 grey pixels are read as free (p(178) = 0.302)
    with pytest.warns(UserWarning, match="60.0 % of the image is grey read as free"):
        occupancy_png(tmp_path / "furnished.png", 0.05, free_thresh=0.35)
    # the same image read white_only: grey is not ambiguous there (all occupied), no warning
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        occupancy_png(tmp_path / "furnished.png", 0.05, preset="white_only")
    # a clean map: black, white and map_saver's free 254 only, plus 1 % of a light grey
    clean = np.full((10, 10), 254, np.uint8)
    clean[0, :] = 0
    clean[5, 5] = 200
    Image.fromarray(clean).save(tmp_path / "clean.png")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        occupancy_png(tmp_path / "clean.png", 0.05)
    assert grey_pixels_note(clean, 0.196, 0.65) is None


def test_grey_note_counts_unknown_as_free(tmp_path):
    g = np.array([[255, 205, 178, 0]])
    note = grey_pixels_note(g, 0.196, 0.65, share=0.1)
    assert "50.0 % of the pixels are grey" in note and "0.0 % of the image is grey read as free" in note
    note = grey_pixels_note(g, 0.196, 0.65, unknown_as="free", share=0.1)
    assert "50.0 % of the image is grey read as free" in note


def test_maps_env_reads_images_with_the_preset_and_refuses_bad_settings(tmp_path):
    img = np.full((20, 20), 255, np.uint8)
    img[:, 10:] = 211
    Image.fromarray(img).save(tmp_path / "a.png")
    Image.fromarray(np.full((20, 20), 255, np.uint8)).save(tmp_path / "a_gt.png")
    env = MapsEnv(str(tmp_path), maps="{id}.png", image_resolution=0.05, gt_format="rooms_white",
                  image_preset="white_only")
    assert env.grid("a").walkable.sum() == 200  # 211 is not free
    with pytest.warns(UserWarning, match="env.image_preset=white_only"):
        assert MapsEnv(str(tmp_path), maps="{id}.png", image_resolution=0.05).grid("a").walkable.sum() == 400
    for kw, expect in [({"image_preset": "grey"}, "env.image_preset is 'grey'; expected one of ['ros', 'white_only']"),
                       ({"free_thresh": 1.5}, "env.free_thresh is 1.5; expected an occupancy probability"),
                       ({"free_thresh": 0.7}, "env.free_thresh 0.7 > env.occupied_thresh 0.65"),
                       ({"reachable": "some"}, "env.reachable is 'some'; expected one of ['start', 'largest', 'all']")]:
        with pytest.raises(ValueError) as e:
            MapsEnv(str(tmp_path), maps="{id}.png", image_resolution=0.05, **kw)
        assert expect in str(e.value) and "\n" not in str(e.value)
