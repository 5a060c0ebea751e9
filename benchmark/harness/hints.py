"""What a command tells a user to type next: hints that run as typed.

A hint names this interpreter the way the user can type it (``.venv/bin/python`` from the
checkout's root, not a bare ``python`` that a new shell may not have), the data command with its
options after the subcommand, and the checkout's root when a command must run from there.
"""

from __future__ import annotations

import os
import shlex
import sys
from pathlib import Path

#: the source checkout this package runs from (holds Makefile and conf/), or None when installed.
CHECKOUT = Path(__file__).resolve().parents[2]
if not ((CHECKOUT / "Makefile").is_file() and (CHECKOUT / "conf").is_dir()):
    CHECKOUT = None  # type: ignore[assignment]


def python_command(cwd: Path | None = None) -> str:
    """This interpreter as a user types it from ``cwd``: a path relative to ``cwd`` when the
    interpreter lives below it (``.venv/bin/python``), else its absolute path; ``python`` when
    the interpreter is unknown."""
    exe = Path(sys.executable) if sys.executable else None
    if exe is None:
        return "python"
    cwd = Path(cwd or os.getcwd()).resolve()
    exe = Path(os.path.abspath(exe))  # not resolved: a venv's python is a link to the base one
    try:
        return shlex.quote(exe.relative_to(cwd).as_posix())
    except ValueError:
        return shlex.quote(str(exe))


def fetch_command(name: str, root: str | Path | None = None) -> str:
    """The command that downloads catalogue dataset ``name`` (into ``root`` when given)."""
    where = f" --root {shlex.quote(str(root))}" if root is not None else ""
    return f"{python_command()} -m benchmark.commands.data fetch {name}{where}"


def dataset_holding(path: str | Path, root: str | Path | None = None) -> str | None:
    """The name of the catalogue dataset (kind ``files``) whose folder under the data root
    ``root`` (default :func:`benchmark.paths.data_dir`) holds ``path``, or None."""
    from envs.datasets.download import load_catalogue

    if root is None:
        from benchmark.paths import data_dir

        root = data_dir()
    p = Path(os.path.abspath(path))
    for ds in load_catalogue().values():
        if ds.kind == "files" and ds.folder:
            folder = Path(os.path.abspath(Path(root) / ds.folder))
            if p == folder or folder in p.parents:
                return ds.name
    return None


def missing_data(e: BaseException, root: str | Path | None = None) -> str | None:
    """One line for an error caused by a file of a catalogue dataset that is absent (a
    :class:`FileNotFoundError` anywhere in ``e``'s chain of causes): the file, and the command
    that fetches it. None for any other error."""
    seen = set()
    while e is not None and id(e) not in seen:
        seen.add(id(e))
        if isinstance(e, FileNotFoundError):
            path = e.filename or (str(e).rsplit(": ", 1)[-1] if ": " in str(e) else None)
            if path:
                name = dataset_holding(path, root)
                if name is not None:
                    if root is None:
                        from benchmark.paths import data_dir

                        root = data_dir()
                    return (f"{path} is absent (dataset {name}, data root {root}); get it with: "
                            f"{fetch_command(name, root)}")
            return None
        e = e.__cause__ or e.__context__
    return None


def outside_root(prog: str) -> str | None:
    """One line saying where to run ``prog`` when the working folder is a subfolder of the
    source checkout (whose default paths, ``results/`` and ``../shared/data``, are relative to
    its root); None from the root itself, from outside the checkout, or for an installed package."""
    if CHECKOUT is None:
        return None
    cwd = Path(os.getcwd()).resolve()
    if cwd == CHECKOUT or CHECKOUT not in cwd.parents:
        return None
    return (f"{prog}: error: run from the checkout's root, {CHECKOUT} (its default paths, results/ and "
            f"../shared/data, are relative to it): cd {shlex.quote(str(CHECKOUT))}")


__all__ = ["CHECKOUT", "dataset_holding", "fetch_command", "missing_data", "outside_root", "python_command"]
