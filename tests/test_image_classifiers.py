"""Image classifiers (CNN, DINOv2 + MLP, VLM) on CPU with tiny random-initialised models
built from configs: no downloads. The VLM scoring is checked against an unbatched,
unpadded reference that reads each class name's log probability token by token."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

try:
    import torch
    import torchvision  # noqa: F401
except ImportError:  # the core suite runs without torch: only the import test below runs
    torch = None

from envs.render.observation import Observation

needs_torch = pytest.mark.skipif(torch is None, reason="torch/torchvision not installed")
REPO = Path(__file__).resolve().parents[1]
CLASSES = ["bathroom", "bedroom", "kitchen"]


def test_modules_import_without_torch_and_say_what_to_install():
    code = (
        "import sys\n"
        "for m in ('torch', 'torchvision', 'transformers'): sys.modules[m] = None\n"
        "import benchmark.classifiers.cnn as cnn, benchmark.classifiers.dinov2, benchmark.classifiers.vlm\n"
        "import benchmark.classifiers.train, benchmark.classifiers.evaluate, benchmark.classifiers.places\n"
        "try:\n"
        "    cnn.CNNClassifier(checkpoint='x.pt')\n"
        "except ImportError as e:\n"
        "    print(str(e))\n"
    )
    r = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    lines = r.stdout.strip().splitlines()
    assert len(lines) == 1 and "need torch" in lines[0] and "roomseg-bench[models]" in lines[0]


# ---------------------------------------------------------------- data helpers

def _images(n, seed=0, size=32):
    rng = np.random.default_rng(seed)
    return [rng.integers(0, 256, (size, size, 3), dtype=np.uint8) for _ in range(n)]


def _coloured(n_per_class, size=32, seed=0):
    """Class k images are dominated by colour channel k (an easy, learnable task)."""
    rng = np.random.default_rng(seed)
    items = []
    for k in range(len(CLASSES)):
        for _ in range(n_per_class):
            img = rng.integers(0, 60, (size, size, 3), dtype=np.uint8)
            img[..., k] = rng.integers(180, 256, (size, size), dtype=np.uint8)
            items.append((img, k))
    return items


def _image_folder(root, n_per_class, size=32, seed=0):
    from PIL import Image

    for i, (img, k) in enumerate(_coloured(n_per_class, size, seed)):
        (root / CLASSES[k]).mkdir(parents=True, exist_ok=True)
        Image.fromarray(img).save(root / CLASSES[k] / f"{i:04d}.png")
    return root


# ---------------------------------------------------------------- CNN

@needs_torch
def test_cnn_shapes_batching_and_checkpoint_round_trip(tmp_path):
    from benchmark.classifiers.cnn import CNNClassifier
    from benchmark.classifiers.torch_common import save_checkpoint

    torch.manual_seed(0)
    clf = CNNClassifier(CLASSES, arch="resnet18", pretrained=False, device="cpu", batch_size=4, image_size=32,
                        allow_untrained=True)
    imgs = _images(6)
    p = clf.predict_proba([Observation(pose=(0, 0, 0), image=im) for im in imgs])
    assert p.shape == (6, 3) and np.allclose(p.sum(1), 1)
    assert np.allclose(np.concatenate([clf.predict_images([im]) for im in imgs]), p, atol=1e-5)
    save_checkpoint(tmp_path / "c.pt", clf.model, CLASSES, {"arch": "resnet18"})
    again = CNNClassifier(CLASSES, checkpoint=str(tmp_path / "c.pt"), arch="resnet18", pretrained=False,
                          device="cpu", image_size=32)
    assert np.allclose(again.predict_images(imgs), p, atol=1e-5)
    with pytest.raises(ValueError, match="trained for classes"):
        CNNClassifier(["a", "b", "c"], checkpoint=str(tmp_path / "c.pt"), arch="resnet18", device="cpu")
    with pytest.raises(ValueError, match="arch='resnet18', the config asks for 'resnet34'"):
        CNNClassifier(CLASSES, checkpoint=str(tmp_path / "c.pt"), arch="resnet34", device="cpu")
    with pytest.raises(ValueError, match="checkpoint is not set"):
        CNNClassifier(CLASSES, arch="resnet18", pretrained=False, device="cpu")
    with pytest.raises(FileNotFoundError, match="checkpoint not found"):
        CNNClassifier(CLASSES, checkpoint=str(tmp_path / "nope.pt"), arch="resnet18", device="cpu")
    with pytest.raises(ValueError, match="observation 1 has no image"):
        clf.predict_proba([Observation(pose=(0, 0, 0), image=imgs[0]), Observation(pose=(0, 0, 0))])
    with pytest.raises(ValueError, match=r"observation 0: image must be \(H, W, 3\)"):
        clf.predict_proba([Observation(pose=(0, 0, 0), image=imgs[0][..., 0])])


@pytest.mark.slow
@needs_torch
def test_train_and_table1_commands_on_a_generated_image_folder(tmp_path, capsys):
    from benchmark.classifiers import train
    from benchmark.classifiers.cnn import CNNClassifier
    from benchmark.classifiers.places import list_images, split
    from benchmark.commands import evaluate
    from benchmark.commands import train as train_cmd

    data = _image_folder(tmp_path / "data", 12)
    tiny = ["arch=resnet18", "pretrained=false", "image_size=32", "device=cpu", f"classes=[{','.join(CLASSES)}]"]
    ck = tmp_path / "cnn.pt"
    rc = train_cmd.main(["--model", "cnn", "--data", str(data), "--out", str(ck), "--epochs", "3", "--batch-size", "8",
                     "--lr", "1e-3", "--split-sizes", "8,2,2", "--workers", "0", *tiny])
    assert rc == 0 and ck.exists()
    hist = json.loads(train.history_path(ck).read_text())
    losses = [x for h in hist for x in h["losses"]]
    assert len(hist) == 3 and len(losses) == 9  # 24 training images, batches of 8, 3 epochs
    assert np.mean(losses[-3:]) < np.mean(losses[:3])
    kept = torch.load(ck, weights_only=True)["extra"]
    assert kept["val_accuracy"] == max(h["val_accuracy"] for h in hist)  # validation-based choice

    out = tmp_path / "table1"
    rc = evaluate.main(["--model", "cnn", "--data", str(data), "--checkpoint", str(ck), "--split-sizes", "8,2,2",
                        "--workers", "0", "--out", str(out), "batch_size=4", *tiny])
    assert rc == 0
    rec = json.loads((out / "table1_cnn.json").read_text())
    assert rec["n_images"] == 6 and (out / "confusion_cnn.png").stat().st_size > 1000
    assert "| cnn |" in (out / "table1.md").read_text()
    # the same numbers straight from the classifier on the same seeded test split
    test = split(list_images(data, CLASSES), CLASSES, 8, 2, 2, seed=0)["test"]
    clf = CNNClassifier(CLASSES, checkpoint=str(ck), arch="resnet18", device="cpu", image_size=32)
    from benchmark.classifiers.places import load_rgb

    pred = clf.predict_images([load_rgb(p) for p, _ in test]).argmax(1)
    assert rec["accuracy"] == pytest.approx(np.mean(pred == [k for _, k in test]))
    assert np.array(rec["confusion"]).sum() == 6

    capsys.readouterr()
    rc = evaluate.main(["--model", "cnn", "--data", str(data), "--checkpoint", str(tmp_path / "missing.pt"),
                        "--workers", "0", *tiny])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "checkpoint not found" in err[0]


# ---------------------------------------------------------------- DINOv2

TINY_DINO = {"hidden_size": 32, "num_hidden_layers": 1, "num_attention_heads": 2, "intermediate_size": 64,
             "image_size": 28, "patch_size": 14}


@needs_torch
def test_dinov2_features_cache_batching_and_head(tmp_path, monkeypatch):
    pytest.importorskip("transformers")
    from benchmark.classifiers.dinov2 import DinoV2Classifier
    from benchmark.classifiers.train import train_mlp

    torch.manual_seed(0)
    kw = {"backbone_config": TINY_DINO, "device": "cpu", "image_size": 28, "feature_cache": str(tmp_path / "f")}
    clf = DinoV2Classifier(CLASSES, allow_untrained=True, batch_size=3, **kw)
    imgs = _images(5, size=40)
    f = clf.features(imgs + imgs[:1])  # a repeated image is computed once
    assert f.shape == (6, 32) and np.array_equal(f[0], f[5])
    files = list((tmp_path / "f").rglob("*.npz"))
    assert len(files) == 5 and files[0].parent.name == "28px" and files[0].parent.parent.name.startswith("config-")
    p = clf.predict_images(imgs)
    assert p.shape == (5, 3) and np.allclose(p.sum(1), 1)
    assert np.allclose(np.concatenate([clf.predict_images([im]) for im in imgs]), p, atol=1e-5)
    from benchmark.classifiers.evaluate import throughput

    n0 = len(clf._mem)
    assert throughput(clf, 2)["n_images"] == 2 and len(clf._mem) == n0 + 2 + 3  # timed images never cached before
    # a fresh classifier reads the disk cache and never runs the backbone on those images
    again = DinoV2Classifier(CLASSES, allow_untrained=True, **kw)
    monkeypatch.setattr(again, "backbone", lambda **_: pytest.fail("backbone ran on a cached image"))
    assert np.allclose(again.features(imgs), f[:5])

    items = _coloured(10, size=28)
    hist = train_mlp(items, items[::5], tmp_path / "head.pt", CLASSES, backbone_config=TINY_DINO, hidden=(16, 16),
                     epochs=30, batch_size=8, lr=1e-2, image_size=28, device="cpu")
    assert hist[-1]["loss"] < hist[0]["loss"]
    trained = DinoV2Classifier(CLASSES, head_checkpoint=str(tmp_path / "head.pt"), backbone_config=TINY_DINO,
                               hidden=(16, 16), device="cpu", image_size=28)
    assert trained.predict_images([im for im, _ in items]).shape == (30, 3)
    with pytest.raises(ValueError, match="hidden"):
        DinoV2Classifier(CLASSES, head_checkpoint=str(tmp_path / "head.pt"), backbone_config=TINY_DINO,
                         hidden=(16, 8), device="cpu", image_size=28)


# ---------------------------------------------------------------- VLM

PROMPT_WORDS = "What type of room is shown in this image? Answer with exactly one of: user: assistant:".split()


def _words(classes):
    return PROMPT_WORDS + [w for c in classes for w in c.split("_")] + \
        [c.replace("_", " ").split()[-1] + p for c in classes for p in ".,"]


def _prefer(model, vocab, words):
    ids = [vocab[w] for w in words.split()]
    bias = 8.0 * torch.nn.functional.one_hot(torch.tensor(ids), len(vocab)).sum(0).float()
    model.lm_head.register_forward_hook(lambda m, i, out: out + bias.to(out.dtype))


def _tiny_lm(words, prefer=None):
    """A 1-layer GPT-2 and a word-level tokenizer with a chat template, built offline."""
    transformers = pytest.importorskip("transformers")
    tokenizers = pytest.importorskip("tokenizers")
    vocab = {w: i for i, w in enumerate(["[PAD]", "[UNK]", *sorted(set(words))])}
    tk = tokenizers.Tokenizer(tokenizers.models.WordLevel(vocab, unk_token="[UNK]"))
    tk.pre_tokenizer = tokenizers.pre_tokenizers.WhitespaceSplit()
    tk.decoder = tokenizers.decoders.WordPiece()  # joins words with spaces
    tok = transformers.PreTrainedTokenizerFast(tokenizer_object=tk, pad_token="[PAD]", unk_token="[UNK]",
                                               eos_token="[PAD]")
    tok.chat_template = "{% for m in messages %}user: {{ m['content'] }} {% endfor %}assistant: "
    torch.manual_seed(0)
    model = transformers.GPT2LMHeadModel(transformers.GPT2Config(vocab_size=len(vocab), n_positions=128, n_embd=16,
                                                                  n_layer=1, n_head=2)).eval()
    if prefer:
        _prefer(model, vocab, prefer)
    return model, tok


def _tiny_qwen(classes, prefer=None):
    """A 1-layer Qwen2.5-VL (vision and text), its image processor and a word-level tokenizer
    with Qwen's special tokens and a Qwen-like chat template, all built offline."""
    transformers = pytest.importorskip("transformers")
    tokenizers = pytest.importorskip("tokenizers")
    special = ["[PAD]", "[UNK]", "<|im_start|>", "<|im_end|>", "<|vision_start|>", "<|vision_end|>",
               "<|image_pad|>", "<|video_pad|>"]
    vocab = {w: i for i, w in enumerate(special + sorted(set(_words(classes)) | {"system"}))}
    tk = tokenizers.Tokenizer(tokenizers.models.WordLevel(vocab, unk_token="[UNK]"))
    tk.pre_tokenizer = tokenizers.pre_tokenizers.WhitespaceSplit()
    tk.decoder = tokenizers.decoders.WordPiece()
    tok = transformers.PreTrainedTokenizerFast(tokenizer_object=tk, pad_token="[PAD]", unk_token="[UNK]",
                                               eos_token="<|im_end|>", additional_special_tokens=special[2:])
    chat = ("{% for m in messages %}<|im_start|> {{ m['role'] }}: {% if m['content'] is string %}{{ m['content'] }}"
            "{% else %}{% for c in m['content'] %}{% if c['type'] == 'image' %}<|vision_start|> <|image_pad|> "
            "<|vision_end|> {% else %}{{ c['text'] }}{% endif %}{% endfor %}{% endif %} <|im_end|> {% endfor %}"
            "{% if add_generation_prompt %}<|im_start|> assistant: {% endif %}")
    proc = transformers.Qwen2_5_VLProcessor(
        image_processor=transformers.Qwen2VLImageProcessor(min_pixels=28 * 28, max_pixels=56 * 56),
        tokenizer=tok, video_processor=transformers.Qwen2VLVideoProcessor(), chat_template=chat)
    cfg = transformers.Qwen2_5_VLConfig(
        text_config={"vocab_size": len(vocab), "hidden_size": 32, "intermediate_size": 64, "num_hidden_layers": 1,
                     "num_attention_heads": 2, "num_key_value_heads": 1, "max_position_embeddings": 256,
                     "rope_parameters": {"rope_type": "default", "mrope_section": [2, 3, 3], "rope_theta": 1e4},
                     "bos_token_id": None, "eos_token_id": vocab["<|im_end|>"], "pad_token_id": 0},
        vision_config={"depth": 1, "hidden_size": 32, "intermediate_size": 64, "num_heads": 2, "out_hidden_size": 32,
                       "patch_size": 14, "spatial_merge_size": 2, "temporal_patch_size": 2,
                       "fullatt_block_indexes": [0], "window_size": 56},
        image_token_id=vocab["<|image_pad|>"], video_token_id=vocab["<|video_pad|>"],
        vision_start_token_id=vocab["<|vision_start|>"], vision_end_token_id=vocab["<|vision_end|>"])
    torch.manual_seed(0)
    model = transformers.Qwen2_5_VLForConditionalGeneration(cfg).eval()
    if prefer:
        _prefer(model, vocab, prefer)
    return model, proc


