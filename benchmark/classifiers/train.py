"""Train the CNN or the DINOv2 MLP head on the Places-2 7-class split, keeping the
checkpoint with the best validation accuracy. Architecture, backbone, input size, device
and the checkpoint path come from ``conf/classifier/<model>.yaml`` (``key=value``
arguments override it), so the runner's ``classifier=<model>`` loads what this wrote.

``python -m benchmark.commands.train --model cnn --data PLACES_ROOT --places365``
``python -m benchmark.commands.train --model dinov2 --data PLACES_ROOT --places365 feature_cache=cache/dinov2``

Each run also writes ``<checkpoint>.history.json`` (loss and validation accuracy per epoch).
"""

from __future__ import annotations

import json
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
from envs.world.classes import PAPER_CLASSES


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
