"""Zero-shot VLM room classifier (Qwen2.5-VL-7B-Instruct in the paper).

The prompt is built from the configured class list, so a new room type is a config change.

``mode="score"`` (default) scores every class as the start of the answer, read from the
model's logits, and softmaxes over the classes, so the output is always a probability
vector. How a model may write a class is covered by its *spellings*
(:func:`class_spellings`): lower case, first letter capitalised and title case, with a
space or an underscore between words ("dining room", "Dining room", "Dining Room",
"dining_room", ...). The rule for a class (:meth:`VLMClassifier.class_log_likelihoods`):

    score(class) = log sum over its spellings s of P(s | image, prompt)
    log P(s | image, prompt) = sum of the log probabilities of s's tokens

Why these two: the sum of a spelling's token log probabilities is the log probability that
the answer starts with exactly that text, a true probability whatever the number of tokens
(a mean per token is not one, and would halve a confident first token of a two-token name
while its second token, e.g. " room" after " dining", is nearly certain anyway). The
spellings of a class are different texts, so the probability that the answer is *any* of
them is the sum of their probabilities: log-sum-exp of their scores. A spelling the
tokenizer cannot write (it has unknown tokens) is left out; one with the same tokens as
another is counted once.

The image and the prompt are encoded once per image: one forward pass over the chat
prefix of ``batch_size`` images (left-padded; the vision encoder sees each image once)
keeps its key/value cache and the next-token distribution, which scores every spelling's
first token; one more pass scores the remaining tokens of every spelling of every class at
once, against that cache (copied per spelling, continuations right-padded, positions
continuing each image's prefix; for Qwen2.5-VL the 3D rope positions from the model's own
``get_rope_index``). When every spelling is one token, the second pass is skipped. The
result equals scoring each full sequence from scratch to floating-point tolerance
(``tests/test_vlm_prefix.py``; ``python -m benchmark.commands.maintainer.vlm_bench`` measures both).

``mode="text"`` generates a free-text answer (greedy, batched; ``generate`` keeps the
prefix's key/value cache, so the image is encoded once per image there too) and parses it:
class names matched case-insensitively as words, ``_``/``-`` read as spaces, plural ``s``
allowed, the earliest mention wins. An answer that names no class gives a uniform vector
and is flagged in ``last_flags`` (and counted in ``n_unparsed``).

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
from typing import Annotated

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
from envs.ranges import Integer
from envs.world.classes import PAPER_CLASSES

log = logging.getLogger(__name__)

DEFAULT_PROMPT = "What type of room is shown in this image? Answer with exactly one of: {options}."


def display_name(cls: str) -> str:
    """``dining_room`` -> ``dining room`` (how a class is written in prompts and answers)."""
    return cls.replace("_", " ")


#: Spelling sets of :func:`class_spellings`: ``all`` (cases x separators) or ``plain`` (the
#: display name only, the scoring before the spellings were added).
SPELLINGS = ("all", "plain")


def class_spellings(cls: str, which: str = "all") -> list[str]:
    """The texts a model may answer for class ``cls``, in a fixed order without repeats.

    ``all``: lower case, first letter capitalised, title case ("dining room", "Dining room",
    "Dining Room"), each with words joined by a space and, for multi-word classes, by an
    underscore ("dining_room", "Dining_room", "Dining_Room"): 2 spellings for one word, 6
    for more. ``plain``: the display name only (``dining_room`` -> "dining room").

    Returns:
        list of strings, the display name first.
    """
    if which not in SPELLINGS:
        raise ValueError(f"VLM spellings must be one of {SPELLINGS}, got {which!r}")
    words = display_name(cls).lower().split()
    if which == "plain" or not words:
        return [display_name(cls)]
    forms = [words, [words[0].capitalize(), *words[1:]], [w.capitalize() for w in words]]
    out: list[str] = [display_name(cls)]
    for sep in ([" ", "_"] if len(words) > 1 else [" "]):
        for f in forms:
            t = sep.join(f)
            if t not in out:
                out.append(t)
    return out


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


def _repeat_cache(cache, repeats: int):
    """The key/value cache with each batch row repeated ``repeats`` times in place (rows
    b*repeats .. b*repeats+repeats-1 are row b): transformers' ``Cache`` objects, or the
    legacy tuple of (key, value) tensors (batch first)."""
    if hasattr(cache, "batch_repeat_interleave"):
        cache.batch_repeat_interleave(repeats)
        return cache
    return tuple(tuple(t.repeat_interleave(repeats, dim=0) for t in layer) for layer in cache)


class VLMClassifier(Classifier):
    """Args:
        classes: the ordered class names (their display names go into the prompt).
        model_id: Hugging Face id or local folder of the VLM.
        mode: ``score`` (class-name likelihoods) or ``text`` (free text, parsed).
        prompt: template with ``{options}`` (the comma-separated class names).
        load_in_4bit: bitsandbytes 4-bit on CUDA (ignored elsewhere).
        device: ``auto``, ``cpu`` or ``cuda[:i]``; dtype: ``auto``, ``float32``, ``float16``, ``bfloat16``.
        batch_size: images per prefix forward pass (score mode: the continuation pass then
            holds images x spellings rows, each with a copy of its image's key/value cache).
        max_new_tokens: generation budget of the text mode, tokens.
        spellings: ``all`` (the class in lower, capitalised and title case, with spaces or
            underscores; see :func:`class_spellings`) or ``plain`` (its display name only).
        max_pixels: cap on the processor's resized image area, pixels (null: the model's default).
        model, processor: an already loaded model and processor or tokenizer (skips loading).
    """

    def __init__(self, classes: Sequence[str] = PAPER_CLASSES, model_id: str = "Qwen/Qwen2.5-VL-7B-Instruct",
                 mode: str = "score", prompt: str = DEFAULT_PROMPT, load_in_4bit: bool = True,
                 device: str = "auto", dtype: str = "auto", batch_size: Annotated[int, Integer(1)] = 4,
                 max_new_tokens: int = 12, max_pixels: int | None = None, spellings: str = "all", model=None,
                 processor=None):
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
        if spellings not in SPELLINGS:
            raise ValueError(f"VLM spellings must be one of {SPELLINGS}, got {spellings!r}")
        self.spellings = spellings
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
        self.spelling_table = self._spelling_table()
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

    def _spelling_table(self) -> list[tuple[int, str, tuple[int, ...]]]:
        """(class index, spelling, its token ids after the prompt) for every spelling scored.

        A spelling with the tokenizer's unknown token is left out (the model cannot write it);
        one whose tokens repeat another's of the same class is counted once; two classes with
        a spelling of the same tokens, a class with no spelling left, or a tokenizer that
        merges the answer into the prompt's last token are errors."""
        pre = self._ids(self._prefix)
        unk = getattr(self.tokenizer, "unk_token_id", None)
        table, owner = [], {}
        for k, c in enumerate(self.classes):
            for text in class_spellings(c, self.spellings):
                full = self._ids(self._prefix + text)
                if full[:len(pre)] != pre or len(full) == len(pre):
                    raise ValueError(f"the tokenizer merges the answer {text!r} into the prompt; end the chat "
                                     "template's generation prompt with a space or newline")
                ids = tuple(full[len(pre):])
                if unk is not None and unk in ids:
                    continue
                if ids in owner:
                    if owner[ids] != k:
                        raise ValueError(f"classes {self.classes[owner[ids]]!r} and {c!r} have a spelling with the "
                                         f"same tokens ({text!r}); rename one")
                    continue
                owner[ids] = k
                table.append((k, text, ids))
            if not any(row[0] == k for row in table):
                raise ValueError(f"the tokenizer cannot write class {c!r} in any spelling "
                                 f"({class_spellings(c, self.spellings)}): every one has unknown tokens")
        return table

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

    def _prefix_positions(self, enc) -> tuple[object, object]:
        """Position ids of the encoded prefixes and, per row, the position the answer starts at.

        Text-only LMs: (B, P) from the attention mask (left padding counts real tokens only).
        Models with 3D rope (Qwen2.5-VL): (3, B, P) from the model's own ``get_rope_index``,
        the same ids its forward would compute; the answer continues one past the largest.

        Returns:
            (position_ids, next_position (B,) long).
        """
        rope = getattr(getattr(self.model, "model", None), "get_rope_index", None)
        if rope is not None and "image_grid_thw" in enc:
            params = inspect.signature(rope).parameters
            kw = {k: v for k, v in enc.items() if k in params and k != "input_ids"}
            pos, _ = rope(enc["input_ids"], **kw)
            return pos, pos.amax(dim=(0, 2)) + 1
        mask = enc["attention_mask"]
        pos = (mask.cumsum(-1) - 1).clamp(min=0)
        return pos, mask.sum(-1)

    def class_log_likelihoods(self, images: Sequence[np.ndarray]) -> np.ndarray:
        """(N, C) log-likelihood of each class as the answer for each image: log-sum-exp over
        the class's spellings of the sum of each spelling's token log probabilities (see the
        module docstring for the rule and why).

        Two forward passes per ``images`` chunk: the chat prefix with the images (the vision
        encoder runs once per image), then every spelling's tokens after the first against
        the prefix's key/value cache (skipped when every spelling is one token).

        Returns:
            float64 array (N, C), natural-log probabilities (<= 0).
        """
        torch = self.torch
        b = len(images)
        table = self.spelling_table
        k_sp = len(table)
        enc = self._encode([self._prefix] * b, list(images))
        enc.pop("position_ids", None)
        pos, nxt = self._prefix_positions(enc)
        with torch.inference_mode():
            kw = {"logits_to_keep": 1} if self._keep_kw else {}
            out = self.model(**enc, position_ids=pos, use_cache=True, **kw)
            first = torch.log_softmax(out.logits[:, -1].float(), dim=-1)  # (B, V): each spelling's first token
            scores = first[:, [ids[0] for _, _, ids in table]]  # (B, K)
            longest = max(len(ids) for _, _, ids in table)
            if longest > 1:
                dev = first.device
                width = longest - 1  # tokens fed: all but each spelling's last
                feed = torch.zeros((k_sp, width), dtype=torch.long)
                fmask = torch.zeros((k_sp, width), dtype=enc["attention_mask"].dtype)
                for j, (_, _, ids) in enumerate(table):
                    feed[j, :len(ids) - 1] = torch.tensor(ids[:-1], dtype=torch.long)
                    fmask[j, :len(ids) - 1] = 1
                feed, fmask = feed.to(dev).repeat(b, 1), fmask.to(dev).repeat(b, 1)  # row r = image r // K
                cache = _repeat_cache(out.past_key_values, k_sp)
                mask = torch.cat([enc["attention_mask"].repeat_interleave(k_sp, dim=0), fmask], dim=1)
                cpos = nxt.to(dev).repeat_interleave(k_sp)[:, None] + torch.arange(width, device=dev)[None, :]
                if pos.ndim == 3:
                    cpos = cpos[None].expand(pos.shape[0], -1, -1)
                logits = self.model(input_ids=feed, attention_mask=mask, position_ids=cpos, past_key_values=cache,
                                    use_cache=True).logits.float()
                logp = torch.log_softmax(logits, dim=-1)  # (B*K, width, V): token t+1 given tokens <= t
                rest = torch.zeros((b * k_sp,), dtype=logp.dtype, device=dev)
                for j, (_, _, ids) in enumerate(table):
                    if len(ids) > 1:
                        tgt = torch.tensor(ids[1:], dtype=torch.long, device=dev)
                        rows = torch.arange(j, b * k_sp, k_sp, device=dev)
                        steps = torch.arange(len(ids) - 1, device=dev)
                        rest[rows] = logp[rows[:, None], steps[None, :], tgt[None, :]].sum(-1)
                scores = scores + rest.view(b, k_sp)
        sp = scores.double().cpu().numpy()  # (B, K) log P(spelling)
        res = np.full((b, len(self.classes)), -np.inf)
        for k in range(len(self.classes)):
            cols = [j for j, row in enumerate(table) if row[0] == k]
            m = sp[:, cols].max(axis=1, keepdims=True)
            res[:, k] = (m + np.log(np.exp(sp[:, cols] - m).sum(axis=1, keepdims=True)))[:, 0]
        return res

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
