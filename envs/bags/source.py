"""Opening a bag: ``rosbags`` imported lazily, every reader failure one line naming the file.

A bag is a ROS 1 ``.bag`` file, a ROS 2 bag folder (``metadata.yaml`` + ``.db3`` or
``.mcap``) or a lone ``.mcap`` / ``.db3`` file. Messages are streamed (one in memory at a
time); stamps are integers in nanoseconds.

Bounds: every file read is a regular file (:func:`regular_file`, checked with ``stat`` before
anything opens it: a FIFO would block the reader forever, ``/dev/zero`` would feed it without
end), and no message is decoded whose serialised size is over :data:`MAX_MESSAGE_BYTES`.
"""

from __future__ import annotations

import sqlite3
import struct
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from envs.files import regular_file

#: The largest serialised message decoded (bytes): 128 MiB holds a 20 M cell OccupancyGrid (20 MB)
#: or an 8K raw RGB image (100 MB); a message over it is one line naming it, never decoded.
MAX_MESSAGE_BYTES = 128 * 1024 * 1024
#: The storage files of a ROS 2 bag folder that ``rosbags`` reads (beside ``metadata.yaml``).
STORAGE_SUFFIXES = (".db3", ".mcap", ".zstd")

#: What to install when ``rosbags`` is missing.
INSTALL_HINT = "reading ROS bags needs rosbags: make setup installs it (or pip install rosbags)"


class BagError(ValueError):
    """A bag that cannot be used: the message is one line naming the file, topic or stamp."""


def require_rosbags():
    """The ``rosbags.highlevel`` module, or ImportError with the install line."""
    try:
        from rosbags import highlevel  # noqa: PLC0415
    except ImportError:  # pragma: no cover - depends on the environment
        raise ImportError(INSTALL_HINT) from None
    return highlevel


def stamp_s(ns: int) -> str:
    """A stamp in nanoseconds as seconds text for messages (``1700000000.123456789 s``)."""
    return f"{ns // 1_000_000_000}.{ns % 1_000_000_000:09d} s"


def header_ns(msg: Any, fallback: int) -> int:
    """The message's ``header.stamp`` in nanoseconds, or ``fallback`` (the record time) for a
    message without a header or with a zero stamp."""
    h = getattr(msg, "header", None)
    if h is None:
        return int(fallback)
    st = h.stamp
    ns = int(st.sec) * 1_000_000_000 + int(getattr(st, "nanosec", getattr(st, "nsec", 0)))
    return ns if ns > 0 else int(fallback)


def _reader_errors() -> tuple[type[BaseException], ...]:
    from rosbags.highlevel.anyreader import AnyReaderError  # noqa: PLC0415
    from rosbags.rosbag1 import ReaderError as R1  # noqa: PLC0415
    from rosbags.rosbag2 import ReaderError as R2  # noqa: PLC0415
    from rosbags.serde import SerdeError  # noqa: PLC0415
    from rosbags.typesys import TypesysError  # noqa: PLC0415

    return (AnyReaderError, R1, R2, SerdeError, TypesysError, sqlite3.Error, struct.error, EOFError,
            KeyError, IndexError, UnicodeDecodeError, AssertionError, ValueError, RuntimeError)


def _what(e: BaseException) -> str:
    text = " ".join(str(e).split()) or type(e).__name__
    return text if len(text) < 300 else text[:297] + "..."


@dataclass(frozen=True)
class Topic:
    """One topic of a bag: name, ROS 2 style type (``nav_msgs/msg/OccupancyGrid``), count."""

    name: str
    msgtype: str
    count: int


