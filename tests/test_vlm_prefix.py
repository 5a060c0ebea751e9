"""VLM scoring: every spelling of a class (case, spaces vs underscores) with the documented
rule (sum of a spelling's token log probabilities, log-sum-exp over a class's spellings),
and the image + prompt encoded once per image, checked against a slow reference that runs
one full, unpadded sequence per (image, spelling) and shares no code with the classifier."""

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("transformers")
pytest.importorskip("tokenizers")

from benchmark.classifiers.vlm import VLMClassifier, class_spellings  # noqa: E402
from benchmark.commands.maintainer.vlm_bench import (  # noqa: E402
    Counter,
    full_sequence_log_likelihoods,
    tiny_qwen,
    tiny_text_lm,
)

CLASSES = ["bathroom", "dining_room", "kitchen"]


def _images(sizes, seed=0):
    rng = np.random.default_rng(seed)
    return [rng.integers(0, 256, (s, s, 3), dtype=np.uint8) for s in sizes]


def _prefer(model, tok, text, bias=10.0):
    """Make the model favour the tokens of ``text`` everywhere (a hook on its output head)."""
    ids = tok(text, add_special_tokens=False)["input_ids"]
    vec = torch.zeros(len(tok))
    vec[ids] = bias
    head = model.get_output_embeddings()
    head.register_forward_hook(lambda m, i, out: out + vec.to(out.dtype))


def _reference(clf, image):
    """(C,) class scores the slow way: for each spelling, one unpadded sequence (chat prefix
    with the image, then the spelling), full logits, its tokens' log probabilities summed by
    hand; per class, log of the sum of its spellings' probabilities."""
    prefix = clf.processor.apply_chat_template(
        [{"role": "user", "content": ([{"type": "image"}, {"type": "text", "text": clf.prompt}] if clf.multimodal
                                      else clf.prompt)}], tokenize=False, add_generation_prompt=True)
    n_prefix_text = len(clf.tokenizer(prefix, add_special_tokens=False)["input_ids"])
    per_class = {k: [] for k in range(len(clf.classes))}
    seen = set()
    for k, c in enumerate(clf.classes):
        for text in class_spellings(c, clf.spellings):
            full_text_ids = clf.tokenizer(prefix + text, add_special_tokens=False)["input_ids"]
            answer = full_text_ids[n_prefix_text:]
            if clf.tokenizer.unk_token_id in answer or tuple(answer) in seen:
                continue
            seen.add(tuple(answer))
            if clf.multimodal:
                enc = clf.processor(text=[prefix + text], images=[image], return_tensors="pt")
            else:
                enc = clf.tokenizer([prefix + text], return_tensors="pt", add_special_tokens=False)
            with torch.inference_mode():
                logits = clf.model(**enc).logits[0].double()
            ids = enc["input_ids"][0].tolist()
            total = 0.0
            for t in range(len(ids) - len(answer), len(ids)):
                row = logits[t - 1]
                total += float(row[ids[t]] - torch.logsumexp(row, 0))
            per_class[k].append(total)
    return np.array([np.log(np.sum(np.exp(per_class[k]))) for k in range(len(clf.classes))])


def test_spellings_of_a_class():
    assert class_spellings("bathroom") == ["bathroom", "Bathroom"]
    assert class_spellings("dining_room") == ["dining room", "Dining room", "Dining Room", "dining_room",
                                              "Dining_room", "Dining_Room"]
    assert class_spellings("dining_room", "plain") == ["dining room"]
    with pytest.raises(ValueError, match="spellings"):
        class_spellings("kitchen", "some")


def test_the_classifier_scores_every_spelling_the_tokenizer_can_write():
    model, tok = tiny_text_lm(CLASSES, layers=1, width=16)
    clf = VLMClassifier(CLASSES, model=model, processor=tok)
    table = [(k, text, len(ids)) for k, text, ids in clf.spelling_table]
    assert table == [(0, "bathroom", 1), (0, "Bathroom", 1), (1, "dining room", 2), (1, "Dining room", 2),
                     (1, "Dining Room", 2), (1, "dining_room", 1), (1, "Dining_room", 1), (1, "Dining_Room", 1),
                     (2, "kitchen", 1), (2, "Kitchen", 1)]
    assert [t for _, t, _ in VLMClassifier(CLASSES, model=model, processor=tok, spellings="plain").spelling_table] \
        == ["bathroom", "dining room", "kitchen"]


@pytest.mark.parametrize("answer,want", [("Bathroom", 0), ("Kitchen", 2), ("Dining Room", 1), ("dining_room", 1)])
def test_a_capitalised_or_underscored_answer_picks_its_class(answer, want):
    model, tok = tiny_text_lm(CLASSES, layers=1, width=16)
    _prefer(model, tok, answer)
    p = VLMClassifier(CLASSES, model=model, processor=tok).predict_images(_images([16, 16]))
    assert (p.argmax(1) == want).all() and (p[:, want] > 0.9).all(), p


