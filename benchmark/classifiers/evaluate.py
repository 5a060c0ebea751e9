"""Table I: macro precision, recall, accuracy and F1 of a classifier on the Places-2 test
split, and its confusion matrix.

``python -m benchmark.classifiers.evaluate --model cnn --checkpoint ckpt/cnn.pt --data PLACES_ROOT --places365 --out results/table1``
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from envs.classes import PAPER_CLASSES


def table1_metrics(y_true: Sequence[int], y_pred: Sequence[int], n_classes: int) -> dict[str, float]:
    """Macro precision, recall and F1 over classes, accuracy over images, and the confusion
    matrix (rows: true class, columns: predicted)."""
    t = np.asarray(y_true, int)
    p = np.asarray(y_pred, int)
    if t.shape != p.shape or t.size == 0:
        raise ValueError(f"need equal, non-empty label arrays, got {t.shape} and {p.shape}")
    cm = np.bincount(t * n_classes + p, minlength=n_classes * n_classes).reshape(n_classes, n_classes)
    tp = np.diag(cm).astype(float)
    prec = np.divide(tp, cm.sum(0), out=np.zeros(n_classes), where=cm.sum(0) > 0)
    rec = np.divide(tp, cm.sum(1), out=np.zeros(n_classes), where=cm.sum(1) > 0)
    f1 = np.divide(2 * prec * rec, prec + rec, out=np.zeros(n_classes), where=(prec + rec) > 0)
    present = cm.sum(1) > 0
    return {"precision": float(prec[present].mean()), "recall": float(rec[present].mean()),
            "accuracy": float(tp.sum() / cm.sum()), "f1": float(f1[present].mean()), "confusion": cm}


def confusion_figure(cm: np.ndarray, classes: Sequence[str], path: Path, title: str = "") -> None:
    import matplotlib  # noqa: PLC0415

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    from benchmark.plotting import save  # noqa: PLC0415

    norm = cm / np.maximum(cm.sum(1, keepdims=True), 1)
    fig, ax = plt.subplots(figsize=(6, 5))
    ax.imshow(norm, cmap="Blues", vmin=0, vmax=1)
    names = [c.replace("_", " ") for c in classes]
    ax.set_xticks(range(len(names)), names, rotation=45, ha="right")
    ax.set_yticks(range(len(names)), names)
    for i in range(len(names)):
        for j in range(len(names)):
            ax.text(j, i, f"{norm[i, j]:.2f}", ha="center", va="center", fontsize=7,
                    color="white" if norm[i, j] > 0.5 else "black")
    ax.set_xlabel("predicted")
    ax.set_ylabel("true")
    ax.set_title(title, fontsize=10)
    save(fig, path)


def build(model: str, classes: Sequence[str], checkpoint: str | None, device: str, arch: str = "resnet50",
          batch_size: int = 32):
    if model == "cnn":
        from benchmark.classifiers.cnn import CNNClassifier  # noqa: PLC0415

        return CNNClassifier(classes, checkpoint=checkpoint, arch=arch, device=device, batch_size=batch_size)
    if model == "dinov2":
        from benchmark.classifiers.dinov2 import DinoV2Classifier  # noqa: PLC0415

        return DinoV2Classifier(classes, head_checkpoint=checkpoint, device=device, batch_size=batch_size)
    if model == "vlm":
        from benchmark.classifiers.vlm import VLMClassifier  # noqa: PLC0415

        return VLMClassifier(classes, device=device)
    raise ValueError(f"unknown model {model!r}; expected cnn, dinov2 or vlm")


def main(argv: list[str] | None = None) -> int:
    from benchmark.classifiers.places import list_images, load_rgb, split  # noqa: PLC0415
    from envs.atomic import atomic_write_text  # noqa: PLC0415

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--model", required=True, choices=["cnn", "dinov2", "vlm"])
    ap.add_argument("--checkpoint", default=None)
    ap.add_argument("--data", type=Path, required=True)
    ap.add_argument("--places365", action="store_true", help="--data is a Places365 image root")
    ap.add_argument("--split", default="test", choices=["train", "val", "test"])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--device", default="auto")
    ap.add_argument("--arch", default="resnet50")
    ap.add_argument("--batch-size", type=int, default=32)
    ap.add_argument("--out", type=Path, default=Path("results/table1"))
    a = ap.parse_args(argv)
    classes = list(PAPER_CLASSES)
    items = split(list_images(a.data, classes, a.places365), classes, seed=a.seed)[a.split]
    clf = build(a.model, classes, a.checkpoint, a.device, a.arch, a.batch_size)
    preds = []
    for i in range(0, len(items), 256):
        chunk = items[i:i + 256]
        preds += clf.predict_images([load_rgb(p) for p, _ in chunk]).argmax(1).tolist()
    m = table1_metrics([k for _, k in items], preds, len(classes))
    line = (f"| {a.model} | {100 * m['precision']:.2f} | {100 * m['recall']:.2f} | {100 * m['accuracy']:.2f} | "
            f"{100 * m['f1']:.2f} | {len(items)} |")
    text = "| model | precision | recall | accuracy | F1 | images |\n|---|---|---|---|---|---|\n" + line + "\n"
    print(text)
    atomic_write_text(a.out / f"table1_{a.model}.md", text)
    confusion_figure(m["confusion"], classes, a.out / f"confusion_{a.model}.png", f"{a.model}, Places-2 {a.split}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
