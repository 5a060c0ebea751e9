"""``python -m benchmark.commands.evaluate``: the command-line front of :mod:`benchmark.classifiers.evaluate`."""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

from benchmark.classifiers.evaluate import (
    CHECKPOINT_KEY,
    MODELS,
    parse_split_sizes,
    predict_items,
    table1_metrics,
    throughput,
    write_table,
)
from benchmark.commands import cli
from benchmark.commands.errors import cli_errors, one_line
from benchmark.config import build_classifier, classifier_config
from benchmark.reports.confusion import confusion_figure


def main(argv: list[str] | None = None) -> int:
    ap = cli.ArgumentParser(from_root=True, description=__doc__.split("\n\n")[0],
                                 epilog="extra key=value arguments override conf/classifier/<model>.yaml")
    ap.add_argument("--model", required=True, choices=MODELS)
    ap.add_argument("--data", type=Path, help="Places365 root / image folder, or an ImageFolder of class folders")
    ap.add_argument("--places365", action="store_true", help="--data is Places365 (torchvision root or image folder)")
    ap.add_argument("--split", default="test", choices=["train", "val", "test"])
    ap.add_argument("--split-sizes", default="4000,500,500", help="per-class train,val,test sizes")
    ap.add_argument("--seed", type=int, default=0, help="split seed")
    ap.add_argument("--checkpoint", default=None, help="shortcut for the config's checkpoint / head_checkpoint")
    ap.add_argument("--workers", type=int, default=4, help="image decoding processes")
    ap.add_argument("--out", type=Path, default=Path("results/table1"))
    ap.add_argument("--throughput", type=int, default=0, metavar="N",
                    help="only time the classifier on N random 256 px images (no data needed)")
    ap.add_argument("overrides", nargs="*", help="classifier config overrides, key=value")
    a = ap.parse_args(argv)
    try:
        return _main(a)
    except cli_errors() as e:
        print(f"error: {one_line(e)}", file=sys.stderr)
        return 2


def _main(a) -> int:
    from benchmark.classifiers.places import list_images, split  # noqa: PLC0415
    from envs.atomic import atomic_write_text  # noqa: PLC0415

    overrides = list(a.overrides)
    if a.checkpoint is not None:
        if a.model not in CHECKPOINT_KEY:
            raise ValueError(f"--checkpoint does not apply to {a.model}")
        overrides.append(f"{CHECKPOINT_KEY[a.model]}={a.checkpoint}")
    if a.throughput:
        clf, _ = build_classifier(a.model, overrides)
        r = throughput(clf, a.throughput)
        print(f"{a.model} on {getattr(clf, 'device', '?')}: {r['n_images']} images in {r['seconds']:.2f} s = "
              f"{r['images_per_s']:.2f} images/s")
        return 0
    if a.data is None:
        raise ValueError("--data is required (unless --throughput)")
    cfg = classifier_config(a.model, overrides)
    classes = list(cfg.classes)
    n_train, n_val, n_test = parse_split_sizes(a.split_sizes)
    items = split(list_images(a.data, classes, a.places365), classes, n_train, n_val, n_test, seed=a.seed)[a.split]
    clf, _ = build_classifier(a.model, overrides)
    t = time.perf_counter()
    proba = predict_items(clf, items, a.workers, progress=True)
    seconds = time.perf_counter() - t
    m = table1_metrics([k for _, k in items], proba.argmax(1), len(classes))
    record = {"model": a.model, "split": a.split, "seed": a.seed, "split_sizes": a.split_sizes, "data": str(a.data),
              "n_images": len(items), "seconds": round(seconds, 2), "classes": classes,
              "overrides": overrides, **{k: m[k] for k in ("precision", "recall", "accuracy", "f1")},
              "confusion": m["confusion"].tolist()}
    if getattr(clf, "last_flags", None) is not None and a.model == "vlm":
        record["n_unparsed"] = int(getattr(clf, "n_unparsed", 0))
    atomic_write_text(a.out / f"table1_{a.model}.json", json.dumps(record, indent=1))
    confusion_figure(m["confusion"], classes, a.out / f"confusion_{a.model}.png",
                     f"{a.model}, Places-2 {a.split} ({len(items)} images)")
    print(write_table(a.out))
    print(f"{a.model}: {len(items)} images in {seconds:.1f} s; confusion matrix {a.out / f'confusion_{a.model}.png'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