class Bag:
    """An open bag (use :func:`open_bag`): its topics and a message stream."""

    def __init__(self, path: Path, reader: Any, max_message_bytes: int = MAX_MESSAGE_BYTES):
        self.path, self.reader, self.max_message_bytes = path, reader, int(max_message_bytes)

    @property
    def topics(self) -> dict[str, Topic]:
        out = {}
        for c in self.reader.connections:
            t = out.get(c.topic)
            out[c.topic] = Topic(c.topic, c.msgtype, (t.count if t else 0) + int(c.msgcount))
        return out

    @property
    def start_ns(self) -> int:
        return int(self.reader.start_time)

    @property
    def end_ns(self) -> int:
        """The last message's record time (rosbags' ``end_time`` is one past it)."""
        return int(self.reader.end_time) - 1

    def messages(self, topics: Sequence[str]) -> Iterator[tuple[str, str, int, Any]]:
        """Stream ``(topic, msgtype, record time ns, message)`` of ``topics`` in record-time
        order, deserialising one message at a time.

        Raises:
            BagError: a message that cannot be read (truncated file, unknown type) or whose
                serialised size is over ``max_message_bytes``, naming the file, topic and
                record time.
        """
        errors = _reader_errors()
        conns = [c for c in self.reader.connections if c.topic in set(topics)]
        if not conns:
            return
        it = self.reader.messages(connections=conns)
        last: tuple[str, int] | None = None
        while True:
            try:
                item = next(it)
            except StopIteration:
                return
            except errors as e:
                where = f" after {last[0]} at {stamp_s(last[1])}" if last else ""
                raise BagError(f"{self.path}: cannot read on{where}: {_what(e)} (a truncated or damaged bag?)") from None
            conn, t, raw = item
            last = (conn.topic, t)
            if len(raw) > self.max_message_bytes:
                raise BagError(f"{self.path}: topic {conn.topic} at {stamp_s(t)}: a {conn.msgtype} message of "
                               f"{len(raw)} bytes, over the limit of {self.max_message_bytes} bytes a message; "
                               f"expected a smaller message")
            try:
                msg = self.reader.deserialize(raw, conn.msgtype)
            except errors as e:
                raise BagError(f"{self.path}: topic {conn.topic} at {stamp_s(t)}: cannot decode a {conn.msgtype} "
                               f"message: {_what(e)}") from None
            yield conn.topic, conn.msgtype, int(t), msg


def _bag_paths(path: Path) -> list[Path]:
    """``[path]``, once ``path`` and every file of it that ``rosbags`` reads are regular files
    (:func:`regular_file`): a ``.bag`` / ``.mcap`` / ``.db3`` file, or a folder's
    ``metadata.yaml`` and storage files."""
    if not path.exists():
        raise BagError(f"bag={path} does not exist; expected a ROS 1 .bag file, a ROS 2 bag folder or an .mcap file")
    if not path.is_dir():
        regular_file(path, "bag", BagError)
        return [path]
    for p in sorted(path.iterdir()):
        if p.name == "metadata.yaml" or p.name.endswith(STORAGE_SUFFIXES):
            regular_file(p, "bag", BagError)
    return [path]


@contextmanager
def open_bag(path: str | Path, max_message_bytes: int = MAX_MESSAGE_BYTES) -> Iterator[Bag]:
    """Open ``path`` for reading (a context manager yielding a :class:`Bag`).

    Args:
        path: the bag (see the module doc).
        max_message_bytes: the largest serialised message :meth:`Bag.messages` decodes.

    Raises:
        ImportError: ``rosbags`` is not installed (the message says what to install).
        BagError: the file is missing, not a regular file (a FIFO, a device), unindexed,
            truncated, or not a bag (one line naming it).
    """
    highlevel = require_rosbags()
    path = Path(path).expanduser()
    paths = _bag_paths(path)
    errors = _reader_errors()
    try:
        reader = highlevel.AnyReader(paths)
        reader.open()
    except errors as e:
        fix = {".bag": "a ROS 1 bag can be reindexed with `rosbag reindex`",
               ".mcap": "an MCAP file can be recovered with `mcap recover` (the mcap CLI)"}.get(
            path.suffix.lower() if path.is_file() else "", "a ROS 2 bag folder can be reindexed with `ros2 bag reindex`")
        raise BagError(f"{path}: not a readable bag: {_what(e)} (truncated, unindexed or not a bag: {fix})") from None
    except OSError as e:
        raise BagError(f"{path}: cannot open: {_what(e)}") from None
    try:
        yield Bag(path, reader, max_message_bytes)
    finally:
        try:
            reader.close()
        except errors:  # pragma: no cover - closing a damaged bag
            pass
