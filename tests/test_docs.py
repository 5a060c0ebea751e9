"""The docs site: the generated reference pages are current (a command or config change without
``make docs`` fails here), and the site builds with MkDocs in strict mode (a broken link, an
unknown anchor or a page missing from the nav fails)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from benchmark.commands import docs

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_generated_reference_pages_are_current():
    for path, text in docs.pages().items():
        assert path.exists(), f"{path} missing: run `python -m benchmark.commands.maintainer.docs reference`"
        assert path.read_text(encoding="utf-8") == text, (
            f"{path.relative_to(ROOT)} is stale: run `python -m benchmark.commands.maintainer.docs reference`")


def test_the_reference_lists_every_command_and_group():
    names = docs.commands()
    assert {"bench", "segment", "tables", "figures", "report"} <= set(names) and "errors" not in names
    page = docs.config_page()
    for group in ("aggregator", "classifier", "env", "experiment", "segmenter", "viewpoints"):
        assert f"## {group}\n" in page
    assert "max_range_m: 10.0" in page  # an option's file, as it is


def test_subcommands_are_read_from_the_usage_line():
    assert docs._subcommands("usage: x [-h] {fig3,fig4,from-run} ...\n\nmore") == ["fig3", "fig4", "from-run"]
    assert docs._subcommands("usage: x [-h] paths [paths ...]\n\nthe {a,b} later") == []


@pytest.mark.slow
def test_the_site_builds_strict(tmp_path):
    exe = shutil.which("mkdocs", path=str(Path(sys.executable).parent)) or shutil.which("mkdocs")
    if exe is None:
        pytest.skip("mkdocs is not installed (pip install 'roomseg-bench[docs]')")
    r = subprocess.run([exe, "build", "--strict", "--site-dir", str(tmp_path / "site")], cwd=ROOT,
                       env={**os.environ, "NO_MKDOCS_2_WARNING": "1"}, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    assert (tmp_path / "site" / "reference" / "commands" / "index.html").exists()


@pytest.mark.slow
def test_a_broken_link_fails_the_strict_build(tmp_path):
    """The check itself: the same site with one link to a missing page and one to a missing
    anchor does not build, nor with an included file that is missing."""
    exe = shutil.which("mkdocs", path=str(Path(sys.executable).parent)) or shutil.which("mkdocs")
    if exe is None:
        pytest.skip("mkdocs is not installed (pip install 'roomseg-bench[docs]')")
    shutil.copytree(ROOT / "docs", tmp_path / "docs")
    shutil.copytree(ROOT / "examples", tmp_path / "examples")  # files the pages include (snippets)
    (tmp_path / "results").mkdir()
    for f in (ROOT / "results" / "published").glob("*.md"):  # published measurements the pages include
        (tmp_path / "results" / "published").mkdir(exist_ok=True)
        shutil.copy(f, tmp_path / "results" / "published" / f.name)
    shutil.copy(ROOT / "README.md", tmp_path / "README.md")
    shutil.copy(ROOT / "mkdocs.yml", tmp_path / "mkdocs.yml")

    def build() -> subprocess.CompletedProcess:
        return subprocess.run([exe, "build", "--strict", "--site-dir", str(tmp_path / "site")], cwd=tmp_path,
                              env={**os.environ, "NO_MKDOCS_2_WARNING": "1"}, capture_output=True, text=True,
                              timeout=300)

    assert build().returncode == 0  # the copy builds as it is
    index = tmp_path / "docs" / "index.md"
    good = index.read_text(encoding="utf-8")
    index.write_text(good + "\n[gone](nope.md) and [here](reference/config.md#no-such-anchor)\n", encoding="utf-8")
    r = build()
    assert r.returncode != 0 and "nope.md" in r.stderr and "no-such-anchor" in r.stderr
    # an included file that is missing (an example moved without its page) fails too
    index.write_text(good + '\n```python\n--8<-- "examples/plugins/gone.py"\n```\n', encoding="utf-8")
    r = build()
    assert r.returncode != 0 and "examples/plugins/gone.py" in r.stderr
