"""A sweep as one static HTML page: configurations with their mean metrics (sortable), the
failures with their errors, and per house the ground truth beside the raw and
post-processed maps of every configuration.

``python -m benchmark.commands.report RUN_DIR --out report.html [--house ID ...] [--houses-per-dataset N]``

Maps are drawn for ``N`` houses of every dataset of the run (default 2), so generated houses
and ProcTHOR houses both show. Label maps are drawn in the class colours; instance maps (the
geometric segmenters and the sanity rows) in a colour per segment; both with their segment
borders in white (black is "not walkable"). A robustness run (rows with ``corruption``) adds a
section with the summary table and a figure per robot condition; its maps are those of the
clean condition.

The page needs no server and no network: maps are PNGs embedded as data URIs (drawn at the
map's own resolution, scaled by the browser without smoothing), the sorting is a few lines
of inline JavaScript, and the page logs nothing to the console. Runs are read only through
the run store (:mod:`benchmark.harness.store`); ground truth comes from each job's env.
"""

from __future__ import annotations

import base64
import html
import io
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from benchmark.reports import formatting
from benchmark.stats import bootstrap_ci

#: metric columns shown (those the run has), as fractions in the rows -> percent on the page.
METRICS = ("iou", "precision", "recall", "accuracy", "matched_iou", "room_iou", "pq", "pq_semantic", "class_iou",
           "view_accuracy")
#: count-like columns shown as plain means.
COUNTS = ("count_error",)
#: longest side of a map image on the page, CSS pixels.
MAP_CSS_PX = 260
#: houses drawn per dataset when no house is named.
HOUSES_PER_DATASET = 2
#: colours (RGB) of an instance map's rooms, cycled by room id: Paul Tol's colour-blind safe "muted"
#: scheme, none of them a class colour (Okabe-Ito), so rooms are never read as classes.
INSTANCE_COLORS = ((204, 102, 119), (51, 34, 136), (221, 204, 119), (17, 119, 51), (136, 204, 238),
                   (136, 34, 85), (68, 170, 153), (153, 153, 51), (170, 68, 153))
#: colour (RGB) of the lines between segments on the page: white, so that it differs from the
#: black of pixels that are not walkable (the figures, on a white page, draw them dark).
PAGE_BORDER_COLOR: tuple[int, int, int] = (255, 255, 255)

_CSS = """
body{font-family:system-ui,-apple-system,'Segoe UI',sans-serif;margin:24px;color:#222;background:#fff}
h1{font-size:22px;margin:0 0 4px}h2{font-size:18px;margin:28px 0 8px;border-bottom:1px solid #ddd}
h3{font-size:15px;margin:18px 0 6px}.muted{color:#666;font-size:13px}
table{border-collapse:collapse;font-size:13px}th,td{padding:3px 6px;border-bottom:1px solid #e4e4e4}
th{background:#f3f3f3;text-align:left;vertical-align:bottom}td.num{white-space:nowrap}
#configs td:not(.num){max-width:22ch}#configs th,#configs td{padding:3px 4px}#configs small.ci{white-space:normal}.robust img{max-width:640px;width:100%}td.num,th.num{text-align:right;font-variant-numeric:tabular-nums}
table.sortable th{cursor:pointer;user-select:none}table.sortable th[data-dir=asc]::after{content:' \\25B2'}
table.sortable th[data-dir=desc]::after{content:' \\25BC'}
.maps{display:grid;gap:6px 10px;align-items:start}.maps figure{margin:0}
.maps figcaption{font-size:12px;color:#444;margin-bottom:2px}
.maps img{image-rendering:pixelated;border:1px solid #ccc;display:block}
.scope{background:#fff6d5;border:1px solid #e8d48b;padding:6px 10px;font-size:13px}
.filters{font-size:13px}.filters select{margin-right:12px}
.label{font-size:12px;align-self:center;width:190px}.legend span{display:inline-block;margin:0 10px 4px 0;font-size:12px}
.legend i{display:inline-block;width:12px;height:12px;margin-right:4px;vertical-align:-2px;border:1px solid #999}
td.err{font-family:ui-monospace,monospace;font-size:12px;max-width:70ch;overflow-wrap:anywhere}
"""

