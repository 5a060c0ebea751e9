"""A furnished two-room office through ``env=maps`` and the runner (issue #30 acceptance):
grey furniture read as obstacles with the ``white_only`` preset, the desk island's enclosed
pocket unlabelled and unscored, two rooms from every geometric segmenter. And the seeded
furnished offices of ``benchmark.commands.clutter_example``."""

from __future__ import annotations

import hashlib
import warnings

import numpy as np
import pytest
from hydra import compose, initialize_config_dir

from benchmark.commands.clutter_example import (
    DESK,
    GREYS,
    main,
    office,
    two_room_office,
    write_office,
)
from benchmark.harness.runner import CONF_DIR, run
from benchmark.harness.store import Job
from envs.npz import load_npz


def _run(tmp_path, folder, segmenter, *extra):
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        cfg = compose("config", overrides=[
            "env=maps", f"env.dir={folder}", "env.maps='{id}.png'", "env.image_resolution=0.05",
            "env.gt_format=rooms_white", f"segmenter={segmenter}", "run.progress=false",
            f"run.results_dir={tmp_path / 'res'}", f"run.cache_dir={tmp_path / 'cache'}", *extra],
            return_hydra_config=True)
    choices = {k: str(v) for k, v in cfg.hydra.runtime.choices.items() if not k.startswith("hydra")}
    out = tmp_path / "out" / f"{segmenter}{len(extra)}{abs(hash(extra))}"
    row = run(cfg, out, choices).iloc[0]
    assert row["status"] == "ok", row["error"]
    return row, load_npz(Job(out).maps_path("office"))["instances"]


@pytest.fixture(scope="module")
def furnished(tmp_path_factory):
    folder = tmp_path_factory.mktemp("clutter")
    o = two_room_office()
    write_office(folder, "office", o)
    return folder / "furnished", o


def test_the_hand_made_office(furnished):
    _, o = furnished
    levels = set(np.unique(o.furnished).tolist())
    assert {DESK, 211, 200} <= levels and levels <= {0, 255, DESK, *GREYS}
    assert o.pockets.sum() == 24 * 20  # 1.2 x 1.0 m at 0.05 m/px
    assert (o.furnished[o.pockets] == 255).all() and (o.gt[o.pockets] == 255).all()


@pytest.mark.parametrize("segmenter", ["distance", "morphological", "voronoi"])
def test_two_rooms_and_an_unlabelled_pocket_with_every_segmenter(tmp_path, furnished, segmenter):
    folder, o = furnished
    row, inst = _run(tmp_path, folder, segmenter, "env.image_preset=white_only")
    assert row["n_gt_segments"] == 2 and row["n_pred_segments"] == 2 and row["count_error"] == 0
    assert row["matched_iou"] > 0.95
    assert (inst[o.pockets] == -1).all()  # the pocket is no room
    assert (inst[o.furnished < 250] == -1).all()  # grey furniture is no floor
    # each room is one segment
    for k in range(2):
        assert len(np.unique(inst[(o.rooms == k) & (inst >= 0)])) == 1


def test_without_the_reachable_area_the_pocket_is_a_room(tmp_path, furnished):
    """What the two settings change (the same map): every free cell kept, the pocket becomes
    a segment of its own."""
    folder, o = furnished
    row, inst = _run(tmp_path, folder, "voronoi", "env.image_preset=white_only", "env.reachable=all")
    assert row["n_gt_segments"] == 2 and row["n_pred_segments"] == 3
    pocket = np.unique(inst[o.pockets])
    assert len(pocket) == 1 and pocket[0] >= 0 and (inst == pocket[0]).sum() == o.pockets.sum()


def test_read_with_ros_defaults_the_chairs_are_floor_and_the_merge_removes_their_fragments(tmp_path, furnished):
    """The ROS reading frees the 211 chairs (a warning says so); the Voronoi's skeleton is pruned
    as ipa_room_segmentation's is (its spurs into the strips between chairs and desks go back to
    their junction), so it no longer cuts those strips into fragments: two rooms with the merge
    of small parts and without it (before the pruning, more than two without it)."""
    folder, o = furnished
    with pytest.warns(UserWarning, match="grey read as free"):
        row, inst = _run(tmp_path, folder, "voronoi")
    assert (inst[o.furnished == 211] >= 0).all() and row["n_pred_segments"] == 2
    with warnings.catch_warnings():  # the same map again: warned once per process at most
        warnings.simplefilter("ignore", UserWarning)
        loose, _ = _run(tmp_path, folder, "voronoi", "segmenter.min_room_area=0")
    assert loose["n_pred_segments"] == 2


def test_seeded_offices_are_reproducible_and_furnished(tmp_path, capsys):
    a, b = office(3), office(3)
    for f in ("furnished", "empty", "gt", "rooms", "pockets"):
        assert np.array_equal(getattr(a, f), getattr(b, f))
    assert not np.array_equal(office(4).furnished, a.furnished) or office(4).furnished.shape != a.furnished.shape
    # furniture stands only on floor, walls are the same in both images
    assert ((a.furnished != a.empty) <= (a.rooms >= 0)).all()
    assert np.array_equal(a.furnished == 0, a.empty == 0)
    assert main([str(tmp_path / "o"), "--maps", "2", "--seed", "3"]) == 0
    assert "env.image_preset=white_only" in capsys.readouterr().out
    names = sorted(p.relative_to(tmp_path / "o").as_posix() for p in (tmp_path / "o").rglob("*.png"))
    assert names == ["empty/office_00.png", "empty/office_00_gt.png", "empty/office_01.png", "empty/office_01_gt.png",
                     "furnished/office_00.png", "furnished/office_00_gt.png", "furnished/office_01.png",
                     "furnished/office_01_gt.png"]
    digest = hashlib.sha256((tmp_path / "o" / "furnished" / "office_00.png").read_bytes()).hexdigest()
    assert main([str(tmp_path / "p"), "--maps", "1", "--seed", "3"]) == 0
    assert hashlib.sha256((tmp_path / "p" / "furnished" / "office_00.png").read_bytes()).hexdigest() == digest
    assert main([str(tmp_path / "q"), "--maps", "0"]) == 2
    assert main([str(tmp_path / "h"), "--hand-made"]) == 0
    assert sorted(p.name for p in (tmp_path / "h" / "furnished").iterdir()) == ["two_rooms.png", "two_rooms_gt.png"]
