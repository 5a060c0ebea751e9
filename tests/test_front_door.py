"""What a user reads (issue 39, item 8): ``--help`` names the program as typed and has no
reStructuredText markup; a warning is one line, ``<prog>: warning: <message>``."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from benchmark.commands.cli import plain

ROOT = Path(__file__).resolve().parents[1]
MARKUP = re.compile(r"``|:(mod|func|class|meth|data|attr):`")


def test_markup_is_removed_as_a_reader_expects():
    assert plain("``python -m x``: the front of :mod:`benchmark.reports.tables`") == \
        "python -m x: the front of benchmark.reports.tables"
    assert plain("see :func:`~benchmark.reports.tables.load_rows` and :class:`Job`") == "see load_rows and Job"
    assert plain("a **bold** word, 2**3 and a*b*c stay") == "a bold word, 2**3 and a*b*c stay"


@pytest.mark.slow
@pytest.mark.parametrize("args", [["tables"], ["data"], ["data", "fetch"], ["robustness"], ["figures", "from-run"],
                                  ["scaling"], ["robot_coverage"]])
def test_help_names_the_command_as_typed_without_markup(args, tmp_path):
    r = subprocess.run([sys.executable, "-m", f"benchmark.commands.{args[0]}", *args[1:], "--help"], cwd=tmp_path,
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith(f"usage: python -m benchmark.commands.{' '.join(args)} "), r.stdout[:200]
    assert ".py" not in r.stdout.splitlines()[0]
    assert not MARKUP.search(r.stdout), MARKUP.search(r.stdout)


@pytest.mark.slow
def test_a_warning_is_one_line_naming_the_command(tmp_path):
    """A map image that is half grey warns; the warning is one line naming the command, without
    Python's ``file.py:LINE: UserWarning`` and the source line."""
    grey = np.full((60, 80), 205, np.uint8)
    grey[10:50, 10:70] = 254
    Image.fromarray(grey).save(tmp_path / "grey.png")
    r = subprocess.run([sys.executable, "-m", "benchmark.commands.segment", "map=grey.png", "resolution=0.05",
                        "segmenter=voronoi", f"out={tmp_path / 'out'}"], cwd=tmp_path, capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr
    lines = [line for line in r.stderr.splitlines() if "warning" in line.lower()]
    assert len(lines) == 1 and lines[0].startswith("python -m benchmark.commands.segment: warning: grey.png: "), \
        r.stderr
    assert "UserWarning" not in r.stderr and ".py:" not in r.stderr and "occupancy_png(" not in r.stderr