# Click a header to sort by that column (numbers by value, text alphabetically); again to
# reverse. Cells carry their sort value in data-v. Marks each table data-sortable="ready".
# ``#sort=N[,desc]`` in the address sorts the configurations by column N when the page opens.
_JS = r"""
(function () {
  function key(td) { var v = td.getAttribute('data-v'); if (v === null) return td.textContent;
    var f = parseFloat(v); return isNaN(f) ? v : f; }
  function sortBy(table, col, th) {
    var dir = th.getAttribute('data-dir') === 'asc' ? 'desc' : 'asc';
    var heads = table.tHead.rows[0].cells;
    for (var i = 0; i < heads.length; i++) heads[i].removeAttribute('data-dir');
    th.setAttribute('data-dir', dir);
    var body = table.tBodies[0], rows = Array.prototype.slice.call(body.rows);
    rows.sort(function (a, b) {
      var x = key(a.cells[col]), y = key(b.cells[col]);
      var mx = x === '', my = y === '';
      if (mx || my) return mx === my ? 0 : (mx ? 1 : -1);  // missing values last, either way
      var nx = typeof x === 'number', ny = typeof y === 'number';
      var c = nx && ny ? x - y : (nx ? -1 : (ny ? 1 : String(x).localeCompare(String(y))));
      return dir === 'asc' ? c : -c;
    });
    rows.forEach(function (r) { body.appendChild(r); });
  }
  var tables = document.querySelectorAll('table.sortable');
  for (var t = 0; t < tables.length; t++) {
    (function (table) {
      var heads = table.tHead.rows[0].cells;
      for (var i = 0; i < heads.length; i++) {
        (function (col, th) { th.addEventListener('click', function () { sortBy(table, col, th); }); })(i, heads[i]);
      }
      table.setAttribute('data-sortable', 'ready');
    })(tables[t]);
  }
  // the page's width need (a test opens it at 1400 px and reads this back)
  var wrap = document.getElementById('configs-wrap');
  document.body.setAttribute('data-scroll-width', String(Math.max(document.documentElement.scrollWidth,
    wrap ? wrap.scrollWidth + wrap.getBoundingClientRect().left : 0)));
  // a robustness run: show the configurations of one robot condition and/or severity
  var sels = document.querySelectorAll('#config-filters select');
  function applyFilters() {
    var rows = document.getElementById('configs').tBodies[0].rows, shown = 0;
    for (var i = 0; i < rows.length; i++) {
      var ok = true;
      for (var j = 0; j < sels.length; j++) {
        var v = sels[j].value;
        if (v !== '' && rows[i].getAttribute('data-' + sels[j].getAttribute('data-attr')) !== v) ok = false;
      }
      rows[i].style.display = ok ? '' : 'none';
      if (ok) shown++;
    }
    document.getElementById('filter-count').textContent = shown + ' of ' + rows.length + ' configurations';
  }
  for (var s = 0; s < sels.length; s++) sels[s].addEventListener('change', applyFilters);
  // report.html#condition=scan&severity=3 opens the table filtered
  var want = /^#(?:.*&)?condition=([^&]*)/.exec(window.location.hash), sev = /[#&]severity=([^&]*)/.exec(window.location.hash);
  if (want && document.getElementById('filter-condition')) document.getElementById('filter-condition').value = decodeURIComponent(want[1]);
  if (sev && document.getElementById('filter-severity')) document.getElementById('filter-severity').value = decodeURIComponent(sev[1]);
  if (sels.length) applyFilters();
  // report.html#sort=COLUMN[,desc] opens the configurations sorted (a link to a ranking)
  var m = /^#sort=(\d+)(,desc)?$/.exec(window.location.hash);
  var configs = document.getElementById('configs');
  if (m && configs && +m[1] < configs.tHead.rows[0].cells.length) {
    var th = configs.tHead.rows[0].cells[+m[1]];
    sortBy(configs, +m[1], th);
    if (m[2]) sortBy(configs, +m[1], th);
  }
})();
"""


def png_data_uri(rgb: np.ndarray) -> str:
    """(H, W, 3) uint8 -> ``data:image/png;base64,...``."""
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(rgb, dtype=np.uint8)).save(buf, format="PNG", optimize=True)
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode("ascii")


def map_rgb(labels: np.ndarray, classes: Sequence[str], walkable: np.ndarray | None,
            segments: np.ndarray | None = None) -> np.ndarray:
    """(H, W) class labels -> (H, W, 3) uint8 in the class colours with segment borders (as
    in the figures)."""
    from benchmark.reports.plotting import colorize, label_segments, segment_borders

    rgb = colorize(labels, classes, walkable).copy()
    seg = label_segments(labels) if segments is None else segments
    rgb[segment_borders(seg)] = PAGE_BORDER_COLOR
    return rgb


