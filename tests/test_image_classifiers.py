"""Image classifiers on CPU with tiny random-initialised models (no downloads)."""

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("torchvision")

from benchmark.classifiers.evaluate import table1_metrics  # noqa: E402
from benchmark.classifiers.torch_common import save_checkpoint  # noqa: E402
from envs.observation import Observation  # noqa: E402

CLASSES = ["bathroom", "bedroom", "kitchen"]


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


def test_cnn_shapes_batching_and_checkpoint(tmp_path):
    from benchmark.classifiers.cnn import CNNClassifier

    torch.manual_seed(0)
    clf = CNNClassifier(CLASSES, arch="resnet18", pretrained=False, device="cpu", batch_size=4, image_size=32,
                        allow_untrained=True)
    imgs = _images(6)
    p = clf.predict_proba([Observation(pose=(0, 0, 0), image=im) for im in imgs])
    assert p.shape == (6, 3) and np.allclose(p.sum(1), 1)
    one = np.concatenate([clf.predict_images([im]) for im in imgs])
    assert np.allclose(p, one, atol=1e-5)
    save_checkpoint(tmp_path / "c.pt", clf.model, CLASSES)
    again = CNNClassifier(CLASSES, checkpoint=str(tmp_path / "c.pt"), arch="resnet18", pretrained=False,
                          device="cpu", image_size=32)
    assert np.allclose(again.predict_images(imgs), p, atol=1e-5)
    with pytest.raises(ValueError, match="trained for classes"):
        CNNClassifier(["a", "b", "c"], checkpoint=str(tmp_path / "c.pt"), arch="resnet18", pretrained=False,
                      device="cpu", image_size=32)
    with pytest.raises(ValueError, match="checkpoint is not set"):
        CNNClassifier(CLASSES, arch="resnet18", pretrained=False, device="cpu")
    with pytest.raises(ValueError, match="observation 1 has no image"):
        clf.predict_proba([Observation(pose=(0, 0, 0), image=imgs[0]), Observation(pose=(0, 0, 0))])


def test_cnn_training_reduces_loss(tmp_path):
    from benchmark.classifiers.train import train_cnn

    items = _coloured(8)
    hist = train_cnn(items, items[::4], tmp_path / "cnn.pt", CLASSES, arch="resnet18", pretrained=False, epochs=3,
                     batch_size=8, lr=1e-3, image_size=32, device="cpu")
    losses = [x for h in hist for x in h["losses"]]
    assert np.mean(losses[-3:]) < np.mean(losses[:3])
    assert (tmp_path / "cnn.pt").exists()


TINY_DINO = {"hidden_size": 32, "num_hidden_layers": 1, "num_attention_heads": 2, "intermediate_size": 64,
             "image_size": 28, "patch_size": 14}


def test_dinov2_features_cache_and_head(tmp_path):
    pytest.importorskip("transformers")
    from benchmark.classifiers.dinov2 import DinoV2Classifier
    from benchmark.classifiers.train import train_mlp

    torch.manual_seed(0)
    clf = DinoV2Classifier(CLASSES, backbone_config=TINY_DINO, device="cpu", image_size=28,
                           feature_cache=str(tmp_path / "f"), allow_untrained=True, batch_size=3)
    imgs = _images(5, size=40)
    f = clf.features(imgs)
    assert f.shape == (5, 32) and len(list((tmp_path / "f").glob("*.npy"))) == 5
    p = clf.predict_images(imgs)
    assert p.shape == (5, 3) and np.allclose(p.sum(1), 1)
    assert np.allclose(np.concatenate([clf.predict_images([im]) for im in imgs]), p, atol=1e-5)
    items = _coloured(10, size=28)
    hist = train_mlp(items, items[::5], tmp_path / "head.pt", CLASSES, backbone_config=TINY_DINO, hidden=(16, 16),
                     epochs=30, batch_size=8, lr=1e-2, image_size=28, device="cpu")
    assert hist[-1]["loss"] < hist[0]["loss"]
    trained = DinoV2Classifier(CLASSES, head_checkpoint=str(tmp_path / "head.pt"), backbone_config=TINY_DINO,
                               hidden=(16, 16), device="cpu", image_size=28)
    assert trained.predict_images([im for im, _ in items]).shape == (30, 3)


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
        ids = [vocab[w] for w in prefer.split()]
        model.lm_head.register_forward_hook(lambda m, i, out: out + 8.0 * torch.nn.functional.one_hot(
            torch.tensor(ids), len(vocab)).sum(0).float())
    return model, tok


