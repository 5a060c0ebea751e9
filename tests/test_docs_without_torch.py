"""``make docs`` needs the core and MkDocs only (issue 39, item 9): its recipe installs no torch
and no test extra, and every command's ``--help`` (what the reference page is made of) runs
with torch, torchvision, transformers and ai2thor unimportable."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from benchmark.commands import docs

ROOT = Path(__file__).resolve().parents[1]
HEAVY = ("torch", "torchvision", "transformers", "ai2thor")


def test_make_docs_installs_the_core_and_mkdocs_only(tmp_path):
    if shutil.which("make") is None:
        pytest.skip("make is not installed")
    r = subprocess.run(["make", "-n", "docs", f"VENV={tmp_path / 'venv'}"], cwd=ROOT, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    plan = r.stdout
    assert 'pip install -q -e ".[docs]"' in plan and "mkdocs build --strict" in plan
    assert "torch" not in plan and "[test]" not in plan and ".installed-test" not in plan


@pytest.mark.slow
def test_every_command_help_runs_without_torch(tmp_path):
    for name in HEAVY:  # packages that raise ImportError, ahead of the installed ones
        (tmp_path / name).mkdir()
        (tmp_path / name / "__init__.py").write_text(f"raise ImportError('{name} is not installed (test)')\n")
    env = {**os.environ, "PYTHONPATH": f"{tmp_path}{os.pathsep}{ROOT}"}
    failed = []
    for name in docs.commands():
        r = subprocess.run([sys.executable, "-m", f"benchmark.commands.{name}", "--help"], cwd=ROOT, env=env,
                           capture_output=True, text=True, timeout=120)
        if r.returncode != 0 or not r.stdout.strip():
            failed.append(f"{name}: {(r.stderr.strip().splitlines() or ['?'])[-1]}")
    assert failed == []
    r = subprocess.run([sys.executable, "-c", "import torch"], env=env, capture_output=True, text=True)
    assert "torch is not installed (test)" in r.stderr  # the check itself: torch was unimportable
