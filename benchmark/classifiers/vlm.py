"""Zero-shot VLM room classifier (Qwen2.5-VL-7B-Instruct in the paper).

The prompt is built from the configured class list, so a new room type is a config change.
``mode="score"`` (default) scores every class name as the answer: the sum of the log
probabilities of its tokens after the prompt (one forward pass per class, batched over the
classes), softmaxed over classes, so the output is always a probability vector.
``mode="text"`` generates a free-text answer and parses it (class names matched
case-insensitively, with ``_``/``-`` read as spaces; the earliest mention wins); an answer
naming no class gives a uniform vector and is flagged in ``last_flags``.

The real model loads through transformers (4-bit with bitsandbytes on CUDA, full precision
elsewhere). Any causal LM with a chat-template tokenizer, or a VLM with a processor, can be
passed in directly (``model=``, ``processor=``), which is how the tests run tiny models.
"""

from __future__ import annotations

import re
from collections.abc import Sequence

import numpy as np

from benchmark.classifiers.torch_common import images_of, pick_device, require_torch
from envs.classes import PAPER_CLASSES

DEFAULT_PROMPT = ("What type of room is shown in this image? Answer with exactly one of: {options}.")


def display_name(cls: str) -> str:
    """``dining_room`` -> ``dining room``."""
    return cls.replace("_", " ")


def parse_answer(text: str, classes: Sequence[str]) -> int:
    """Index of the class the answer names first, -1 if none."""
    t = re.sub(r"[_\-]+", " ", text.lower())
    best, where = -1, len(t) + 1
    for i, c in enumerate(classes):
        m = re.search(r"\b" + re.escape(display_name(c).lower()) + r"s?\b", t)
        if m and m.start() < where:
            best, where = i, m.start()
    return best


def load_qwen(model_id: str, load_in_4bit: bool, device: str, dtype: str):
    """Load a Qwen2.5-VL model and processor (one clear line when something is missing)."""
    torch = require_torch()
    try:
        import transformers  # noqa: PLC0415
    except ImportError:
        raise ImportError("the VLM classifier needs transformers: pip install 'roomseg-bench[models]'") from None
    quant = None
    if load_in_4bit and device.startswith("cuda"):
        try:
            import bitsandbytes  # noqa: F401, PLC0415
        except ImportError:
            raise ImportError("4-bit loading needs bitsandbytes: pip install 'roomseg-bench[gpu]' "
                              "(or classifier.load_in_4bit=false)") from None
        quant = transformers.BitsAndBytesConfig(load_in_4bit=True, bnb_4bit_compute_dtype=torch.float16)
    torch_dtype = {"auto": "auto", "float16": torch.float16, "bfloat16": torch.bfloat16,
                   "float32": torch.float32}[dtype]
    try:
        model = transformers.Qwen2_5_VLForConditionalGeneration.from_pretrained(
            model_id, torch_dtype=torch_dtype, quantization_config=quant,
            device_map=device if device.startswith("cuda") else None)
        processor = transformers.AutoProcessor.from_pretrained(model_id)
    except Exception as e:
        raise RuntimeError(f"could not load {model_id!r} ({type(e).__name__}); download it once on a machine with "
                           "network access (Hugging Face cache) or point classifier.model_id at a local folder") from None
    if quant is None:
        model.to(device)
    return model.eval(), processor


