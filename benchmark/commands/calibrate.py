"""The simulated scanner fitted to the four shared real laser logs (issue 59 item 3).

Each log's FLASER scans at its corrected poses, against the map built from the log's own scans
(:func:`benchmark.conditions.calibration.fit_log`): the share of beams returning nothing, dropout and
grazing dropout, the correlation of dropouts along a scan and over time, the range noise and the
readings shorter or longer than the map, the noise and losses by incidence angle, and the
``ScanSettings`` fields each log gives. ``--out`` writes the tables to a Markdown file headed by the
command (``make docs-numbers``: ``results/published/calibration.md``, included by
``docs/calibration.md``).

    python -m benchmark.commands.calibrate --out results/published/calibration.md
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from benchmark.commands.errors import cli_errors, one_line

#: the four shared logs (../shared/data/real_logs): the fit set, and nothing else
LOGS = {"Intel": "intel-corrected.log.gz", "ACES": "aces-corrected.log.gz", "CSAIL": "csail-corrected.log.gz",
        "Freiburg 079": "freiburg-079-corrected.log.gz"}
#: metres per cell of the map built from each log
RESOLUTION = 0.02
#: metres; a reading within this of the map's range is the surface the map expects
GATE = 0.3
#: metres; beams the map expects beyond this count as expecting nothing (the longest readings of
#: the four logs are 25-50 m; the beams' walks stay short enough for a few seconds a log)
FIT_RANGE = 40.0


def log_arrays(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """``(poses, ranges, angles, max_reading)`` of a log's FLASER scans: (M, 3) corrected laser
    poses, (M, B) ranges with the log's max-range reading as NaN (no return), (B,) beam angles."""
    from envs.logs.carmen import read_carmen  # noqa: PLC0415

    log = read_carmen(path)
    scans = log.of_kind("FLASER")
    if not scans:
        raise ValueError(f"{path}: no FLASER scans: expected a CARMEN log of front laser scans")
    ranges = log.scan_ranges("FLASER")
    top = float(ranges.max())
    # the log's "nothing returned" reading: its largest value (81.83 / 81.91 on the SICK logs, 50 on ACES)
    ranges = np.where(ranges >= top - 0.005, np.nan, ranges)
    return log.laser_poses("FLASER"), ranges, scans[0].angles(), top


def fit_logs(folder: Path) -> dict:
    """Name -> (:class:`ScanFit`, max-range reading) for each shared log under ``folder``."""
    from benchmark.conditions.calibration import fit_log  # noqa: PLC0415

    out = {}
    for name, file in LOGS.items():
        path = folder / file
        if not path.is_file():
            raise FileNotFoundError(f"real log not found: {path} (expected the shared logs; set --logs)")
        poses, ranges, angles, top = log_arrays(path)
        fit, _ = fit_log(poses, ranges, angles, min(FIT_RANGE, float(np.nanmax(ranges))), RESOLUTION, GATE)
        out[name] = (fit, top)
    return out


def _f(v: float, digits: int = 3) -> str:
    return "n/a" if not math.isfinite(v) else f"{v:.{digits}f}"


def tables(fits: dict) -> str:
    """The Markdown the command prints and publishes."""
    rows = []
    for name, (f, top) in fits.items():
        rows.append({"log": name, "scans": f.n_scans, "max-range reading (m)": f"{top:g}",
                     "no return": _f(f.no_return_share), "dropout": _f(f.dropout),
                     "grazing_dropout": _f(f.grazing_dropout), "dropout corr. along scan": _f(f.dropout_corr_beam, 2),
                     "dropout corr. over time": _f(f.dropout_corr_scan, 2), "range_noise (m)": _f(f.range_noise),
                     "range bias (m)": _f(f.range_bias), "short readings": _f(f.short_share),
                     "long readings": _f(f.long_share), "longest reading (m)": _f(f.longest_reading, 1)})
    main = pd.DataFrame(rows).to_markdown(index=False, disable_numparse=True)
    inc = []
    names = list(fits)
    for k, b in enumerate(next(iter(fits.values()))[0].by_incidence):
        row = {"incidence (deg)": f"{b['from_deg']:g}-{b['to_deg']:g}"}
        for name in names:
            bb = fits[name][0].by_incidence[k]
            row[f"{name}: sigma (m)"] = _f(bb["range_sigma"])
            row[f"{name}: no return"] = _f(bb["no_return"])
        inc.append(row)
    by_inc = pd.DataFrame(inc).to_markdown(index=False, disable_numparse=True)
    told = []
    for name, (f, _) in fits.items():
        s = f.settings()
        told.append({"log": name, "range_noise": f"{s.range_noise:g}", "dropout": f"{s.dropout:g}",
                     "grazing_dropout": f"{s.grazing_dropout:g}", "max_range at least": _f(f.longest_reading, 1)})
    settings = pd.DataFrame(told).to_markdown(index=False, disable_numparse=True)
    return (f"{main}\n\nScans: each log's FLASER scans (180 beams over 180 degrees) at its corrected poses; the map: "
            f"each log's own beam ends on {RESOLUTION} m cells. No return: the log's max-range reading. Dropout: "
            f"no return where the map expects a surface within {FIT_RANGE:g} m, the intercept of its line against "
            f"1 - cos(incidence); grazing_dropout its slope over 1 - dropout. Correlations: of neighbouring beams' "
            f"dropouts (beam b and b + 1; one beam in consecutive scans) beyond what incidence explains. "
            f"range_noise: 1.4826 x MAD of measured - expected within {GATE:g} m, less the cells' own "
            f"{RESOLUTION:g} / sqrt(12) m; short / long readings: more than {GATE:g} m before / past the map's "
            f"surface, as shares of the beams returning where the map expects one.\n\n"
            f"By incidence angle (beams the map expects to return):\n\n{by_inc}\n\n"
            f"The ScanSettings fields each log gives (the others it cannot tell):\n\n{settings}")


def main(argv: list[str] | None = None) -> int:
    from benchmark.paths import data_dir  # noqa: PLC0415

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--logs", type=Path, default=None, help="folder of the four shared logs "
                    "(default: $ROOMSEG_SHARED_DATA/real_logs, ../shared/data/real_logs)")
    ap.add_argument("--out", type=Path, default=None,
                    help="also write the tables to this Markdown file, headed by the command that made it "
                         "(make docs-numbers: results/published/calibration.md, which docs/calibration.md includes)")
    a = ap.parse_args(argv)
    try:
        text = tables(fit_logs(a.logs or data_dir() / "real_logs"))
    except cli_errors() as e:
        print(f"error: {one_line(e)}", file=sys.stderr)
        return 2
    print(text)
    if a.out is not None:
        from benchmark.reports.published import write_published  # noqa: PLC0415

        command = ["python -m benchmark.commands.calibrate", *([f"--logs {a.logs}"] if a.logs else []),
                   f"--out {a.out}"]
        err = write_published(a.out, " ".join(command), text)
        if err is not None:
            print(f"error: {err}", file=sys.stderr)
            return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