def instances_rgb(instances: np.ndarray) -> np.ndarray:
    """(H, W) segment ids (a geometric segmenter's output; -1 none) -> RGB, a colour per
    segment from a fixed cycle (neighbours may share a colour: the white borders tell them
    apart), with borders; black where -1."""
    from benchmark.reports.plotting import segment_borders

    cycle = np.array(INSTANCE_COLORS, np.uint8)
    inst = np.asarray(instances)
    rgb = np.zeros((*inst.shape, 3), np.uint8)
    rgb[inst >= 0] = cycle[inst[inst >= 0] % len(cycle)]
    rgb[segment_borders(inst)] = PAGE_BORDER_COLOR
    return rgb


def _esc(x) -> str:
    return html.escape(str(x), quote=True)


def _img(uri: str, shape: tuple[int, int], alt: str) -> str:
    h, w = shape
    scale = MAP_CSS_PX / max(h, w, 1)
    return f'<img src="{uri}" width="{round(w * scale)}" height="{round(h * scale)}" alt="{_esc(alt)}">'


def job_label(names: dict, oracle_accuracy: float | None) -> str:
    """A configuration in words (classifier and its accuracy, aggregator, post-processing)."""
    if names.get("segmenter"):
        return f"{names['segmenter']} (geometric)"
    clf = names.get("classifier", "")
    if oracle_accuracy is not None:
        clf += f" @ {oracle_accuracy:.0%}"
    return f"{clf} + {formatting.value_label('aggregator', names.get('aggregator', ''))}"


def _config_rows(jobs) -> tuple[list[str], list[dict]]:
    """Per job: names, counts and mean metrics over its successful houses."""
    present = set()
    out = []
    for job, summary, df in jobs:
        ok = df[df["status"] == "ok"]
        names = summary.get("names", {})
        acc = formatting.finite_float(df["oracle_accuracy"].dropna().iloc[0]) if "oracle_accuracy" in df and df[
            "oracle_accuracy"].notna().any() else None
        rec = {"job": job, "names": names, "dataset": str(df["dataset"].iloc[0]) if "dataset" in df and len(df) else "",
               "condition": _first(df, "corruption"), "severity": _first(df, "severity"),
               "oracle_accuracy": acc, "n": len(df), "n_ok": len(ok), "n_failed": len(df) - len(ok),
               "wall": formatting.finite_float(summary.get("wall_time_s"))}
        for m in (*METRICS, *COUNTS):
            if m in ok and len(ok):
                v = pd.to_numeric(ok[m], errors="coerce")
                if v.notna().any():
                    rec[m] = float(v.mean())
                    rec[f"{m} ci"] = bootstrap_ci(v.dropna().to_numpy())
                    present.add(m)
        out.append(rec)
    cols = [m for m in (*METRICS, *COUNTS) if m in present]
    return cols, out


def _ci_words(ci: tuple[float, float] | None, scale: float) -> str:
    """The 95 % interval under a cell's mean (small, muted, one decimal, so that the table keeps
    its width), or "" without one (one house)."""
    if ci is None or not all(np.isfinite(ci)):
        return ""
    return f'<br><small class="muted ci">[{scale * ci[0]:.1f},<wbr> {scale * ci[1]:.1f}]</small>'


def _partial_lines(run_dirs) -> list[str]:
    """One line per sweep under ``run_dirs`` whose jobs did not all finish."""
    from benchmark.reports.sweep_jobs import partial_sweep_lines

    try:
        return partial_sweep_lines(list(run_dirs))
    except ValueError as e:  # an unreadable multirun.yaml: say so rather than guess
        return [str(e)]


def _first(df: pd.DataFrame, col: str) -> str:
    """The column's first value as text ("" when the column is absent or empty)."""
    if col not in df or not df[col].notna().any():
        return ""
    v = df[col].dropna().iloc[0]
    return str(int(v)) if isinstance(v, (int, float, np.integer, np.floating)) and float(v).is_integer() else str(v)


def _robot_columns(rows: list[dict]) -> bool:
    """Whether the configurations differ in robot condition (a robustness run)."""
    return any(r["condition"] not in ("", "clean") for r in rows)


def _condition_words(condition: str) -> str:
    from benchmark.reports.robustness import FAMILY_WORDS

    return FAMILY_WORDS.get(condition, condition) or "–"


