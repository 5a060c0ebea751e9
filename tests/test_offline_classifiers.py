import numpy as np
import pytest

from benchmark.classifiers.objects import ObjectsClassifier
from benchmark.classifiers.oracle import OracleClassifier, true_labels
from envs.observation import Observation


def _obs(n, rng):
    out = []
    for i in range(n):
        v = rng.random(7) * (rng.random(7) < 0.5)
        out.append(Observation(pose=(float(i), float(rng.random()), 0.0), visible_classes=v))
    return out


def test_oracle_exact_and_deterministic():
    rng = np.random.default_rng(0)
    obs = _obs(200, rng)
    truth = true_labels(obs)
    o = OracleClassifier(accuracy=1.0)
    p = o.predict_proba(obs)
    seen = truth >= 0
    assert np.array_equal(p[seen].argmax(1), truth[seen])
    assert np.allclose(p[~seen], 1 / 7) and np.array_equal(o.last_flags, ~seen)
    noisy = OracleClassifier(accuracy=0.5, seed=3)
    a = noisy.predict_proba(obs)
    assert np.array_equal(a, noisy.predict_proba(obs[::-1])[::-1])  # order does not matter


@pytest.mark.parametrize("acc", [0.9, 0.7, 0.5])
def test_oracle_accuracy_within_sampling_error(acc):
    rng = np.random.default_rng(1)
    obs = [Observation(pose=(float(i), 0.0, 0.0), visible_classes=np.eye(7)[i % 7]) for i in range(4000)]
    p = OracleClassifier(accuracy=acc, seed=7).predict_proba(obs)
    measured = np.mean(p.argmax(1) == np.arange(4000) % 7)
    assert abs(measured - acc) < 4 * np.sqrt(acc * (1 - acc) / 4000)
    assert rng is not None


def test_oracle_confusion_matrix_and_errors():
    conf = np.zeros((7, 7))
    conf[0, 3] = 1.0  # balcony is always mistaken for corridor
    obs = [Observation(pose=(float(i), 0.0, 0.0), visible_classes=np.eye(7)[0]) for i in range(300)]
    p = OracleClassifier(accuracy=0.5, confusion=conf).predict_proba(obs).argmax(1)
    assert set(p.tolist()) == {0, 3}
    with pytest.raises(ValueError, match="accuracy"):
        OracleClassifier(accuracy=1.5)
    with pytest.raises(ValueError, match="visible_classes"):
        OracleClassifier().predict_proba([Observation(pose=(0, 0, 0))])


def test_objects_classifier_learns_and_refuses_overlap(procthor_file):
    clf = ObjectsClassifier(str(procthor_file), 0, 20)
    beds = clf.predict_proba([Observation(pose=(0, 0, 0), objects=[("Bed", 0.3), ("Pillow", 0.2)])])
    toilet = clf.predict_proba([Observation(pose=(0, 0, 0), objects=[("Toilet", 0.2)])])
    fridge = clf.predict_proba([Observation(pose=(0, 0, 0), objects=[("Fridge", 0.2)])])
    assert beds.argmax() == 2 and toilet.argmax() == 1 and fridge.argmax() == 5
    none = clf.predict_proba([Observation(pose=(0, 0, 0), objects=[("NoSuchThing", 1.0)])])
    assert clf.last_flags.tolist() == [True] and np.allclose(none, np.exp(clf.log_prior) / np.exp(clf.log_prior).sum())
    clf.setup(["procthor-10k-uniform-hard-val-00075"])
    with pytest.raises(ValueError, match="also evaluated"):
        clf.setup(["procthor-10k-uniform-hard-val-00003"])
