import numpy as np
import pytest

from benchmark.classifiers.objects import ObjectsClassifier
from benchmark.classifiers.oracle import OracleClassifier
from benchmark.view_accuracy import true_labels
from envs.render.observation import Observation


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
    obs = [Observation(pose=(float(i), 0.0, 0.0), visible_classes=np.eye(7)[i % 7]) for i in range(4000)]
    p = OracleClassifier(accuracy=acc, seed=7).predict_proba(obs)
    measured = np.mean(p.argmax(1) == np.arange(4000) % 7)
    assert abs(measured - acc) < 4 * np.sqrt(acc * (1 - acc) / 4000)


def test_oracle_wrong_labels_are_uniform_over_the_other_classes():
    n = 6000
    obs = [Observation(pose=(float(i), 1.0, 0.0), visible_classes=np.eye(7)[2]) for i in range(n)]
    lab = OracleClassifier(accuracy=0.0, seed=2).predict_proba(obs).argmax(1)
    assert not (lab == 2).any()
    freq = np.bincount(lab, minlength=7)[[0, 1, 3, 4, 5, 6]] / n
    assert np.abs(freq - 1 / 6).max() < 4 * np.sqrt((1 / 6) * (5 / 6) / n)


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


def test_objects_classifier_table_is_naive_bayes_with_smoothing():
    clf = ObjectsClassifier(train_synthetic=[100000, 100010], alpha=0.5)
    assert clf.train_ids[0] == "synthetic-s100000" and len(clf.train_ids) == 10
    # recompute the table by hand from the room counts and check a prediction against it
    from benchmark.classifiers.objects import room_object_counts
    from envs.datasets.synthetic import generate_house

    rooms, types = room_object_counts([generate_house(s) for s in range(100000, 100010)], clf.classes)
    seen = ["Bed", clf.types[0]]
    per_class = np.array([types[u] for u in clf.types]).sum(0)  # (C,) object count per class
    logp = np.log((rooms + 0.5) / (rooms.sum() + 0.5 * 7))
    for t in set(seen):
        logp += np.log((types[t] + 0.5) / (per_class + 0.5 * len(clf.types)))
    expect = np.exp(logp - logp.max())
    got = clf.predict_proba([Observation(pose=(0, 0, 0), objects=[(t, 0.1) for t in seen])])
    assert np.allclose(got[0], expect / expect.sum())
    with pytest.raises(ValueError, match="also evaluated"):
        clf.setup(["synthetic-s100003", "synthetic-s5"])
    clf.setup(["synthetic-s5"])
    with pytest.raises(ValueError, match="no training houses"):
        ObjectsClassifier()


def test_classifiers_on_rendered_views_share_the_interface(procthor_file):
    from benchmark.viewpoints import Autotrace
    from envs.datasets.house_files import load_houses
    from envs.maps.scene import rasterise_house
    from envs.render.floorplan import FloorplanRenderer

    house = load_houses(procthor_file, 100, 101)[0]
    scene = rasterise_house(house, resolution=0.1)
    obs = FloorplanRenderer().render(house, scene, Autotrace().generate(scene))
    for clf in (OracleClassifier(accuracy=0.7, seed=1), ObjectsClassifier(str(procthor_file), 0, 10)):
        clf.setup([house.id])
        p = clf.predict_proba(obs)
        assert p.shape == (len(obs), 7) and np.allclose(p.sum(1), 1) and (p >= 0).all()
        assert clf.last_flags.shape == (len(obs),)
    truth = true_labels(obs)
    # every rendered view's true label is a class of a room of this house
    assert set(truth.tolist()) <= set(scene.instance_classes.tolist())


def test_objects_training_key_is_kept_per_process_and_follows_the_training_file(tmp_path, shared_houses):
    """The key is hashed once per settings and training file (every job of a sweep builds its
    own classifier); it equals the key computed afresh, and a training file rewritten with other
    houses gives the new content's key."""
    import json
    import os

    from benchmark.classifiers import objects

    f = tmp_path / "train.jsonl"
    f.write_text("\n".join(json.dumps(h.data) for h in shared_houses[:3]) + "\n")
    first = ObjectsClassifier(train_path=str(f)).training_key()
    assert ObjectsClassifier(train_path=str(f)).training_key() == first
    assert ObjectsClassifier(train_path=str(f))._training_key() == first  # the memo holds the real key
    assert ObjectsClassifier(train_path=str(f), train_stop=2).training_key() != first
    before = len(objects._TRAINING_KEYS)
    ObjectsClassifier(train_path=str(f)).training_key()
    assert len(objects._TRAINING_KEYS) == before  # no new entry: kept
    f.write_text("\n".join(json.dumps(h.data) for h in shared_houses[3:6]) + "\n")
    os.utime(f, ns=(1, 1))  # an old modification time: the size differs
    changed = ObjectsClassifier(train_path=str(f)).training_key()
    assert changed != first and changed == ObjectsClassifier(train_path=str(f))._training_key()
    # the training ids too (a job's setup needs only them): kept without reading the houses
    # again, and the new file's ids once it changes
    ids = [h.id for h in ObjectsClassifier(train_path=str(f)).training_houses()]
    assert len(ids) == 3 and ObjectsClassifier(train_path=str(f)).train_ids == ids
    kept = ObjectsClassifier(train_path=str(f))
    kept.training_houses = None  # would fail if called
    assert kept.train_ids == ids
    with pytest.raises(ValueError, match="also evaluated"):
        kept.setup([ids[1]])
    f.write_text("\n".join(json.dumps(h.data) for h in shared_houses[7:8]) + "\n")
    os.utime(f, ns=(2, 2))
    assert ObjectsClassifier(train_path=str(f)).train_ids == ids[:1]  # one house now


def test_true_labels_equal_each_views_own_argmax():
    """All views at once (rows of one length) and one at a time (rows of different lengths)
    give each view's first largest visible class, -1 where it saw nothing: on random shares
    with ties and empty views."""
    rng = np.random.default_rng(4)
    for lengths in ([7] * 300, list(rng.integers(1, 9, 300))):
        obs = []
        for i, n in enumerate(lengths):
            v = rng.integers(0, 3, n).astype(float) * (rng.random() < 0.8)  # ties of whole shares
            obs.append(Observation(pose=(float(i), 0.0, 0.0), visible_classes=v))
        want = [int(np.flatnonzero(o.visible_classes == o.visible_classes.max())[0])
                if o.visible_classes.max() > 0 else -1 for o in obs]
        got = true_labels(obs)
        assert got.dtype == np.int64 and got.tolist() == want
        assert -1 in want and len(set(want)) > 3
    assert true_labels([]).shape == (0,)
    with pytest.raises(ValueError, match="observation 1 has no visible_classes"):
        true_labels([obs[0], Observation(pose=(0.0, 0.0, 0.0))])
