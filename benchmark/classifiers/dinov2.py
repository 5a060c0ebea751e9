"""DINOv2 + MLP: frozen DINOv2 features (ViT-L/14, 1024-d CLS token of a 224 x 224 image in
the paper) and a 3-layer MLP head trained on them (``train --model dinov2``). Features are
cached by image content (in memory, and on disk under ``feature_cache`` when given)."""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from benchmark.classifiers.torch_common import (
    batches,
    eval_transform,
    images_of,
    load_checkpoint,
    pick_device,
    require_torch,
)
from envs.classes import PAPER_CLASSES


def build_backbone(backbone: str, backbone_config: dict | None = None):
    """A DINOv2 model: a Hugging Face id (``facebook/dinov2-large``), ``torchhub:<name>``
    (``torchhub:dinov2_vitl14``), or a random-initialised one from ``backbone_config``
    (transformers ``Dinov2Config`` fields; tests)."""
    torch = require_torch()
    if backbone_config is not None:
        from transformers import Dinov2Config, Dinov2Model  # noqa: PLC0415

        return Dinov2Model(Dinov2Config(**backbone_config)), "hf"
    try:
        if backbone.startswith("torchhub:"):
            return torch.hub.load("facebookresearch/dinov2", backbone.split(":", 1)[1]), "hub"
        from transformers import Dinov2Model  # noqa: PLC0415

        return Dinov2Model.from_pretrained(backbone), "hf"
    except ImportError:
        raise ImportError("DINOv2 from Hugging Face needs transformers: pip install 'roomseg-bench[models]'") from None
    except Exception as e:
        raise RuntimeError(f"could not load DINOv2 backbone {backbone!r} ({type(e).__name__}); download it once "
                           "(HF cache or torch hub) on a machine with network access") from None


def mlp_head(in_dim: int, hidden: Sequence[int], n_classes: int, dropout: float = 0.2):
    """The 3-layer MLP: in -> hidden[0] -> hidden[1] -> classes, ReLU and dropout between."""
    torch = require_torch()
    nn = torch.nn
    return nn.Sequential(nn.Linear(in_dim, hidden[0]), nn.ReLU(), nn.Dropout(dropout),
                         nn.Linear(hidden[0], hidden[1]), nn.ReLU(), nn.Dropout(dropout),
                         nn.Linear(hidden[1], n_classes))


class DinoV2Classifier:
    """Args:
        head_checkpoint: trained MLP head (``train --model dinov2``); required for
            predictions unless ``allow_untrained``.
        backbone, backbone_config: see :func:`build_backbone`.
        hidden: MLP hidden sizes. feature_cache: folder for cached features (optional).
        device, batch_size, image_size: inference settings.
    """

    def __init__(self, classes: Sequence[str] = PAPER_CLASSES, head_checkpoint: str | None = None,
                 backbone: str = "facebook/dinov2-large", backbone_config: dict | None = None,
                 hidden: Sequence[int] = (512, 256), feature_cache: str | None = None, device: str = "auto",
                 batch_size: int = 32, image_size: int = 224, allow_untrained: bool = False):
        torch = require_torch()
        self.classes = tuple(classes)
        self.device = pick_device(device)
        self.batch_size, self.image_size = int(batch_size), int(image_size)
        if head_checkpoint is None and not allow_untrained:
            raise ValueError("classifier.head_checkpoint is not set: train the MLP head first with "
                             "python -m benchmark.classifiers.train --model dinov2 ...")
        self.backbone, self.kind = build_backbone(backbone, dict(backbone_config) if backbone_config else None)
        self.backbone.to(self.device).eval()
        for p in self.backbone.parameters():
            p.requires_grad_(False)
        dim = self.backbone.config.hidden_size if self.kind == "hf" else self.backbone.embed_dim
        self.head = mlp_head(dim, hidden, len(self.classes))
        if head_checkpoint is not None:
            load_checkpoint(head_checkpoint, self.head, self.classes)
        self.head.to(self.device).eval()
        self.cache_dir = Path(feature_cache) if feature_cache else None
        self._mem: dict[str, np.ndarray] = {}
        self._tf = eval_transform(self.image_size)
        self._torch = torch

    def setup(self, eval_house_ids: Sequence[str]) -> None:
        """Nothing to prepare."""

    def _key(self, img: np.ndarray) -> str:
        return hashlib.sha1(np.ascontiguousarray(img).tobytes() + str(img.shape).encode()).hexdigest()

    def features(self, images: Sequence[np.ndarray]) -> np.ndarray:
        """(N, D) frozen CLS features, from the cache where possible."""
        torch = self._torch
        keys = [self._key(img) for img in images]
        todo = [i for i, k in enumerate(keys) if k not in self._mem and not self._on_disk(k)]
        with torch.inference_mode():
            for chunk in batches(todo, self.batch_size):
                x = torch.stack([self._tf(images[i]) for i in chunk]).to(self.device)
                if self.kind == "hf":
                    f = self.backbone(pixel_values=x).pooler_output
                else:
                    f = self.backbone(x)
                for i, v in zip(chunk, f.float().cpu().numpy()):
                    self._store(keys[i], v)
        return np.stack([self._mem[k] for k in keys]) if keys else np.zeros((0, 0))

    def _on_disk(self, key: str) -> bool:
        if self.cache_dir is None:
            return False
        p = self.cache_dir / f"{key}.npy"
        if p.exists():
            self._mem[key] = np.load(p)
            return True
        return False

    def _store(self, key: str, v: np.ndarray) -> None:
        self._mem[key] = v
        if self.cache_dir is not None:
            import io  # noqa: PLC0415

            from envs.atomic import atomic_write_bytes  # noqa: PLC0415

            buf = io.BytesIO()
            np.save(buf, v)
            atomic_write_bytes(self.cache_dir / f"{key}.npy", buf.getvalue())

    def predict_features(self, feats: np.ndarray) -> np.ndarray:
        torch = self._torch
        with torch.inference_mode():
            logits = self.head(torch.as_tensor(feats, dtype=torch.float32, device=self.device))
            return torch.softmax(logits, dim=1).cpu().numpy()

    def predict_images(self, images: Sequence[np.ndarray]) -> np.ndarray:
        return self.predict_features(self.features(list(images)))

    def predict_proba(self, observations: Sequence) -> np.ndarray:
        return self.predict_images(images_of(observations))