def _filters(rows: list[dict]) -> str:
    """Selects above a robustness run's configuration table: show one robot condition and/or
    one severity (the script hides the other rows and says how many show)."""
    conds = sorted({r["condition"] for r in rows if r["condition"]}, key=lambda c: (c != "clean", c))
    sevs = sorted({r["severity"] for r in rows if r["severity"] != ""}, key=lambda v: (len(v), v))

    def select(name: str, words: str, values: list[str], label) -> str:
        opts = "".join(f'<option value="{_esc(v)}">{_esc(label(v))}</option>' for v in values)
        return (f'<label>{words} <select id="filter-{name}" data-attr="{name}">'
                f'<option value="">all</option>{opts}</select></label> ')

    return ('<p class="filters" id="config-filters">Show: ' + select("condition", "robot condition", conds, _condition_words)
            + select("severity", "severity", sevs, lambda v: v)
            + f'<span class="muted" id="filter-count">{len(rows)} of {len(rows)} configurations</span></p>')


def _configs_table(cols: list[str], rows: list[dict]) -> str:
    robot = _robot_columns(rows)
    heads = [("dataset", False), ("classifier", False), ("aggregator", False), ("post-processing", False)]
    if robot:
        heads[1:1] = [("robot condition", False), ("severity", True)]
    heads += [(formatting.METRIC_LABELS.get(m, m.replace("_", " ")) + ("" if m in COUNTS else " %"), True) for m in cols]
    heads += [("houses ok", True), ("failed", True), ("wall s", True)]
    out = ['<table class="sortable" id="configs"><thead><tr>']
    out += [f'<th class="{"num" if n else ""}">{_esc(h)}</th>' for h, n in heads]
    out.append("</tr></thead><tbody>")
    for r in rows:
        nm = r["names"]
        clf = nm.get("segmenter") or nm.get("classifier", "")
        if r["oracle_accuracy"] is not None and not nm.get("segmenter"):
            clf += f" @ {r['oracle_accuracy']:.0%}"
        cells = [formatting.value_label("dataset", r["dataset"]), clf,
                 formatting.value_label("aggregator", nm.get("aggregator", "")) or "–",
                 formatting.value_label("postprocess", nm.get("postprocess", "")) if not nm.get("segmenter") else "–"]
        # the job folder (often longer than the rest of the row) is the first cell's tooltip
        line = f'<td title="{_esc(r["job"].dir.name)}">{_esc(cells[0])}</td>'
        if robot:  # the condition and its severity in columns of their own (sortable, filtered)
            line += (f'<td>{_esc(_condition_words(r["condition"]))}</td>'
                     f'<td class="num" data-v="{_esc(r["severity"])}">{_esc(r["severity"] or "–")}</td>')
        line += "".join(f"<td>{_esc(c)}</td>" for c in cells[1:])
        for m in cols:
            v = r.get(m)
            if v is None:
                line += '<td class="num" data-v="">–</td>'
            elif m in COUNTS:
                line += f'<td class="num" data-v="{v:.6g}">{v:.2f}{_ci_words(r.get(f"{m} ci"), 1.0)}</td>'
            else:
                line += f'<td class="num" data-v="{v:.6g}">{100 * v:.2f}{_ci_words(r.get(f"{m} ci"), 100.0)}</td>'
        line += f'<td class="num" data-v="{r["n_ok"]}">{r["n_ok"]} / {r["n"]}</td>'
        line += f'<td class="num" data-v="{r["n_failed"]}">{r["n_failed"]}</td>'
        wall = r["wall"]
        line += f'<td class="num" data-v="{"" if wall is None else wall}">{"–" if wall is None else f"{wall:.1f}"}</td>'
        attrs = (f' data-condition="{_esc(r["condition"])}" data-severity="{_esc(r["severity"])}"' if robot else "")
        out.append(f"<tr{attrs}>{line}</tr>")
    out.append("</tbody></table>")
    return (_filters(rows) if robot else "") + "".join(out)


def _failures(jobs) -> str:
    items = []
    for job, _, df in jobs:
        bad = df[df["status"] != "ok"]
        for _, r in bad.iterrows():
            items.append((job.dir.name, str(r["house_id"]), str(r.get("error", "") or "")))
    if not items:
        return '<p class="muted" id="failures">No failures: every house of every configuration was scored.</p>'
    out = [f'<p class="muted">{len(items)} failed (house, configuration) pairs.</p>',
           '<table class="sortable" id="failures"><thead><tr><th>job folder</th><th>house</th><th>error</th></tr>'
           "</thead><tbody>"]
    out += [f'<tr><td>{_esc(j)}</td><td>{_esc(h)}</td><td class="err">{_esc(e)}</td></tr>' for j, h, e in items]
    out.append("</tbody></table>")
    return "".join(out)


