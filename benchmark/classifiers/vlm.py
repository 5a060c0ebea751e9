"""Zero-shot VLM room classifier (Qwen2.5-VL-7B-Instruct in the paper).

The prompt is built from the configured class list, so a new room type is a config change.

``mode="score"`` (default) scores every class name as the answer: log P(name | image,
prompt), the sum of the log probabilities of the name's tokens after the chat prompt,
read from the model's logits; softmaxed over the classes, so the output is always a
probability vector. One forward pass holds ``batch_size`` images x C class names
(left-padded, so only the last few positions' logits are computed).

``mode="text"`` generates a free-text answer (greedy, batched) and parses it: class names
matched case-insensitively as words, ``_``/``-`` read as spaces, plural ``s`` allowed, the
earliest mention wins. An answer that names no class gives a uniform vector and is flagged
in ``last_flags`` (and counted in ``n_unparsed``).

The real model loads through transformers (4-bit with bitsandbytes on CUDA, full precision
elsewhere). Any model with a processor (image + text) or any causal LM with a
chat-template tokenizer can be passed in directly (``model=``, ``processor=``); a text-only
LM ignores the image, which is how the tests check the scoring with tiny models.
"""

from __future__ import annotations

import inspect
import logging
import re
from collections.abc import Sequence

import numpy as np

from benchmark.classifiers.torch_common import (
    batches,
    check_image,
    images_of,
    pick_device,
    require_torch,
    require_transformers,
    resolve_dtype,
)
from benchmark.interfaces import Classifier
from envs.world.classes import PAPER_CLASSES

log = logging.getLogger(__name__)

DEFAULT_PROMPT = "What type of room is shown in this image? Answer with exactly one of: {options}."


def display_name(cls: str) -> str:
    """``dining_room`` -> ``dining room`` (how a class is written in prompts and answers)."""
    return cls.replace("_", " ")


def parse_answer(text: str, classes: Sequence[str]) -> int:
    """Index of the class the free-text answer names first, -1 if it names none."""
    t = re.sub(r"[_\-]+", " ", str(text).lower())
    best, where = -1, len(t) + 1
    for i, c in enumerate(classes):
        name = r"\s+".join(re.escape(w) for w in display_name(c).lower().split())
        m = re.search(r"\b" + name + r"(?:e?s)?\b", t)
        if m and m.start() < where:
            best, where = i, m.start()
    return best


def load_vlm(model_id: str, load_in_4bit: bool, device: str, dtype: str, max_pixels: int | None = None):
    """Load an image-text-to-text model (Qwen2.5-VL) and its processor: 4-bit (bitsandbytes)
    on CUDA when ``load_in_4bit``, else ``dtype`` (``auto``: full precision off CUDA).
    Anything missing is one line saying what to do."""
    transformers = require_transformers("the VLM classifier")
    from packaging.version import Version  # noqa: PLC0415

    torch_dtype = resolve_dtype(dtype, device)
    kw: dict = {}
    if device.startswith("cuda"):
        kw["device_map"] = {"": device}
        if load_in_4bit:
            try:
                import bitsandbytes  # noqa: F401, PLC0415
            except ImportError:
                raise ImportError("4-bit loading needs bitsandbytes: pip install 'roomseg-bench[gpu]' "
                                  "(or classifier.load_in_4bit=false)") from None
            kw["quantization_config"] = transformers.BitsAndBytesConfig(
                load_in_4bit=True, bnb_4bit_quant_type="nf4", bnb_4bit_compute_dtype=torch_dtype)
    kw["dtype" if Version(transformers.__version__) >= Version("4.56") else "torch_dtype"] = torch_dtype
    try:
        model = transformers.AutoModelForImageTextToText.from_pretrained(model_id, **kw)
        processor = transformers.AutoProcessor.from_pretrained(
            model_id, **({"max_pixels": int(max_pixels)} if max_pixels else {}))
    except Exception as e:
        raise RuntimeError(f"could not load {model_id!r} ({type(e).__name__}); download it once on a machine with "
                           "network access (Hugging Face cache; HF_HUB_OFFLINE=1 skips the network) or point classifier.model_id at a local folder"
                           ) from None
    if "device_map" not in kw:
        model.to(device)
    return model.eval(), processor


