"""DINOv2 + MLP: frozen DINOv2 features (ViT-L/14, the 1024-d normalised CLS token of a
224 x 224 image in the paper) and a 3-layer MLP head trained on them (``train --model
dinov2``). Features are cached by image content, in memory and, with ``feature_cache``, on
disk in a folder per backbone and input size (so another backbone never reads them), each an
``.npz`` with a checksum of its content: a damaged file is recomputed with a warning."""

from __future__ import annotations

import hashlib
import json
import logging
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Annotated

import numpy as np

from benchmark.classifiers.torch_common import (
    batches,
    eval_transform,
    images_of,
    load_checkpoint,
    pick_device,
    require_torch,
    require_transformers,
)
from benchmark.interfaces import Classifier
from envs.ranges import Integer
from envs.world.classes import PAPER_CLASSES

log = logging.getLogger(__name__)


def build_backbone(backbone: str, backbone_config: dict | None = None):
    """A DINOv2 model and its kind (``"hf"`` or ``"hub"``): a Hugging Face id or local folder
    (``facebook/dinov2-large``), ``torchhub:<name>`` (``torchhub:dinov2_vitl14``), or a
    random-initialised one from ``backbone_config`` (transformers ``Dinov2Config`` fields;
    tests and timing)."""
    torch = require_torch()
    if backbone_config is not None:
        transformers = require_transformers("a DINOv2 backbone from a config")
        return transformers.Dinov2Model(transformers.Dinov2Config(**backbone_config)), "hf"
    if backbone.startswith("torchhub:"):
        try:
            return torch.hub.load("facebookresearch/dinov2", backbone.split(":", 1)[1]), "hub"
        except Exception as e:
            raise RuntimeError(f"could not load DINOv2 {backbone!r} from torch hub ({type(e).__name__}); run it once "
                               "on a machine with network access (cached in $TORCH_HOME/hub)") from None
    transformers = require_transformers("DINOv2 from Hugging Face")
    try:
        return transformers.Dinov2Model.from_pretrained(backbone), "hf"
    except Exception as e:
        raise RuntimeError(f"could not load DINOv2 {backbone!r} ({type(e).__name__}); download it once on a machine "
                           "with network access (Hugging Face cache; HF_HUB_OFFLINE=1 skips the network) or point classifier.backbone at a local folder"
                           ) from None


def mlp_head(in_dim: int, hidden: Sequence[int], n_classes: int, dropout: float = 0.2):
    """The 3-layer MLP: in -> hidden[0] -> hidden[1] -> classes, ReLU and dropout between."""
    torch = require_torch()
    if len(hidden) != 2:
        raise ValueError(f"the 3-layer MLP head takes two hidden sizes, got {list(hidden)}")
    nn = torch.nn
    return nn.Sequential(nn.Linear(in_dim, hidden[0]), nn.ReLU(), nn.Dropout(dropout),
                         nn.Linear(hidden[0], hidden[1]), nn.ReLU(), nn.Dropout(dropout),
                         nn.Linear(hidden[1], n_classes))


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9._-]+", "_", text).strip("_") or "backbone"