def _legend(classes: Sequence[str]) -> str:
    from benchmark.reports.plotting import UNLABELLED_LABEL
    from envs.world.classes import UNLABELLED_COLOR, class_colors

    items = [(c.replace("_", " "), rgb) for c, rgb in zip(classes, class_colors(classes))]
    items += [(UNLABELLED_LABEL, UNLABELLED_COLOR), ("not walkable", (0, 0, 0)),
              ("border between segments", PAGE_BORDER_COLOR)]
    seen: set[tuple] = set()  # one swatch per colour (a class coloured like another entry is named once)
    items = [(n, rgb) for n, rgb in items if not (tuple(rgb) in seen or seen.add(tuple(rgb)))]
    return '<div class="legend">' + "".join(
        f'<span><i style="background:rgb{tuple(int(v) for v in rgb)}"></i>{_esc(n)}</span>' for n, rgb in items) + "</div>"


def pick_houses(jobs, houses: Sequence[str] | None, per_dataset: int = HOUSES_PER_DATASET) -> list[str]:
    """The houses to draw: ``houses`` (each scored by some job), else per dataset of the run
    the first ``per_dataset`` houses scored by the most jobs of that dataset (every dataset
    shows, in the order the run first scored it).

    Raises:
        ValueError: a requested house that no job scored."""
    scored: dict[tuple[str, str], int] = {}
    order: list[tuple[str, str]] = []
    for _, _, df in jobs:
        ok = df[df["status"] == "ok"]
        datasets = ok["dataset"].astype(str) if "dataset" in ok else [""] * len(ok)
        for key in zip(datasets, ok["house_id"].astype(str)):
            if key not in scored:
                order.append(key)
            scored[key] = scored.get(key, 0) + 1
    if houses:
        known = {h for _, h in order}
        missing = [h for h in houses if h not in known]
        if missing:
            raise ValueError(f"--house {missing[0]!r}: no job of the run scored it; scored houses are e.g. "
                             f"{[h for _, h in order[:3]]}")
        return list(dict.fromkeys(houses))
    out: list[str] = []
    for dataset in dict.fromkeys(d for d, _ in order):
        best = max(n for (d, _), n in scored.items() if d == dataset)
        out += [h for (d, h) in order if d == dataset and scored[(d, h)] == best][:per_dataset]
    return list(dict.fromkeys(out))


def _house_section(hid: str, jobs) -> str:
    """Ground truth, then per configuration (post-processing grouped) raw | post-processed."""
    from hydra.utils import instantiate

    from benchmark.harness.cache import load_npz

    groups: dict[tuple, dict] = {}
    skipped: list[str] = []
    scene = None
    for job, summary, df in jobs:
        rows = df[(df["house_id"].astype(str) == hid) & (df["status"] == "ok")]
        if "corruption" in rows:  # a robustness run: the maps of the clean condition (the others: its section)
            rows = rows[rows["corruption"].astype(str) == "clean"]
        if rows.empty:
            continue
        try:
            path = job.maps_path(hid)
        except KeyError:
            continue
        if not path.exists():
            continue
        names = summary.get("names", {})
        if scene is None:
            cfg = job.config()
            scene = instantiate(cfg.env).scene(hid)
        maps = load_npz(path)
        shape = next((np.asarray(maps[k]).shape for k in ("raw", "instances", "post") if k in maps), None)
        if shape != scene.grid.shape:  # another grid (e.g. env.resolution changed): not beside this one
            skipped.append(job.dir.name)
            continue
        acc = formatting.finite_float(rows["oracle_accuracy"].iloc[0]) if "oracle_accuracy" in rows else None
        key = (names.get("env"), names.get("segmenter") or "", names.get("classifier"), acc, names.get("aggregator"))
        g = groups.setdefault(key, {"label": job_label(names, acc), "cells": {}})
        if names.get("segmenter"):
            inst = maps.get("instances", maps.get("post"))
            if inst is not None:  # its rooms, in the first map column
                g["cells"]["raw"] = ("rooms (a colour per room)", instances_rgb(inst))
            continue
        g["cells"].setdefault("raw", ("raw", map_rgb(maps["raw"], scene.classes, scene.grid.walkable)))
        if names.get("postprocess") not in ("none", ""):
            kind = f"post-processed ({names['postprocess']})"
            g["cells"][kind] = (kind, map_rgb(maps["post"], scene.classes, scene.grid.walkable))
    if scene is None:
        return f'<section class="house"><h3>House {_esc(hid)}</h3><p class="muted">No saved maps for this house ' \
               f"(run with run.save_maps=true).</p></section>"
    kinds = list(dict.fromkeys(k for g in groups.values() for k in g["cells"]))
    shape = scene.grid.shape
    gt_img = _img(png_data_uri(map_rgb(scene.semantic, scene.classes, scene.grid.walkable,
                                       segments=scene.instances)), shape, f"{hid} ground truth")
    out = [f'<section class="house" id="house-{_esc(hid)}"><h3>House {_esc(hid)}</h3>',
           f'<div class="maps" style="grid-template-columns:190px repeat({len(kinds) + 1}, max-content)">']
    for key in sorted(groups, key=lambda k: tuple("" if v is None else str(v) for v in k)):
        g = groups[key]
        out.append(f'<div class="label">{_esc(g["label"])}</div>')
        out.append(f"<figure><figcaption>ground truth</figcaption>{gt_img}</figure>")
        for k in kinds:
            if k in g["cells"]:
                caption, rgb = g["cells"][k]
                alt = f"{hid} {g['label']} {caption}"
                out.append(f"<figure><figcaption>{_esc(caption)}</figcaption>"
                           f"{_img(png_data_uri(rgb), shape, alt)}</figure>")
            else:
                out.append("<div></div>")
    out.append("</div>")
    if skipped:
        out.append(f'<p class="muted">Not shown (maps on another grid than this ground truth): '
                   f"{_esc(', '.join(skipped))}.</p>")
    out.append("</section>")
    return "".join(out)