PROMPT_WORDS = "What type of room is shown in this image? Answer with exactly one of: user: assistant:".split()


def _words(classes):
    return PROMPT_WORDS + [w.strip(",.") for c in classes for w in c.split("_")] + \
        [c.replace("_", " ").split()[-1] + "." for c in classes] + [c.replace("_", " ").split()[-1] + "," for c in classes]


def test_vlm_scoring_picks_the_preferred_class():
    from benchmark.classifiers.vlm import VLMClassifier

    classes = ["bathroom", "dining_room", "kitchen"]
    model, tok = _tiny_lm(_words(classes), prefer="dining room")
    clf = VLMClassifier(classes, model=model, processor=tok)
    p = clf.predict_proba([Observation(pose=(0, 0, 0), image=im) for im in _images(3)])
    assert p.shape == (3, 3) and np.allclose(p.sum(1), 1)
    assert (p.argmax(1) == 1).all()
    model2, tok2 = _tiny_lm(_words(classes), prefer="kitchen")
    text = VLMClassifier(classes, model=model2, processor=tok2, mode="text", max_new_tokens=3)
    assert (text.predict_images(_images(2)).argmax(1) == 2).all() and not text.last_flags.any()
    assert text.answer(_images(1)[0]).split()[0] == "kitchen"


def test_vlm_prompt_follows_the_class_list_and_parsing():
    from benchmark.classifiers.vlm import VLMClassifier, parse_answer

    classes = ["bathroom", "kitchen"]
    model, tok = _tiny_lm(_words(classes + ["garage"]))
    a = VLMClassifier(classes, model=model, processor=tok)
    b = VLMClassifier(classes + ["garage"], model=model, processor=tok)
    assert "bathroom, kitchen." in a.prompt and "garage" in b.prompt and "garage" not in a.prompt
    assert b.chat_prefix().startswith("user: What type")
    assert parse_answer("It is a Living-Room, not a kitchen", ["kitchen", "living_room"]) == 1
    assert parse_answer("no idea", ["kitchen"]) == -1
    with pytest.raises(ValueError, match="options"):
        VLMClassifier(classes, model=model, processor=tok, prompt="Which room?")


def test_table1_metrics_by_hand():
    m = table1_metrics([0, 0, 1, 1, 2, 2], [0, 1, 1, 1, 2, 0], 3)
    # precision: c0 1/2, c1 2/3, c2 1/1; recall: c0 1/2, c1 1, c2 1/2
    assert m["precision"] == pytest.approx((0.5 + 2 / 3 + 1) / 3)
    assert m["recall"] == pytest.approx((0.5 + 1 + 0.5) / 3)
    assert m["accuracy"] == pytest.approx(4 / 6)
    assert m["confusion"].tolist() == [[1, 1, 0], [0, 2, 0], [1, 0, 1]]
    with pytest.raises(ValueError):
        table1_metrics([], [], 3)


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
    assert a == b and len(a["train"]) == 3 * 8 and len(a["val"]) == len(a["test"]) == 3  # 10 of 20 per class
    assert not ({p for p, _ in a["train"]} & {p for p, _ in a["test"]})
    with pytest.raises(FileNotFoundError, match="no images for class"):
        list_images(tmp_path, ["garage"])
