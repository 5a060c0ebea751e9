"""Tables for papers: Markdown that renders, LaTeX that compiles and fits, only tables with data.

Every test reads hand-made ``metrics.csv`` files whose means are known."""

from __future__ import annotations

import re
import shutil
import subprocess

import pandas as pd
import pytest

from benchmark.reports import formatting
from benchmark.reports.tables import render

PARAMS = "segments: 4-connected; match: best iou"


def _rows(**fixed):
    base = {"dataset": "synthetic", "env": "synthetic", "viewpoints": "autotrace", "renderer": "floorplan",
            "classifier": "oracle", "oracle_accuracy": 0.8, "aggregator": "graph_knn", "postprocess": "default",
            "segmenter": "", "status": "ok", "error": "", "metric_params": PARAMS, "precision": 0.9,
            "recall": 0.5, "matched_iou": 0.45, "pq": 0.4, "room_iou": 0.55, "ipa_recall": 0.7, "ipa_precision": 0.8}
    base.update(fixed)
    return base


def _write(path, rows):
    path.parent.mkdir(parents=True, exist_ok=True)
    pd.DataFrame(rows).to_csv(path, index=False)
    return path


@pytest.fixture
def sensitivity_run(tmp_path):
    """Two oracle accuracies x two aggregators x post on/off, two houses each.

    IoU of house h is base + 0.1 * h, base = acc/2 (+0.2 for the cone, +0.1 with post), so
    every cell's mean is base + 0.05 and its std (ddof 1) 0.0707."""
    rows = []
    for acc in (0.5, 1.0):
        for agg, bump in (("graph_knn", 0.0), ("vision_cone", 0.2)):
            for post, pb in (("none", 0.0), ("default", 0.1)):
                for h in range(2):
                    rows.append(_rows(house_id=f"h{h}", oracle_accuracy=acc, aggregator=agg, postprocess=post,
                                      iou=acc / 2 + bump + pb + 0.1 * h, accuracy=acc))
    _write(tmp_path / "sens" / "job" / "metrics.csv", rows)
    return tmp_path / "sens"


@pytest.fixture
def table4_run(tmp_path):
    """A Table IV sweep on two datasets, post-processing only: IoU 0.4 / 0.6 per house."""
    rows = []
    for ds in ("synthetic", "procthor"):
        for clf in ("objects", "oracle"):
            for agg in ("graph_knn", "vision_cone", "euclidean_knn"):
                for h, iou in enumerate((0.4, 0.6)):
                    rows.append(_rows(house_id=f"{ds}{h}", dataset=ds, env=ds, classifier=clf, aggregator=agg,
                                      iou=iou, accuracy=0.5, oracle_accuracy=0.8 if clf == "oracle" else None))
    _write(tmp_path / "t4" / "job" / "metrics.csv", rows)
    return tmp_path / "t4"


def _md_tables(text):
    """(header cells, separator cells, body rows) of every pipe table in ``text``."""
    out, lines = [], text.splitlines()
    for i, line in enumerate(lines[:-1]):
        if line.startswith("|") and re.fullmatch(r"\|(:?-+:?\|)+", lines[i + 1]):
            head = [c.strip() for c in line.strip("|").split("|")]
            sep = lines[i + 1].strip("|").split("|")
            body = []
            for b in lines[i + 2:]:
                if not b.startswith("|"):
                    break
                body.append([c.strip() for c in b.strip("|").split("|")])
            out.append((head, sep, body))
    return out


