"""The Markdown files under ``results/published/`` that docs pages include (``make docs-numbers``):
the first line names the command that wrote the file, the rest is what it printed.
tests/test_docs_numbers.py runs that command again and compares the files."""

from __future__ import annotations

from pathlib import Path


def header(command: str) -> str:
    """The first line of a published file: ``Written by `COMMAND`.``"""
    return f"Written by `{command}`."


def write_published(out: Path, command: str, text: str) -> str | None:
    """Write ``text`` to ``out`` (atomically) under :func:`header` and a blank line.

    Returns:
        None, or the one line a command prints when the file cannot be written (a full disk, a
        read-only folder), naming the file."""
    from benchmark.harness.write_errors import cannot_write  # noqa: PLC0415
    from envs.atomic import atomic_write_text  # noqa: PLC0415

    try:
        atomic_write_text(out, f"{header(command)}\n\n{text.rstrip()}\n")
    except OSError as e:
        return cannot_write(e, out)
    return None