def _reference_log_likelihoods(clf, image):
    """(C,) log P(name | prompt, image), one unpadded sequence per class, full logits."""
    out = []
    for c in clf.classes:
        text = clf.chat_prefix() + c.replace("_", " ")
        if clf.multimodal:
            enc = clf.processor(text=[text], images=[image], return_tensors="pt")
        else:
            enc = clf.tokenizer([text], return_tensors="pt", add_special_tokens=False)
        n = len(clf.tokenizer(c.replace("_", " "), add_special_tokens=False)["input_ids"])
        with torch.inference_mode():
            logp = torch.log_softmax(clf.model(**enc).logits[0].float(), -1)
        ids = enc["input_ids"][0]
        out.append(sum(float(logp[t - 1, ids[t]]) for t in range(len(ids) - n, len(ids))))
    return np.array(out)


@needs_torch
def test_vlm_scoring_matches_the_reference_and_picks_the_preferred_class():
    from benchmark.classifiers.vlm import VLMClassifier

    classes = ["bathroom", "dining_room", "kitchen"]
    model, tok = _tiny_lm(_words(classes))
    imgs = _images(3)
    batched = VLMClassifier(classes, model=model, processor=tok, batch_size=2)
    s = batched.class_log_likelihoods(imgs[:2])
    assert s.shape == (2, 3) and np.allclose(s[0], _reference_log_likelihoods(batched, imgs[0]), atol=1e-4)
    p = batched.predict_proba([Observation(pose=(0, 0, 0), image=im) for im in imgs])
    one = VLMClassifier(classes, model=model, processor=tok, batch_size=1).predict_images(imgs)
    assert p.shape == (3, 3) and np.allclose(p.sum(1), 1) and np.allclose(p, one, atol=1e-5)

    model, tok = _tiny_lm(_words(classes), prefer="dining room")
    p = VLMClassifier(classes, model=model, processor=tok).predict_images(imgs)
    assert (p.argmax(1) == 1).all() and (p[:, 1] > 0.9).all()


