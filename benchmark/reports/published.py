"""The Markdown files under ``results/published/`` that docs pages include (``make docs-numbers``):
the first line names the command that wrote the file, the rest is what it printed.
tests/test_docs_numbers.py runs that command again and compares the files."""

from __future__ import annotations

from pathlib import Path


def header(command: str) -> str:
    """The first line of a published file: ``Written by `COMMAND`.``"""
    return f"Written by `{command}`."


def write_published(out: Path, command: str, text: str, csv: str | None = None) -> str | None:
    """Write ``text`` to ``out`` (atomically) under :func:`header` and a blank line; with ``csv``
    (the table's rows as CSV text), that text to ``out`` with the suffix ``.csv`` after it.

    Returns:
        None, or the one line a command prints when a file cannot be written (a full disk, a
        read-only folder), naming the file."""
    from benchmark.harness.write_errors import cannot_write  # noqa: PLC0415
    from envs.atomic import atomic_write_text  # noqa: PLC0415

    files = [(out, f"{header(command)}\n\n{text.rstrip()}\n")]
    files += [(out.with_suffix(".csv"), csv)] if csv is not None else []
    for path, content in files:
        try:
            atomic_write_text(path, content)
        except OSError as e:
            return cannot_write(e, path)
    return None


def write_measured(out: Path, module: str, argv: list[str] | None, text: str) -> None:
    """Write a measurement (``results/published/perf.md``, ``scaling.md``, ...) to ``out``
    (atomically, its folder made): :func:`benchmark.reports.readme_tables.measured_line` (when,
    where, at which commit and by ``python -m MODULE ARGV``; ``argv`` None: this process's
    arguments), a blank line, ``text`` and a newline."""
    import sys  # noqa: PLC0415

    from benchmark.reports.readme_tables import measured_line  # noqa: PLC0415
    from envs.atomic import atomic_write_text  # noqa: PLC0415

    head = measured_line(module, list(argv if argv is not None else sys.argv[1:]))
    atomic_write_text(out, f"{head}\n\n{text}\n")