def test_scores_are_probabilities_of_the_answer_text():
    """Summed token log probabilities are probabilities of disjoint answer texts: over every
    spelling of every class they add up to at most 1 (a per-token mean would not be)."""
    model, tok = tiny_text_lm(CLASSES, layers=1, width=16)
    s = VLMClassifier(CLASSES, model=model, processor=tok).class_log_likelihoods(_images([16]))
    assert s.shape == (1, 3) and (s < 0).all() and np.exp(s).sum() <= 1.0


@pytest.mark.parametrize("spellings", ["all", "plain"])
def test_text_lm_scores_equal_the_full_sequence_reference(spellings):
    model, tok = tiny_text_lm(CLASSES, layers=2, width=32)
    clf = VLMClassifier(CLASSES, model=model, processor=tok, batch_size=3, spellings=spellings)
    imgs = _images([16, 16, 16])
    s = clf.class_log_likelihoods(imgs)
    assert np.allclose(s[0], _reference(clf, imgs[0]), atol=1e-5, rtol=0)
    assert np.allclose(s, full_sequence_log_likelihoods(clf, imgs), atol=1e-5, rtol=0)


@pytest.mark.parametrize("spellings", ["all", "plain"])
def test_qwen25_vl_scores_equal_the_full_sequence_reference_with_padding(spellings):
    """Images of different sizes give prefixes of different lengths (4 and 16 image tokens):
    left padding, 3D rope positions carried on from each image's prefix."""
    model, proc = tiny_qwen(CLASSES, layers=2, width=32, vision_depth=1, max_pixels=56 * 56)
    clf = VLMClassifier(CLASSES, model=model, processor=proc, batch_size=3, spellings=spellings)
    imgs = _images([28, 56, 40], seed=1)
    s = clf.class_log_likelihoods(imgs)
    for i in range(3):
        assert np.allclose(s[i], _reference(clf, imgs[i]), atol=1e-5, rtol=0), i
    assert np.allclose(s, full_sequence_log_likelihoods(clf, imgs), atol=1e-5, rtol=0)
    assert not np.allclose(s[0], s[1], atol=1e-6)  # the image changes the scores
    one = VLMClassifier(CLASSES, model=model, processor=proc, batch_size=1, spellings=spellings)
    assert np.allclose(one.predict_images(imgs), clf.predict_images(imgs), atol=1e-6)


def test_the_vision_encoder_runs_once_per_image():
    model, proc = tiny_qwen(CLASSES, layers=1, width=32, vision_depth=1, max_pixels=56 * 56)
    clf = VLMClassifier(CLASSES, model=model, processor=proc, batch_size=4)
    imgs = _images([28] * 6)
    counter = Counter(model)
    try:
        clf.predict_images(imgs)
    finally:
        counter.close()
    assert counter.images == 6  # once per image, not once per class or spelling
    assert counter.calls == 4  # chunks of 4 + 2 images: prefix pass + spelling pass each
    before = Counter(model)
    try:
        full_sequence_log_likelihoods(clf, imgs[:2])
    finally:
        before.close()
    assert before.images == 2 * len(clf.spelling_table)
    text = VLMClassifier(CLASSES, model=model, processor=proc, batch_size=4, mode="text", max_new_tokens=3)
    counter = Counter(model)
    try:
        text.predict_images(imgs[:4])
    finally:
        counter.close()
    assert counter.images == 4 and counter.calls == 3  # generate: the image once, then one call per new token


def test_spelling_errors_are_one_line():
    model, tok = tiny_text_lm(CLASSES, layers=1, width=16)
    with pytest.raises(ValueError, match="cannot write class 'garage'") as e:
        VLMClassifier([*CLASSES, "garage"], model=model, processor=tok)
    assert "\n" not in str(e.value)
    with pytest.raises(ValueError, match="'dining_room' and 'Dining_Room' have a spelling with the same tokens"):
        VLMClassifier([*CLASSES, "Dining_Room"], model=model, processor=tok)
    with pytest.raises(ValueError, match="spellings"):
        VLMClassifier(CLASSES, model=model, processor=tok, spellings="upper")


@pytest.mark.slow
def test_the_bench_command_prints_before_and_after(capsys):
    from benchmark.commands.maintainer.vlm_bench import main

    assert main(["--images", "2", "--batch-size", "2", "--image-size", "28", "--repeats", "1", "--layers", "1",
                 "--width", "32"]) == 0
    out = capsys.readouterr().out
    rows = [line.split() for line in out.splitlines() if line.startswith(("qwen", "gpt2")) and "against" not in line]
    assert len(rows) == 10 and out.count("against before (plain, the classifier as it was)") == 2
    qwen_after = next(r for r in rows if r[0] == "qwen" and r[1] == "after" and r[4] == "all")
    assert float(qwen_after[6]) == 1.0 and float(qwen_after[-1]) < 1e-4  # vision once per image, same scores
