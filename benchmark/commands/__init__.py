"""Commands: every ``python -m benchmark.commands.<name>`` (and console script) lives here,
on top of the algorithms and the harness; nothing below imports this package."""
