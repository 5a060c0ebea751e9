"""CNN room classifier: a torchvision ResNet (ResNet-50 from IMAGENET1K_V2 weights in the
paper) with a new head over the configured classes, fine-tuned on Places-2 (see
``benchmark.classifiers.train``). Inference in batches, softmax probabilities."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Annotated

import numpy as np

from benchmark.classifiers.torch_common import (
    batches,
    eval_transform,
    images_of,
    load_checkpoint,
    pick_device,
    require_torch,
)
from benchmark.interfaces import Classifier
from envs.ranges import Integer
from envs.world.classes import PAPER_CLASSES


def build_resnet(arch: str, n_classes: int, pretrained: bool):
    """torchvision ``arch`` (ImageNet ``IMAGENET1K_V2`` weights for resnet50, the default
    weights otherwise, when ``pretrained``) with a new ``n_classes``-way ``fc`` head."""
    torch = require_torch()
    import torchvision  # noqa: PLC0415

    if n_classes < 2:
        raise ValueError(f"a classifier needs at least 2 classes, got {n_classes}")
    if arch not in torchvision.models.list_models(torchvision.models):
        raise ValueError(f"unknown torchvision architecture {arch!r} (e.g. resnet50, resnet18)")
    weights = None
    if pretrained:
        weights = "IMAGENET1K_V2" if arch == "resnet50" else "DEFAULT"
    try:
        model = torchvision.models.get_model(arch, weights=weights)
    except Exception as e:  # offline, or a blocked download
        raise RuntimeError(f"could not get the {arch} {weights} weights ({type(e).__name__}); download them once "
                           "into $TORCH_HOME on a machine with network access, or set classifier.pretrained=false"
                           ) from None
    if not hasattr(model, "fc"):
        raise ValueError(f"architecture {arch!r} has no fc head; use a ResNet-style model")
    model.fc = torch.nn.Linear(model.fc.in_features, n_classes)
    return model


class CNNClassifier(Classifier):
    """Args:
        classes: ordered class names (the head's outputs).
        checkpoint: fine-tuned weights (``train --model cnn``); required unless
            ``allow_untrained`` (tests, timing).
        arch: torchvision architecture (``resnet50``; tests use ``resnet18``).
        pretrained: start from ImageNet weights (only used without a checkpoint).
        device: ``auto``, ``cpu`` or ``cuda[:i]``.
        batch_size: images per forward pass. image_size: network input side, pixels.
    """

    def __init__(self, classes: Sequence[str] = PAPER_CLASSES, checkpoint: str | None = None,
                 arch: str = "resnet50", pretrained: bool = True, device: str = "auto",
                 batch_size: Annotated[int, Integer(1)] = 32, image_size: Annotated[int, Integer(1)] = 224,
                 allow_untrained: bool = False):
        torch = require_torch()
        self.classes = tuple(classes)
        self.device = pick_device(device)
        self.arch = arch
        self.batch_size, self.image_size = int(batch_size), int(image_size)
        if checkpoint is None and not allow_untrained:
            raise ValueError("classifier.checkpoint is not set: fine-tune first with "
                             "python -m benchmark.commands.train --model cnn ...")
        self.model = build_resnet(arch, len(self.classes), pretrained and checkpoint is None)
        if checkpoint is not None:
            load_checkpoint(checkpoint, self.model, self.classes, expect={"arch": arch})
        self.model.to(self.device).eval()
        self._tf = eval_transform(self.image_size)
        self._torch = torch

    def setup(self, eval_house_ids: Sequence[str]) -> None:
        """Nothing to prepare (trained on Places-2, not on houses)."""

    def predict_images(self, images: Sequence[np.ndarray]) -> np.ndarray:
        """(N, C) softmax probabilities of (H, W, 3) uint8 RGB images, ``batch_size`` at a time."""
        torch = self._torch
        out = []
        with torch.inference_mode():
            for chunk in batches(list(images), self.batch_size):
                x = torch.stack([self._tf(img) for img in chunk]).to(self.device)
                out.append(torch.softmax(self.model(x).float(), dim=1).cpu().numpy())
        return np.concatenate(out).astype(np.float64) if out else np.zeros((0, len(self.classes)))

    def predict_proba(self, observations: Sequence) -> np.ndarray:
        """(N, C) class probabilities of the observations' images."""
        return self.predict_images(images_of(observations))
