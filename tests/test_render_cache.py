import numpy as np
import pytest

from envs.observation import Observation
from envs.render_cache import is_complete, read_observations, write_observations


def test_round_trip_with_and_without_images(tmp_path):
    rng = np.random.default_rng(0)
    obs = [
        Observation(pose=(1.0 / 3, -2.5, 359.99), objects=[("Bed", 0.125), ("Pillow", 1 / 7)],
                    visible_classes=rng.random(7), meta={"n_visible_cells": 12}),
        Observation(pose=(0.1, 0.2, 0.3), image=rng.integers(0, 256, (8, 6, 3), dtype=np.uint8),
                    meta={"refused": True, "error": "teleport failed"}),
    ]
    folder = tmp_path / "house-1"
    assert not is_complete(folder)
    write_observations(folder, obs)
    assert is_complete(folder)
    back = read_observations(folder)
    assert len(back) == 2
    for a, b in zip(obs, back):
        assert a.pose == b.pose and a.objects == b.objects and a.meta == b.meta
        assert (a.visible_classes is None) == (b.visible_classes is None)
        if a.visible_classes is not None:
            assert np.array_equal(a.visible_classes, b.visible_classes)
        assert (a.image is None and b.image is None) or np.array_equal(a.image, b.image)
    assert (folder / "images" / "000001.png").exists()
    # rewriting replaces the old render
    write_observations(folder, obs[:1])
    assert len(read_observations(folder)) == 1 and not (folder / "images").exists()


def test_incomplete_and_bad(tmp_path):
    (tmp_path / "x").mkdir()
    with pytest.raises(FileNotFoundError, match="no complete render"):
        read_observations(tmp_path / "x")
    with pytest.raises(ValueError, match="uint8"):
        write_observations(tmp_path / "y", [Observation(pose=(0, 0, 0), image=np.zeros((2, 2)))])
    assert not (tmp_path / "y").exists() and len(list(tmp_path.iterdir())) == 1