@needs_torch
def test_vlm_text_mode_parses_and_falls_back_to_uniform():
    from benchmark.classifiers.vlm import VLMClassifier

    classes = ["bathroom", "dining_room", "kitchen"]
    model, tok = _tiny_lm(_words(classes), prefer="kitchen")
    text = VLMClassifier(classes, model=model, processor=tok, mode="text", max_new_tokens=3, batch_size=2)
    assert text.answer(_images(1)[0]).split()[0] == "kitchen"
    p = text.predict_images(_images(3))
    assert (p == np.eye(3)[[2, 2, 2]]).all() and not text.last_flags.any()
    model, tok = _tiny_lm(_words(classes), prefer="room")  # "room room room" names no class
    vague = VLMClassifier(classes, model=model, processor=tok, mode="text", max_new_tokens=3)
    p = vague.predict_images(_images(2))
    assert np.allclose(p, 1 / 3) and vague.last_flags.all() and vague.n_unparsed == 2


@needs_torch
def test_qwen25_vl_scoring_sees_the_image_batches_and_picks_the_preferred_class():
    from benchmark.classifiers.vlm import VLMClassifier

    classes = ["bathroom", "dining_room", "kitchen"]
    model, proc = _tiny_qwen(classes)
    clf = VLMClassifier(classes, model=model, processor=proc, batch_size=3)
    assert clf.multimodal and "<|image_pad|>" in clf.chat_prefix() and "dining room, kitchen." in clf.chat_prefix()
    imgs = _images(1, size=40) + _images(1, seed=5, size=56) + _images(2, seed=1, size=40)
    s = clf.class_log_likelihoods(imgs[:3])  # 1 and 4 image tokens: padded to one length
    for i in range(3):
        assert np.allclose(s[i], _reference_log_likelihoods(clf, imgs[i]), atol=1e-4)
    assert not np.allclose(s[0], s[1], atol=1e-6)  # the image changes the scores
    p = clf.predict_images(imgs)
    one = VLMClassifier(classes, model=model, processor=proc, batch_size=1).predict_images(imgs)
    assert np.allclose(p.sum(1), 1) and np.allclose(p, one, atol=1e-5)

    model, proc = _tiny_qwen(classes, prefer="dining room")
    p = VLMClassifier(classes, model=model, processor=proc).predict_images(imgs)
    assert (p.argmax(1) == 1).all()


