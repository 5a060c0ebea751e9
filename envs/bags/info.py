"""What a bag holds: its storage, time span, topics (type, count, frame), tf tree, every map
message's stamp and the bag's own class list (a ``vision_msgs/LabelInfo``)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from envs.bags.occupancy import stamps_text
from envs.bags.source import BagError, header_ns, open_bag, stamp_s
from envs.bags.views import LABEL_INFO_TYPES, MAP_TYPES, TF_TYPES, label_info_classes


def storage_of(path: Path) -> str:
    """``ros1`` (a ``.bag`` file), ``mcap`` or ``sqlite3`` (ROS 2), from the files."""
    if path.is_file():
        return {".bag": "ros1", ".mcap": "mcap", ".db3": "sqlite3"}.get(path.suffix.lower(), "unknown")
    if any(path.glob("*.mcap")):
        return "mcap"
    if any(path.glob("*.db3")):
        return "sqlite3"
    return "unknown"


def bag_contents(path: str | Path) -> dict[str, Any]:
    """The bag's storage, start / end (ns), and per topic: type, count, the first message's
    frame (``header.frame_id``; for tf, the ``parent -> child`` edges; for a map topic, every
    message's header stamp, ``stamps_ns``). Reads the first message of each topic and every
    tf and map message (no image is decoded).

    Raises:
        BagError: an unreadable bag (one line naming it)."""
    path = Path(path).expanduser()
    out: dict[str, Any] = {"bag": str(path), "storage": storage_of(path), "topics": {}}
    with open_bag(path) as bag:
        out["start_ns"], out["end_ns"] = bag.start_ns, bag.end_ns
        for name, t in sorted(bag.topics.items()):
            row: dict[str, Any] = {"type": t.msgtype, "count": t.count, "frame": None}
            if t.msgtype in TF_TYPES:
                edges: dict[str, int] = {}
                for _, _, _, msg in bag.messages([name]):
                    for ts in msg.transforms:
                        key = f"{str(ts.header.frame_id).lstrip('/')} -> {str(ts.child_frame_id).lstrip('/')}"
                        edges[key] = edges.get(key, 0) + 1
                row["edges"] = edges
            elif t.msgtype in MAP_TYPES:
                row["stamps_ns"] = []
                for _, _, rec, msg in bag.messages([name]):
                    if row["frame"] is None:
                        row["frame"] = str(msg.header.frame_id)
                    row["stamps_ns"].append(header_ns(msg, rec))
            elif t.count:
                for _, _, rec, msg in bag.messages([name]):
                    h = getattr(msg, "header", None)
                    row["frame"] = str(h.frame_id) if h is not None else None
                    row["first_stamp_ns"] = header_ns(msg, rec)
                    break
            out["topics"][name] = row
    return out


def format_contents(info: dict[str, Any]) -> list[str]:
    """Text lines of :func:`bag_contents` (a table of topics, then the tf edges)."""
    dur = (info["end_ns"] - info["start_ns"]) / 1e9
    lines = [f"{info['bag']}: {info['storage']}, {len(info['topics'])} topics, {dur:.1f} s "
             f"({stamp_s(info['start_ns'])} .. {stamp_s(info['end_ns'])})"]
    w = max([len(k) for k in info["topics"]] + [5])
    tw = max([len(v["type"]) for v in info["topics"].values()] + [4])
    lines.append(f"  {'topic':<{w}}  {'type':<{tw}}  {'count':>7}  frame")
    for name, row in info["topics"].items():
        frame = row.get("frame") or ("" if "edges" not in row else f"{len(row['edges'])} tf edges")
        lines.append(f"  {name:<{w}}  {row['type']:<{tw}}  {row['count']:>7}  {frame}")
    for name, row in info["topics"].items():
        for e, n in row.get("edges", {}).items():
            lines.append(f"  tf {name}: {e} ({n})")
    for name, row in info["topics"].items():
        if "stamps_ns" in row:
            lines.append(f"  map stamps {name}: {stamps_text(row['stamps_ns'])}")
    return lines


def bag_classes(path: str | Path) -> tuple[str, tuple[str, ...]] | None:
    """The bag's own class list: (topic, names in ``class_id`` order) of its
    ``vision_msgs/LabelInfo`` topic (the last message), or None when it has none.

    Raises:
        BagError: two LabelInfo topics, or a class map that is not ids 0 .. n-1 (one line)."""
    path = Path(path).expanduser()
    with open_bag(path) as bag:
        found = sorted(n for n, t in bag.topics.items() if t.msgtype in LABEL_INFO_TYPES and t.count)
        if not found:
            return None
        if len(found) > 1:
            raise BagError(f"{path}: {len(found)} LabelInfo topics {found}; expected one class list (or pass "
                           f"classes=[...])")
        last = None
        for _, _, rec, msg in bag.messages(found):
            last = (rec, msg)
        return found[0], label_info_classes(last[1], f"{path} {found[0]} at {stamp_s(last[0])}")