class DinoV2Classifier(Classifier):
    """Args:
        classes: ordered class names (the head's outputs).
        head_checkpoint: trained MLP head (``train --model dinov2``); required unless
            ``allow_untrained``.
        backbone, backbone_config: see :func:`build_backbone`.
        hidden: the MLP's two hidden sizes. feature_cache: folder for cached features.
        device: ``auto``, ``cpu`` or ``cuda[:i]``; batch_size: images per forward pass;
        image_size: backbone input side, pixels (a multiple of the 14 px patch).
    """

    def __init__(self, classes: Sequence[str] = PAPER_CLASSES, head_checkpoint: str | None = None,
                 backbone: str = "facebook/dinov2-large", backbone_config: dict | None = None,
                 hidden: Sequence[int] = (512, 256), feature_cache: str | None = None, device: str = "auto",
                 batch_size: Annotated[int, Integer(1)] = 32, image_size: Annotated[int, Integer(1)] = 224,
                 allow_untrained: bool = False):
        torch = require_torch()
        self.classes = tuple(classes)
        self.device = pick_device(device)
        self.batch_size, self.image_size = int(batch_size), int(image_size)
        self.hidden = [int(h) for h in hidden]
        if head_checkpoint is None and not allow_untrained:
            raise ValueError("classifier.head_checkpoint is not set: train the MLP head first with "
                             "python -m benchmark.commands.train --model dinov2 ...")
        cfg = dict(backbone_config) if backbone_config else None
        self.backbone_name = backbone if cfg is None else "config-" + hashlib.sha1(
            json.dumps(cfg, sort_keys=True).encode()).hexdigest()[:12]
        self.backbone, self.kind = build_backbone(backbone, cfg)
        self.backbone.to(self.device).eval()
        for p in self.backbone.parameters():
            p.requires_grad_(False)
        self.dim = int(self.backbone.config.hidden_size if self.kind == "hf" else self.backbone.embed_dim)
        self.head = mlp_head(self.dim, self.hidden, len(self.classes))
        if head_checkpoint is not None:
            load_checkpoint(head_checkpoint, self.head, self.classes,
                            expect={"backbone": self.backbone_name, "hidden": self.hidden})
        self.head.to(self.device).eval()
        self.cache_dir = (Path(feature_cache) / _slug(self.backbone_name) / f"{self.image_size}px"
                          if feature_cache else None)
        self._mem: dict[str, np.ndarray] = {}
        self._tf = eval_transform(self.image_size)
        self._torch = torch

    def setup(self, eval_house_ids: Sequence[str]) -> None:
        """Nothing to prepare."""

    @staticmethod
    def _key(img: np.ndarray) -> str:
        return hashlib.sha1(np.ascontiguousarray(img).tobytes() + str(img.shape).encode()).hexdigest()

    def features(self, images: Sequence[np.ndarray]) -> np.ndarray:
        """(N, D) frozen CLS features of (H, W, 3) uint8 images, from the cache where possible."""
        torch = self._torch
        images = list(images)
        keys = [self._key(img) for img in images]
        todo, seen = [], set()
        for i, k in enumerate(keys):
            if k not in seen and k not in self._mem and not self._from_disk(k):
                todo.append(i)
                seen.add(k)
        with torch.inference_mode():
            for chunk in batches(todo, self.batch_size):
                x = torch.stack([self._tf(images[i]) for i in chunk]).to(self.device)
                f = self.backbone(pixel_values=x).pooler_output if self.kind == "hf" else self.backbone(x)
                for i, v in zip(chunk, f.float().cpu().numpy()):
                    self._store(keys[i], v)
        return np.stack([self._mem[k] for k in keys]) if keys else np.zeros((0, self.dim), np.float32)

    def _from_disk(self, key: str) -> bool:
        if self.cache_dir is None:
            return False
        from envs.npz import load_npz  # noqa: PLC0415

        p = self.cache_dir / f"{key}.npz"
        if not p.exists():
            return False
        try:
            v = load_npz(p)["features"]  # checked against the checksum written with it
        except (ValueError, KeyError) as e:
            log.warning("%s: bad feature cache entry, recomputing it (%s)", p, " ".join(str(e).split()))
            return False
        if v.shape != (self.dim,):
            return False  # a stale or foreign file: recompute and overwrite
        self._mem[key] = v
        return True

    def _store(self, key: str, v: np.ndarray) -> None:
        self._mem[key] = v
        if self.cache_dir is not None:
            from envs.npz import save_npz  # noqa: PLC0415

            save_npz(self.cache_dir / f"{key}.npz", features=v)

    def predict_features(self, feats: np.ndarray) -> np.ndarray:
        """(N, C) softmax probabilities of the head on (N, D) features."""
        torch = self._torch
        with torch.inference_mode():
            logits = self.head(torch.as_tensor(np.asarray(feats), dtype=torch.float32, device=self.device))
            return torch.softmax(logits, dim=1).cpu().numpy().astype(np.float64)

    def predict_images(self, images: Sequence[np.ndarray]) -> np.ndarray:
        """(N, C) class probabilities of (H, W, 3) uint8 RGB images."""
        return self.predict_features(self.features(images))

    def predict_proba(self, observations: Sequence) -> np.ndarray:
        """(N, C) class probabilities of the observations' images."""
        return self.predict_images(images_of(observations))
