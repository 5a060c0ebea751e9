"""The project's geometric ports against ipa_room_segmentation's originals (issue 60 item 4):
the Voronoi port's graph pruning, the morphological port's two rules, and the published tables
``results/published/ipa_ports.md`` and ``selros_table5_ipa.md`` (well-formed, their summary
numbers recomputed from their per-map rows where they carry them). Tests that run the authors'
build skip, with the reason, where ``.ipa-env`` holds none (CI); the published files need none."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from benchmark.segmenters.morphological import Morphological
from benchmark.segmenters.voronoi import Voronoi, prune_spurs
from envs.maps.gridmap import GridMap
from tests.test_ipa import NEEDS_BUILD  # the build, or why not: one check for both files

# ---------------------------------------------------------------- Voronoi: the pruned graph


def test_prune_spurs_removes_branches_into_corners_and_keeps_open_ends():
    """A path between two junction-free ends: the end at a clearance maximum above ``room`` (a
    room's middle) stays; a branch whose clearance falls towards its tip goes back to the
    junction it leaves from; the junction stays."""
    skel = np.zeros((9, 20), bool)
    skel[4, 2:18] = True  # the main path, columns 2..17
    skel[1:4, 10] = True  # a spur up from the junction at (4, 10)
    clearance = np.full(skel.shape, 5.0)
    clearance[4, 2] = 9.0  # left tip: a room's middle (a maximum, above room = 6)
    clearance[4, 17] = 3.0  # right tip: runs into a corner (clearance falls)
    clearance[4, 14:17] = [4.5, 4.0, 3.5]
    clearance[1:4, 10] = [2.0, 3.0, 4.0]  # the spur narrows towards its tip
    out = prune_spurs(skel, clearance, room=6.0)
    assert out[4, 2:12].all()  # the left part with its open end, and the junction
    assert not out[4, 12:18].any()  # the right branch went back to the junction
    assert not out[1:3, 10].any() and out[3, 10]  # so did the spur (its foot is a junction pixel)
    # the same tip under a higher ``room`` is a pocket's, not a room's: it goes back too
    low = prune_spurs(skel, clearance, room=10.0)
    assert not low[4, 2:9].any() and low[4, 9:12].all()


def pocket_map() -> GridMap:
    """Two 4 x 4 m rooms (0.05 m/px) joined by a 0.8 m door; in the left room a 1.1 x 1.1 m
    pocket between furniture (0.2 m thick pieces) opening into the room by a 0.6 m gap."""
    walk = np.zeros((84, 166), bool)
    walk[2:82, 2:82] = True
    walk[2:82, 84:164] = True
    walk[34:50, 82:84] = True  # the door
    walk[16:46, 12:42] = False  # the furniture around the pocket
    walk[20:42, 16:38] = True  # the pocket, 22 px
    walk[25:37, 38:42] = True  # its 0.6 m opening to the room
    return GridMap(walk, 0.05, (0.0, 0.0))


def test_voronoi_does_not_cut_a_pocket_between_furniture():
    """Before the pruning, the skeleton's branch into the pocket narrowed at its opening and
    cut the pocket off as a third room (1.2 m^2, above min_room_area); pruned, the branch goes
    and only the door cuts: the two rooms."""
    grid = pocket_map()
    inst = Voronoi()(grid)
    assert inst.max() + 1 == 2
    left, right = np.unique(inst[:, :82][grid.walkable[:, :82]]), np.unique(inst[:, 84:][grid.walkable[:, 84:]])
    assert len(left) == 1 and len(right) == 1 and left[0] != right[0]


# ---------------------------------------------------------------- morphological: the two rules


def two_rooms() -> GridMap:
    """Two 4 x 4 m rooms (0.05 m/px) joined by a 0.8 m door: 32 m^2 in all."""
    walk = np.zeros((84, 166), bool)
    walk[2:82, 2:82] = True
    walk[2:82, 84:164] = True
    walk[34:50, 82:84] = True
    return GridMap(walk, 0.05, (0.0, 0.0))


def test_morphological_split_rule_and_the_originals_limits_rule():
    """The port's rule waits until the door parts the two rooms; the original's (``limits``)
    takes the whole 32 m^2 map as one room at its first erosion step, as it is under 47 m^2,
    and parts it only when the upper limit is below the map's area."""
    grid = two_rooms()
    assert Morphological()(grid).max() + 1 == 2
    assert Morphological(min_seed_area=0.8, max_area=47.0, rule="limits")(grid).max() + 1 == 1
    split = Morphological(min_seed_area=0.8, max_area=20.0, rule="limits")(grid)
    assert split.max() + 1 == 2
    assert len(np.unique(split[:, :82][grid.walkable[:, :82]])) == 1


def test_morphological_rule_is_checked():
    with pytest.raises(ValueError, match=r"segmenter.rule='erode': expected split or limits"):
        Morphological(rule="erode")


# ---------------------------------------------------------------- the published tables

ROOT = Path(__file__).resolve().parents[1]
PUBLISHED = ROOT / "results" / "published"


def _tables(text: str) -> list[list[list[str]]]:
    """The Markdown tables of a page: per table its rows (header first, the rule left out) as cells."""
    tables, cur = [], None
    for line in text.splitlines():
        if line.startswith("|"):
            cells = [c.strip() for c in line.strip().strip("|").split("|")]
            if cur is None:
                cur = []
                tables.append(cur)
            if not all(set(c) <= set(":-") for c in cells):
                cur.append(cells)
        else:
            cur = None
    return tables


def _interval(cell: str) -> tuple[float, float, float]:
    m = re.fullmatch(r"(-?[\d.]+) \[(-?[\d.]+), (-?[\d.]+)\]", cell)
    assert m, cell
    return tuple(float(x) for x in m.groups())


def test_published_ipa_ports_is_well_formed_and_recomputes_from_its_rows():
    """results/published/ipa_ports.md (docs/baselines.md includes it): the command on its first
    line is the Makefile's; every number of its tables is the mean (and interval) of its per-map
    rows, published beside it as ipa_ports.csv."""
    from benchmark.commands.ipa_ports import COLUMNS, OVER_SPLIT, PORTS, SOURCE_NAMES, per_room
    from benchmark.stats import bootstrap_ci, paired_ci

    text = (PUBLISHED / "ipa_ports.md").read_text(encoding="utf-8")
    command = re.match(r"Written by `(python -m benchmark\.commands\.ipa_ports [^`]*)`\.\n", text).group(1)
    assert command.replace("python -m", "$(PY) -m") in (ROOT / "Makefile").read_text(encoding="utf-8")
    assert '--8<-- "results/published/ipa_ports.md"' in (ROOT / "docs" / "baselines.md").read_text(encoding="utf-8")
    assert "ipa rows: run here from ipa_coverage_planning at commit " in text
    df = pd.read_csv(PUBLISHED / "ipa_ports.csv")
    assert list(df.columns) == COLUMNS
    assert set(df["algorithm"]) == set(PORTS)
    counts = df.groupby("source")["map"].nunique().to_dict()
    assert counts == {"selros": 30, "real": 4, "synthetic": 100}
    assert df.groupby(["source", "map"]).size().eq(len(PORTS)).all()  # every algorithm on every map
    assert df.loc[df["source"] == "real", "rooms"].isna().all() and df.loc[df["source"] != "real", "rooms"].notna().all()
    names = {v: k for k, v in SOURCE_NAMES.items()}
    summary, split, real = _tables(text)
    assert summary[0][:3] == ["maps", "algorithm", "n"] and len(summary) == 1 + 2 * len(PORTS)
    for cells in summary[1:]:
        g = df[(df["source"] == names[cells[0]]) & (df["algorithm"] == cells[1])]
        assert int(cells[2]) == len(g)
        ag = g["agreement_matched_iou"].to_numpy(float)
        sp, so = per_room(g, "port"), per_room(g, "original")
        want = [(ag.mean() * 100, *(100 * v for v in bootstrap_ci(ag))), (sp.mean(), *bootstrap_ci(sp)),
                (so.mean(), *bootstrap_ci(so)),
                tuple(100 * v for v in paired_ci(g["port_matched_iou"], g["original_matched_iou"])),
                tuple(100 * v for v in paired_ci(g["port_pq"], g["original_pq"]))]
        for cell, w in zip(cells[3:], want, strict=True):
            assert np.allclose(_interval(cell), w, atol=0.011), (cells[:2], cell, w)
    assert len(split) == 1 + 2 * len(PORTS)
    for cells in split[1:]:
        g = df[(df["source"] == names[cells[0]]) & (df["algorithm"] == cells[1])]
        sp, so = per_room(g, "port"), per_room(g, "original")
        over = sp > OVER_SPLIT
        worst = int(np.argmax(sp))
        assert cells[2] == f"{g['map'].iloc[worst]}: {sp[worst]:.2f} / {so[worst]:.2f}"
        assert [int(cells[3]), int(cells[4]), int(cells[6])] == [over.sum(), (over & (so > OVER_SPLIT)).sum(),
                                                               (so > OVER_SPLIT).sum()]
    assert len(real) == 1 + 4 * len(PORTS)
    for cells in real[1:]:
        r = df[(df["source"] == "real") & (df["map"] == cells[0]) & (df["algorithm"] == cells[1])].iloc[0]
        assert abs(float(cells[2]) - 100 * r["agreement_matched_iou"]) <= 0.006
        assert [int(cells[3]), int(cells[4])] == [r["port_segments"], r["original_segments"]]


def test_published_selros_table5_ipa_is_well_formed_and_its_ipa_rows_are_the_ports_tables():
    """results/published/selros_table5_ipa.md: 30 maps a row, every mean inside its interval, the
    same rooms behind every row (segments - count error), and the originals' matched IoU and PQ
    on the SeLRoS maps the means of ipa_ports.csv's rows (the same maps, build and scoring)."""
    text = (PUBLISHED / "selros_table5_ipa.md").read_text(encoding="utf-8")
    assert re.match(r"Written by `python -m benchmark\.commands\.selros --ipa [^`]*--markdown "
                    r"results/published/selros_table5_ipa\.md`\.\n", text)
    assert "ipa rows: run here from ipa_coverage_planning at commit " in text
    (rows,) = _tables(text)
    head = rows[0]
    body = {r[0]: dict(zip(head, r)) for r in rows[1:]}
    assert {"ipa_morphological", "ipa_distance", "ipa_voronoi", "ipa_semantic", "ipa_vrf", "morphological",
            "distance", "voronoi"} <= set(body)
    rooms = []
    for name, r in body.items():
        assert r["maps"] == "30", name
        for col in ("iou", "precision", "recall", "matched_iou", "pq"):
            mean, lo, hi = _interval(r[col])
            assert lo <= mean <= hi and 0 <= lo and hi <= 100, (name, col)
        rooms.append(float(r["segments"]) - float(r["count_error"]))
    assert max(rooms) - min(rooms) <= 0.11  # one decimal each
    df = pd.read_csv(PUBLISHED / "ipa_ports.csv")
    sel = df[df["source"] == "selros"]
    for algorithm in ("morphological", "distance", "voronoi"):
        g = sel[sel["algorithm"] == algorithm]
        r = body[f"ipa_{algorithm}"]
        assert abs(_interval(r["matched_iou"])[0] - 100 * g["original_matched_iou"].mean()) <= 0.006, algorithm
        assert abs(_interval(r["pq"])[0] - 100 * g["original_pq"].mean()) <= 0.006, algorithm


# ---------------------------------------------------------------- the command


def test_ports_command_refuses_bad_options_in_one_line(capsys):
    from benchmark.commands.ipa_ports import main

    assert main(["--sources", "selros,mars"]) == 2
    assert main(["--algorithms", "voronoi,watershed"]) == 2
    assert main(["--sources", "synthetic", "--houses", "0"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 3
    assert err[0] == "error: --sources selros,mars: expected a comma list of selros, real, synthetic"
    assert err[1].startswith("error: --algorithms voronoi,watershed: expected a comma list of morphological, ")
    assert err[2].startswith("error: --houses 0 --seed-start 0 --limit None: expected houses >= 1")


def test_ports_command_on_generated_houses_without_a_build_is_one_line(tmp_path, monkeypatch, capsys):
    from benchmark.commands.ipa_ports import main

    monkeypatch.setenv("ROOMSEG_IPA_ENV", str(tmp_path / "nothing"))
    assert main(["--sources", "synthetic", "--houses", "1"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("error: segmenter=ipa_morphological: no ipa_room_segmentation build")


@NEEDS_BUILD
def test_ports_command_on_one_generated_house_and_one_real_map(tmp_path, capsys):
    """With the build: one generated house and (where the shared data has them) one real map;
    the file is headed by the command, the per-map rows beside it; the limits rule agrees with
    the original on the house."""
    from benchmark.commands.ipa_ports import main
    from benchmark.paths import data_dir

    sources = "real,synthetic" if (data_dir() / "real_maps").is_dir() else "synthetic"
    out = tmp_path / "ports.md"
    assert main(["--sources", sources, "--houses", "1", "--seed-start", "7", "--limit", "1",
                 "--algorithms", "morphological_limits,voronoi", "--markdown", str(out)]) == 0
    capsys.readouterr()
    text = out.read_text(encoding="utf-8")
    assert text.startswith(f"Written by `python -m benchmark.commands.ipa_ports --sources {sources} --houses 1 "
                           f"--seed-start 7 --limit 1 --algorithms morphological_limits,voronoi --markdown {out}`.")
    assert "seeds 7-7" in text
    df = pd.read_csv(out.with_suffix(".csv"))
    house = df[df["source"] == "synthetic"]
    assert list(house["map"]) == ["synthetic-s000007"] * 2
    assert house.set_index("algorithm").loc["morphological_limits", "agreement_matched_iou"] > 0.9
    assert len(df) == 2 * len(sources.split(","))
