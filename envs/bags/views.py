"""Views from a bag: which message types are views, their labels, their images, and the
subsampling by distance and turn.

Label messages (a robot that already classifies its views):

* ``std_msgs/String``: ``data`` is the class name;
* ``vision_msgs/Classification`` (ROS 2): ``results[].class_id`` and ``score``: class scores;
* ``vision_msgs/Classification2D`` (ROS 1): ``results[].id`` (an index into ``classes``) and
  ``score``.

The class list of label views (``roomseg-segment bag=``) never comes from the labels seen:
it is ``classes=``, else the bag's own list (a ``vision_msgs/LabelInfo``: ``class_map`` by
``class_id``), else the paper's seven; a view's class outside it is one line. (Classes taken from the labels seen
would shift every later class index when one class never occurs, and an index ground truth
would be misread without a word.)

What the views are picks the aggregator (:func:`aggregator_for`): a label says which room the
robot is in (a place label: graph KNN spreads it by path distance, as far as the next views'
labels), an image shows what the camera sees (the vision cone puts its class where it looks).

Image messages: ``sensor_msgs/Image`` (``rgb8``, ``bgr8``, ``rgba8``, ``bgra8``, ``mono8``,
``mono16``, ``8UC1``, ``8UC3`` (as ``bgr8``), ``16UC1``) and ``sensor_msgs/CompressedImage``
(JPEG / PNG, decoded with Pillow), all to (H, W, 3) uint8 RGB.
"""

from __future__ import annotations

import io
import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from envs.bags.source import BagError

LABEL_TYPES = ("std_msgs/msg/String", "vision_msgs/msg/Classification", "vision_msgs/msg/Classification2D")
IMAGE_TYPES = ("sensor_msgs/msg/Image", "sensor_msgs/msg/CompressedImage")
VIEW_TYPES = LABEL_TYPES + IMAGE_TYPES
MAP_TYPES = ("nav_msgs/msg/OccupancyGrid",)
TF_TYPES = ("tf2_msgs/msg/TFMessage",)
POSE_TYPES = ("geometry_msgs/msg/PoseStamped", "geometry_msgs/msg/PoseWithCovarianceStamped",
              "nav_msgs/msg/Odometry")
CAMERA_INFO_TYPES = ("sensor_msgs/msg/CameraInfo",)
#: A bag's own class list (ROS 2 vision_msgs >= 4).
LABEL_INFO_TYPES = ("vision_msgs/msg/LabelInfo",)

#: The aggregator ``roomseg-segment bag=...`` picks per kind of views (an explicit
#: ``aggregator=`` wins), and why.
AGGREGATOR_FOR = {
    "labels": ("graph_knn", "the views are place labels (the room the robot is in): graph KNN spreads each "
                            "along paths to the nearest views; the vision cone would spread it through open doors"),
    "images": ("vision_cone", "the views are camera images (what the camera sees): the vision cone puts each "
                              "view's class where the camera looks"),
}


def aggregator_for(kind: str) -> tuple[str, str]:
    """(the aggregator option, the reason) for views of ``kind`` (``labels`` or ``images``)."""
    return AGGREGATOR_FOR[kind]


def label_info_classes(msg: Any, where: str) -> tuple[str, ...]:
    """The class names of a ``vision_msgs/LabelInfo``, in ``class_id`` order.

    Raises:
        BagError: no classes, an empty name, or ids that are not 0 .. n-1 each once (a class
            index is a position in the list; one line naming ``where``)."""
    pairs = [(int(c.class_id), str(c.class_name).strip()) for c in msg.class_map]
    ids = sorted(k for k, _ in pairs)
    if not pairs or ids != list(range(len(pairs))) or any(not n for _, n in pairs):
        raise BagError(f"{where}: LabelInfo class_map {[list(p) for p in sorted(pairs)][:10]}; expected classes "
                       f"with ids 0 .. n-1, each once, and names (or pass classes=[...])")
    return tuple(n for _, n in sorted(pairs))


def check_label_names(labels: Sequence[str | dict[str, float]], classes: Sequence[str], where: str,
                      source: str) -> None:
    """Every class a kept view names is in ``classes`` (compared lowercase, as a labels file's
    columns are).

    Args:
        source: where the class list came from, for the message.

    Raises:
        BagError: one line naming the topic, the names outside the list, the first view that
            has one, and the list."""
    known = {str(c).strip().lower() for c in classes}
    bad: dict[str, int] = {}
    for i, v in enumerate(labels):
        for name in ([v] if isinstance(v, str) else list(v)):
            if str(name).strip().lower() not in known:
                bad.setdefault(str(name), i)
    if bad:
        first = min(bad.values())
        raise BagError(f"{where}: class(es) {sorted(bad)} (first at kept view {first}) not in the class list "
                       f"{list(classes)} ({source}); expected every view's class in it: pass classes=[...] in the "
                       f"order of your ground truth's indices")


