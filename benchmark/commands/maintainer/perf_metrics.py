"""``python -m benchmark.commands.maintainer.perf_metrics``: time the segment labelling of the metrics.

On each shared ProcTHOR house (first ``--houses``, rasterised at ``--resolution``) and its
ground-truth class map (a label map as our method's output is: adjacent rooms of one class
merge), three ways to split a label map into connected segments are timed, best of
``--repeat``: :func:`benchmark.metrics.segments` (one ``skimage.measure.label`` pass over
the whole map), a loop over labels with one ``cv2.connectedComponents`` each (what the
metrics did before), and a loop over labels with ``scipy.ndimage.label``. All three must give
the same segments. Then the whole :func:`benchmark.metrics.score_semantic` (every metric) is
timed. Prints per-house medians (milliseconds) and the ratios.
"""

from __future__ import annotations

import time
from functools import partial

import cv2
import numpy as np
from scipy import ndimage

from benchmark.commands import cli
from benchmark.metrics import MetricParams, score_semantic, segments
from benchmark.paths import procthor_houses


def loop_cv2(labels: np.ndarray, connectivity: int = 4) -> np.ndarray:
    """One cv2.connectedComponents per label value (the former implementation)."""
    out = np.full(labels.shape, -1, dtype=np.int32)
    nxt = 0
    for v in np.unique(labels[labels >= 0]):
        n, comp = cv2.connectedComponents((labels == v).astype(np.uint8), connectivity=connectivity,
                                          ltype=cv2.CV_32S)
        m = comp > 0
        out[m] = comp[m] - 1 + nxt
        nxt += n - 1
    return out


def loop_ndimage(labels: np.ndarray, connectivity: int = 4) -> np.ndarray:
    """One scipy.ndimage.label per label value."""
    out = np.full(labels.shape, -1, dtype=np.int32)
    nxt = 0
    st = ndimage.generate_binary_structure(2, 1 if connectivity == 4 else 2)
    for v in np.unique(labels[labels >= 0]):
        comp, n = ndimage.label(labels == v, structure=st)
        m = comp > 0
        out[m] = comp[m] - 1 + nxt
        nxt += n
    return out


def _best(fn, *args, repeat: int) -> tuple[object, float]:
    """(result, best wall time in seconds over ``repeat`` calls)."""
    best, out = float("inf"), None
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn(*args)
        best = min(best, time.perf_counter() - t)
    return out, best


def main(argv: list[str] | None = None) -> int:
    from envs.datasets.procthor import ProcTHOREnv

    ap = cli.ArgumentParser(from_root=True, description=__doc__.split("\n\n")[0])
    ap.add_argument("--houses", type=int, default=150)
    ap.add_argument("--resolution", type=float, default=0.05)
    ap.add_argument("--repeat", type=int, default=5)
    a = ap.parse_args(argv)
    env = ProcTHOREnv(path=str(procthor_houses()), start=0, stop=a.houses, resolution=a.resolution)
    t = {"skimage": [], "cv2 loop": [], "ndimage loop": [], "score_semantic": []}
    pixels, same_partition = [], 0
    for hid in env.house_ids():
        s = env.scene(hid)
        cls = np.asarray(s.instance_classes)
        labels = np.where(s.instances >= 0, cls[np.maximum(s.instances, 0)], -1)
        pixels.append(labels.size)
        fast, t1 = _best(segments, labels, 4, repeat=a.repeat)
        ref, t2 = _best(loop_cv2, labels, 4, repeat=a.repeat)
        nd, t3 = _best(loop_ndimage, labels, 4, repeat=a.repeat)
        if not ((fast == ref).all() and (fast == nd).all()):
            raise AssertionError(f"house {hid}: the labellings differ")
        same_partition += 1
        score = partial(score_semantic, resolution=s.grid.resolution)
        _, t4 = _best(score, labels, s.instances, cls, MetricParams(), list(s.classes), repeat=a.repeat)
        for k, v in zip(t, (t1, t2, t3, t4)):
            t[k].append(v)
    med = {k: 1000 * float(np.median(v)) for k, v in t.items()}
    print(f"{same_partition} houses at {a.resolution} m/px (median {np.median(pixels) / 1e6:.2f} Mpx), identical "
          f"segments from all three; median ms per map, best of {a.repeat}:")
    for k, v in med.items():
        print(f"  {k:15s} {v:8.2f} ms")
    print(f"  cv2 loop / skimage: {med['cv2 loop'] / med['skimage']:.2f}x; "
          f"ndimage loop / skimage: {med['ndimage loop'] / med['skimage']:.2f}x")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
