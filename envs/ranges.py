"""Value ranges of stage settings, said next to the parameter with :data:`typing.Annotated`.

A type says ``float``; a range says "a share in [0, 1]" or "an odd window". A stage class
puts both on the parameter its config key fills::

    from typing import Annotated
    from envs.ranges import Odd, Positive

    class MyAggregator:
        def __init__(self, window: Annotated[int, Odd()] = 5, radius_m: Annotated[float, Positive()] = 1.0):
            ...

The configuration check (``benchmark.harness.typed.check_targets``) reads the markers from the
annotation of the ``_target_`` class of every config node and refuses a value out of range, before
any work, with one line: ``aggregator.window=4: expected an odd integer >= 1``. A null value is
refused too, unless the annotation admits None (``Annotated[int | None, Integer(0)]``: the
words then end in ", or null"). The stage itself is not changed by a marker: Python does not
check annotations when the class is built directly.

Every marker is a callable ``marker(value) -> bool`` (a plain config value: int, float, bool,
str, list) with ``marker.what``, the words after "expected" (and :meth:`Range.explain`, the
words after ``key=value:``, which a marker may make more precise). Standard library only, so
that ``envs`` and ``benchmark`` modules alike can import it; the harness's own ``run`` settings
use the same markers (``benchmark.harness.run_settings``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any


def _number(v: Any) -> bool:
    """An int or float, not a bool, not NaN (infinity passes)."""
    return isinstance(v, int | float) and not isinstance(v, bool) and not math.isnan(v)


class Range:
    """A value range a type cannot say. Subclasses set :attr:`what` and :meth:`__call__`."""

    #: the words after "expected" in the one-line message (e.g. ``"a number in [0, 1]"``).
    what: str = "a valid value"

    def __call__(self, value: Any) -> bool:  # pragma: no cover - every marker overrides it
        raise NotImplementedError

    def explain(self, value: Any, nullable: bool = False) -> str:
        """The words after ``key=value:`` for a ``value`` this marker refuses: ``"expected "``
        and :attr:`what` (and ``", or null"`` where the type admits None)."""
        return f"expected {self.what}{', or null' if nullable else ''}"

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.what!r})"

    def __eq__(self, other: object) -> bool:
        return type(self) is type(other) and vars(self) == vars(other)

    def __hash__(self) -> int:
        return hash((type(self), self.what))


class Between(Range):
    """A number between ``low`` and ``high`` (each end closed unless ``*_open``); finite unless
    ``inf_ok`` (then +infinity passes when ``high`` is infinite).

    Args:
        low, high: the ends, in the parameter's unit.
        low_open, high_open: whether the end itself is left out.
        inf_ok: +infinity allowed (an unlimited range, ``.inf`` in YAML).
        what: the words of the message; default "a number in [low, high]" etc.
    """

    def __init__(self, low: float = -math.inf, high: float = math.inf, *, low_open: bool = False,
                 high_open: bool = False, inf_ok: bool = False, what: str | None = None):
        self.low, self.high, self.low_open, self.high_open, self.inf_ok = low, high, low_open, high_open, inf_ok
        if what is None:
            if math.isinf(high):
                what = f"a number {'>' if low_open else '>='} {low:g}"
            else:
                what = f"a number in {'(' if low_open else '['}{low:g}, {high:g}{')' if high_open else ']'}"
        self.what = what

    def __call__(self, value: Any) -> bool:
        if not _number(value):
            return False
        if math.isinf(value) and not (self.inf_ok and value > 0 and math.isinf(self.high)):
            return False
        above = value > self.low if self.low_open else value >= self.low
        below = value < self.high if self.high_open else value <= self.high
        return above and (below or math.isinf(value))


class Positive(Between):
    """A finite number > 0 (a length, a duration, a rate)."""

    def __init__(self) -> None:
        super().__init__(0, low_open=True, what="a number > 0")


class NonNegative(Between):
    """A finite number >= 0 (an area, a sigma, a tolerance)."""

    def __init__(self) -> None:
        super().__init__(0, what="a number >= 0")


class Seconds(Positive):
    """A duration in seconds > 0, finite (a timeout)."""

    def __init__(self) -> None:
        super().__init__()
        self.what = "seconds > 0"


class Share(Between):
    """A number in [0, 1] (a probability, a share of views)."""

    def __init__(self) -> None:
        super().__init__(0, 1, what="a number in [0, 1]")


class Angle(Between):
    """An angle in (0, 360] degrees (a field of view, a beam step)."""

    def __init__(self) -> None:
        super().__init__(0, 360, low_open=True, what="an angle in (0, 360] degrees")


class Metres(Between):
    """A distance in metres > 0; with ``inf_ok``, ``.inf`` for an unlimited sensor."""

    def __init__(self, inf_ok: bool = False) -> None:
        super().__init__(0, low_open=True, inf_ok=inf_ok,
                         what="metres > 0 (.inf: unlimited)" if inf_ok else "metres > 0")


class Integer(Range):
    """An integer (not a bool) >= ``low`` (a count, an index)."""

    def __init__(self, low: int = 0) -> None:
        self.low = low
        self.what = f"an integer >= {low}"

    def __call__(self, value: Any) -> bool:
        return isinstance(value, int) and not isinstance(value, bool) and value >= self.low


class Odd(Integer):
    """An odd integer >= 1 (a window of pixels with a centre)."""

    def __init__(self) -> None:
        super().__init__(1)
        self.what = "an odd integer >= 1"

    def __call__(self, value: Any) -> bool:
        return super().__call__(value) and value % 2 == 1


class OneOf(Range):
    """One of the values given (compared with ``==``; ``True`` is not ``1`` here)."""

    def __init__(self, *allowed: Any) -> None:
        self.allowed = tuple(allowed)
        self.what = "one of " + ", ".join(map(repr, allowed))

    def __call__(self, value: Any) -> bool:
        return any(value == a and isinstance(value, bool) == isinstance(a, bool) for a in self.allowed)


class LowHigh(Range):
    """``[low, high]`` with ``0 < low <= high``, both finite (a range to draw a size from)."""

    what = "[low, high] with 0 < low <= high"

    def __call__(self, value: Any) -> bool:
        return (isinstance(value, Sequence) and not isinstance(value, str) and len(value) == 2
                and all(Positive()(x) for x in value) and value[0] <= value[1])


class Text(Range):
    """A string, or a number read as text (``run.name=2024``, ``run.cache_salt=2``); not a bool,
    a list or null."""

    what = "a string or a number (read as text)"

    def __call__(self, value: Any) -> bool:
        return isinstance(value, str) or (_number(value) and not math.isinf(value))


class NonEmpty(Range):
    """A list with at least one item (each item's type is left to the annotation).

    Args:
        of: the items, in words (``"house ids"``): ``what`` is "a non-empty list of <of>".
    """

    def __init__(self, of: str = "values") -> None:
        self.of = of
        self.what = f"a non-empty list of {of}"

    def __call__(self, value: Any) -> bool:
        return isinstance(value, list | tuple) and len(value) > 0


#: a camera's horizontal field of view, degrees (a pinhole camera sees less than 180).
CAMERA_FOV = Between(0, 180, low_open=True, high_open=True, what="an angle in (0, 180) degrees")
#: the spread of a view's headings, degrees (0: one heading; 360: all around).
HEADING_SPREAD = Between(0, 360, what="a number in [0, 360] degrees")
#: the share of a scanner's beams that return nothing (1 would be no scan at all).
DROPOUT = Between(0, 1, high_open=True, what="a share in [0, 1)")


__all__ = ["CAMERA_FOV", "DROPOUT", "HEADING_SPREAD", "Angle", "Between", "Integer", "LowHigh", "Metres", "NonEmpty",
           "NonNegative", "OneOf", "Odd", "Positive", "Range", "Seconds", "Share", "Text"]
