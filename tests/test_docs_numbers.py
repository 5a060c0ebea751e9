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
                                               ("coverage", "method.md", r"\d+ poses per house"),
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
    ("sensitivity", "method.md", r"\| independent \| 1\.0 \|", False),
    ("oracle_confusion", "method.md", r"rendered views of 50 other generated houses \(\d", False),
    ("slam_levels", "robot-conditions.md", r"\| slam_1 +\| +\d", True),
    ("map_calibration", "robot-conditions.md", r"\| intel_map\.png +\| +\d", True)])
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
    if name == "map_calibration" and not (SHARED.parent / "real_maps").is_dir():
        pytest.skip("the real laser maps are absent")
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


@pytest.mark.slow
def test_the_shipped_confusion_matrix_is_what_its_command_computes(tmp_path, capsys):
    """conf/classifier/confusion/objects_synthetic.json (the default of classifier=oracle_confusion,
    summarised in docs/method.md) is the view_confusion command's output for the overrides it
    records: every field but the wall time, the matrix count for count."""
    import json

    from benchmark.commands import view_confusion

    shipped = ROOT / "conf" / "classifier" / "confusion" / "objects_synthetic.json"
    want = json.loads(shipped.read_text(encoding="utf-8"))
    out = tmp_path / "confusion.json"
    assert view_confusion.main(["--out", str(out), *want["overrides"]]) == 0
    capsys.readouterr()
    got = json.loads(out.read_text(encoding="utf-8"))
    assert got["confusion"] == want["confusion"] and got["n_images"] == want["n_images"] == 11217
    assert {k: v for k, v in got.items() if k != "seconds"} == {k: v for k, v in want.items() if k != "seconds"}


def test_the_confusion_summary_on_a_known_matrix():
    """view_confusion.summary: per true class its views, the share right, its errors and where most
    of them go (the first class on a tie), then a row for all views; a class with no views is
    left out and a matrix of the wrong shape is refused in one line."""
    from benchmark.commands.view_confusion import summary

    record = {"model": "M", "data": "d", "truth": "majority visible class", "classes": ["a", "b", "c"],
              "confusion": [[6, 3, 1], [2, 2, 2], [0, 0, 0]]}
    rows = [[c.strip() for c in line.strip("|").split("|")] for line in summary(record).splitlines()
            if line.startswith("| ")]
    assert rows[1:] == [["a", "10", "60.0", "4", "b", "75"], ["b", "6", "33.3", "4", "a", "50"],
                        ["all", "16", "50.0", "8", "", ""]]
    with pytest.raises(ValueError, match=r"confusion \(2, 2\): expected 3 x 3"):
        summary({**record, "confusion": [[1, 0], [0, 1]]})


#: a number as the docs type it: 1234, 1,234, 12.34 (not part of a word, a version or a range like 1.2.3)
NUMBER = re.compile(r"(?<![\w.,])(?:\d{1,3}(?:,\d{3})+|\d+)(?:\.\d+)?(?![\w]|[.,]\d)")

#: figures the docs credit to a paper (the paper's Table I, ROSE²'s paper): typed, and allowed to
#: coincide with a number of a published table
PAPER_FIGURES = {"87.17", "87.08", "87.03", "87.06", "92.37", "92.42", "92.40", "92.38", "92.32", "24.42", "73.24",
                 "27.38"}


def _significant(token: str):
    """The value of a typed number when it has at least 3 significant digits (trailing zeros of an
    integer and of a decimal not counted: 150, 40.0 and 2.60 have fewer), else None."""
    from decimal import Decimal

    value = Decimal(token.replace(",", "")).normalize()
    return value if len(value.as_tuple().digits) >= 3 else None


def published_numbers(folder: Path) -> dict[Path, set]:
    """For each results/published/*.md: the values of 3+ significant digits in its table cells and
    its list items (measurements), the first column (the row's name: settings, house ranges, seeds)
    and the notes left out."""
    found = {}
    for f in sorted(folder.glob("*.md")):
        values = set()
        for line in f.read_text(encoding="utf-8").splitlines()[1:]:
            if line.startswith("- "):
                cells = [line]
            elif line.startswith("|") and not set(line) <= set("|:- "):
                cells = line.strip().strip("|").split("|")[1:]
            else:
                continue
            for cell in cells:
                values |= {v for v in map(_significant, NUMBER.findall(cell)) if v is not None}
        found[f] = values
    return found