def test_sensitivity_markdown_has_a_column_per_aggregator_and_post(sensitivity_run, tmp_path):
    text = render([sensitivity_run], ["sensitivity"], tmp_path / "out")
    tables = _md_tables(text)
    assert len(tables) == 2  # IoU, pixel accuracy
    head, sep, body = tables[0]
    assert "oracle accuracy" in head and "|" not in "".join(head)
    assert head[-4:] == ["graph KNN", "graph KNN + post", "vision cone", "vision cone + post"]
    assert len(sep) == len(head)
    assert all(len(b) == len(head) for b in body)
    # mean = acc/2 + bump + post + 0.05 over two houses 10 points apart: the bootstrap interval of a
    # mean of two houses is [lower, higher] (resamples: both low, one each, both high)
    acc_col = head.index("oracle accuracy")
    assert [b[acc_col] for b in body] == ["0.5", "1"]
    assert body[0][-4:] == ["30.00 [25.00, 35.00]", "40.00 [35.00, 45.00]", "50.00 [45.00, 55.00]",
                            "60.00 [55.00, 65.00]"]
    assert body[1][-4:] == ["55.00 [50.00, 60.00]", "65.00 [60.00, 70.00]", "75.00 [70.00, 80.00]",
                            "85.00 [80.00, 90.00]"]
    assert tables[1][2][0][-4:] == ["50.00 [50.00, 50.00]"] * 4  # pixel accuracy = oracle accuracy
    assert "2 houses per cell." in text
    assert (tmp_path / "out" / "sensitivity.png").stat().st_size > 10_000
    tex = (tmp_path / "out" / "sensitivity.tex").read_text()
    assert "0.500000" not in tex and "$30.0$ [$25.0$, $35.0$]" in tex


def test_tables_prints_only_tables_with_data_and_says_why(table4_run):
    text = render([table4_run])
    assert "### Table IV" in text and "### Table V" not in text
    assert "Table V: comparison with baselines: left out, it compares methods with baselines" in text
    assert "### Table II" not in text and "### Table III" not in text and "### Sensitivity" not in text
    assert "Table II: viewpoint strategies (no post-processing): left out, no rows with postprocess=none" in text
    assert "Table III: post-processing" in text and "the rows read have 1 (post)" in text
    assert re.search(r"Sensitivity to classifier accuracy \(oracle[^\n]*: left out, it compares oracle accuracies", text)
    head, sep, body = _md_tables(text)[0]
    assert head == ["classifier", "aggregator", "ProcTHOR IoU", "ProcTHOR matched IoU", "ProcTHOR PQ", "ProcTHOR acc",
                    "synthetic IoU", "synthetic matched IoU", "synthetic PQ", "synthetic acc"]
    assert body[0] == ["objects", "graph KNN", "50.00 [40.00, 60.00]", "45.00 [45.00, 45.00]", "40.00 [40.00, 40.00]",
                       "50.00 [50.00, 50.00]", "50.00 [40.00, 60.00]", "45.00 [45.00, 45.00]",
                       "40.00 [40.00, 40.00]", "50.00 [50.00, 50.00]"]
    assert [b[1] for b in body[:3]] == ["graph KNN", "vision cone", "Euclidean KNN"]


def test_asked_for_empty_table_says_why(table4_run):
    text = render([table4_run], ["table2"])
    assert "left out, no rows with postprocess=none among the 24 rows read" in text


def test_failures_show_in_house_counts(tmp_path):
    rows = [_rows(house_id="a", iou=0.5, accuracy=0.5), _rows(house_id="b", iou=0.7, accuracy=0.7),
            _rows(house_id="c", iou=None, accuracy=None, status="failed", error="HouseError: bad wall"),
            _rows(house_id="a", aggregator="vision_cone", iou=0.2, accuracy=0.2)]
    _write(tmp_path / "r" / "metrics.csv", rows)
    text = render([tmp_path / "r"], ["table4"])
    head, _, body = _md_tables(text)[0]
    assert head[-1] == "synthetic houses"
    assert body[0][-1] == "2 (1 failed)" and body[1][-1] == "1"
    assert body[1][2] == "20.00"  # one house: no std
    assert "1 of 4 rows failed: HouseError x1" in text


