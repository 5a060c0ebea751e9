"""The VRF's two causes of few segments on the SeLRoS maps, map by map (issue 60 item 3):
``benchmark.commands.maintainer.vrf_causes``'s table and counts from hand-made per-map results,
the ipa segmenter's working resolution and the driver's field-node line with a stand-in driver
(no build needed), and, with the build and the SeLRoS release (skipped without), one map run
through the command."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from benchmark.commands.maintainer import vrf_causes
from benchmark.commands.maintainer.vrf_causes import COLUMNS, one_class, summary, table
from benchmark.segmenters.ipa import PAD_PX, IpaSegmenter, ipa_image, labels_to_instances
from envs.maps.gridmap import GridMap
from tests.test_ipa import BUILD, standin_build

ROOT = Path(__file__).resolve().parents[1]


def _row(mid, rooms, seg_a, seg_o, nodes_a, nodes_o, iou_a=0.5, iou_o=0.5, error=""):
    row = {"map": mid, "rooms": rooms, "authors_resolution": 0.05, "own_resolution": 0.02,
           "authors_segments": seg_a, "own_segments": seg_o, "authors_matched_iou": iou_a,
           "own_matched_iou": iou_o, "error": error}
    for run, nodes in (("authors", nodes_a), ("own", nodes_o)):
        for c, v in zip(("room", "hallway", "doorway"), nodes or (np.nan,) * 3, strict=True):
            row[f"{run}_nodes_{c}"] = v
    return row


def _fixture() -> pd.DataFrame:
    rows = [_row("a", 3, 0, 3, (50, 0, 0), (100, 20, 5), 0.125, 0.6),   # one class, and more at 0.02: both
            _row("b", 2, 1, 1, (30, 5, 2), (60, 0, 0), 0.4, 0.4),       # neither at 0.05; one class at 0.02
            _row("c", 4, 4, 5, (80, 10, 6), (150, 30, 9)),              # not a map of few segments
            _row("d", 2, 0, 0, None, None),                             # the build did not say
            _row("e", 3, np.nan, np.nan, None, None, np.nan, np.nan,
                 "the ipa driver failed on vrf (exit 1): boom"),         # a failed map
            _row("f", 1, 1, 1, (0, 12, 0), (0, 30, 0))]                 # one class (hallway) only
    return pd.DataFrame(rows, columns=COLUMNS)


def test_one_class_says_which_class_none_or_unknown():
    df = _fixture().set_index("map")
    assert one_class(df.loc["a"], "authors") == "room" and one_class(df.loc["a"], "own") == ""
    assert one_class(df.loc["f"], "authors") == "hallway"
    assert one_class(df.loc["d"], "authors") is None and one_class(df.loc["e"], "own") is None


def test_the_table_from_per_map_results():
    text = table(_fixture())
    lines = text.splitlines()
    assert lines[0] == ("| map | rooms | segments at 0.05 | at 0.02 | field nodes at 0.05: room / hallway / doorway "
                        "| one class | at 0.02: room / hallway / doorway | one class | matched IoU at 0.05 | at 0.02 |")
    assert lines[2] == "| a | 3 | 0 | 3 | 50 / 0 / 0 | yes (room) | 100 / 20 / 5 | no | 12.50 | 60.00 |"
    assert lines[3] == "| b | 2 | 1 | 1 | 30 / 5 / 2 | no | 60 / 0 / 0 | yes (room) | 40.00 | 40.00 |"
    assert lines[5] == "| d | 2 | 0 | 0 | – | unknown | – | unknown | 50.00 | 50.00 |"
    assert lines[6] == "| e | 3 | failed | | | | | | | |"
    assert lines[7] == "| f | 1 | 1 | 1 | 0 / 12 / 0 | yes (hallway) | 0 / 30 / 0 | yes (hallway) | 50.00 | 50.00 |"
    assert "- e: the ipa driver failed on vrf (exit 1): boom" in lines
    assert summary(_fixture()) in text


def test_the_maps_counted_per_cause():
    # few segments (<= 1 at 0.05) among the 5 maps that ran: a, b, d, f (a, b, d with > 1 room);
    # one class at 0.05: a, f; more at 0.02: a; both: a; neither: b; unknown: d
    assert summary(_fixture()) == (
        "**Maps per cause**: 4 of the 5 maps end with at most 1 segment at 0.05 m/px (3 of them with more than one "
        "room in the ground truth); every field node one class there (cause 2): 2; more segments at 0.02 m/px "
        "(cause 1): 1; both: 1; neither: 1; the build did not say how the nodes were labelled on 1; over all 5 "
        "maps, more segments at 0.02 m/px than at 0.05 m/px on 2, at most 1 segment at 0.02 m/px on 3, every field "
        "node one class at 0.05 m/px on 2 and at 0.02 m/px on 2. 1 map(s) failed (below).")


# ---------------------------------------------------------------- the segmenter, a stand-in driver
STANDIN = r'''#!{python}
"""A stand-in for ipa_segment: writes its arguments beside itself, one room over the free space,
the VRF's chatter (the field-node line) on stderr with --verbose 1; IPA_STANDIN=fail: chatter,
then the driver's one line, exit 1."""
import json, os, sys
import cv2, numpy as np
a = dict(zip(sys.argv[1::2], sys.argv[2::2]))
json.dump(sys.argv[1:], open(os.path.join(os.path.dirname(__file__), "argv.json"), "w"))
if a.get("--verbose") == "1":
    print("created graph. Time: 1ms\nroomseg field nodes: room 7 hallway 2 doorway 1\nfound segments: 1", file=sys.stderr)
