"""Commands: every ``python -m benchmark.commands.<name>`` (and console script) lives here,
on top of the algorithms and the harness; nothing below imports this package."""

import os as _os
import sys as _sys

# A command run by a user (``python -m benchmark.commands.<name>``: this package is imported
# while ``sys.argv[0]`` is still ``-m``; or a ``roomseg*`` console script) prints a warning as
# one line, ``<prog>: warning: <message>``, not Python's file, line number and source line.
if _sys.argv[:1] == ["-m"] or (_sys.argv and _os.path.basename(_sys.argv[0]).startswith("roomseg")):
    from benchmark.commands.cli import one_line_warnings as _one_line_warnings

    _one_line_warnings()