def _apart_table(apart: dict) -> str:
    """The robustness section's table of the ipa rows of one dataset (:func:`benchmark.reports.
    robustness.apart_summary`): matched IoU per condition beside the ports on the same houses,
    reported apart, and its notes."""
    table, houses = apart["table"], apart["houses"]
    lead = (f"ipa_room_segmentation (the authors' C++, <code>make ipa-env</code>) beside the ports, on houses of "
            f"its own: {len(houses)} house(s) ({_esc(', '.join(houses))}); matched IoU in percent with its 95 % "
            "interval; reported apart, in no mean, mCE, reference or ranking above"
            + (f"; left out (failed in a row of this table): {_esc(', '.join(apart['dropped']))}"
               if apart["dropped"] else "") + ".")
    notes = "".join(f'<p class="muted">{_esc(n)}</p>' for n in apart["notes"])
    cols = list(apart["conditions"])
    if not cols or not len(table.columns):
        return f'<p class="muted">{lead}</p>{notes}'
    head = "".join(f'<th class="num">{_esc(c)}</th>' for c in cols)
    body = "".join(f"<tr><td>{_esc(m)}</td>" + "".join(_robust_cell(table, m, c) for c in cols) + "</tr>"
                   for m in table.index)
    return (f'<p class="muted">{lead}</p><table class="robust-table ipa-table"><thead><tr><th>method</th>{head}'
            f"</tr></thead><tbody>{body}</tbody></table>{notes}")


def _robust_cell(table: pd.DataFrame, m: str, c: str) -> str:
    """One cell of the robustness table: the number and its 95 % interval (a dash when missing)."""
    v, lo, hi = (table.loc[m, k] if k in table else float("nan") for k in (c, f"{c} lo", f"{c} hi"))
    if pd.isna(v):
        return '<td class="num">–</td>'
    iv = "" if pd.isna(lo) or pd.isna(hi) else f'<br><small class="muted">[{lo:.1f}, {hi:.1f}]</small>'
    return f'<td class="num" data-v="{v:.6g}">{v:.1f}{iv}</td>'