class VLMClassifier:
    """Args:
        classes: the ordered class names (their display names go into the prompt).
        model_id: Hugging Face id or local folder of the VLM.
        mode: "score" (class-name likelihoods) or "text" (free text, parsed).
        prompt: template with ``{options}``; load_in_4bit: bitsandbytes 4-bit on CUDA.
        device, dtype: where and in which precision the model runs.
        max_new_tokens: generation budget of the text mode.
        model, processor: an already loaded model and processor/tokenizer (skips loading).
    """

    def __init__(self, classes: Sequence[str] = PAPER_CLASSES, model_id: str = "Qwen/Qwen2.5-VL-7B-Instruct",
                 mode: str = "score", prompt: str = DEFAULT_PROMPT, load_in_4bit: bool = True, device: str = "auto",
                 dtype: str = "auto", max_new_tokens: int = 12, model=None, processor=None):
        self.torch = require_torch()
        if mode not in ("score", "text"):
            raise ValueError(f"VLM mode must be 'score' or 'text', got {mode!r}")
        if "{options}" not in prompt:
            raise ValueError("the VLM prompt must contain '{options}' (where the class names go)")
        self.classes, self.mode, self.prompt_template = tuple(classes), mode, prompt
        self.max_new_tokens = int(max_new_tokens)
        if model is None:
            dev = pick_device(device)
            model, processor = load_qwen(model_id, load_in_4bit, dev, dtype)
        self.model, self.processor = model, processor
        self.tokenizer = getattr(processor, "tokenizer", processor)
        self.multimodal = hasattr(processor, "image_processor")
        self.last_flags = np.zeros(0, dtype=bool)

    def setup(self, eval_house_ids: Sequence[str]) -> None:
        """Nothing to prepare (zero-shot)."""

    @property
    def prompt(self) -> str:
        return self.prompt_template.format(options=", ".join(display_name(c) for c in self.classes))

    def chat_prefix(self) -> str:
        """The chat-formatted prompt up to where the answer starts."""
        content = [{"type": "image"}, {"type": "text", "text": self.prompt}] if self.multimodal else self.prompt
        return self.processor.apply_chat_template([{"role": "user", "content": content}], tokenize=False,
                                                  add_generation_prompt=True)

    def _encode(self, texts: list[str], image, padding_side: str):
        self.tokenizer.padding_side = padding_side
        if self.multimodal:
            enc = self.processor(text=texts, images=[image] * len(texts), padding=True, return_tensors="pt")
        else:
            enc = self.tokenizer(texts, padding=True, return_tensors="pt", add_special_tokens=False)
        return {k: v.to(self.model.device) for k, v in enc.items()}

    def class_log_likelihoods(self, image) -> np.ndarray:
        """(C,) log P(class name | image, prompt): summed over the name's tokens."""
        torch = self.torch
        prefix = self.chat_prefix()
        texts = [prefix + display_name(c) for c in self.classes]
        n_prefix = len(self.tokenizer(prefix, add_special_tokens=False)["input_ids"])
        n_answer = [len(self.tokenizer(t, add_special_tokens=False)["input_ids"]) - n_prefix for t in texts]
        enc = self._encode(texts, image, "right")
        with torch.inference_mode():
            logits = self.model(**enc).logits.float()
        logp = torch.log_softmax(logits, dim=-1)
        lengths = enc["attention_mask"].sum(dim=1).tolist()
        out = np.zeros(len(texts))
        for i, (length, n) in enumerate(zip(lengths, n_answer)):
            ids = enc["input_ids"][i, length - n:length]
            out[i] = float(logp[i, length - n - 1:length - 1].gather(1, ids[:, None]).sum())
        return out

    def answer(self, image) -> str:
        """The model's free-text answer to the prompt."""
        torch = self.torch
        enc = self._encode([self.chat_prefix()], image, "left")
        with torch.inference_mode():
            out = self.model.generate(**enc, max_new_tokens=self.max_new_tokens, do_sample=False)
        return self.tokenizer.decode(out[0, enc["input_ids"].shape[1]:], skip_special_tokens=True)

    def predict_images(self, images: Sequence) -> np.ndarray:
        c = len(self.classes)
        out = np.zeros((len(images), c))
        flags = np.zeros(len(images), dtype=bool)
        for i, img in enumerate(images):
            if self.mode == "score":
                s = self.class_log_likelihoods(img)
                e = np.exp(s - s.max())
                out[i] = e / e.sum()
            else:
                k = parse_answer(self.answer(img), self.classes)
                if k < 0:
                    out[i] = 1.0 / c
                    flags[i] = True
                else:
                    out[i, k] = 1.0
        self.last_flags = flags
        return out

    def predict_proba(self, observations: Sequence) -> np.ndarray:
        return self.predict_images(images_of(observations))