@needs_torch
def test_vlm_prompt_follows_the_class_list_and_parsing():
    from benchmark.classifiers.vlm import VLMClassifier, parse_answer
    from benchmark.config import classifier_config

    classes = ["bathroom", "kitchen"]
    model, tok = _tiny_lm(_words(classes + ["garage"]))
    a = VLMClassifier(classes, model=model, processor=tok)
    b = VLMClassifier(classes + ["garage"], model=model, processor=tok)
    assert "bathroom, kitchen." in a.prompt and "bathroom, kitchen, garage." in b.prompt and "garage" not in a.prompt
    assert b.chat_prefix().startswith("user: What type")
    cfg = classifier_config("vlm", ["classes=[kitchen,garage,wine_cellar]"])
    assert list(cfg.classifier.classes) == ["kitchen", "garage", "wine_cellar"] and "{options}" in cfg.classifier.prompt
    assert parse_answer("It is a Living-Room, not a kitchen", ["kitchen", "living_room"]) == 1
    assert parse_answer("Bathrooms.", ["kitchen", "bathroom"]) == 1
    assert parse_answer("a dining\nroom", ["kitchen", "dining_room"]) == 1
    assert parse_answer("the kitchenette", ["kitchen"]) == -1
    assert parse_answer("no idea", ["kitchen"]) == -1
    with pytest.raises(ValueError, match="options"):
        VLMClassifier(classes, model=model, processor=tok, prompt="Which room?")
    with pytest.raises(ValueError, match="only use the"):
        VLMClassifier(classes, model=model, processor=tok, prompt="{options} or {other}")