def _robustness_section(run_dirs: Sequence[str | Path], jobs) -> str:
    """A robustness run's summary (``experiment=robustness``; rows with ``corruption``): per
    dataset, matched IoU under each robot condition (mean over its severities) with its 95 %
    interval, mCE, relative mCE and mean drop against a reference every family degrades, and a
    figure per condition (matched IoU vs severity, one line per method). Empty for a run without robot conditions (told from ``jobs``' rows, so that an
    ordinary run's metrics are not read a second time)."""
    import tempfile

    from benchmark.reports import robustness as rb
    from benchmark.reports.formatting import metric_words
    from benchmark.reports.tables import load_rows

    if not any("corruption" in df and (df["corruption"].dropna().astype(str) != "clean").any()
               for _, _, df in jobs):
        return ""
    rows = load_rows(list(run_dirs))
    if "corruption" not in rows or "severity" not in rows:
        return ""
    rows = rows[rows["corruption"].notna()].copy()
    if not (rows["corruption"].astype(str) != "clean").any():  # every run is clean: nothing to compare
        return ""
    rows["severity"] = pd.to_numeric(rows["severity"]).astype(int)
    tops = set(rows.loc[rows["corruption"].astype(str) != "clean"].groupby("corruption")["severity"].max())
    span = "1-5" if tops == {5} else "1 up to its highest"
    out = ['<h2 id="robustness">Robustness to robot conditions</h2>',
           f'<p class="muted">Matched IoU in percent under each robot condition (mean over its severities {span}) with '
           "its 95 % interval over houses, mCE and relative mCE (corruption error relative to a method every "
           "family degrades, named below; 100 = as robust, lower is better; <code>realistic</code> apart, not in "
           "the mean"
           + ("; the labelled conditions <code>lost</code> and <code>kidnap</code> (each severity a situation of "
              "its own) apart too" if rows["corruption"].astype(str).isin(rb.LABELLED).any() else "")
           + ("; the ablation <code>pose</code> (views-only pose noise on a perfect map, which no robot has) apart "
              "too" if rows["corruption"].astype(str).isin(rb.ABLATION).any() else "")
           + ") and the mean drop from the clean score"
           + (" (from a family's own severity 0 where the run has one: named below)"
              if ((rows["corruption"].astype(str) != "clean") & (rows["severity"] == 0)).any() else "")
           + "; the full tables (PQ, the paper's IoU, CE and drop "
           "per condition, rankings, power) are written by <code>python -m benchmark.commands.robustness</code>.</p>"]
    try:
        expected, unrecorded = rb.expected_severities(run_dirs)  # the sweep's, else every one conf/corruption defines
        parts = rb.summarise(rows, ("matched_iou",), "auto", expected, unrecorded=unrecorded)
    except rb.RobustnessError as e:
        return "".join(out) + f'<p class="muted">No robustness table for this run: {_esc(e)}</p>'
    for (dataset, _), part in parts.items():
        table = part["table"]
        cols = ["clean", *[f for f in rb.FAMILIES if f in table], "mCE", "rel mCE", "mean drop"]
        words = {f: rb.FAMILY_WORDS[f] for f in rb.FAMILIES}
        head = "".join(f'<th class="num">{_esc(words.get(c, c))}</th>' for c in cols)
        body = "".join(f"<tr><td>{_esc(m)}</td>" + "".join(_robust_cell(table, m, c) for c in cols) + "</tr>"
                       for m in table.index)
        dropped = f"; left out (failed under some condition): {', '.join(part['dropped'])}" if part["dropped"] else ""
        out += [f"<h3>{_esc(formatting.value_label('dataset', dataset))}</h3>",
                f'<p class="muted">{part["houses"]} houses per cell{_esc(dropped)}.</p>',
                f'<table class="robust-table"><thead><tr><th>method</th>{head}</tr></thead><tbody>{body}</tbody></table>',
                "".join(f'<p class="muted">{_esc(n)}</p>' for n in part["notes"])]
        apart = part.get("apart")
        if apart is not None:  # the authors' ipa_room_segmentation on houses of its own, beside the ports
            out.append(_apart_table(apart))
        out.append('<div class="robust">')
        with tempfile.TemporaryDirectory() as tmp:
            for family in rb.FAMILIES:
                if family not in set(part["cells"]["corruption"]) or family in rb.LABELLED:  # no ladder to draw
                    continue
                png = rb.family_figure(part["cells"], family, Path(tmp) / family, metric_words("matched_iou"),
                                       f"{dataset}: {rb.FAMILY_WORDS[family]}")[0]
                uri = "data:image/png;base64," + base64.b64encode(png.read_bytes()).decode("ascii")
                out.append(f'<img src="{uri}" alt="{_esc(dataset)} matched IoU vs severity: '
                           f'{_esc(rb.FAMILY_WORDS[family])}">')
        out.append("</div>")
    return "".join(out)


