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


#: the lines of a published table that a ROSE² run adds or changes (its rows, the line naming its
#: checkout, the rankings, which group every row): compared only where ROOMSEG_ROSE2 names a checkout
ROSE2_LINES = re.compile(r"rose2|ROSE²|^- Ranking on ", re.IGNORECASE)


@pytest.mark.slow
@pytest.mark.parametrize("name, page, typed, shared", [
    ("selros_table5", "baselines.md", r"\| SeLRoS +\| +30 \|", False),
    ("leaderboard", "baselines.md", r"\| ProcTHOR \| distance +\|", True),
    ("objects_accuracy", "method.md", r"\| shared ProcTHOR houses 0-74 +\|", True),
    ("sensitivity", "method.md", r"\| independent \| 1\.0 \|", False)])
def test_the_published_tables_are_what_their_commands_write(name, page, typed, shared, tmp_path, monkeypatch,
                                                             capsys):
    """A page includes results/published/<name>.md; the command its first line names (a line of
    the Makefile's docs-numbers) writes it again line for line, and the page types no copy.
    ROSE² needs a checkout (make rose2-env): without ROOMSEG_ROSE2 the command runs without it
    and every line but those ROSE² changes (its rows, the line naming its commit, the rankings)
    is compared; with it, every line is."""
    import importlib
    import os
    import shlex

    if shared and not SHARED.is_dir():
        pytest.skip("the shared ProcTHOR houses are absent")
    if not shared and name == "selros_table5" and not (SHARED.parent / "selros").is_dir():
        pytest.skip("the SeLRoS release is absent")
    published = ROOT / "results" / "published" / f"{name}.md"
    text = (ROOT / "docs" / page).read_text(encoding="utf-8")
    assert f'--8<-- "results/published/{name}.md"' in text
    assert not re.search(typed, text)  # no typed copy of the table beside the included one
    want = published.read_text(encoding="utf-8").splitlines()
    module, command = re.fullmatch(r"Written by `python -m (benchmark\.commands\.[\w.]+) (.*)`\.", want[0]).groups()
    assert f"-m {module} {command}\n" in (ROOT / "Makefile").read_text(encoding="utf-8")
    args = shlex.split(command)
    out = tmp_path / f"{name}.md"
    flag = "--markdown" if "--markdown" in args else "--out"
    args[args.index(flag) + 1] = str(out)
    monkeypatch.setenv("ROOMSEG_SHARED_DATA", str(SHARED.parent))
    rose2 = os.environ.get("ROOMSEG_ROSE2")
    if not (rose2 and Path(rose2).expanduser().is_dir()):
        monkeypatch.delenv("ROOMSEG_ROSE2", raising=False)
        rose2 = None
    assert importlib.import_module(module).main(args) == 0
    capsys.readouterr()
    got = out.read_text(encoding="utf-8").splitlines()
    assert got[0] == want[0].replace(str(published.relative_to(ROOT)), str(out))
    if rose2 is None:
        got, want = ([line for line in lines if not ROSE2_LINES.search(line)] for lines in (got, want))
    assert got[1:] == want[1:]
    assert len(got) > 5