def test_latex_is_booktabs_with_caption_label_and_right_aligned_numbers(table4_run, tmp_path):
    render([table4_run], ["table4"], tmp_path / "out")
    tex = (tmp_path / "out" / "table4.tex").read_text()
    first = tex.splitlines()[0]
    assert first.startswith("%") and "booktabs" in first
    assert "\\caption{Table IV" in tex and "\\label{tab:table4}" in tex
    assert "\\begin{tabular}{llrrrrrrrr}" in tex and "\\toprule" in tex and "\\bottomrule" in tex
    numbers = re.findall(r"\$(\d+\.\d+)\$(?: |\\\\\{\})\[\$(\d+\.\d+)\$, \$(\d+\.\d+)\$\]", tex)
    # mean [interval], beside it or (a wide table) under it
    assert len(numbers) == 48 and all(len(x.split(".")[1]) == 1 for trio in numbers for x in trio)
    assert all(float(lo) <= float(m) <= float(hi) for m, lo, hi in numbers)
    assert "\\multicolumn{4}{c}{ProcTHOR}" in tex


def test_markdown_never_puts_a_pipe_in_a_cell():
    summ = pd.DataFrame({"method": ["a|b"], "iou_mean": [0.5], "iou_std": [0.1], "n": [3], "n_failed": [0]})
    grid = formatting.build_grid(summ, ["method"], [], ["iou"], "t")
    md = formatting.to_markdown(grid)
    assert "a/b" in md and md.splitlines()[2].count("|") == 3


def _pdflatex_or_skip():
    exe = shutil.which("pdflatex")
    if exe is None:
        pytest.skip("pdflatex is not installed (apt-get install texlive-latex-base texlive-latex-recommended)")
    return exe


def _compile(tmp_path, body: str) -> str:
    exe = _pdflatex_or_skip()
    doc = ("\\documentclass[twocolumn]{article}\n\\usepackage{booktabs}\n\\begin{document}\n" + body +
           "\n\\end{document}\n")
    (tmp_path / "doc.tex").write_text(doc)
    p = subprocess.run([exe, "-interaction=nonstopmode", "-halt-on-error", "doc.tex"], cwd=tmp_path,
                       capture_output=True, text=True, timeout=120)
    log = (tmp_path / "doc.log").read_text(errors="replace")
    assert p.returncode == 0, log[-2000:]
    return log


def _tabular_width(tmp_path, tex: str) -> tuple[float, float, float]:
    """pdflatex's width of the tabular in ``tex`` (pt), with \\columnwidth and \\textwidth."""
    tab = tex[tex.index("\\begin{tabular}"):tex.rindex("\\end{tabular}") + len("\\end{tabular}")]
    (tmp_path / "tab.tex").write_text(tab)
    sep = re.search(r"\\tabcolsep\}\{([\d.]+)pt\}", tex).group(1)
    size = tex.splitlines()[3]  # \footnotesize or \scriptsize
    log = _compile(tmp_path, "\\newsavebox\\tb\\sbox\\tb{" + size + "\\setlength{\\tabcolsep}{" + sep + "pt}"
                   "\\input{tab.tex}}\\typeout{TABW=\\the\\wd\\tb;COLW=\\the\\columnwidth;TEXTW=\\the\\textwidth;}")
    m = re.search(r"TABW=([\d.]+)pt;COLW=([\d.]+)pt;TEXTW=([\d.]+)pt;", log)
    return float(m.group(1)), float(m.group(2)), float(m.group(3))


@pytest.mark.slow
def test_latex_compiles_and_fits_what_its_first_line_says(table4_run, sensitivity_run, tmp_path):
    _pdflatex_or_skip()
    out = tmp_path / "out"
    render([table4_run], ["table4", "table5", "all"], out)  # asked for: table5 printed without baselines
    render([sensitivity_run], ["sensitivity"], out)
    for name in ("table4", "table5", "all", "sensitivity"):
        tex = (out / f"{name}.tex").read_text()
        d = tmp_path / name
        d.mkdir()
        (d / "t.tex").write_text(tex)
        log = _compile(d, "\\input{t.tex}\n\\ref{tab:" + name + "}")
        assert "Overfull \\hbox" not in log, f"{name}: {re.search(r'Overfull.*', log).group(0)}"
        width, col, page = _tabular_width(d, tex)
        est = float(re.search(r"estimated (\d+) pt", tex.splitlines()[0]).group(1))
        assert abs(est - width) < 0.1 * width + 10, (name, est, width)
        if "table*" in tex:
            assert "full page" in tex.splitlines()[0] and col < width <= page

        else:
            assert "one column" in tex.splitlines()[0] and width <= col