def view_label(msg: Any, msgtype: str, where: str, classes: Sequence[str] | None = None) -> str | dict[str, float]:
    """A label message's class name, or its class scores ``{name: score}``.

    Raises:
        BagError: an empty name, no results, a negative score, or an integer id with no
            ``classes`` to index (one line naming ``where``: topic and stamp)."""
    if msgtype == "std_msgs/msg/String":
        name = str(msg.data).strip()
        if not name:
            raise BagError(f"{where}: empty class name; expected a class name per view")
        return name
    results = list(msg.results)
    if not results:
        raise BagError(f"{where}: {msgtype.rsplit('/', 1)[-1]} with no results; expected at least one class hypothesis")
    out: dict[str, float] = {}
    for r in results:
        if hasattr(r, "class_id"):
            name = str(r.class_id).strip()
        else:
            k = int(r.id)
            if classes is None or not (0 <= k < len(classes)):
                raise BagError(f"{where}: class id {k} needs classes=[...] (the names the ids index, in order); "
                               f"got {None if classes is None else list(classes)}")
            name = str(classes[k])
        score = float(r.score)
        if not (math.isfinite(score) and score >= 0):
            raise BagError(f"{where}: class {name!r} has score {score!r}; expected a score >= 0")
        out[name] = out.get(name, 0.0) + score
    return out


def _raw_image(msg: Any, where: str) -> np.ndarray:
    h, w, step, enc = int(msg.height), int(msg.width), int(msg.step), str(msg.encoding).lower()
    chans = {"rgb8": 3, "bgr8": 3, "8uc3": 3, "rgba8": 4, "bgra8": 4, "mono8": 1, "8uc1": 1, "mono16": 2, "16uc1": 2}
    if enc not in chans:
        raise BagError(f"{where}: image encoding {msg.encoding!r}; expected one of {sorted(chans)} (or a "
                       f"CompressedImage)")
    bpp = chans[enc]
    data = np.asarray(msg.data, dtype=np.uint8)
    if h <= 0 or w <= 0 or step < w * bpp or data.size < h * step:
        raise BagError(f"{where}: image of {w} x {h} px, step {step}, {data.size} bytes; expected step >= "
                       f"{w * bpp} and {h * step} bytes")
    rows = data[:h * step].reshape(h, step)[:, :w * bpp]
    if bpp == 2:
        big = bool(getattr(msg, "is_bigendian", 0))
        v = rows.copy().view(">u2" if big else "<u2").reshape(h, w).astype(np.float64)
        top = v.max() if v.size and v.max() > 0 else 1.0
        g = np.round(v * (255.0 / top)).astype(np.uint8)
        return np.repeat(g[:, :, None], 3, axis=2)
    px = rows.reshape(h, w, bpp)
    if bpp == 1:
        return np.repeat(px, 3, axis=2)
    rgb = px[:, :, :3]
    if enc in ("bgr8", "bgra8", "8uc3"):
        rgb = rgb[:, :, ::-1]
    return np.ascontiguousarray(rgb)


def decode_image(msg: Any, msgtype: str, where: str) -> np.ndarray:
    """(H, W, 3) uint8 RGB of an Image or CompressedImage message.

    Raises:
        BagError: an unknown encoding, a size that does not match the data, or bytes that
            do not decode (one line naming ``where``)."""
    if msgtype == "sensor_msgs/msg/Image":
        return _raw_image(msg, where)
    from PIL import Image, UnidentifiedImageError  # noqa: PLC0415

    try:
        with Image.open(io.BytesIO(np.asarray(msg.data, dtype=np.uint8).tobytes())) as im:
            return np.asarray(im.convert("RGB"))
    except (UnidentifiedImageError, OSError, ValueError) as e:
        raise BagError(f"{where}: CompressedImage (format {str(msg.format)!r}) does not decode: {e}") from None


def subsample(poses: np.ndarray, min_distance_m: float, min_turn_deg: float) -> np.ndarray:
    """Indices of the views to keep along a route: the first, then each view that has moved
    at least ``min_distance_m`` or turned at least ``min_turn_deg`` from the last kept one
    (autotrace's spacing: 1 m between points, 90 degrees between headings). With both 0
    every view is kept.

    Args:
        poses: (N, 3) ROS ``x, y`` metres, ``theta`` radians, in route order.

    Returns:
        (K,) int64 increasing indices.
    """
    if min_distance_m < 0 or min_turn_deg < 0:
        raise ValueError(f"bag_options.min_distance_m={min_distance_m}, bag_options.min_turn_deg={min_turn_deg}; expected >= 0")
    n = len(poses)
    if n == 0:
        return np.zeros(0, np.int64)
    turn = math.radians(min_turn_deg)
    keep = [0]
    lx, ly, lt = poses[0]
    for i in range(1, n):
        x, y, t = poses[i]
        d = math.hypot(x - lx, y - ly)
        a = abs((t - lt + math.pi) % (2 * math.pi) - math.pi)
        if d >= min_distance_m or a >= turn - 1e-12:
            keep.append(i)
            lx, ly, lt = x, y, t
    return np.asarray(keep, np.int64)


def horizontal_fov_deg(msg: Any, where: str) -> float:
    """Horizontal field of view (degrees) of a ``CameraInfo``: ``2 atan(width / (2 fx))``.

    Raises:
        BagError: a zero width or focal length."""
    k = getattr(msg, "k", None)
    if k is None:
        k = msg.K
    fx, w = float(np.asarray(k, float)[0]), int(msg.width)
    if not (fx > 0 and w > 0):
        raise BagError(f"{where}: CameraInfo width {w}, fx {fx}; expected both > 0 for the field of view")
    return math.degrees(2.0 * math.atan(w / (2.0 * fx)))
