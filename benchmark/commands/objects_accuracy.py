"""``python -m benchmark.commands.objects_accuracy``: the command-line front of :mod:`benchmark.classifiers.objects`.

Per-view accuracy of the objects classifier against the oracle's true label (the class covering
most of a view's visible floor) on shared ProcTHOR houses, one row per training set:

    python -m benchmark.commands.objects_accuracy --train 0:75 --eval 75:150
    python -m benchmark.commands.objects_accuracy --train 0:75 --train generated:100000:100200 --eval 75:150 \\
        --out results/published/objects_accuracy.md

``--train A:B`` trains on the shared houses [A, B); ``--train generated:FIRST:LAST`` on the
generated houses with seeds [FIRST, LAST); ``--train`` repeats for more rows. ``--out`` writes
the table to a Markdown file headed by the command (``make docs-numbers``; docs/method.md
includes it).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from benchmark.classifiers.objects import ObjectsClassifier
from benchmark.commands import cli
from benchmark.paths import procthor_houses
from benchmark.stats import N_BOOT, SEED
from envs.maps.scene import rasterise_house

DEFAULT_TRAIN = "0:75"


@dataclass(frozen=True)
class TrainingSet:
    """One ``--train`` value: shared houses [start, stop) or generated seeds [first, last)."""

    spec: str
    houses: tuple[int, int] | None = None
    seeds: tuple[int, int] | None = None

    def words(self) -> str:
        """The training set in words, for the table."""
        parts = []
        if self.houses is not None:
            parts.append(f"shared ProcTHOR houses {self.houses[0]}-{self.houses[1] - 1}")
        if self.seeds is not None:
            parts.append(f"{self.seeds[1] - self.seeds[0]} generated houses (seeds {self.seeds[0]}-{self.seeds[1] - 1})")
        return " + ".join(parts)


def _range(text: str, what: str) -> tuple[int, int]:
    """``"a:b"`` as (a, b) with 0 <= a <= b; one-line ValueError naming ``what`` otherwise."""
    try:
        a, b = (int(v) for v in text.split(":"))
    except ValueError:
        raise ValueError(f"{what} {text!r}: expected a range A:B of whole numbers") from None
    if not 0 <= a <= b:
        raise ValueError(f"{what} {text!r}: expected 0 <= A <= B")
    return a, b


def training_set(spec: str, synthetic: tuple[int, int] | None = None) -> TrainingSet:
    """Parse one ``--train`` value (``A:B`` or ``generated:FIRST:LAST``); ``synthetic``: the old
    ``--synthetic FIRST LAST``, generated seeds added to the set."""
    if spec.startswith("generated:"):
        first, last = _range(spec.removeprefix("generated:"), "--train generated:")
        if first == last:
            raise ValueError(f"--train {spec!r}: expected at least one seed (FIRST < LAST)")
        return TrainingSet(spec, seeds=(first, last))
    a, b = _range(spec, "--train")
    if synthetic is not None:
        _range(f"{synthetic[0]}:{synthetic[1]}", "--synthetic")
    if a == b and not synthetic:
        raise ValueError(f"--train {spec!r}: expected at least one house (A < B), or --synthetic FIRST LAST")
    return TrainingSet(spec, houses=(a, b) if a < b else None, seeds=tuple(synthetic) if synthetic else None)


def accuracy_table(houses_path: Path, sets: list[TrainingSet], e0: int, e1: int):
    """Per-view accuracy of the objects classifier trained on each set, on the shared houses [e0, e1)
    (floorplan renderer, autotrace views; each house rendered once for every set).

    Returns:
        (DataFrame with one row per set: trained on, per-view accuracy (percent, with its 95 % interval
        over houses), views, views with no known object; the number of evaluated houses)."""
    import pandas as pd

    from benchmark.view_accuracy import true_labels
    from benchmark.viewpoints import Autotrace
    from envs.datasets.house_files import load_houses
    from envs.render.floorplan import FloorplanRenderer

    houses = load_houses(houses_path, e0, e1)
    if not houses:
        raise ValueError(f"--eval {e0}:{e1}: no house of {houses_path} in that range")
    clfs = []
    for s in sets:
        clf = ObjectsClassifier(str(houses_path) if s.houses else None, *(s.houses or (0, 0)),
                                train_synthetic=s.seeds)
        clf.setup([h.id for h in houses])  # refuses a training house that is also evaluated
        clfs.append(clf)
    renderer, vp = FloorplanRenderer(), Autotrace()
    correct = np.zeros((len(sets), len(houses)), dtype=np.int64)  # (sets, houses) views right
    prior_only = np.zeros(len(sets), dtype=np.int64)
    total = np.zeros(len(houses), dtype=np.int64)  # (houses,) views that see some floor
    for j, h in enumerate(houses):
        scene = rasterise_house(h)
        obs = renderer.render(h, scene, vp.generate(scene))
        truth = true_labels(obs)
        m = truth >= 0
        total[j] = int(m.sum())
        for i, clf in enumerate(clfs):
            pred = clf.predict_proba(obs).argmax(1)
            correct[i, j] = int((pred[m] == truth[m]).sum())
            prior_only[i] += int(clf.last_flags.sum())
    rows = [{"trained on": s.words(), "per-view accuracy %": _pooled_with_interval(c, total),
             "views": f"{total.sum():,}", "views with no known object": f"{p:,}"}
            for s, c, p in zip(sets, correct, prior_only)]
    return pd.DataFrame(rows), len(houses)


def _pooled_with_interval(correct: np.ndarray, total: np.ndarray) -> str:
    """The share of views right over all houses, in percent, with its 95 % percentile bootstrap
    interval over houses (houses resampled as every table does, :func:`benchmark.stats.resample_indices`):
    ``mean [lo, hi]``; the mean alone for one house.

    Args:
        correct, total: (houses,) views right and views counted per house."""
    from benchmark.stats import LEVEL, resample_indices

    mean = 100 * correct.sum() / max(int(total.sum()), 1)
    if len(total) < 2:
        return f"{mean:.1f}"
    idx = resample_indices(len(total))
    shares = 100 * correct[idx].sum(1) / np.maximum(total[idx].sum(1), 1)
    lo, hi = np.quantile(shares, [(1 - LEVEL) / 2, 1 - (1 - LEVEL) / 2])
    return f"{mean:.1f} [{lo:.1f}, {hi:.1f}]"


def main(argv: list[str] | None = None) -> int:
    default = procthor_houses()
    ap = cli.ArgumentParser(from_root=True, description="objects classifier per-view accuracy vs the oracle's true label")
    ap.add_argument("--houses", type=Path, default=default)
    ap.add_argument("--train", action="append", default=None, metavar="A:B | generated:FIRST:LAST",
                    help=f"a training set, one row each (repeatable; default {DEFAULT_TRAIN}): the shared houses "
                         "[A, B), or the generated houses with seeds [FIRST, LAST)")
    ap.add_argument("--eval", default="75:150", help="evaluation index range a:b")
    ap.add_argument("--synthetic", type=int, nargs=2, default=None, metavar=("FIRST", "LAST"),
                    help="also train each A:B set on generated houses with seeds [FIRST, LAST)")
    ap.add_argument("--out", type=Path, default=None,
                    help="also write the table to this Markdown file, headed by the command that made it "
                         "(make docs-numbers: results/published/objects_accuracy.md, which docs/method.md includes)")
    a = ap.parse_args(argv)
    trains = a.train or [DEFAULT_TRAIN]
    try:
        sets = [training_set(t, a.synthetic) for t in trains]
        e0, e1 = _range(a.eval, "--eval")
        table, n = accuracy_table(a.houses, sets, e0, e1)
    except (ValueError, FileNotFoundError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    text = (table.to_markdown(index=False, colalign=("left", "right", "right", "right")) +
            f"\n\nObjects classifier (naive Bayes over the object types in view), evaluated on the shared ProcTHOR "
            f"houses {e0}-{e1 - 1} ({n} houses; floorplan renderer, autotrace views): the share of views whose top "
            f"class is the class covering most of the view's visible floor (the oracle's true label; views that see "
            f"no floor left out), pooled over views, with its 95 % interval (percentile bootstrap over houses, "
            f"{N_BOOT} resamples, seed {SEED}). A view that sees no known object gets the class prior.\n")
    print(text)
    if a.out is not None:
        from benchmark.reports.published import write_published

        command = ["python -m benchmark.commands.objects_accuracy"]
        if a.houses != default:
            command.append(f"--houses {a.houses}")
        command += [f"--train {t}" for t in trains]
        if a.synthetic:
            command.append(f"--synthetic {a.synthetic[0]} {a.synthetic[1]}")
        command += [f"--eval {a.eval}", f"--out {a.out}"]
        err = write_published(a.out, " ".join(command), text)
        if err:
            print(f"error: {err}", file=sys.stderr)
            return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
