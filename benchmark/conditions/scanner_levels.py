"""The scanner of the robot levels set from the fit to real logs (issue 59 item 6): plain functions.

Each of the four shared real logs (Intel, ACES, MIT CSAIL, Freiburg 079; SICK LMS scanners) gives
the three :class:`envs.maps.scan.ScanSettings` fields a log can tell (:mod:`benchmark.conditions.calibration`):
``range_noise`` (metres, sigma), ``dropout`` (share of beams returning nothing where a surface is in
range) and ``grazing_dropout`` (the extra share lost at grazing incidence, times ``1 - cos i``). The
five severities of a field are a ladder over the four logs' values:

* severity 1: the best log (the smallest value),
* severity 3: the typical one (the median of the four),
* severity 5: the poorest (the largest),
* severities 2 and 4: half way between their neighbours,

each rounded to three significant figures. Severity 0 is ``corruption=clean`` (no noise, no dropout).

The ladder sets those three fields, wherever a level file holds them, in the ``scan_k``, ``slam_k``
and ``realistic_k`` levels (the mapping scanner and the front end's scanner alike); every other
field of a level stays set by hand, because no log tells it: ``max_range`` (every log reads past
25 m; the levels model shorter-range scanners), closed doors, people and surface dropout (the logs
do not mark glass, doors or people), and the odometry alphas (the shared logs are corrected: no raw
wheel odometry). ``lost_k`` and ``kidnap_k`` keep a noiseless scanner: they isolate the front end's
data association and the carried robot.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping

import numpy as np

#: the ScanSettings fields a log tells, in the order of the tables
FITTED = ("range_noise", "dropout", "grazing_dropout")
#: the level families whose scanner follows the fit
FAMILIES = ("scan", "slam", "realistic")
SEVERITIES = (1, 2, 3, 4, 5)


def _round3(v: float) -> float:
    """``v`` to three significant figures (0 stays 0)."""
    if v == 0 or not math.isfinite(v):
        return float(v)
    return float(round(v, 2 - int(math.floor(math.log10(abs(v))))))


def ladder(values) -> tuple[float, float, float, float, float]:
    """Severities 1..5 of one field from the logs' values (module docstring): min, half way to the
    median, the median, half way to the max, the max; three significant figures.

    >>> ladder([0.0229, 0.0282, 0.0345, 0.0558])
    (0.0229, 0.0271, 0.0314, 0.0436, 0.0558)
    """
    v = np.asarray([float(x) for x in values], dtype=float)
    if v.size == 0 or not np.all(np.isfinite(v)) or np.any(v < 0):
        raise ValueError(f"ladder of {list(values)}: expected one finite value >= 0 per log")
    lo, med, hi = float(v.min()), float(np.median(v)), float(v.max())
    return tuple(_round3(x) for x in (lo, (lo + med) / 2, med, (med + hi) / 2, hi))


def levels_from_fits(fits: Mapping[str, object]) -> dict[int, dict[str, float]]:
    """Severity -> {field: value} for :data:`FITTED` from ``fits`` (log name -> an object with
    those attributes, e.g. :class:`benchmark.conditions.calibration.ScanFit`)."""
    if not fits:
        raise ValueError("levels from the fit: no fitted logs")
    out = {s: {} for s in SEVERITIES}
    for f in FITTED:
        for s, value in zip(SEVERITIES, ladder([getattr(fit, f) for fit in fits.values()])):
            out[s][f] = value
    return out


_LINE = re.compile(r"^(?P<indent>[ \t]+)(?P<key>[a-z_]+):(?P<space>[ \t]*)(?P<value>[^ \t#\n]+)(?P<rest>.*)$")


def fitted_values(text: str) -> dict[tuple[str, str], float]:
    """``{(section, field): value}`` of the :data:`FITTED` fields a level file's text holds under
    its top-level sections (``mapping``, ``pose_error``)."""
    out, section = {}, None
    for line in text.splitlines():
        if line and not line[0].isspace() and not line.startswith("#"):
            section = line.split(":", 1)[0].strip()
            continue
        m = _LINE.match(line)
        if m and section and m["key"] in FITTED:
            out[(section, m["key"])] = float(m["value"])
    return out


def set_fitted(text: str, values: Mapping[str, float]) -> str:
    """``text`` (a level file) with every :data:`FITTED` field it holds set to ``values[field]``;
    the lines' comments are kept and say the value is the fit's. Fields it does not hold are not added."""
    out, section = [], None
    for line in text.splitlines(keepends=True):
        body = line.rstrip("\n")
        if body and not body[0].isspace() and not body.startswith("#"):
            section = body.split(":", 1)[0].strip()
        m = _LINE.match(body)
        if m and section and m["key"] in FITTED:
            rest = m["rest"]
            if "fitted to the real logs" not in rest:
                rest = (rest + ";" if rest.strip() else "  #") + " fitted to the real logs (docs/calibration.md)"
            body = f"{m['indent']}{m['key']}:{m['space']}{values[m['key']]!r}{rest}"
            line = body + ("\n" if line.endswith("\n") else "")
        out.append(line)
    return "".join(out)
