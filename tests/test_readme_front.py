"""The README is the front door: it fits on a screen (at most 15 KB), every number in it is
written by a command (inside a generated block), and every page and picture it links to
exists."""

from __future__ import annotations

import re
from pathlib import Path

from benchmark.reports import readme_tables as rt

ROOT = Path(__file__).resolve().parents[1]
MAX_BYTES = 15_000

#: a number: a digit that does not continue a word, a path or a version (fig3, Qwen2.5 are names).
NUMBER = re.compile(r"(?<![A-Za-z0-9_.\-/])[0-9][0-9,.]*")


def _outside_generated(text: str) -> str:
    """``text`` with every generated block (between its BEGIN and END markers) cut out."""
    for name, body in rt.blocks_in(text).items():
        text = text.replace(body, f"<generated {name}>", 1)
    return text


def hand_typed_numbers(text: str) -> list[str]:
    """Numbers outside the generated blocks, each with its line."""
    out = []
    for line in _outside_generated(text).splitlines():
        out += [f"{m.group(0)!r} in: {line.strip()}" for m in NUMBER.finditer(line)]
    return out


def test_readme_is_at_most_15_kb():
    size = (ROOT / "README.md").stat().st_size
    assert size <= MAX_BYTES, f"README.md is {size} bytes; at most {MAX_BYTES}: move text to a page under docs/"


def test_every_number_in_the_readme_is_generated():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    assert set(rt.blocks_in(text)) >= {"bench-timing", "bench-table4", "robustness-timing", "robustness-power"}
    assert hand_typed_numbers(text) == []


def test_the_check_finds_a_hand_typed_number():
    """The check itself: a number typed outside a block is caught, inside a block it is not,
    and names with digits are not numbers."""
    assert hand_typed_numbers("took 33 s\n") == ["'33' in: took 33 s"]
    assert hand_typed_numbers("a 2.5x speed-up, 1,096 px\n") == ["'2.5' in: a 2.5x speed-up, 1,096 px",
                                                                "'1,096' in: a 2.5x speed-up, 1,096 px"]
    assert hand_typed_numbers("fig3.png, Qwen2.5-VL, DINOv2, ROSE², sha-256\n") == []
    block = "<!-- BEGIN generated: bench-table3 (x) -->\n| 12.5 |\n<!-- END generated: bench-table3 -->\n"
    assert hand_typed_numbers("intro\n" + block + "outro\n") == []
    assert hand_typed_numbers("intro 7\n" + block) == ["'7' in: intro 7"]


def test_readme_links_and_pictures_exist():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    targets = re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text)
    assert targets
    local = [t for t in targets if "://" not in t]
    missing = [t for t in local if not (ROOT / t).exists()]
    assert missing == [], f"README links to missing files: {missing}"
    pages = {t for t in local if t.startswith("docs/") and t.endswith(".md")}
    assert {"docs/getting-started.md", "docs/plugins.md", "docs/metrics.md", "docs/gpu.md",
            "docs/reliability.md"} <= pages
