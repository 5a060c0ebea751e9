"""Docs a user can type and trust (issue 39, items 5 and 7): every page's commands run as typed
in a new shell (the environment activated on the page first), none writes over a tracked file,
no page carries development notes; a command run from a subfolder of the checkout says in one
line where to run it and writes nothing; the robot-coverage numbers the docs show are the
command's own, published as a file the page includes."""

from __future__ import annotations

import re
import sys
from pathlib import Path

import pytest

from benchmark.commands import docs

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "data" / "procthor"


def test_the_checks_of_a_page_catch_what_they_name():
    page = ("Fixed in issue #12 on this branch.\n\n```bash\nmake setup\npython -m benchmark.commands.tables R\n```\n\n"
            "```bash\nsource .venv/bin/activate\nroomseg-bench run.limit=2\n"
            "python -m benchmark.commands.figures fig3 --out docs/figures/fig3.png\n```\n")
    probs = docs.page_problems(page, tracked=["docs/figures/fig3.png", "README.md"])
    assert len(probs) == 4, probs
    assert probs[0].startswith("line 5: `python -m benchmark.commands.tables R` needs the project's environment")
    assert probs[1].startswith("line 11: ") and "writes over the tracked docs/figures/fig3.png" in probs[1]
    assert "issue #12" in probs[2] and "this branch" in probs[3]
    assert docs.page_problems("```bash\n.venv/bin/python -m x --out results/a.png\n```\n", ["docs/a.png"]) == []


def test_every_page_runs_as_typed_in_a_new_shell_and_leaves_tracked_files_alone():
    tracked = docs.tracked_files()
    pages = sorted((ROOT / "docs").glob("*.md"))
    assert len(pages) > 10
    problems = [f"{p.relative_to(ROOT)} {line}" for p in pages
                for line in docs.page_problems(p.read_text(encoding="utf-8"), tracked)]
    assert problems == []


def test_a_command_from_a_subfolder_says_where_to_run_it(monkeypatch, capsys):
    from benchmark.commands import bench, data, robot_coverage

    monkeypatch.chdir(ROOT / "docs")
    monkeypatch.delenv("ROOMSEG_SHARED_DATA", raising=False)
    monkeypatch.setattr(sys, "argv", ["roomseg-bench", "run.limit=1"])
    assert bench.main() == 2
    assert data.main(["list"]) == 2
    with pytest.raises(SystemExit) as e:
        robot_coverage.main(["--n", "1"])
    assert e.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 3 and all(f"run from the checkout's root, {ROOT}" in line for line in err), err
    assert err[0].startswith("roomseg-bench: error: ") and err[2].startswith("python -m benchmark.commands.robot_coverage")
    assert not (ROOT / "docs" / "results").exists()


@pytest.mark.slow
@pytest.mark.skipif(not SHARED.is_dir(), reason="the shared ProcTHOR houses are absent")
@pytest.mark.parametrize("name, page, typed", [("robot_coverage", "robot-conditions.md", r"\| frontier 40 m \|"),
                                               ("house_stats", "houses.md", r"\| rooms per house +\|"),
                                               ("clutter_tables", "maps-and-clutter.md", r"\| +\d+ / 38 \|"),
                                               ("tables_examples", "reliability-tables.md", r"\| oracle +\| graph KNN +\|"),
                                               ])
def test_the_published_docs_numbers_are_what_the_commands_write(name, page, typed, tmp_path, monkeypatch, capsys):
    """A page includes results/published/<name>.md; the command the file names (a line of the
    Makefile's docs-numbers) writes it again byte for byte, and the page types no copy of it."""
    import importlib

    published = ROOT / "results" / "published" / f"{name}.md"
    text = (ROOT / "docs" / page).read_text(encoding="utf-8")
    assert f'--8<-- "results/published/{name}.md"' in text
    assert not re.search(typed, text)  # no typed copy of the table beside the included one
    head = published.read_text(encoding="utf-8").splitlines()[0]
    command = re.fullmatch(rf"Written by `python -m benchmark.commands.{name} (.*)`\.", head).group(1)
    assert command in (ROOT / "Makefile").read_text(encoding="utf-8")
    args = command.split()
    out = tmp_path / f"{name}.md"
    args[args.index("--out") + 1] = str(out)
    monkeypatch.setenv("ROOMSEG_SHARED_DATA", str(SHARED.parent))
    assert importlib.import_module(f"benchmark.commands.{name}").main(args) == 0
    capsys.readouterr()
    assert out.read_text(encoding="utf-8").splitlines()[1:] == published.read_text(encoding="utf-8").splitlines()[1:]


@pytest.mark.slow
def test_the_data_page_runs_in_a_new_shell_from_a_fresh_copy(tmp_path, capsys):
    """docs/data.md as a user types it in a new shell (fetching skipped: no internet here)."""
    work = tmp_path / "clone"
    rc = docs.run_blocks(ROOT / "docs" / "data.md", workdir=work, skips=[(r"data fetch", "needs internet access")],
                         venv_from=sys.executable, env={"ROOMSEG_SHARED_DATA": str(SHARED.parent)})
    out = capsys.readouterr().out
    assert rc == 0, out
    assert "every block ran" in out
