"""The robustness report's configuration table (issue 39, item 3): robot condition and severity
columns, and the page's script that shows one condition and/or severity, run under Node with a
small stand-in for the page's DOM (no browser here)."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path
from types import SimpleNamespace

import pytest

from benchmark.reports import html_report


def _rows():
    rows = []
    for cond, sevs in (("clean", ("0",)), ("scan", ("1", "2")), ("pose", ("1", "2"))):
        for sev in sevs:
            for agg in ("graph_knn", "vision_cone"):
                rows.append({"job": SimpleNamespace(dir=Path(f"{cond}_{sev}_{agg}")), "dataset": "synthetic",
                             "names": {"classifier": "oracle", "aggregator": agg, "postprocess": "default"},
                             "condition": cond, "severity": sev, "oracle_accuracy": 0.8, "n": 2, "n_ok": 2,
                             "n_failed": 0, "wall": 1.0, "iou": 0.5})
    return rows


def test_a_robustness_table_has_condition_and_severity_columns():
    html = html_report._configs_table(["iou"], _rows())
    assert html.index('id="config-filters"') < html.index('id="configs"')
    assert ">robot condition</th>" in html and ">severity</th>" in html
    assert html.count("<tr data-condition=") == 10 and "<td>scan map</td>" in html
    assert '<option value="scan">scan map</option>' in html and '<option value="2">2</option>' in html
    plain = html_report._configs_table(["iou"], [dict(r, condition="", severity="") for r in _rows()[:2]])
    assert "config-filters" not in plain and "robot condition" not in plain and "<tr>" in plain


NODE_DOM = r"""
const rowsIn = JSON.parse(process.argv[1]), hash = process.argv[2];
function el(attrs) { return { attrs, style: {}, getAttribute(n) { return n in this.attrs ? this.attrs[n] : null; },
  setAttribute(n, v) { this.attrs[n] = v; }, listeners: {}, addEventListener(t, f) { this.listeners[t] = f; } }; }
const rows = rowsIn.map(r => el({'data-condition': r[0], 'data-severity': r[1]}));
const sels = [el({'data-attr': 'condition'}), el({'data-attr': 'severity'})];
sels.forEach(s => { s.value = ''; });
const count = { textContent: '' };
const configs = { tBodies: [{ rows }], tHead: { rows: [{ cells: [] }] } };
const byId = { configs, 'filter-count': count, 'filter-condition': sels[0], 'filter-severity': sels[1] };
global.window = { location: { hash } };
global.document = { querySelectorAll(q) { return q === '#config-filters select' ? sels : []; },
  getElementById(id) { return byId[id] || null; }, body: el({}), documentElement: { scrollWidth: 1000 } };
eval(process.argv[3]);
const shown = () => rows.filter(r => r.style.display !== 'none').length;
const out = { initial: shown(), count: count.textContent };
sels[0].value = 'scan'; sels[0].listeners.change(); out.scan = shown();
sels[1].value = '2'; sels[1].listeners.change(); out.scan2 = shown();
sels[0].value = ''; sels[0].listeners.change(); out.sev2 = shown(); out.count2 = count.textContent;
console.log(JSON.stringify(out));
"""


@pytest.mark.parametrize("hash_, initial", [("", 10), ("#condition=pose&severity=1", 2)])
def test_the_page_script_filters_by_condition_and_severity(hash_, initial):
    node = shutil.which("node")
    if node is None:
        pytest.skip("node is not installed")
    html = html_report._configs_table(["iou"], _rows())
    rows = re.findall(r'<tr data-condition="([^"]*)" data-severity="([^"]*)">', html)
    assert len(rows) == 10
    r = subprocess.run([node, "-e", NODE_DOM, json.dumps(rows), hash_, html_report._JS], capture_output=True,
                       text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["initial"] == initial
    assert out["scan"] == (4 if not hash_ else 2)  # with the hash, severity 1 stays chosen
    assert out["scan2"] == 2 and out["sev2"] == 4 and out["count2"] == "4 of 10 configurations"
