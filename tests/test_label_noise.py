"""Classifier noise on top of any classifier (the robustness benchmark's classifier family)."""

from __future__ import annotations

import numpy as np
import pytest

from benchmark.classifiers.noise import PerRoom
from benchmark.conditions.label_noise import LabelNoise


def _views(n=4000, c=7, seed=0):
    rng = np.random.default_rng(seed)
    poses = np.column_stack([rng.uniform(0, 20, n), rng.uniform(0, 20, n), rng.uniform(0, 360, n)])
    proba = rng.dirichlet(np.ones(c), n)
    return poses, proba


def test_share_zero_is_the_classifier_bit_for_bit():
    poses, proba = _views()
    out, info = LabelNoise(share=0.0)(proba, poses)
    assert out is proba or np.array_equal(out, proba)
    assert info == {"label_noise_share": 0.0}


def test_a_share_of_views_is_relabelled_to_a_wrong_one_hot_class():
    poses, proba = _views()
    out, info = LabelNoise(share=0.3, seed=1)(proba, poses)
    flipped = out.argmax(1) != proba.argmax(1)
    assert info["label_noise_share"] == pytest.approx(flipped.mean())
    assert 0.27 < flipped.mean() < 0.33  # 4000 draws: 3 standard deviations ~ 0.022
    assert np.allclose(out[flipped].max(1), 1.0) and np.allclose(out[flipped].sum(1), 1.0)
    assert np.array_equal(out[~flipped], proba[~flipped])
    again, _ = LabelNoise(share=0.3, seed=1)(proba[::-1], poses[::-1])  # order does not matter
    assert np.array_equal(again[::-1], out)
    other, _ = LabelNoise(share=0.3, seed=2)(proba, poses)
    assert not np.array_equal(other, out)


def test_wrong_classes_follow_the_confusion_rows():
    poses, proba = _views(c=3)
    conf = np.array([[0, 1, 0], [0, 0, 1], [1, 0, 0]], float)  # 0 -> 1, 1 -> 2, 2 -> 0 only
    out, _ = LabelNoise(share=1.0, confusion=conf)(proba, poses)
    assert np.array_equal(out.argmax(1), (proba.argmax(1) + 1) % 3)


def test_the_oracle_draws_are_not_reused():
    """The stage's draws are salted apart from an oracle with the same seed: an oracle at
    accuracy 0.7 and this stage at share 0.3 do not flip the same views."""
    from benchmark.classifiers.noise import Independent, uniform_confusion

    poses, proba = _views(c=7)
    own = proba.argmax(1)
    oracle = Independent().labels(own, poses, 0.7, uniform_confusion(7), 0)
    out, _ = LabelNoise(share=0.3, seed=0)(proba, poses)
    both = ((oracle != own) & (out.argmax(1) != own)).mean()
    assert both == pytest.approx(0.09, abs=0.03)  # independent: 0.3 x 0.3


def test_bad_settings_are_one_line():
    with pytest.raises(ValueError, match=r"label_noise.share=1.5: expected a share of views in \[0, 1\]"):
        LabelNoise(share=1.5)
    with pytest.raises(ValueError, match="NoiseModel"):
        LabelNoise(share=0.1, noise="per_room")
    assert "per_room" in LabelNoise(share=0.2, noise=PerRoom(1.0)).describe()