class VLMClassifier(Classifier):
    """Args:
        classes: the ordered class names (their display names go into the prompt).
        model_id: Hugging Face id or local folder of the VLM.
        mode: ``score`` (class-name likelihoods) or ``text`` (free text, parsed).
        prompt: template with ``{options}`` (the comma-separated class names).
        load_in_4bit: bitsandbytes 4-bit on CUDA (ignored elsewhere).
        device: ``auto``, ``cpu`` or ``cuda[:i]``; dtype: ``auto``, ``float32``, ``float16``, ``bfloat16``.
        batch_size: images per forward pass (score mode runs images x classes sequences).
        max_new_tokens: generation budget of the text mode, tokens.
        max_pixels: cap on the processor's resized image area, pixels (null: the model's default).
        model, processor: an already loaded model and processor or tokenizer (skips loading).
    """

    def __init__(self, classes: Sequence[str] = PAPER_CLASSES, model_id: str = "Qwen/Qwen2.5-VL-7B-Instruct",
                 mode: str = "score", prompt: str = DEFAULT_PROMPT, load_in_4bit: bool = True, device: str = "auto",
                 dtype: str = "auto", batch_size: int = 4, max_new_tokens: int = 12, max_pixels: int | None = None,
                 model=None, processor=None):
        self.torch = require_torch()
        if mode not in ("score", "text"):
            raise ValueError(f"VLM mode must be 'score' or 'text', got {mode!r}")
        if "{options}" not in prompt:
            raise ValueError("the VLM prompt must contain '{options}' (where the class names go)")
        self.classes, self.mode, self.prompt_template = tuple(classes), mode, prompt
        if len(self.classes) < 2:
            raise ValueError(f"the VLM needs at least 2 classes to choose from, got {list(self.classes)}")
        try:
            self.prompt = prompt.format(options=", ".join(display_name(c) for c in self.classes))
        except (KeyError, IndexError, ValueError) as e:
            raise ValueError(f"the VLM prompt may only use the {{options}} field ({type(e).__name__}: {e})") from None
        if int(batch_size) < 1:
            raise ValueError(f"batch_size must be >= 1, got {batch_size}")
        self.batch_size, self.max_new_tokens = int(batch_size), int(max_new_tokens)
        if model is None:
            model, processor = load_vlm(model_id, load_in_4bit, pick_device(device), dtype, max_pixels)
        elif processor is None:
            raise ValueError("a VLM passed in as model= needs its processor= (or tokenizer)")
        self.model, self.processor = model, processor
        self.tokenizer = getattr(processor, "tokenizer", processor)
        if self.tokenizer.pad_token is None:
            self.tokenizer.pad_token = self.tokenizer.eos_token
        self.multimodal = hasattr(processor, "image_processor")
        self._keep_kw = "logits_to_keep" in inspect.signature(self.model.forward).parameters
        self._prefix = self.chat_prefix()
        self._answers = self._answer_lengths()
        self.last_flags = np.zeros(0, dtype=bool)
        self.n_unparsed = 0

    def setup(self, eval_house_ids: Sequence[str]) -> None:
        """Nothing to prepare (zero-shot)."""

    def chat_prefix(self) -> str:
        """The chat-formatted prompt (with the image placeholder) up to where the answer starts."""
        content = [{"type": "image"}, {"type": "text", "text": self.prompt}] if self.multimodal else self.prompt
        return self.processor.apply_chat_template([{"role": "user", "content": content}], tokenize=False,
                                                  add_generation_prompt=True)

    def _ids(self, text: str) -> list[int]:
        return list(self.tokenizer(text, add_special_tokens=False)["input_ids"])

    def _answer_lengths(self) -> list[int]:
        """Tokens of each class name after the prompt; the prompt's tokens must not change."""
        pre = self._ids(self._prefix)
        out = []
        for c in self.classes:
            full = self._ids(self._prefix + display_name(c))
            if full[:len(pre)] != pre or len(full) == len(pre):
                raise ValueError(f"the tokenizer merges the answer {display_name(c)!r} into the prompt; end the "
                                 "chat template's generation prompt with a space or newline")
            out.append(len(full) - len(pre))
        return out

    def _encode(self, texts: list[str], images: list[np.ndarray]):
        """Left-padded model inputs for the texts (with one image each when multimodal)."""
        self.tokenizer.padding_side = "left"
        if self.multimodal:
            enc = self.processor(text=texts, images=images, padding=True, return_tensors="pt")
        else:
            enc = self.tokenizer(texts, padding=True, return_tensors="pt", add_special_tokens=False)
            mask = enc["attention_mask"]
            enc["position_ids"] = (mask.cumsum(-1) - 1).clamp(min=0)  # left padding: count real tokens only
        return {k: v.to(self.model.device) for k, v in enc.items()}

    def class_log_likelihoods(self, images: Sequence[np.ndarray]) -> np.ndarray:
        """(N, C) log P(class name | image, prompt), summed over each name's tokens."""
        torch = self.torch
        c = len(self.classes)
        names = [display_name(k) for k in self.classes]
        texts = [self._prefix + name for _ in images for name in names]
        enc = self._encode(texts, [img for img in images for _ in names])
        keep = max(self._answers) + 1
        with torch.inference_mode():
            kw = {"logits_to_keep": keep} if self._keep_kw else {}
            logits = self.model(**enc, **kw).logits[:, -keep:].float()
        logp = torch.log_softmax(logits, dim=-1)
        ids = enc["input_ids"]
        out = np.zeros(len(texts))
        for r in range(len(texts)):
            n = self._answers[r % c]
            answer = ids[r, ids.shape[1] - n:]
            out[r] = float(logp[r, keep - n - 1:keep - 1].gather(1, answer[:, None]).sum())
        return out.reshape(len(images), c)

    def answers(self, images: Sequence[np.ndarray]) -> list[str]:
        """The model's free-text answers (greedy) for the images."""
        torch = self.torch
        enc = self._encode([self._prefix] * len(images), list(images))
        enc.pop("position_ids", None)  # generate() derives them from the mask
        with torch.inference_mode():
            out = self.model.generate(**enc, max_new_tokens=self.max_new_tokens, do_sample=False,
                                      pad_token_id=self.tokenizer.pad_token_id)
        start = enc["input_ids"].shape[1]
        return [self.tokenizer.decode(row[start:], skip_special_tokens=True) for row in out]

    def answer(self, image: np.ndarray) -> str:
        """The model's free-text answer for one image."""
        return self.answers([image])[0]

    def predict_images(self, images: Sequence[np.ndarray]) -> np.ndarray:
        """(N, C) class probabilities of (H, W, 3) uint8 RGB images, ``batch_size`` at a time."""
        images = [check_image(img, f"image {i}") for i, img in enumerate(images)]
        c = len(self.classes)
        out = np.zeros((len(images), c))
        flags = np.zeros(len(images), dtype=bool)
        for start, chunk in zip(range(0, len(images), self.batch_size), batches(images, self.batch_size)):
            rows = slice(start, start + len(chunk))
            if self.mode == "score":
                s = self.class_log_likelihoods(chunk)
                e = np.exp(s - s.max(axis=1, keepdims=True))
                out[rows] = e / e.sum(axis=1, keepdims=True)
                continue
            for j, text in enumerate(self.answers(chunk)):
                k = parse_answer(text, self.classes)
                if k < 0:
                    out[start + j] = 1.0 / c
                    flags[start + j] = True
                    log.debug("VLM answer names no class (uniform vector used): %r", text)
                else:
                    out[start + j, k] = 1.0
        self.last_flags = flags
        self.n_unparsed += int(flags.sum())
        if flags.any():
            log.warning("VLM text mode: %d of %d answers named no class; uniform vectors used",
                        int(flags.sum()), len(images))
        return out

    def predict_proba(self, observations: Sequence) -> np.ndarray:
        """(N, C) class probabilities of the observations' images."""
        return self.predict_images(images_of(observations))