# ---------------------------------------------------------------- errors, metrics, data

@needs_torch
def test_missing_gpu_and_missing_downloads_are_one_line(tmp_path, monkeypatch):
    import torchvision.models._api as tv_api

    from benchmark.classifiers.cnn import build_resnet
    from benchmark.classifiers.torch_common import pick_device
    from benchmark.classifiers.vlm import VLMClassifier

    if not torch.cuda.is_available():
        with pytest.raises(RuntimeError, match="no CUDA GPU"):
            pick_device("cuda")

    def offline(*a, **k):
        raise OSError("network is unreachable")

    monkeypatch.setattr(tv_api, "load_state_dict_from_url", offline)
    with pytest.raises(RuntimeError) as e:
        build_resnet("resnet18", 7, pretrained=True)
    assert "TORCH_HOME" in str(e.value) and "\n" not in str(e.value)
    empty = tmp_path / "no-model"
    empty.mkdir()
    pytest.importorskip("transformers")
    with pytest.raises(RuntimeError) as e:
        VLMClassifier(CLASSES, model_id=str(empty), device="cpu")
    assert "could not load" in str(e.value) and "\n" not in str(e.value)


def test_table1_metrics_by_hand(tmp_path):
    from benchmark.classifiers.evaluate import table1_metrics
    from benchmark.reports.confusion import confusion_figure

    m = table1_metrics([0, 0, 1, 1, 2, 2], [0, 1, 1, 1, 2, 0], 3)
    # precision: c0 1/2, c1 2/3, c2 1/1; recall: c0 1/2, c1 1, c2 1/2
    assert m["precision"] == pytest.approx((0.5 + 2 / 3 + 1) / 3)
    assert m["recall"] == pytest.approx((0.5 + 1 + 0.5) / 3)
    assert m["accuracy"] == pytest.approx(4 / 6)
    f1 = [0.5, 2 * (2 / 3) / (2 / 3 + 1), 2 * 0.5 / 1.5]
    assert m["f1"] == pytest.approx(np.mean(f1))
    assert m["confusion"].tolist() == [[1, 1, 0], [0, 2, 0], [1, 0, 1]]
    with pytest.raises(ValueError):
        table1_metrics([], [], 3)
    with pytest.raises(ValueError, match="0..2"):
        table1_metrics([0, 3], [0, 1], 3)
    confusion_figure(m["confusion"], CLASSES, tmp_path / "cm.png", "test")
    assert (tmp_path / "cm.png").stat().st_size > 1000


