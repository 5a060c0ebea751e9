"""Commands: every ``python -m benchmark.commands.<name>`` (and console script) lives here,
on top of the algorithms and the harness; nothing below imports this package."""

import sys as _sys

#: old module -> the ``roomseg`` subcommand that replaced it (benchmark/cli.py's list).
_MOVED = {"tables": "tables", "report": "report", "figures": "figures", "robustness": "robustness",
          "baselines": "baselines", "baselines_score": "score", "data": "data", "doctor": "doctor",
          "evaluate": "evaluate", "train": "train", "view_confusion": "confusion", "robot_coverage": "coverage",
          "house_stats": "houses", "draw_house": "draw-house", "annotations": "annotations", "bench": "bench", "bag_info": "bag-info",
          "segment": "segment"}


def _say_what_replaced() -> None:
    """``python -m benchmark.commands.<name>`` typed on a terminal: one line on stderr naming the
    ``roomseg`` subcommand that replaced it (the old name keeps working; scripts and pipes see
    nothing new)."""
    argv = list(getattr(_sys, "orig_argv", []))
    if "-m" not in argv or not _sys.stderr.isatty():
        return
    mod = argv[argv.index("-m") + 1] if argv.index("-m") + 1 < len(argv) else ""
    name = mod.rpartition(".")[2]
    if mod.startswith("benchmark.commands.") and name in _MOVED:
        print(f"note: `python -m {mod}` is now `roomseg {_MOVED[name]}` (both work)", file=_sys.stderr)


_say_what_replaced()


def prog(name: str) -> str:
    """A command's name in its usage line: ``roomseg <name>`` (what ``roomseg`` set as
    ``sys.argv[0]``, or the subcommand that replaced ``python -m benchmark.commands.<module>``)."""
    return _sys.argv[0] if str(_sys.argv[0]).startswith("roomseg") else f"roomseg {name}"
