"""Table I: macro precision, recall, accuracy and F1 of a classifier on the Places-2 test
split, and its confusion matrix. The classifier is built from ``conf/classifier/<model>.yaml``
exactly as the runner builds it; ``key=value`` arguments override that config.

``python -m benchmark.commands.evaluate --model cnn --data PLACES_ROOT --places365``
``python -m benchmark.commands.evaluate --model vlm --data PLACES_ROOT --places365 mode=text``
``python -m benchmark.commands.evaluate --model cnn --throughput 64 checkpoint=null +allow_untrained=true pretrained=false``

Writes ``<out>/table1_<model>.json``, ``<out>/confusion_<model>.png`` and
``<out>/table1.md`` with a row for every model evaluated into ``<out>`` so far.
"""

from __future__ import annotations

import json
import sys
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

MODELS = ("cnn", "dinov2", "vlm")
CHECKPOINT_KEY = {"cnn": "checkpoint", "dinov2": "head_checkpoint"}


def table1_metrics(y_true: Sequence[int], y_pred: Sequence[int], n_classes: int) -> dict:
    """Macro precision, recall and F1 over the classes present in ``y_true``, accuracy over
    images, and the (C, C) confusion matrix (rows: true class, columns: predicted)."""
    t = np.asarray(y_true, int)
    p = np.asarray(y_pred, int)
    if t.shape != p.shape or t.ndim != 1 or t.size == 0:
        raise ValueError(f"need equal, non-empty 1-D label arrays, got {t.shape} and {p.shape}")
    if min(t.min(), p.min()) < 0 or max(t.max(), p.max()) >= n_classes:
        raise ValueError(f"labels must lie in 0..{n_classes - 1}")
    cm = np.bincount(t * n_classes + p, minlength=n_classes * n_classes).reshape(n_classes, n_classes)
    tp = np.diag(cm).astype(float)
    prec = np.divide(tp, cm.sum(0), out=np.zeros(n_classes), where=cm.sum(0) > 0)
    rec = np.divide(tp, cm.sum(1), out=np.zeros(n_classes), where=cm.sum(1) > 0)
    f1 = np.divide(2 * prec * rec, prec + rec, out=np.zeros(n_classes), where=(prec + rec) > 0)
    present = cm.sum(1) > 0
    return {"precision": float(prec[present].mean()), "recall": float(rec[present].mean()),
            "accuracy": float(tp.sum() / cm.sum()), "f1": float(f1[present].mean()), "confusion": cm}


def parse_split_sizes(text: str) -> tuple[int, int, int]:
    """``"4000,500,500"`` -> per-class train, val, test sizes."""
    try:
        a, b, c = (int(x) for x in text.split(","))
    except ValueError:
        raise ValueError(f"--split-sizes must be three integers train,val,test, got {text!r}") from None
    return a, b, c


def predict_items(clf, items: Sequence, workers: int = 0, chunk: int = 256, progress: bool = False) -> np.ndarray:
    """(N, C) probabilities of (image path or array, label) items, ``chunk`` images in memory at a time."""
    from benchmark.classifiers.torch_common import image_chunks  # noqa: PLC0415

    out = []
    it = image_chunks(items, chunk, workers)
    if progress:
        from tqdm.auto import tqdm  # noqa: PLC0415

        it = tqdm(it, total=-(-len(items) // chunk), unit="chunk", file=sys.stderr)
    for imgs in it:
        out.append(np.asarray(clf.predict_images(imgs)))
    return np.concatenate(out) if out else np.zeros((0, len(clf.classes)))


def write_table(out: Path) -> str:
    """``table1.md`` from every ``table1_<model>.json`` in ``out``; returns the text."""
    from envs.atomic import atomic_write_text  # noqa: PLC0415

    rows = ["| model | precision | recall | accuracy | F1 | images | split |", "|---|---|---|---|---|---|---|"]
    for p in sorted(out.glob("table1_*.json")):
        r = json.loads(p.read_text())
        rows.append(f"| {r['model']} | {100 * r['precision']:.2f} | {100 * r['recall']:.2f} | "
                    f"{100 * r['accuracy']:.2f} | {100 * r['f1']:.2f} | {r['n_images']} | {r['split']} |")
    text = "\n".join(rows) + "\n"
    atomic_write_text(out / "table1.md", text)
    return text


def throughput(clf, n: int, size: int = 256, seed: int = 0) -> dict:
    """Images per second of ``clf.predict_images`` on ``n`` random size x size images, after
    a warm-up batch of other images (so no feature cache can serve the timed ones)."""
    rng = np.random.default_rng(seed)
    warm = max(1, int(getattr(clf, "batch_size", 1)))
    imgs = [rng.integers(0, 256, (size, size, 3), dtype=np.uint8) for _ in range(n + warm)]
    clf.predict_images(imgs[n:])
    t = time.perf_counter()
    clf.predict_images(imgs[:n])
    dt = time.perf_counter() - t
    return {"n_images": n, "seconds": dt, "images_per_s": n / dt}