def test_places_split_is_seeded_and_disjoint(tmp_path):
    from PIL import Image

    from benchmark.classifiers.places import list_images, split

    for c in CLASSES:
        (tmp_path / c).mkdir()
        for i in range(20):
            Image.fromarray(np.zeros((4, 4, 3), np.uint8)).save(tmp_path / c / f"{i}.png")
    imgs = list_images(tmp_path, CLASSES)
    a = split(imgs, CLASSES, n_train=8, n_val=1, n_test=1, seed=3)
    b = split(imgs, CLASSES, n_train=8, n_val=1, n_test=1, seed=3)
    c = split(imgs, CLASSES, n_train=8, n_val=1, n_test=1, seed=4)
    assert a == b and a != c
    assert len(a["train"]) == 3 * 8 and len(a["val"]) == len(a["test"]) == 3  # 10 of 20 per class
    paths = [p for part in a.values() for p, _ in part]
    assert len(set(paths)) == len(paths)
    assert all(p.parent.name == CLASSES[k] for part in a.values() for p, k in part)
    small = split(imgs, CLASSES, n_train=40, n_val=5, n_test=5)  # only 20 per class: same proportions
    assert [len(small[s]) for s in ("train", "val", "test")] == [3 * 16, 3 * 2, 3 * 2]
    with pytest.raises(FileNotFoundError, match="no images for class"):
        list_images(tmp_path, ["garage"])
    with pytest.raises(ValueError, match="no Places365 category"):
        list_images(tmp_path, ["garage"], places365=True)


