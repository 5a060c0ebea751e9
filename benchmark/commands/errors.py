"""How a command reports an error it expects (bad input, a missing file or model): one line,
the innermost cause, instead of a traceback."""

from __future__ import annotations


def one_line(e: BaseException) -> str:
    """The innermost cause of an error (Hydra wraps constructor errors) as one line:
    ``Type: first line of its message``, or the type alone when the message is empty."""
    while e.__cause__ is not None:
        e = e.__cause__
    text = (str(e).strip().splitlines() or [""])[0].strip()
    return f"{type(e).__name__}: {text}" if text else type(e).__name__


def cli_errors() -> tuple[type[BaseException], ...]:
    """The errors a command reports as one line instead of a traceback."""
    from hydra.errors import HydraException  # noqa: PLC0415

    return (ImportError, RuntimeError, OSError, ValueError, KeyError, HydraException)

