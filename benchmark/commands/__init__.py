"""Commands: every ``python -m benchmark.commands.<name>`` (and console script) lives here,
on top of the algorithms and the harness; nothing below imports this package."""

import os as _os
import sys as _sys

# A command run by a user (``python -m benchmark.commands.<name>``: this package is imported
# while ``sys.argv[0]`` is still ``-m``; or a ``roomseg*`` console script) prints a warning as
# one line, ``<prog>: warning: <message>``, not Python's file, line number and source line,
# and Ctrl-C as one line, ``<prog>: interrupted`` (exit status 130), not a traceback.
if _sys.argv[:1] == ["-m"] or (_sys.argv and _os.path.basename(_sys.argv[0]).startswith("roomseg")):
    from benchmark.commands.cli import handle_interrupts as _handle_interrupts
    from benchmark.commands.cli import one_line_warnings as _one_line_warnings

    _one_line_warnings()
    _handle_interrupts()  # Ctrl-C: one line and exit status 130, not a traceback

def _say_what_replaced() -> None:
    """``python -m benchmark.commands.<name>`` typed on a terminal: one line on stderr naming the
    ``roomseg`` subcommand that replaced it (the old name keeps working; scripts and pipes see
    nothing new)."""
    argv = list(getattr(_sys, "orig_argv", []))
    if "-m" not in argv or not _sys.stderr.isatty():
        return
    mod = argv[argv.index("-m") + 1] if argv.index("-m") + 1 < len(argv) else ""
    name = mod.rpartition(".")[2]
    from benchmark.cli import (
        COMMANDS,  # the one list of subcommands: module -> the name that replaced it
    )

    moved = {module: sub for sub, (module, _) in COMMANDS.items()}
    if mod.startswith("benchmark.commands.") and name in moved:
        print(f"note: `python -m {mod}` is now `roomseg {moved[name]}` (both work)", file=_sys.stderr)


_say_what_replaced()


#: maintainer tools that moved to ``benchmark/commands/maintainer/``: their old module names
#: (``python -m benchmark.commands.perf``) keep working, and say where they went on a terminal.
_MAINTAINER = ("docs", "gpu_check", "vlm_bench", "perf", "perf_metrics", "perf_postprocess", "scaling",
               "readme_tables", "bag_memory", "slam_levels")


class _MovedTools:
    """A finder that resolves ``benchmark.commands.<tool>`` to ``benchmark.commands.maintainer.<tool>``."""

    @staticmethod
    def find_spec(name, path=None, target=None):
        import importlib.util

        prefix = "benchmark.commands."
        tool = name[len(prefix):] if name.startswith(prefix) else ""
        if tool not in _MAINTAINER:
            return None
        if _sys.stderr.isatty():
            print(f"note: `{name}` is now `benchmark.commands.maintainer.{tool}` (both work)", file=_sys.stderr)
        moved = importlib.util.find_spec(f"benchmark.commands.maintainer.{tool}")
        return importlib.util.spec_from_file_location(name, moved.origin) if moved is not None else None


if not any(isinstance(f, _MovedTools) for f in _sys.meta_path):
    _sys.meta_path.append(_MovedTools())
