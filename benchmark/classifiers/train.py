"""Train the CNN or the DINOv2 MLP head on the Places-2 7-class split, keeping the
checkpoint with the best validation accuracy. Architecture, backbone, input size, device
and the checkpoint path come from ``conf/classifier/<model>.yaml`` (``key=value``
arguments override it), so the runner's ``classifier=<model>`` loads what this wrote.

``python -m benchmark.classifiers.train --model cnn --data PLACES_ROOT --places365``
``python -m benchmark.classifiers.train --model dinov2 --data PLACES_ROOT --places365 feature_cache=cache/dinov2``

Each run also writes ``<checkpoint>.history.json`` (loss and validation accuracy per epoch).
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from benchmark.classifiers.torch_common import (
    ItemDataset,
    image_chunks,
    require_torch,
    save_checkpoint,
    train_transform,
)
from envs.classes import PAPER_CLASSES


def history_path(out: str | Path) -> Path:
    """Where the per-epoch history of checkpoint ``out`` goes."""
    out = Path(out)
    return out.with_name(out.stem + ".history.json")


def _write_history(out: str | Path, history: list[dict]) -> None:
    from envs.atomic import atomic_write_text  # noqa: PLC0415

    atomic_write_text(history_path(out), json.dumps(history, indent=1))


def _accuracy(proba: np.ndarray, items: Sequence) -> float:
    if not len(items):
        return float("nan")
    return float(np.mean(proba.argmax(1) == np.array([k for _, k in items])))


def train_cnn(train_items: Sequence, val_items: Sequence, out: str | Path, classes: Sequence[str] = PAPER_CLASSES,
              arch: str = "resnet50", pretrained: bool = True, epochs: int = 10, batch_size: int = 32,
              lr: float = 1e-4, weight_decay: float = 1e-4, image_size: int = 224, device: str = "auto",
              workers: int = 0, max_steps: int | None = None, seed: int = 0) -> list[dict]:
    """Fine-tune a ResNet (AdamW, ``lr`` per step, cross-entropy) with the paper's augmentation;
    save the checkpoint of the epoch with the best validation accuracy to ``out``.

    Items are (image path or (H, W, 3) uint8 array, class index). Each epoch visits every
    training item once in a seeded random order; ``workers`` processes decode and augment.
    Returns the per-epoch history (mean loss, per-step losses, validation accuracy)."""
    torch = require_torch()
    from benchmark.classifiers.cnn import CNNClassifier  # noqa: PLC0415
    from benchmark.classifiers.evaluate import predict_items  # noqa: PLC0415

    if not train_items:
        raise ValueError("no training images")
    torch.manual_seed(seed)
    clf = CNNClassifier(classes, arch=arch, pretrained=pretrained, device=device, image_size=image_size,
                        allow_untrained=True, batch_size=batch_size)
    model, dev = clf.model, clf.device
    loader = torch.utils.data.DataLoader(
        ItemDataset(train_items, train_transform(image_size)), batch_size=batch_size, shuffle=True,
        num_workers=workers, generator=torch.Generator().manual_seed(seed), pin_memory=dev.startswith("cuda"),
        persistent_workers=workers > 0)
    opt = torch.optim.AdamW(model.parameters(), lr=lr, weight_decay=weight_decay)
    amp = dev.startswith("cuda") and torch.cuda.is_bf16_supported()
    history, best, step = [], -1.0, 0
    for epoch in range(epochs):
        model.train()
        losses = []
        for x, y in loader:
            x, y = x.to(dev, non_blocking=True), y.to(dev, non_blocking=True)
            with torch.autocast("cuda", dtype=torch.bfloat16, enabled=amp):
                loss = torch.nn.functional.cross_entropy(model(x).float(), y)
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
            losses.append(float(loss.detach()))
            step += 1
            if max_steps and step >= max_steps:
                break
        model.eval()
        val = _accuracy(predict_items(clf, val_items, workers), val_items)
        history.append({"epoch": epoch, "loss": float(np.mean(losses)), "losses": losses, "val_accuracy": val})
        if np.isnan(val) or val > best:
            best = val
            save_checkpoint(out, model, classes, {"arch": arch, "epoch": epoch, "val_accuracy": val})
        _write_history(out, history)
        if max_steps and step >= max_steps:
            break
    return history


def dinov2_features(clf, items: Sequence, workers: int = 0, chunk: int = 256) -> np.ndarray:
    """(N, D) frozen features of the items' images (through the classifier's feature cache),
    ``chunk`` images in memory at a time."""
    out = [clf.features(imgs) for imgs in image_chunks(items, chunk, workers)]
    return np.concatenate(out) if out else np.zeros((0, clf.dim), np.float32)


def train_mlp(train_items: Sequence, val_items: Sequence, out: str | Path, classes: Sequence[str] = PAPER_CLASSES,
              backbone: str = "facebook/dinov2-large", backbone_config: dict | None = None,
              hidden: Sequence[int] = (512, 256), epochs: int = 50, batch_size: int = 256, lr: float = 1e-3,
              image_size: int = 224, device: str = "auto", feature_cache: str | None = None,
              feature_batch_size: int = 32, workers: int = 0, seed: int = 0) -> list[dict]:
    """Train the 3-layer MLP head (Adam, cross-entropy) on frozen DINOv2 features (computed
    once, cached); save the head of the epoch with the best validation accuracy to ``out``."""
    torch = require_torch()
    from benchmark.classifiers.dinov2 import DinoV2Classifier  # noqa: PLC0415

    if not train_items:
        raise ValueError("no training images")
    torch.manual_seed(seed)
    clf = DinoV2Classifier(classes, backbone=backbone, backbone_config=backbone_config, hidden=hidden,
                           feature_cache=feature_cache, device=device, image_size=image_size,
                           batch_size=feature_batch_size, allow_untrained=True)
    dev = clf.device
    xtr = torch.as_tensor(dinov2_features(clf, train_items, workers), dtype=torch.float32, device=dev)
    ytr = torch.tensor([k for _, k in train_items], device=dev)
    xva = dinov2_features(clf, val_items, workers)
    head = clf.head
    opt = torch.optim.Adam(head.parameters(), lr=lr)
    g = torch.Generator().manual_seed(seed)
    history, best = [], -1.0
    for epoch in range(epochs):
        head.train()
        perm = torch.randperm(len(xtr), generator=g).to(dev)
        losses = []
        for i in range(0, len(xtr), batch_size):
            idx = perm[i:i + batch_size]
            loss = torch.nn.functional.cross_entropy(head(xtr[idx]), ytr[idx])
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
            losses.append(float(loss.detach()))
        head.eval()
        val = _accuracy(clf.predict_features(xva), val_items)
        history.append({"epoch": epoch, "loss": float(np.mean(losses)), "val_accuracy": val})
        if np.isnan(val) or val > best:
            best = val
            save_checkpoint(out, head, classes, {"backbone": clf.backbone_name, "hidden": clf.hidden,
                                                 "epoch": epoch, "val_accuracy": val})
        _write_history(out, history)
    return history


def main(argv: list[str] | None = None) -> int:
    from benchmark.classifiers.evaluate import cli_errors, one_line  # noqa: PLC0415

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 epilog="extra key=value arguments override conf/classifier/<model>.yaml")
    ap.add_argument("--model", required=True, choices=["cnn", "dinov2"])
    ap.add_argument("--data", type=Path, required=True,
                    help="Places365 root / image folder, or an ImageFolder of class folders")
    ap.add_argument("--places365", action="store_true", help="--data is Places365 (torchvision root or image folder)")
    ap.add_argument("--out", type=Path, default=None, help="checkpoint path (default: the config's)")
    ap.add_argument("--epochs", type=int, default=None, help="default: cnn 10, dinov2 50")
    ap.add_argument("--batch-size", type=int, default=None, help="training batch, images (default: cnn 32, dinov2 256)")
    ap.add_argument("--lr", type=float, default=None, help="learning rate (default: cnn 1e-4, dinov2 1e-3)")
    ap.add_argument("--split-sizes", default="4000,500,500", help="per-class train,val,test sizes")
    ap.add_argument("--seed", type=int, default=0, help="split and training seed")
    ap.add_argument("--workers", type=int, default=4, help="image decoding processes")
    ap.add_argument("overrides", nargs="*", help="classifier config overrides, key=value")
    a = ap.parse_args(argv)
    try:
        return _main(a)
    except cli_errors() as e:
        print(f"error: {one_line(e)}", file=sys.stderr)
        return 2


def _main(a) -> int:
    from benchmark.classifiers.evaluate import classifier_config, parse_split_sizes  # noqa: PLC0415
    from benchmark.classifiers.places import list_images, split  # noqa: PLC0415

    cfg = classifier_config(a.model, a.overrides)
    c = cfg.classifier
    classes = list(cfg.classes)
    sizes = parse_split_sizes(a.split_sizes)
    parts = split(list_images(a.data, classes, a.places365), classes, *sizes, seed=a.seed)
    print(f"split (seed {a.seed}): {len(parts['train'])} train, {len(parts['val'])} val, {len(parts['test'])} test")
    kw = {k: v for k, v in (("epochs", a.epochs), ("batch_size", a.batch_size), ("lr", a.lr)) if v is not None}
    common = {"device": c.device, "image_size": int(c.image_size), "workers": a.workers, "seed": a.seed}
    if a.model == "cnn":
        out = a.out or Path(c.checkpoint)
        hist = train_cnn(parts["train"], parts["val"], out, classes, arch=c.arch, pretrained=bool(c.pretrained),
                         **common, **kw)
    else:
        out = a.out or Path(c.head_checkpoint)
        bcfg = c.get("backbone_config")
        hist = train_mlp(parts["train"], parts["val"], out, classes, backbone=c.backbone,
                         backbone_config=dict(bcfg) if bcfg else None, hidden=list(c.hidden),
                         feature_cache=c.get("feature_cache"), feature_batch_size=int(c.batch_size), **common, **kw)
    for h in hist:
        print(f"epoch {h['epoch']}: loss {h['loss']:.4f}, val accuracy {h['val_accuracy']:.4f}")
    scored = [h for h in hist if not np.isnan(h["val_accuracy"])]
    best = max(scored, key=lambda h: h["val_accuracy"]) if scored else hist[-1]  # first of equals, as saved
    print(f"kept epoch {best['epoch']} (val accuracy {best['val_accuracy']:.4f}): {out}; history {history_path(out)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
