"""``python -m benchmark.commands.objects_accuracy``: the command-line front of :mod:`benchmark.classifiers.objects`."""

from __future__ import annotations

from benchmark.classifiers.objects import ObjectsClassifier
from benchmark.commands import cli
from benchmark.paths import procthor_houses
from envs.maps.scene import rasterise_house


def main(argv: list[str] | None = None) -> int:
    from pathlib import Path

    from benchmark.view_accuracy import true_labels
    from benchmark.viewpoints import Autotrace
    from envs.datasets.house_files import load_houses
    from envs.render.floorplan import FloorplanRenderer

    default = procthor_houses()
    ap = cli.ArgumentParser(from_root=True, description="objects classifier per-view accuracy vs the oracle's true label")
    ap.add_argument("--houses", type=Path, default=default)
    ap.add_argument("--train", default="0:75", help="training index range a:b")
    ap.add_argument("--eval", default="75:150", help="evaluation index range a:b")
    ap.add_argument("--synthetic", type=int, nargs=2, default=None, metavar=("FIRST", "LAST"),
                    help="also train on generated houses with seeds [FIRST, LAST)")
    a = ap.parse_args(argv)
    t0, t1 = map(int, a.train.split(":"))
    e0, e1 = map(int, a.eval.split(":"))
    clf = ObjectsClassifier(str(a.houses), t0, t1, train_synthetic=a.synthetic)
    houses = load_houses(a.houses, e0, e1)
    clf.setup([h.id for h in houses])
    renderer, vp = FloorplanRenderer(), Autotrace()
    correct = total = prior_only = 0
    for h in houses:
        scene = rasterise_house(h)
        obs = renderer.render(h, scene, vp.generate(scene))
        truth = true_labels(obs)
        pred = clf.predict_proba(obs).argmax(1)
        m = truth >= 0
        correct += int((pred[m] == truth[m]).sum())
        total += int(m.sum())
        prior_only += int(clf.last_flags.sum())
    src = f"houses [{a.train}]" + (f" + generated seeds [{a.synthetic[0]}, {a.synthetic[1]})" if a.synthetic else "")
    print(f"objects classifier trained on {src}, evaluated on [{a.eval}] ({len(houses)} houses): "
          f"per-view accuracy {correct / max(total, 1):.4f} over {total} views; {prior_only} views saw no "
          f"known object (prior only)")
    return 0




if __name__ == "__main__":
    raise SystemExit(main())
