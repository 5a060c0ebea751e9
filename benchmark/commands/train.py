"""``python -m benchmark.commands.train``: the command-line front of :mod:`benchmark.classifiers.train`."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from benchmark.classifiers.train import history_path, train_cnn, train_mlp
from benchmark.commands import cli


def main(argv: list[str] | None = None) -> int:
    from benchmark.commands.errors import cli_errors, one_line  # noqa: PLC0415

    ap = cli.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 epilog="extra key=value arguments override conf/classifier/<model>.yaml")
    ap.add_argument("--model", required=True, choices=["cnn", "dinov2"])
    ap.add_argument("--data", type=Path, required=True,
                    help="Places365 root / image folder, or an ImageFolder of class folders")
    ap.add_argument("--places365", action="store_true", help="--data is Places365 (torchvision root or image folder)")
    ap.add_argument("--out", type=Path, default=None, help="checkpoint path (default: the config's)")
    ap.add_argument("--epochs", type=int, default=None, help="default: cnn 10, dinov2 50")
    ap.add_argument("--batch-size", type=int, default=None, help="training batch, images (default: cnn 32, dinov2 256)")
    ap.add_argument("--lr", type=float, default=None, help="learning rate (default: cnn 1e-4, dinov2 1e-3)")
    ap.add_argument("--split-sizes", default="4000,500,500", help="per-class train,val,test sizes")
    ap.add_argument("--seed", type=int, default=0, help="split and training seed")
    ap.add_argument("--workers", type=int, default=4, help="image decoding processes")
    ap.add_argument("overrides", nargs="*", help="classifier config overrides, key=value")
    a = ap.parse_args(argv)
    try:
        return _main(a)
    except cli_errors() as e:
        print(f"error: {one_line(e)}", file=sys.stderr)
        return 2


def _main(a) -> int:
    from benchmark.classifiers.evaluate import parse_split_sizes  # noqa: PLC0415
    from benchmark.classifiers.places import list_images, split  # noqa: PLC0415
    from benchmark.config import classifier_config  # noqa: PLC0415

    cfg = classifier_config(a.model, a.overrides)
    c = cfg.classifier
    classes = list(cfg.classes)
    sizes = parse_split_sizes(a.split_sizes)
    parts = split(list_images(a.data, classes, a.places365), classes, *sizes, seed=a.seed)
    print(f"split (seed {a.seed}): {len(parts['train'])} train, {len(parts['val'])} val, {len(parts['test'])} test")
    kw = {k: v for k, v in (("epochs", a.epochs), ("batch_size", a.batch_size), ("lr", a.lr)) if v is not None}
    common = {"device": c.device, "image_size": int(c.image_size), "workers": a.workers, "seed": a.seed}
    if a.model == "cnn":
        out = a.out or Path(c.checkpoint)
        hist = train_cnn(parts["train"], parts["val"], out, classes, arch=c.arch, pretrained=bool(c.pretrained),
                         **common, **kw)
    else:
        out = a.out or Path(c.head_checkpoint)
        bcfg = c.get("backbone_config")
        hist = train_mlp(parts["train"], parts["val"], out, classes, backbone=c.backbone,
                         backbone_config=dict(bcfg) if bcfg else None, hidden=list(c.hidden),
                         feature_cache=c.get("feature_cache"), feature_batch_size=int(c.batch_size), **common, **kw)
    for h in hist:
        print(f"epoch {h['epoch']}: loss {h['loss']:.4f}, val accuracy {h['val_accuracy']:.4f}")
    scored = [h for h in hist if not np.isnan(h["val_accuracy"])]
    best = max(scored, key=lambda h: h["val_accuracy"]) if scored else hist[-1]  # first of equals, as saved
    print(f"kept epoch {best['epoch']} (val accuracy {best['val_accuracy']:.4f}): {out}; history {history_path(out)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
