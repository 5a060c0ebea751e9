"""A per-process memo bounded by bytes: values kept by key, the least recently used dropped
first. The harness keeps its rasterised scenes in one, the route planner its routes."""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Hashable, Iterator
from typing import Any


class ByteLRU:
    """Values by key, each with its size in bytes; :meth:`put` drops the least recently used
    until the sizes sum to at most its ``limit`` (a limit of 0 keeps nothing)."""

    def __init__(self) -> None:
        self._items: OrderedDict[Hashable, tuple[Any, int]] = OrderedDict()
        self._held = 0  # the sizes kept, summed (kept as they change: a put costs no pass over the values)

    def get(self, key: Hashable) -> Any | None:
        """The value kept for ``key`` (now the most recently used), or None."""
        if key not in self._items:
            return None
        self._items.move_to_end(key)
        return self._items[key][0]

    def put(self, key: Hashable, value: Any, nbytes: int, limit: float) -> None:
        """Keep ``value`` (``nbytes`` bytes) for ``key``, then drop the least recently used
        values until at most ``limit`` bytes are kept."""
        old = self._items.get(key)
        if old is not None:
            self._held -= old[1]
        self._items[key] = (value, int(nbytes))
        self._items.move_to_end(key)
        self._held += int(nbytes)
        while self._items and self._held > limit:
            self._held -= self._items.popitem(last=False)[1][1]

    def values(self) -> Iterator[Any]:
        """The values kept, least recently used first."""
        return (v for v, _ in self._items.values())

    def __iter__(self) -> Iterator[Hashable]:
        return iter(self._items)

    def __len__(self) -> int:
        return len(self._items)


__all__ = ["ByteLRU"]
