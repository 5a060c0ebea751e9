"""What a bag holds: its storage, time span, topics (type, count, frame) and tf tree."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from envs.bags.source import header_ns, open_bag, stamp_s
from envs.bags.views import TF_TYPES


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
    frame (``header.frame_id``; for tf, the ``parent -> child`` edges). Reads the first
    message of each topic and every tf message (no image is decoded).

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
    return lines