def test_method_names_in_words():
    assert formatting.value_label("method", "oracle@0.8+vision_cone +post") == "oracle@0.8 + vision cone + post"
    assert formatting.value_label("method", "objects+graph_knn") == "objects + graph KNN"
    assert formatting.value_label("method", "voronoi") == "voronoi"


def test_table5_printed_when_a_baseline_is_there(table4_run, tmp_path):
    rows = [_rows(house_id=f"synthetic{h}", classifier="", aggregator="", postprocess="", oracle_accuracy=None,
                  segmenter="voronoi", iou=0.3, accuracy=None) for h in range(2)]
    _write(table4_run / "seg" / "metrics.csv", rows)
    text = render([table4_run])
    head, _, body = next(t for t in _md_tables(text) if "method" in t[0])
    assert [b[1] for b in body if b[0] == "synthetic"][-1] == "voronoi"
    assert next(b for b in body if b[1] == "voronoi")[2] == "30.00 [30.00, 30.00]"


def test_a_missing_grouping_value_keeps_its_cells():
    """objects rows have no oracle accuracy (NaN): their cells are found, the value shows as a dash."""
    summ = pd.DataFrame({"classifier": ["oracle", "objects"], "oracle_accuracy": [0.8, float("nan")],
                         "iou_mean": [0.5, 0.25], "iou_std": [0.1, float("nan")], "n": [2, 1], "n_failed": [0, 0]})
    grid = formatting.build_grid(summ, ["classifier", "oracle_accuracy"], [], ["iou"], "t")
    assert grid.rows == [("objects", "–"), ("oracle", "0.8")]
    assert [formatting.fmt_cell(r[0], 2) for r in grid.cells] == ["25.00", "50.00 ± 10.00"]


def test_counts_are_not_scaled_to_percent():
    """count_error (segments minus rooms) is a count: 1.5 stays 1.5 while IoU 0.5 shows 50."""
    summ = pd.DataFrame([{"method": "m", "iou_mean": 0.5, "iou_std": 0.1, "count_error_mean": 1.5,
                          "count_error_std": 0.5, "n": 3, "n_failed": 0}])
    grid = formatting.build_grid(summ, rows=("method",), cols=(), metrics=("iou", "count_error"), title="t")
    (line,) = grid.cells
    assert line[0][:2] == pytest.approx((50.0, 10.0)) and line[1][:2] == pytest.approx((1.5, 0.5))


def test_table4_carries_the_sanity_rows(table4_run):
    """Rows of the sanity segmenters join Table IV as rows of their own (after the method's),
    other segmenters do not."""
    rows = [_rows(house_id=f"synthetic{h}", classifier="", aggregator="", postprocess="", segmenter=seg,
                  oracle_accuracy=None, iou=iou, accuracy=None, matched_iou=0.1, pq=0.05)
            for seg, iou in (("one_room", 0.4), ("gt_geometry", 1.0), ("voronoi", 0.3)) for h in range(2)]
    _write(table4_run / "sanity" / "metrics.csv", rows)
    head, _, body = _md_tables(render([table4_run], ["table4"]))[0]
    sanity = [b for b in body if b[0] == "(sanity row)"]
    assert [b[1] for b in sanity] == ["one room", "ground-truth geometry"] and body[-2:] == sanity
    assert sanity[0][head.index("synthetic IoU")] == "40.00 [40.00, 40.00]"
    assert sanity[1][head.index("synthetic IoU")] == "100.00 [100.00, 100.00]"
    assert sanity[0][head.index("ProcTHOR IoU")] == "–"