def _places_tree(root, with_devkit):
    """A miniature Places365: both balcony categories, bathroom, and a category we do not use."""
    from PIL import Image

    cats = ["/a/airfield", "/b/balcony/exterior", "/b/balcony/interior", "/b/bathroom"]
    lines = []
    for idx, cat in enumerate(cats):
        for i in range(3):
            lines.append(f"{cat}/{i + 1:08d}.jpg {idx}")
    if with_devkit:
        (root / "categories_places365.txt").write_text("".join(f"{c} {i}\n" for i, c in enumerate(cats)))
        (root / "places365_train_standard.txt").write_text("\n".join(lines) + "\n")
    return lines, lambda image_dir: [
        (image_dir / line.split()[0].lstrip("/")).parent.mkdir(parents=True, exist_ok=True)
        or Image.fromarray(np.zeros((4, 4, 3), np.uint8)).save(image_dir / line.split()[0].lstrip("/"))
        for line in lines]


def test_places365_image_folder_layout(tmp_path):
    from benchmark.classifiers.places import list_images

    _, make = _places_tree(tmp_path, with_devkit=False)
    make(tmp_path)
    got = list_images(tmp_path, ["balcony", "bathroom"], places365=True)
    assert len(got["balcony"]) == 6 and {p.parent.name for p in got["balcony"]} == {"exterior", "interior"}
    assert len(got["bathroom"]) == 3
    with pytest.raises(FileNotFoundError, match="no images for class 'kitchen'"):
        list_images(tmp_path, ["bathroom", "kitchen"], places365=True)


@needs_torch
def test_places365_torchvision_root(tmp_path, monkeypatch):
    from torchvision.datasets import Places365

    from benchmark.classifiers.places import list_images

    _, make = _places_tree(tmp_path, with_devkit=True)
    # our miniature devkit files cannot have the real md5 sums torchvision checks
    monkeypatch.setattr(Places365, "_check_integrity", lambda self, *a, **k: True)
    with pytest.raises(FileNotFoundError, match="extract train_256_places365standard.tar"):
        list_images(tmp_path, ["balcony", "bathroom"], places365=True)
    image_dir = Path(Places365(str(tmp_path), split="train-standard", small=True, download=False).images_dir)
    make(image_dir)
    got = list_images(tmp_path, ["balcony", "bathroom"], places365=True)
    assert len(got["balcony"]) == 6 and len(got["bathroom"]) == 3 and all(p.exists() for p in got["balcony"])