def build_report(run_dirs: Sequence[str | Path], houses: Sequence[str] | None = None,
                 per_dataset: int = HOUSES_PER_DATASET, title: str | None = None, last_sweep: bool = False) -> str:
    """The report page's HTML for the jobs under ``run_dirs``.

    Args:
        run_dirs: sweep or job folders (every finished job under them).
        houses: house ids to draw; default ``per_dataset`` houses of every dataset in the run.
        per_dataset: how many houses of each dataset by default.
        title: page title (default: the run folder names).
        last_sweep: read only the jobs of the last multirun into each folder (its
            ``last_sweep.json``); otherwise a folder that also holds earlier runs' jobs is said
            so at the top of the page.

    Returns:
        one self-contained HTML document (str).

    Raises:
        FileNotFoundError: no finished job under ``run_dirs``.
        ValueError: a requested house no job scored.
    """
    from benchmark.harness.store import RUN_SUMMARY_MAPPINGS, find_jobs, sweep_scope
    from benchmark.reports.tables import read_rows

    scope = sweep_scope(list(run_dirs), last_sweep)
    jobs = []
    for job in find_jobs(scope.files):
        df = read_rows(job.metrics_path)  # the checks of every reader of rows: one line naming the file
        df["house_id"] = df["house_id"].astype(str)
        jobs.append((job, job.summary(RUN_SUMMARY_MAPPINGS), df))
    cols, rows = _config_rows(jobs)
    chosen = pick_houses(jobs, houses, per_dataset)
    n_rows = sum(len(df) for _, _, df in jobs)
    n_failed = sum(int((df["status"] != "ok").sum()) for _, _, df in jobs)
    classes = ()
    for job, _, _ in jobs:
        cls = job.config().get("classes")
        if cls:
            classes = tuple(cls)
            break
    name = title or ", ".join(str(Path(p)) for p in run_dirs)
    robust = _robustness_section(scope.files, jobs)
    notes = sorted({str(v) for _, _, df in jobs if "metric_params" in df for v in df["metric_params"].dropna()})
    parts = [
        "<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        f"<title>roomseg-bench report: {_esc(name)}</title><style>{_CSS}</style></head><body>",
        f"<h1>Sweep report: {_esc(name)}</h1>",
        *(f'<p class="err">Partial sweep: {_esc(line)}.</p>' for line in _partial_lines(run_dirs)),
        f'<p class="muted">{len(jobs)} configurations, {n_rows} (house, configuration) rows, {n_failed} failed. '
        "Metrics are means over each configuration's successful houses, in percent, with their 95 % interval "
        "(percentile bootstrap over houses, 2000 resamples, seed 0). "
        + (_esc("Metrics: " + "; ".join(notes) + ".") if notes else "")
        + " Click a column header to sort; hover over a dataset for the job folder.</p>",
        # which runs the page holds, when it is more than one sweep's (make bench reads its own sweep alone)
        f'<p class="scope" id="scope"><strong>Runs read:</strong> {_esc(scope.note)}.</p>' if scope.note else "",
        robust,  # a robustness run leads with its summary; its configurations filter by condition and severity
        "<h2 id=\"configurations\">Configurations</h2>", '<div id="configs-wrap" style="overflow-x:auto">',
        _configs_table(cols, rows),
        "</div>", "<h2>Failures</h2>", _failures(jobs),
        "<h2>Maps</h2>",
        f'<p class="muted">Per house and configuration: the ground truth, the raw label map and the '
        f"post-processed map(s) in class colours, or a geometric segmenter's rooms in a colour per room, side by "
        f"side at the map's resolution. Houses shown: {_esc(', '.join(chosen)) or 'none'}.</p>",
        _legend(classes) if classes else "",
        *(_house_section(h, jobs) for h in chosen),
        f"<script>{_JS}</script>", "</body></html>", ""]
    return "\n".join(parts)


def write_report(run_dirs: Sequence[str | Path], out: str | Path, houses: Sequence[str] | None = None,
                 per_dataset: int = HOUSES_PER_DATASET, last_sweep: bool = False) -> Path:
    """Write :func:`build_report`'s page to ``out`` atomically; returns ``out``."""
    from benchmark.harness.cache import atomic_write_text

    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(out, build_report(run_dirs, houses, per_dataset, last_sweep=last_sweep))
    out.chmod(0o644)
    return out


__all__ = ["build_report", "write_report", "pick_houses", "map_rgb", "instances_rgb", "png_data_uri", "job_label",
           "METRICS", "HOUSES_PER_DATASET", "INSTANCE_COLORS", "PAGE_BORDER_COLOR"]
