"""Train the CNN or the DINOv2 MLP head on the Places-2 7-class split, keeping the
checkpoint with the best validation accuracy.

``python -m benchmark.classifiers.train --model cnn --data PLACES_ROOT --places365 --out ckpt/cnn.pt``
``python -m benchmark.classifiers.train --model dinov2 --data PLACES_ROOT --places365 --out ckpt/dinov2_head.pt --feature-cache cache/dinov2``
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from benchmark.classifiers.torch_common import (
    pick_device,
    require_torch,
    save_checkpoint,
    train_transform,
)
from envs.classes import PAPER_CLASSES


def _image(x) -> np.ndarray:
    if isinstance(x, np.ndarray):
        return x
    from benchmark.classifiers.places import load_rgb  # noqa: PLC0415

    return load_rgb(Path(x))


def _accuracy(predict, items) -> float:
    if not items:
        return float("nan")
    preds = predict([_image(x) for x, _ in items]).argmax(1)
    return float(np.mean(preds == np.array([k for _, k in items])))


def train_cnn(train_items: Sequence, val_items: Sequence, out: str | Path, classes: Sequence[str] = PAPER_CLASSES,
              arch: str = "resnet50", pretrained: bool = True, epochs: int = 10, batch_size: int = 32,
              lr: float = 1e-4, image_size: int = 224, device: str = "auto", max_steps: int | None = None,
              seed: int = 0) -> list[dict]:
    """Fine-tune a ResNet with the paper's augmentation; save the best-validation checkpoint.
    Items are (image path or (H, W, 3) array, class index). Returns per-epoch history."""
    torch = require_torch()
    from benchmark.classifiers.cnn import CNNClassifier  # noqa: PLC0415

    torch.manual_seed(seed)
    clf = CNNClassifier(classes, arch=arch, pretrained=pretrained, device=device, image_size=image_size,
                        allow_untrained=True, batch_size=batch_size)
    model, dev = clf.model, clf.device
    tf = train_transform(image_size)
    opt = torch.optim.AdamW(model.parameters(), lr=lr, weight_decay=1e-4)
    rng = np.random.default_rng(seed)
    history, best, step = [], -1.0, 0
    for epoch in range(epochs):
        model.train()
        losses = []
        for i in range(0, len(train_items), batch_size):
            chunk = [train_items[j] for j in rng.permutation(len(train_items))[i:i + batch_size]]
            x = torch.stack([tf(_image(p)) for p, _ in chunk]).to(dev)
            y = torch.tensor([k for _, k in chunk], device=dev)
            loss = torch.nn.functional.cross_entropy(model(x), y)
            opt.zero_grad()
            loss.backward()
            opt.step()
            losses.append(float(loss.detach()))
            step += 1
            if max_steps and step >= max_steps:
                break
        model.eval()
        val = _accuracy(clf.predict_images, val_items)
        history.append({"epoch": epoch, "loss": float(np.mean(losses)), "losses": losses, "val_accuracy": val})
        if np.isnan(val) or val > best:
            best = val
            save_checkpoint(out, model, classes, {"arch": arch, "epoch": epoch, "val_accuracy": val})
        if max_steps and step >= max_steps:
            break
    return history


def train_mlp(train_items: Sequence, val_items: Sequence, out: str | Path, classes: Sequence[str] = PAPER_CLASSES,
              backbone: str = "facebook/dinov2-large", backbone_config: dict | None = None,
              hidden: Sequence[int] = (512, 256), epochs: int = 50, batch_size: int = 256, lr: float = 1e-3,
              image_size: int = 224, device: str = "auto", feature_cache: str | None = None,
              seed: int = 0) -> list[dict]:
    """Train the MLP head on frozen (cached) DINOv2 features; save the best-validation head."""
    torch = require_torch()
    from benchmark.classifiers.dinov2 import DinoV2Classifier  # noqa: PLC0415

    torch.manual_seed(seed)
    clf = DinoV2Classifier(classes, backbone=backbone, backbone_config=backbone_config, hidden=hidden,
                           feature_cache=feature_cache, device=device, image_size=image_size, allow_untrained=True)
    dev = pick_device(device)
    xtr = torch.as_tensor(clf.features([_image(p) for p, _ in train_items]), dtype=torch.float32, device=dev)
    ytr = torch.tensor([k for _, k in train_items], device=dev)
    xva = clf.features([_image(p) for p, _ in val_items]) if val_items else None
    yva = np.array([k for _, k in val_items])
    head = clf.head
    opt = torch.optim.Adam(head.parameters(), lr=lr)
    g = torch.Generator().manual_seed(seed)
    history, best = [], -1.0
    for epoch in range(epochs):
        head.train()
        perm = torch.randperm(len(xtr), generator=g)
        losses = []
        for i in range(0, len(xtr), batch_size):
            idx = perm[i:i + batch_size].to(dev)
            loss = torch.nn.functional.cross_entropy(head(xtr[idx]), ytr[idx])
            opt.zero_grad()
            loss.backward()
            opt.step()
            losses.append(float(loss.detach()))
        head.eval()
        val = float(np.mean(clf.predict_features(xva).argmax(1) == yva)) if xva is not None else float("nan")
        history.append({"epoch": epoch, "loss": float(np.mean(losses)), "val_accuracy": val})
        if np.isnan(val) or val > best:
            best = val
            save_checkpoint(out, head, classes, {"backbone": backbone, "epoch": epoch, "val_accuracy": val})
    return history


def main(argv: list[str] | None = None) -> int:
    from benchmark.classifiers.places import list_images, split  # noqa: PLC0415

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--model", required=True, choices=["cnn", "dinov2"])
    ap.add_argument("--data", type=Path, required=True)
    ap.add_argument("--places365", action="store_true", help="--data is a Places365 image root")
    ap.add_argument("--out", type=Path, required=True, help="checkpoint path")
    ap.add_argument("--epochs", type=int, default=None)
    ap.add_argument("--batch-size", type=int, default=None)
    ap.add_argument("--lr", type=float, default=None)
    ap.add_argument("--arch", default="resnet50")
    ap.add_argument("--backbone", default="facebook/dinov2-large")
    ap.add_argument("--feature-cache", default=None)
    ap.add_argument("--device", default="auto")
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args(argv)
    classes = list(PAPER_CLASSES)
    parts = split(list_images(a.data, classes, a.places365), classes, seed=a.seed)
    kw = {k: v for k, v in (("epochs", a.epochs), ("batch_size", a.batch_size), ("lr", a.lr)) if v is not None}
    if a.model == "cnn":
        hist = train_cnn(parts["train"], parts["val"], a.out, classes, arch=a.arch, device=a.device, seed=a.seed, **kw)
    else:
        hist = train_mlp(parts["train"], parts["val"], a.out, classes, backbone=a.backbone, device=a.device,
                         feature_cache=a.feature_cache, seed=a.seed, **kw)
    for h in hist:
        print(f"epoch {h['epoch']}: loss {h['loss']:.4f}, val accuracy {h['val_accuracy']:.4f}")
    print(f"best checkpoint: {a.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
