"""Several methods' scores on the same ground truth as one static HTML page (``table5.html``,
written by ``baselines table5 --out DIR``): the Table V-style summary (sortable), the failed or
missing maps, and for the first maps the ground truth beside every method's segments, each in a
colour per room with white borders (as the sweep report draws instance maps).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

from benchmark.reports.html_report import _CSS, _JS, _esc, _img, instances_rgb, png_data_uri


def _table(df: pd.DataFrame, table_id: str, sortable: bool = True) -> str:
    """A DataFrame of strings/numbers as an HTML table; numeric-looking cells right-aligned and
    sorted by their leading number."""
    out = [f'<table class="{"sortable" if sortable else ""}" id="{table_id}"><thead><tr>']
    numeric = {c: df[c].astype(str).str.match(r"^[+-]?\d").all() for c in df.columns}
    out += [f'<th class="{"num" if numeric[c] else ""}">{_esc(str(c).replace("_", " "))}</th>' for c in df.columns]
    out.append("</tr></thead><tbody>")
    for _, r in df.iterrows():
        cells = []
        for c in df.columns:
            v = str(r[c])
            if numeric[c]:
                lead = v.split(" ")[0].lstrip("+")
                cells.append(f'<td class="num" data-v="{_esc(lead)}">{_esc(v)}</td>')
            else:
                cells.append(f"<td>{_esc(v)}</td>")
        out.append("<tr>" + "".join(cells) + "</tr>")
    out.append("</tbody></table>")
    return "".join(out)


def build_scores_page(summary: pd.DataFrame, failed: pd.DataFrame, gt: dict[str, np.ndarray],
                      pred: dict[tuple[str, str], np.ndarray], methods: Sequence[str], title: str,
                      note: str = "") -> str:
    """The page's HTML.

    Args:
        summary: :func:`benchmark.baselines.external.summary_table`'s table.
        failed: :func:`benchmark.baselines.external.failures`'s table.
        gt: map id -> (H, W) int room ids of the ground truth, -1 none.
        pred: (method, map id) -> (H, W) int segments on the ground truth's grid, -1 none.
        methods: the methods in table order (their maps are drawn in this order).
        title: the page's heading.
        note: a line under the table (the metric parameters).
    """
    parts = ["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
             '<meta name="viewport" content="width=device-width, initial-scale=1">',
             f"<title>{_esc(title)}</title><style>{_CSS}</style></head><body>", f"<h1>{_esc(title)}</h1>",
             '<p class="muted">Mean [95 % interval] over maps (percentile bootstrap, 2000 resamples, seed 0), percent; segments and count error (segments - rooms) are '
             f"means. Click a column header to sort. {_esc(note)}</p>",
             '<div id="configs-wrap" style="overflow-x:auto">', _table(summary, "configs"), "</div>",
             "<h2>Failed or missing maps</h2>"]
    if len(failed):
        parts.append(_table(failed, "failures"))
    else:
        parts.append('<p class="muted" id="failures">None: every method scored every map.</p>')
    parts += ["<h2>Maps</h2>",
              '<p class="muted">The ground truth and each method\'s segments, a colour per room (the colours '
              "say which pixels form one room, not a class), white borders between rooms, black not walkable.</p>"]
    for mid in sorted(gt):
        shape = gt[mid].shape
        cells = [("ground truth", gt[mid])] + [(m, pred[(m, mid)]) for m in methods if (m, mid) in pred]
        parts.append(f'<section class="house" id="map-{_esc(mid)}"><h3>Map {_esc(mid)}</h3>'
                     f'<div class="maps" style="grid-template-columns:repeat(4, max-content)">')
        for name, inst in cells:
            parts.append(f"<figure><figcaption>{_esc(name)}</figcaption>"
                         f"{_img(png_data_uri(instances_rgb(inst)), shape, f'{mid} {name}')}</figure>")
        parts.append("</div></section>")
    parts += [f"<script>{_JS}</script>", "</body></html>", ""]
    return "\n".join(parts)


__all__ = ["build_scores_page"]