def prose_lines(text: str):
    """(line number, text) of a page's prose: fenced code, inline code, link targets, snippet
    includes and generated blocks left out."""
    fence = generated = False
    for i, line in enumerate(text.splitlines(), 1):
        if line.startswith("```"):
            fence = not fence
            continue
        if "<!-- BEGIN generated" in line:
            generated = True
        if "<!-- END generated" in line:
            generated = False
            continue
        if fence or generated or line.startswith("--8<--"):
            continue
        line = re.sub(r"`[^`]*`", "", line)
        yield i, re.sub(r"\]\([^)]*\)", "]", line)


def typed_results(page: str, text: str, published: dict[Path, set], commands: dict[Path, list[str]]) -> list[str]:
    """The numbers a page types that a published table holds: one of 4+ significant digits from any
    published table (not a paper's figure), or of 3+ from a table whose command the page names or
    that it includes."""
    from decimal import Decimal

    near = [f for f, names in commands.items()
            if f'--8<-- "results/published/{f.name}"' in text or any(re.search(n, text) for n in names)]
    problems = []
    for i, line in prose_lines(text):
        for token in NUMBER.findall(line):
            value = _significant(token)
            if value is None or token.replace(",", "") in PAPER_FIGURES:
                continue
            wide = len(value.as_tuple().digits) >= 4 and value != Decimal(0)
            hits = [f.name for f in published if value in published[f] and (wide or f in near)]
            if hits:
                problems.append(f"{page}:{i}: {token} is typed; it is in {', '.join(hits)} (include or point at it)")
    return problems


def _commands_of(folder: Path) -> dict[Path, list[str]]:
    """For each published file: patterns of the ways a page names the command its first line names
    (``benchmark.commands.<module>`` and, for a ``roomseg`` subcommand, ``roomseg <name>``)."""
    from benchmark.cli import COMMANDS

    names = {}
    for f in sorted(folder.glob("*.md")):
        module = re.match(r"Written by `python -m benchmark\.commands\.([\w.]+)", f.read_text(encoding="utf-8"))
        if module is None:
            names[f] = []
            continue
        leaf = module.group(1).rpartition(".")[2]
        names[f] = [rf"benchmark\.commands\.{re.escape(module.group(1))}\b"]
        names[f] += [rf"roomseg {re.escape(sub)}\b" for sub, (mod, _) in COMMANDS.items() if mod == leaf]
    return names


def test_no_page_types_a_number_of_a_published_table():
    """Every number in the docs comes from a command: a result the published tables hold is
    included or pointed at, never typed again in a page's prose (where it goes stale)."""
    folder = ROOT / "results" / "published"
    published, commands = published_numbers(folder), _commands_of(folder)
    assert len(published) >= 10 and all(published.values())
    problems = [p for page in sorted((ROOT / "docs").glob("*.md"))
                for p in typed_results(page.name, page.read_text(encoding="utf-8"), published, commands)]
    assert problems == []


def test_the_typed_number_check_finds_what_it_names():
    folder = ROOT / "results" / "published"
    published, commands = published_numbers(folder), _commands_of(folder)
    cov = folder / "coverage.md"
    rooms = re.search(r"\| (\d+) of (\d+) \|", cov.read_text(encoding="utf-8")).group(2)
    confusion = folder / "oracle_confusion.md"
    views = re.search(r"\| all +\| +([\d,]+) \|", confusion.read_text(encoding="utf-8")).group(1)
    # the coverage command named, its room count typed: caught; without the command named, a
    # 3-digit number is left alone, a 5-digit one is caught anywhere
    page = f"On the shared houses (`python -m benchmark.commands.coverage`) {rooms} rooms get a pose.\n"
    assert typed_results("p.md", page, published, commands) == [
        f"p.md:1: {rooms} is typed; it is in coverage.md (include or point at it)"]
    assert typed_results("p.md", f"{rooms} rooms get a pose.\n", published, commands) == []
    assert typed_results("p.md", f"on {views} views\n", published, commands)[0].startswith(f"p.md:1: {views} is typed")
    # code, paper figures, settings (fewer than 3 significant digits) and included files are no problem
    ok = (f"```\n{views}\n```\n`{views}` 150 houses, 40.0 m, seed 2000; the paper reports 87.17.\n"
          f'--8<-- "results/published/{confusion.name}"\n')
    assert typed_results("p.md", ok, published, commands) == []
