"""What every command's user reads: ``--help`` in plain words, warnings on one line.

* :class:`ArgumentParser` names the program as it is typed (``python -m
  benchmark.commands.tables``, or the console script's name; argparse alone says
  ``tables.py``) and prints descriptions and option help without the reStructuredText markup
  of the docstrings they come from (double backticks, ``:mod:`` roles).
* :func:`one_line_warnings` prints a warning as ``<prog>: warning: <message>`` (argparse's
  style) instead of Python's two lines with the file, line number and source line.
"""

from __future__ import annotations

import argparse
import os
import re
import sys
import warnings

#: ``:role:`~pkg.mod.name``` -> ``name``; ``:role:`text``` -> ``text``.
_ROLE = re.compile(r":[a-z]+(?::[a-z]+)?:`~?([^`<]*?)(?:\s*<[^>]*>)?`")
#: ``:role:`~a.b.c``` keeps the last part only.
_TILDE = re.compile(r":[a-z]+(?::[a-z]+)?:`~([^`]*)`")


def plain(text: str | None) -> str | None:
    """``text`` without reStructuredText inline markup: ``` ``x`` ``` -> ``x``, ``:mod:`a.b```
    -> ``a.b``, ``:func:`~a.b``` -> ``b``, ``*x*`` / ``**x**`` -> ``x``."""
    if not text:
        return text
    text = _TILDE.sub(lambda m: m.group(1).rsplit(".", 1)[-1], text)
    text = _ROLE.sub(lambda m: m.group(1), text)
    text = text.replace("``", "")
    text = re.sub(r"(?<![\w*])\*\*([^*\n]+)\*\*(?![\w*])", r"\1", text)
    return text


def prog_name() -> str:
    """The program as the user typed it: ``python -m <module>`` when run with ``-m``, else the
    script's name (a console script such as ``roomseg-bench``)."""
    main = sys.modules.get("__main__")
    spec = getattr(main, "__spec__", None)
    if spec is not None and getattr(spec, "name", None) and spec.name != "__main__":
        name = spec.name[: -len(".__main__")] if spec.name.endswith(".__main__") else spec.name
        return f"python -m {name}"
    return os.path.basename(sys.argv[0]) if sys.argv and sys.argv[0] else "python"


class _PlainFormatter(argparse.RawDescriptionHelpFormatter):
    """Descriptions as written (their line breaks kept), markup removed from them and from help."""

    def _format_text(self, text: str) -> str:
        return super()._format_text(plain(text) or "")

    def _expand_help(self, action: argparse.Action) -> str:
        return plain(super()._expand_help(action)) or ""


class ArgumentParser(argparse.ArgumentParser):
    """``argparse.ArgumentParser`` with the typed program name and plain-text help (the
    sub-command parsers it makes are of this class too)."""

    def __init__(self, *args, prog: str | None = None, from_root: bool = False, **kwargs) -> None:
        if prog is None and not args:  # the command module that builds the parser, as typed
            caller = sys._getframe(1).f_globals
            spec = caller.get("__spec__")
            module = getattr(spec, "name", None) or caller.get("__name__", "")
            prog = f"python -m {module}" if module.startswith("benchmark.commands.") else prog_name()
        if str(sys.argv[0]).startswith("roomseg ") and (prog is None or prog.startswith("python -m ")):
            prog = sys.argv[0]  # run as a subcommand of `roomseg` (benchmark/cli.py): named as typed
        kwargs.setdefault("formatter_class", _PlainFormatter)
        super().__init__(*args, prog=prog, **kwargs)
        self.from_root = from_root

    def parse_known_args(self, args=None, namespace=None):  # noqa: ANN001 - argparse's signature
        """``from_root``: a command whose defaults are paths relative to the checkout's root
        (``results/``, ``../shared/data``) refuses to run from a subfolder
        of the checkout, in one line that says where to run it (exit 2), before it reads or
        writes anything."""
        if getattr(self, "from_root", False):
            from benchmark.harness.hints import outside_root

            where = outside_root(self.prog)
            if where is not None:
                self.exit(2, where + "\n")
        return super().parse_known_args(args, namespace)


def one_line_warnings(prog: str | None = None) -> None:
    """Print warnings as one line each, ``<prog>: warning: <message>`` (the category's name
    when it is not a plain UserWarning), each message once, without Python's file, line
    number and source line."""
    def show(message, category, filename, lineno, file=None, line=None):  # noqa: ANN001 - warnings' signature
        name = prog or prog_name()  # at the warning: __main__ is set up by then
        kind = "" if category is UserWarning else f" ({category.__name__})"
        text = " ".join(str(message).split())
        out = file if file is not None else sys.stderr
        try:
            out.write(f"{name}: warning{kind}: {text}\n")
        except (OSError, ValueError):  # a closed stream: nothing to do
            pass

    warnings.showwarning = show


__all__ = ["ArgumentParser", "one_line_warnings", "plain", "prog_name"]