if os.environ.get("IPA_STANDIN") == "fail":
    sys.exit(print("ipa_segment: vrf returned no label image of the map's size\nmerged rooms together", file=sys.stderr) or 1)
m = cv2.imread(a["--map"], cv2.IMREAD_UNCHANGED)
cv2.imwrite(a["--out"], (m == 255).astype(np.uint16))
print("rooms 1")
'''


@pytest.fixture
def standin(tmp_path: Path) -> Path:
    return standin_build(tmp_path, STANDIN, vrf=True, vrf_fix=True)


def _argv(env: Path) -> dict:
    argv = json.loads((env / "bin" / "argv.json").read_text())
    return dict(zip(argv[::2], argv[1::2], strict=True))


def test_the_driver_gets_the_map_at_the_working_resolution_and_its_field_nodes_are_kept(standin, tmp_path):
    walk = np.zeros((50, 80), bool)  # 1 x 1.6 m at 0.02 m/px, a 0.6 x 1.2 m free rectangle
    walk[10:40, 10:70] = True
    grid = GridMap(walk, 0.02, (0.0, 0.0))
    seg = IpaSegmenter("vrf", env_dir=str(standin), resolution=0.02)
    inst = seg(grid)
    a = _argv(standin)
    assert a["--resolution"] == "0.02" and a["--algorithm"] == "vrf" and a["--verbose"] == "1"
    assert (inst[walk] == 0).all() and (inst[~walk] == -1).all()  # the map unresampled: every cell back
    assert seg.last_field_nodes == {"room": 7, "hallway": 2, "doorway": 1}
    # the default: the authors' 0.05 m/px, the map resampled (2.5 times fewer pixels a side)
    IpaSegmenter("vrf", env_dir=str(standin))(grid)
    assert _argv(standin)["--resolution"] == "0.05"
    # another algorithm: no chatter asked for, no field nodes
    seg = IpaSegmenter("distance", env_dir=str(standin), resolution=0.02)
    seg(grid)
    assert "--verbose" not in _argv(standin) and seg.last_field_nodes is None


def test_a_failed_vrf_run_names_the_drivers_line_not_its_chatter(standin, monkeypatch):
    monkeypatch.setenv("IPA_STANDIN", "fail")
    seg = IpaSegmenter("vrf", env_dir=str(standin))
    with pytest.raises(RuntimeError, match=r"^the ipa driver failed on vrf \(exit 1\): ipa_segment: vrf returned no "
                                           r"label image of the map's size$"):
        seg(GridMap(np.ones((20, 20), bool), 0.05, (0.0, 0.0)))
    assert seg.last_field_nodes is None


def test_the_map_at_its_own_resolution_by_hand():
    walk = np.zeros((6, 8), bool)
    walk[1:5, 2:7] = True
    img = ipa_image(walk, 0.02, 0.02)  # no resampling: the map itself, padded
    assert img.shape == (6 + 2 * PAD_PX, 8 + 2 * PAD_PX)
    assert ((img[PAD_PX:-PAD_PX, PAD_PX:-PAD_PX] == 255) == walk).all() and (img[:PAD_PX] == 0).all()
    labels = np.zeros(img.shape, np.uint16)
    labels[PAD_PX:-PAD_PX, PAD_PX:PAD_PX + 4] = 5  # the driver's room 5 over columns 0-3, room 9 over 4-7
    labels[PAD_PX:-PAD_PX, PAD_PX + 4:-PAD_PX] = 9
    inst = labels_to_instances(labels, walk, 0.02, 0.02)
    want = np.where(walk, np.where(np.arange(8) < 4, 0, 1)[None, :], -1)
    assert (inst == want).all()


@pytest.mark.parametrize("value", [0, -0.05, float("nan"), True, "0.05"])
def test_a_bad_working_resolution_is_one_line(standin, value):
    with pytest.raises(ValueError, match="^" + re.escape(f"segmenter.resolution={value!r}: expected metres per pixel > 0")):
        IpaSegmenter("vrf", env_dir=str(standin), resolution=value)


def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys, monkeypatch):
    assert vrf_causes.main(["--limit", "0"]) == 2
    assert capsys.readouterr().err == "error: --limit 0: expected a number of maps >= 1\n"
    assert vrf_causes.main(["--data", str(tmp_path / "nothing")]) == 2
    assert capsys.readouterr().err == f"error: the SeLRoS release is not at {tmp_path / 'nothing'} (give --data DIR)\n"
    for sub in ("ground_truth", "vrf"):
        (tmp_path / "selros" / sub).mkdir(parents=True)
    monkeypatch.setenv("ROOMSEG_IPA_ENV", str(tmp_path / "no-build"))
    assert vrf_causes.main(["--data", str(tmp_path / "selros")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("error: segmenter=ipa_vrf: no ipa_room_segmentation build in")


# ---------------------------------------------------------------- with the build and the release
def _selros() -> Path | None:
    from benchmark.baselines.selros import default_selros_dir

    try:
        d = default_selros_dir()
    except Exception:  # noqa: BLE001 - no shared-data root configured
        return None
    return d if (d / "ground_truth" / "01_ground_truth.png").is_file() else None


@pytest.mark.slow
@pytest.mark.skipif(isinstance(BUILD, str) or not BUILD["vrf"], reason=f"no ipa_room_segmentation build with VRF: {BUILD}")
@pytest.mark.skipif(_selros() is None, reason="the SeLRoS release is absent (python -m benchmark.commands.data fetch selros)")
def test_one_map_run_through_the_command(tmp_path, capsys):
    out = tmp_path / "vrf_causes.md"
    assert vrf_causes.main(["--limit", "1", "--markdown", str(out)]) == 0
    text = out.read_text()
    assert text.startswith("Written by `python -m benchmark.commands.maintainer.vrf_causes --limit 1 --markdown ")
    rows = pd.read_csv(out.with_suffix(".csv"), dtype={"map": str})
    assert list(rows.columns) == COLUMNS and list(rows["map"]) == ["01"] and rows["error"].isna().all()
    r = rows.iloc[0]
    assert r["rooms"] >= 1
    assert r["authors_resolution"] == 0.05 and r["own_resolution"] == 0.02
    for run in ("authors", "own"):
        assert r[f"{run}_segments"] >= 0 and 0 <= r[f"{run}_matched_iou"] <= 1
        nodes = [r[f"{run}_nodes_{c}"] for c in ("room", "hallway", "doorway")]
        # a build of make ipa-env prints the field nodes' labels (native/ipa/roomseg_vrf_labels.h)
        assert all(n >= 0 for n in nodes) and sum(nodes) > 0, "run make ipa-env again: the driver says no field nodes"
    # more pixels at the map's own resolution: more field nodes
    assert sum(r[f"own_nodes_{c}"] for c in ("room", "hallway", "doorway")) > \
        sum(r[f"authors_nodes_{c}"] for c in ("room", "hallway", "doorway"))
    line = next(x for x in text.splitlines() if x.startswith("| 01 |"))
    assert line.split(" | ")[2] == str(int(r["authors_segments"])) and "unknown" not in line
    assert "**Maps per cause**: " in text and "ipa rows: run here from ipa_coverage_planning at commit" in text
