"""What every command's user reads: ``--help`` in plain words, warnings on one line.

* :class:`ArgumentParser` names the program as it is typed (``python -m
  benchmark.commands.tables``, or the console script's name; argparse alone says
  ``tables.py``) and prints descriptions and option help without the reStructuredText markup
  of the docstrings they come from (double backticks, ``:mod:`` roles).
* :func:`one_line_warnings` prints a warning as ``<prog>: warning: <message>`` (argparse's
  style) instead of Python's two lines with the file, line number and source line.
* :func:`handle_interrupts` / :func:`interrupted`: Ctrl-C is one line, ``<prog>: interrupted``,
  and exit status 130, with no traceback and no worker process left.
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


#: the exit status of a command stopped by Ctrl-C (128 + SIGINT, what a shell shows).
INTERRUPTED = 130


def interrupted(prog: str | None = None, note: str = "") -> None:
    """Ctrl-C: the one handler of every command (:func:`handle_interrupts`, and the commands
    that catch ``KeyboardInterrupt`` themselves, ``roomseg-bench``). Prints one line,
    ``<prog>: interrupted`` (then ``; <note>``), and ends this process at once with exit
    status 130: its worker processes are killed first (those that ignore SIGINT and would go
    on), a second Ctrl-C is ignored, ``atexit`` cleanup runs (temporary folders), threads are
    not waited for. Never returns."""
    import atexit
    import signal

    try:
        signal.signal(signal.SIGINT, signal.SIG_IGN)  # a second Ctrl-C: no traceback from the cleanup
    except ValueError:  # not the main thread
        pass
    name = prog or _typed_prog()
    try:
        sys.stderr.write(f"{name}: interrupted{'; ' + note if note else ''}\n")
        sys.stderr.flush()
    except (OSError, ValueError):
        pass
    stop_children()
    try:
        atexit._run_exitfuncs()
    except BaseException:  # noqa: BLE001 - exiting: a failing cleanup must not print or hang
        pass
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError, AttributeError):
            pass
    os._exit(INTERRUPTED)


def stop_children() -> None:
    """Kill this process's ``multiprocessing`` children (pool workers ignore SIGINT: the
    driver stops them)."""
    mp = sys.modules.get("multiprocessing")
    if mp is None:
        return
    try:
        kids = mp.active_children()
    except Exception:  # noqa: BLE001 - nothing to stop
        return
    for child in kids:
        try:
            child.kill()
        except Exception:  # noqa: BLE001 - already gone
            pass
    for child in kids:
        try:
            child.join(2.0)
        except Exception:  # noqa: BLE001 - already reaped
            pass


def _typed_prog() -> str:
    """The command as typed: ``roomseg <sub>`` under the ``roomseg`` tool, else :func:`prog_name`."""
    argv = sys.argv
    if argv and argv[0].startswith("roomseg "):  # a subcommand running (benchmark/cli.py)
        return argv[0]
    if argv and os.path.basename(argv[0]) == "roomseg":
        return f"roomseg {argv[1]}" if len(argv) > 1 and not argv[1].startswith("-") else "roomseg"
    return prog_name()


def handle_interrupts() -> None:
    """Install :func:`interrupted` as the handler of an uncaught ``KeyboardInterrupt`` (Ctrl-C)
    in this process: one line and exit status 130 instead of Python's traceback. Every command
    a user runs gets it (``benchmark/commands/__init__.py``: ``python -m
    benchmark.commands.<name>`` and the ``roomseg*`` console scripts); other errors keep the
    hook they had."""
    previous = sys.excepthook
    if getattr(previous, "_roomseg_interrupts", False):
        return

    def hook(kind, value, tb):  # noqa: ANN001 - sys.excepthook's signature
        if issubclass(kind, KeyboardInterrupt):
            interrupted()
        previous(kind, value, tb)

    hook._roomseg_interrupts = True  # type: ignore[attr-defined]
    sys.excepthook = hook

    # A Ctrl-C that lands while Python runs a ctypes callback (numba's compiler calls back into
    # llvmlite's object cache) or a ``__del__`` cannot propagate: Python reports it as
    # "Exception ignored ..." and the command went on to finish with exit 0. Such exceptions
    # reach sys.unraisablehook; a KeyboardInterrupt there is the same Ctrl-C.
    previous_unraisable = sys.unraisablehook

    def unraisable(info):  # noqa: ANN001 - sys.unraisablehook's signature
        if info.exc_type is not None and issubclass(info.exc_type, KeyboardInterrupt):
            interrupted()
        previous_unraisable(info)

    sys.unraisablehook = unraisable


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


__all__ = ["INTERRUPTED", "ArgumentParser", "handle_interrupts", "interrupted", "one_line_warnings", "plain", "prog_name",
           "stop_children"]
