"""``python -m benchmark.commands.maintainer.vlm_bench``: what the VLM costs per image, before and after
the shared prefix, measured on CPU with tiny random-initialised models built offline.

Rows (for each model: a 2-layer Qwen2.5-VL with its vision encoder, and a 2-layer GPT-2
that ignores the image):

- ``before``: the scoring as it was: one full sequence (image + prompt + class name) per
  image and class, left-padded into one batch (:func:`full_sequence_log_likelihoods` with
  ``spellings=plain``);
- ``before, all spellings``: the same way over every spelling the classifier now scores;
- ``after``: :meth:`VLMClassifier.class_log_likelihoods` (prefix once per image, spellings
  against its key/value cache), for both spelling sets;
- ``text``: free-text answers (``generate`` keeps its own cache).

Columns: model forward calls, vision-encoder image encodings and language-model token
positions per image, seconds per image (the fastest of ``--repeats``) and the largest
difference of the scores from the ``before`` way with the same spellings.
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import numpy as np

from benchmark.classifiers.torch_common import require_torch, require_transformers
from benchmark.classifiers.vlm import DEFAULT_PROMPT, VLMClassifier, class_spellings, display_name
from benchmark.commands import cli

BENCH_CLASSES = ("balcony", "bathroom", "bedroom", "corridor", "dining_room", "kitchen", "living_room")
SPECIAL = ["[PAD]", "[UNK]", "<|im_start|>", "<|im_end|>", "<|vision_start|>", "<|vision_end|>", "<|image_pad|>",
           "<|video_pad|>"]
#: A Qwen-like chat template in whitespace-separated words (the tiny tokenizers split on spaces).
CHAT = ("{% for m in messages %}<|im_start|> {{ m['role'] }}: {% if m['content'] is string %}{{ m['content'] }}"
        "{% else %}{% for c in m['content'] %}{% if c['type'] == 'image' %}<|vision_start|> <|image_pad|> "
        "<|vision_end|> {% else %}{{ c['text'] }}{% endif %}{% endfor %}{% endif %} <|im_end|> {% endfor %}"
        "{% if add_generation_prompt %}<|im_start|> assistant: {% endif %}")


def tiny_vocab(classes: Sequence[str], prompt: str = DEFAULT_PROMPT) -> list[str]:
    """Whitespace words of the chat prompt and of every spelling of ``classes`` (so each
    spelling is representable: multi-word ones are several tokens), after the special tokens."""
    options = ", ".join(display_name(c) for c in classes)
    words = set(prompt.format(options=options).split()) | {"user:", "assistant:", "system"}
    for c in classes:
        for sp in class_spellings(c, "all"):
            words.update(sp.split())
    return SPECIAL + sorted(words - set(SPECIAL))


def _tokenizer(vocab: list[str]):
    transformers = require_transformers("the VLM benchmark")
    import tokenizers  # noqa: PLC0415

    ids = {w: i for i, w in enumerate(vocab)}
    tk = tokenizers.Tokenizer(tokenizers.models.WordLevel(ids, unk_token="[UNK]"))
    tk.pre_tokenizer = tokenizers.pre_tokenizers.WhitespaceSplit()
    tk.decoder = tokenizers.decoders.WordPiece()  # joins words with spaces
    return transformers.PreTrainedTokenizerFast(tokenizer_object=tk, pad_token="[PAD]", unk_token="[UNK]",
                                                eos_token="<|im_end|>", additional_special_tokens=SPECIAL[2:])


def tiny_text_lm(classes: Sequence[str] = BENCH_CLASSES, layers: int = 2, width: int = 64, seed: int = 0):
    """A GPT-2 (``layers`` blocks, ``width`` wide, random weights) and a word-level tokenizer
    with a chat template, built offline. Returns (model, tokenizer)."""
    torch = require_torch()
    transformers = require_transformers("the VLM benchmark")
    tok = _tokenizer(tiny_vocab(classes))
    tok.chat_template = "{% for m in messages %}user: {{ m['content'] }} {% endfor %}assistant: "
    torch.manual_seed(seed)
    eos = tok.convert_tokens_to_ids("<|im_end|>")
    cfg = transformers.GPT2Config(vocab_size=len(tok), n_positions=512, n_embd=width, n_layer=layers, n_head=2,
                                  bos_token_id=eos, eos_token_id=eos)
    return transformers.GPT2LMHeadModel(cfg).eval(), tok


def tiny_qwen(classes: Sequence[str] = BENCH_CLASSES, layers: int = 2, width: int = 64, vision_depth: int = 2,
              max_pixels: int = 224 * 224, seed: int = 0):
    """A Qwen2.5-VL (``layers`` text blocks, ``vision_depth`` vision blocks, ``width`` wide,
    random weights), its image processor (at most ``max_pixels`` pixels per image: 224 x 224
    gives 64 image tokens) and a word-level tokenizer with Qwen's special tokens, built
    offline. Returns (model, processor)."""
    torch = require_torch()
    transformers = require_transformers("the VLM benchmark")
    vocab = tiny_vocab(classes)
    tok = _tokenizer(vocab)
    proc = transformers.Qwen2_5_VLProcessor(
        image_processor=transformers.Qwen2VLImageProcessor(min_pixels=28 * 28, max_pixels=int(max_pixels)),
        tokenizer=tok, video_processor=transformers.Qwen2VLVideoProcessor(), chat_template=CHAT)
    heads = 2
    half = width // heads // 2  # rope pairs per head, split over (t, h, w)
    section = [half - 2 * (half // 3), half // 3, half // 3]
    cfg = transformers.Qwen2_5_VLConfig(
        text_config={"vocab_size": len(vocab), "hidden_size": width, "intermediate_size": 2 * width,
                     "num_hidden_layers": layers, "num_attention_heads": heads, "num_key_value_heads": 1,
                     "max_position_embeddings": 1024,
                     "rope_parameters": {"rope_type": "default", "mrope_section": section, "rope_theta": 1e4},
                     "bos_token_id": None, "eos_token_id": vocab.index("<|im_end|>"), "pad_token_id": 0},
        vision_config={"depth": vision_depth, "hidden_size": width, "intermediate_size": 2 * width,
                       "num_heads": heads, "out_hidden_size": width, "patch_size": 14, "spatial_merge_size": 2,
                       "temporal_patch_size": 2, "fullatt_block_indexes": [vision_depth - 1], "window_size": 112},
        image_token_id=vocab.index("<|image_pad|>"), video_token_id=vocab.index("<|video_pad|>"),
        vision_start_token_id=vocab.index("<|vision_start|>"), vision_end_token_id=vocab.index("<|vision_end|>"))
    torch.manual_seed(seed)
    return transformers.Qwen2_5_VLForConditionalGeneration(cfg).eval(), proc


def full_sequence_log_likelihoods(clf: VLMClassifier, images: Sequence[np.ndarray]) -> np.ndarray:
    """The scoring before the shared prefix: every (image, spelling) as one full sequence
    (chat prefix with the image, then the spelling), left-padded into one batch, so the
    vision encoder and the prefix run once per spelling; per class, log-sum-exp over its
    spellings of the summed token log probabilities. With ``spellings=plain`` this is the
    old classifier's computation. The measuring stick of :func:`main`, not used to classify.

    Returns:
        float64 array (N, C), natural-log probabilities.
    """
    torch = clf.torch
    table = clf.spelling_table
    texts = [clf._prefix + text for _ in images for _, text, _ in table]
    enc = clf._encode(texts, [img for img in images for _ in table])
    keep = max(len(ids) for _, _, ids in table) + 1
    with torch.inference_mode():
        kw = {"logits_to_keep": keep} if clf._keep_kw else {}
        logp = torch.log_softmax(clf.model(**enc, **kw).logits[:, -keep:].float(), dim=-1)
    ids = enc["input_ids"]
    sp = np.zeros(len(texts))
    for r in range(len(texts)):
        n = len(table[r % len(table)][2])
        answer = ids[r, ids.shape[1] - n:]
        sp[r] = float(logp[r, keep - n - 1:keep - 1].gather(1, answer[:, None]).sum())
    sp = sp.reshape(len(images), len(table))
    out = np.zeros((len(images), len(clf.classes)))
    for k in range(len(clf.classes)):
        cols = [j for j, row in enumerate(table) if row[0] == k]
        m = sp[:, cols].max(axis=1, keepdims=True)
        out[:, k] = (m + np.log(np.exp(sp[:, cols] - m).sum(axis=1, keepdims=True)))[:, 0]
    return out


class Counter:
    """Counts, while attached, the model's forward calls, the token positions its language
    model runs (batch rows x sequence length) and the images its vision encoder encodes
    (rows of ``grid_thw``)."""

    def __init__(self, model):
        self.calls = self.tokens = self.images = 0
        self._hooks = [model.register_forward_pre_hook(self._model, with_kwargs=True)]
        visual = getattr(getattr(model, "model", None), "visual", None)
        if visual is not None:
            self._hooks.append(visual.register_forward_pre_hook(self._visual, with_kwargs=True))

    def _model(self, module, args, kwargs):
        self.calls += 1
        x = kwargs.get("input_ids", args[0] if args else None)
        if x is not None:
            self.tokens += int(x.shape[0] * x.shape[1])

    def _visual(self, module, args, kwargs):
        grid = kwargs.get("grid_thw", args[1] if len(args) > 1 else None)
        self.images += 0 if grid is None else int(grid.shape[0])

    def close(self) -> None:
        for h in self._hooks:
            h.remove()


def _way(clf: VLMClassifier, way: str):
    return {"before": lambda ch: full_sequence_log_likelihoods(clf, ch),
            "after": clf.class_log_likelihoods, "text": clf.answers}[way]


def measure(runs: dict, images: Sequence[np.ndarray], repeats: int = 5) -> dict:
    """Measure each entry of ``runs`` (name -> (classifier, way); way ``before``:
    :func:`full_sequence_log_likelihoods`, ``after``: :meth:`VLMClassifier.class_log_likelihoods`,
    ``text``: :meth:`VLMClassifier.answers`) over ``images`` in chunks of the classifier's
    ``batch_size``: one counted pass, then ``repeats`` timed rounds that take every entry in
    turn (so a busy neighbour on a shared machine slows them alike).

    Returns:
        name -> dict: calls, images_encoded, tokens (per image), s_per_image (seconds per
        image, the fastest round), scores ((N, C) array, or None for ``text``).
    """
    out = {}
    for name, (clf, way) in runs.items():
        fn = _way(clf, way)
        chunks = [images[i:i + clf.batch_size] for i in range(0, len(images), clf.batch_size)]
        fn(chunks[0])  # warm-up
        counter = Counter(clf.model)
        try:
            res = [fn(ch) for ch in chunks]
        finally:
            counter.close()
        n = len(images)
        out[name] = {"calls": counter.calls / n, "images_encoded": counter.images / n, "tokens": counter.tokens / n,
                     "s_per_image": float("inf"), "chunks": chunks, "fn": fn,
                     "scores": None if way == "text" else np.concatenate(res, axis=0)}
    for _ in range(repeats):
        for r in out.values():
            t = time.perf_counter()
            for ch in r["chunks"]:
                r["fn"](ch)
            r["s_per_image"] = min(r["s_per_image"], (time.perf_counter() - t) / len(images))
    for r in out.values():
        del r["chunks"], r["fn"]
    return out


def main(argv: list[str] | None = None) -> int:
    """Print the before/after table (see the module docstring); exit 0."""
    ap = cli.ArgumentParser(description="VLM cost per image, before and after the shared prefix (CPU, tiny models)")
    ap.add_argument("--images", type=int, default=16, help="images classified per row")
    ap.add_argument("--batch-size", type=int, default=4, help="images per chunk")
    ap.add_argument("--image-size", type=int, default=224, help="square images, pixels (224: 64 image tokens)")
    ap.add_argument("--layers", type=int, default=2, help="language-model blocks (and vision blocks)")
    ap.add_argument("--width", type=int, default=64, help="hidden size")
    ap.add_argument("--repeats", type=int, default=5, help="timed runs per row; the fastest is reported")
    ap.add_argument("--models", default="qwen,gpt2", help="comma-separated: qwen, gpt2")
    ap.add_argument("--threads", type=int, default=1, help="torch CPU threads (0: torch's default)")
    a = ap.parse_args(argv)
    torch = require_torch()
    if a.threads:
        torch.set_num_threads(a.threads)
    rng = np.random.default_rng(0)
    images = [rng.integers(0, 256, (a.image_size, a.image_size, 3), dtype=np.uint8) for _ in range(a.images)]
    print(f"VLM cost per image: {a.images} random {a.image_size}x{a.image_size} images, batch {a.batch_size}, "
          f"{len(BENCH_CLASSES)} classes, CPU ({torch.get_num_threads()} threads), fastest of {a.repeats}")
    head = (f"{'model':6} {'way':26} {'spellings':>9} {'forward':>8} {'vision':>7} {'LM tokens':>10} "
            f"{'ms/image':>9} {'speed-up':>8} {'max |diff|':>10}")
    print(head)
    print("-" * len(head))
    for name in [m.strip() for m in a.models.split(",") if m.strip()]:
        if name == "qwen":
            model, proc = tiny_qwen(BENCH_CLASSES, layers=a.layers, width=a.width, vision_depth=a.layers,
                                    max_pixels=a.image_size * a.image_size)
        elif name == "gpt2":
            model, proc = tiny_text_lm(BENCH_CLASSES, layers=a.layers, width=a.width)
        else:
            raise SystemExit(f"--models: unknown model {name!r}; expected qwen or gpt2")
        runs = {}
        for spellings in ("plain", "all"):
            clf = VLMClassifier(BENCH_CLASSES, model=model, processor=proc, batch_size=a.batch_size,
                                spellings=spellings, max_new_tokens=4)
            runs[("before", spellings)] = (clf, "before")
            runs[("after", spellings)] = (clf, "after")
        runs[("text", "-")] = (VLMClassifier(BENCH_CLASSES, model=model, processor=proc, batch_size=a.batch_size,
                                             mode="text", max_new_tokens=4), "text")
        res = measure(runs, images, a.repeats)
        for (way, spellings), r in res.items():
            clf = runs[(way, spellings)][0]
            label = {"before": f"before ({len(clf.spelling_table)} sequences/image)", "after": "after (shared prefix)",
                     "text": "text (generate, 4 tokens)"}[way]
            if way == "text":
                speed = diff = ""
            else:
                ref = res[("before", spellings)]
                speed = f"{ref['s_per_image'] / r['s_per_image']:7.1f}x"
                diff = f"{float(np.abs(r['scores'] - ref['scores']).max()):10.1e}"
            print(f"{name:6} {label:26} {spellings:>9} {r['calls']:8.2f} {r['images_encoded']:7.2f} "
                  f"{r['tokens']:10.0f} {1e3 * r['s_per_image']:9.2f} {speed:>8} {diff:>10}")
        old, new = res[("before", "plain")], res[("after", "all")]
        print(f"{name:6} after (all spellings) against before (plain, the classifier as it was): "
              f"{old['s_per_image'] / new['s_per_image']:.1f}x faster per image")
    print("forward: model calls per image; vision: images through the vision encoder per image; "
          "LM tokens: token positions the language model ran per image; speed-up: against 'before' with the same "
          "spellings; "
          "max |diff|: largest score difference from 'before' with the same spellings (natural log)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
