"""install_sizes: the environment's size by install step, from the installed distributions'
RECORD files, on a fake site-packages whose files have known sizes."""

from __future__ import annotations

from pathlib import Path

import pytest

from benchmark.commands.maintainer import install_sizes as isz


def _dist(site: Path, name: str, files: dict[str, int], requires: list[str] = (), record_extra: list[str] = ()):
    """A ``<name>-1.0.dist-info`` whose RECORD lists ``files`` (written with those byte sizes)
    and ``record_extra`` (listed, not written)."""
    info = site / f"{name.replace('-', '_')}-1.0.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: " + name + "\nVersion: 1.0\n"
                                   + "".join(f"Requires-Dist: {r}\n" for r in requires))
    for rel, size in files.items():
        (site / rel).parent.mkdir(parents=True, exist_ok=True)
        with open(site / rel, "wb") as f:
            f.truncate(size)  # sparse: the apparent size without writing gigabytes
    (info / "RECORD").write_text("".join(f"{rel},,\n" for rel in [*files, *record_extra]))


@pytest.fixture
def site(tmp_path):
    s = tmp_path / "site-packages"
    _dist(s, "proj", {"proj/__init__.py": 1}, ["a", "B_pkg[x]", 'd ; extra == "docs"', 't ; extra == "test"',
                                               'proj[docs] ; extra == "test"', 'w ; sys_platform == "nowhere"',
                                               "not-installed>=1"])
    _dist(s, "a", {"a/a.so": 10}, ["c"], record_extra=["a/gone.py"])
    _dist(s, "b.pkg", {"b/b.py": 100}, ['e ; extra == "x"', 'w ; extra == "y"'])
    _dist(s, "c", {"c/c.py": 1000, "shared/f.bin": 7})
    _dist(s, "e", {"e/e.py": 10_000})
    _dist(s, "d", {"d/d.py": 200_000}, ["a"])
    _dist(s, "t", {"t/t.py": 3_000_000}, ["torch", "nvidia-foo-cu12"])
    _dist(s, "torch", {"torch/lib.so": 40_000_000}, ["triton"])
    _dist(s, "triton", {"triton/t.so": 500_000_000})
    _dist(s, "nvidia_foo_cu12", {"nvidia/foo.so": 6_000_000_000})
    _dist(s, "cuda-bindings", {"cuda/b.so": 20})
    _dist(s, "w", {"w/w.py": 70})
    _dist(s, "pip", {"pip/p.py": 800, "shared/f.bin": 7})  # a file two RECORDs list counts once
    return s


def test_the_groups_and_their_sizes_on_known_distributions(site):
    dists = isz.installed([site])
    assert dists["a"].size == 10 and dists["a"].files == 1  # a listed file that is gone counts nothing
    assert dists["b-pkg"].size == 100  # names normalised
    assert dists["c"].size + dists["pip"].size == 1000 + 800 + 7
    g = {k: sorted(d.name for d in v) for k, v in isz.groups(dists, "proj").items()}
    assert g == {"core": ["a", "b-pkg", "c", "e", "proj"], "docs extra": ["d"], "test extras": ["t"],
                 "torch": ["torch"], "triton": ["triton"], "CUDA libraries": ["cuda-bindings", "nvidia-foo-cu12"],
                 "other": ["pip", "w"]}
    rows = {r[0]: r[1:] for r in ([c.strip() for c in line.strip("|").split("|")]
                                  for line in isz.table(isz.groups(dists, "proj"), largest=1).splitlines()[2:])}
    assert rows["CUDA libraries"][1:] == ["2", "6.00", "nvidia-foo-cu12 6000"]
    assert rows["triton"][1:3] == ["1", "0.50"] and rows["torch"][1:3] == ["1", "0.04"]
    assert rows["test extras"][1:] == ["1", "0.00", "t 3"]
    assert rows["**all**"][1:3] == ["**13**", f"**{(6_543_211_111 + 20 + 70 + 800 + 7) / 1e9:.2f}**"]


def test_the_first_folder_wins_a_name_in_two(site, tmp_path):
    first = tmp_path / "first"
    _dist(first, "c", {"c/c.py": 5})
    assert isz.installed([first, site])["c"].size == 5
    assert isz.installed([site, first])["c"].size == 1007


def test_the_command_writes_a_measured_table_and_refuses_bad_input(site, tmp_path, capsys):
    out = tmp_path / "sizes.md"
    assert isz.main(["--site", str(site), "--project", "proj", "--out", str(out)]) == 0
    lines = out.read_text().splitlines()
    assert lines[0].startswith("Measured on ") and lines[0].endswith(
        f"by `python -m benchmark.commands.maintainer.install_sizes --site {site} --project proj --out {out}`.")
    assert lines[2].startswith("| group |") and any(line.startswith("| core | `make setup` | 5 | 0.00 |")
                                                    for line in lines)
    capsys.readouterr()
    assert isz.main(["--site", str(site)]) == 2
    assert capsys.readouterr().err.strip() == ("install_sizes: error: project 'roomseg-bench': not installed in the "
                                               "folders read (expected its .dist-info there)")
    assert isz.main(["--site", str(tmp_path / "nope")]) == 2
    assert "not a folder" in capsys.readouterr().err
