"""The dependency rules of the layout, read from the source with ``ast`` (no imports run):

* ``envs`` never imports ``benchmark``;
* nothing outside ``benchmark/commands`` imports ``benchmark.commands`` (commands sit on top);
* the algorithms (every ``benchmark`` module outside ``harness``, ``reports`` and ``commands``:
  method, classifiers, aggregators, segmenters, metrics, ...) import neither the harness nor
  the reports, which sit on top of them;
* no import cycle between the modules of the project;
* ``hydra_plugins`` (imported by Hydra whenever any app starts) imports no project module but
  the standard-library-only ones of :data:`PLUGIN_SAFE` (cores, workers that die with their parent).
"""

import ast
import importlib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("envs", "benchmark")


def module_name(path: Path) -> str:
    rel = path.relative_to(ROOT).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def project_imports(path: Path) -> set[str]:
    """Every project module a file imports (at any depth: lazy imports count too)."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    me = module_name(path)
    out: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            assert not node.level, f"{me}: relative import (the project uses absolute imports only)"
            mod = node.module or ""
            names = [mod] + [f"{mod}.{a.name}" for a in node.names]
        else:
            continue
        out.update(n for n in names if n.split(".")[0] in PACKAGES)
    return out


def all_modules() -> dict[str, set[str]]:
    files = [p for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py")]
    return {module_name(p): project_imports(p) for p in files}


@pytest.fixture(scope="module")
def graph():
    return all_modules()


def test_envs_never_imports_benchmark(graph):
    bad = sorted((m, i) for m, imps in graph.items() if m.startswith("envs") for i in imps if i.startswith("benchmark"))
    assert not bad, f"envs modules importing benchmark: {bad}"


def test_only_commands_import_commands(graph):
    # benchmark.cli is the `roomseg` dispatcher: a command by role (it runs the others and installs
    # their one Ctrl-C handler, benchmark.commands.cli, before it dispatches)
    bad = sorted((m, i) for m, imps in graph.items() if not m.startswith("benchmark.commands") and m != "benchmark.cli"
                 for i in imps if i == "benchmark.commands" or i.startswith("benchmark.commands."))
    assert not bad, f"modules importing a command module: {bad}"


#: the packages that sit on top of the algorithms.
UPPER = ("benchmark.harness", "benchmark.reports", "benchmark.commands")


def upward_imports(graph: dict[str, set[str]]) -> list[tuple[str, str]]:
    """(algorithm module, harness/reports module it imports) pairs."""
    def upper(name: str) -> bool:
        return any(name == u or name.startswith(u + ".") for u in UPPER)

    return sorted((m, i) for m, imps in graph.items() if m.startswith("benchmark.") and not upper(m)
                  for i in imps if upper(i) and not i.startswith("benchmark.commands"))


def test_algorithms_import_neither_harness_nor_reports(graph):
    bad = upward_imports(graph)
    assert not bad, f"algorithm modules importing the harness or the reports: {bad}"


def test_the_upward_rule_catches_an_upward_import():
    """A made-up classifier module importing the run store, and a lazy import of a report, are seen."""
    fake = ROOT / "benchmark" / "classifiers" / "_layout_probe_tmp.py"
    try:
        fake.write_text("from benchmark.harness.store import Job\n\ndef f():\n"
                        "    from benchmark.reports.plotting import save\n    return save\n")
        graph = {module_name(fake): project_imports(fake)}
        assert [i for _, i in upward_imports(graph)] == ["benchmark.harness.store", "benchmark.harness.store.Job",
                                                          "benchmark.reports.plotting",
                                                          "benchmark.reports.plotting.save"]
    finally:
        fake.unlink(missing_ok=True)


def test_no_import_cycles(graph):
    modules = set(graph)

    def resolve(name: str) -> str | None:  # `from a.b import c` names a.b.c (module) or a.b (attribute)
        while name and name not in modules:
            name = name.rpartition(".")[0]
        return name or None

    edges = {m: {r for i in imps if (r := resolve(i)) and r != m and not m.startswith(r + ".")} for m, imps in graph.items()}
    # a package's __init__ importing its own submodules is not a cycle of roles: drop parent -> child edges
    edges = {m: {e for e in es if not e.startswith(m + ".")} for m, es in edges.items()}
    state: dict[str, int] = {}
    stack: list[str] = []
    cycles = []

    def visit(m: str) -> None:
        state[m] = 1
        stack.append(m)
        for n in sorted(edges.get(m, ())):
            if state.get(n) == 1:
                cycles.append(stack[stack.index(n):] + [n])
            elif n not in state:
                visit(n)
        stack.pop()
        state[m] = 2

    for m in sorted(edges):
        if m not in state:
            visit(m)
    assert not cycles, f"import cycles: {cycles[:5]}"


#: project modules the Hydra plugins may import: each imports the standard library only.
PLUGIN_SAFE = ("benchmark.harness.processes", "benchmark.harness.write_errors", "benchmark.harness.sweep_progress")


def stdlib_only(path: Path) -> list[str]:
    """The top-level modules ``path`` imports that are not in the standard library."""
    import sys

    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(a.name.split(".")[0] for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            names.add((node.module or "").split(".")[0])
    return sorted(n for n in names if n not in sys.stdlib_module_names and n != "__future__")


def test_hydra_plugins_import_no_project_module():
    """Hydra imports every module under ``hydra_plugins`` when any app starts: the sweeper and
    launcher stay light (Hydra, the standard library and the modules of :data:`PLUGIN_SAFE`,
    which import the standard library only)."""
    files = list((ROOT / "hydra_plugins").rglob("*.py"))
    assert files
    allowed = set(PLUGIN_SAFE) | {f"{m}.{name}" for m in PLUGIN_SAFE for name in dir(importlib.import_module(m))}
    bad = {module_name(p): imps - allowed for p in files if (imps := project_imports(p)) - allowed}
    assert not bad, f"hydra_plugins importing the project: {bad}"
    heavy = {m: extra for m in PLUGIN_SAFE if (extra := stdlib_only(ROOT / (m.replace(".", "/") + ".py")))}
    assert not heavy, f"modules the plugins import that import more than the standard library: {heavy}"


def test_the_plugin_rule_catches_a_heavy_import(tmp_path):
    """The standard-library check sees a third-party import, lazy or not."""
    fake = tmp_path / "mod.py"
    fake.write_text("import os\nfrom collections import deque\n\ndef f():\n    import numpy\n    return numpy\n")
    assert stdlib_only(fake) == ["numpy"]


def test_the_rules_catch_a_bad_import(tmp_path):
    """The checker itself: a made-up envs module importing benchmark is seen."""
    fake = ROOT / "envs" / "_layout_probe_tmp.py"
    try:
        fake.write_text("def f():\n    from benchmark.commands.bench import main\n    return main\n")
        imps = project_imports(fake)
        assert "benchmark.commands.bench" in imps and "benchmark.commands.bench.main" in imps
    finally:
        fake.unlink(missing_ok=True)


def test_the_harness_never_imports_the_reports(graph):
    """The harness runs houses and writes rows; tables, figures and pages read them afterwards."""
    bad = sorted((m, i) for m, imps in graph.items() if m.startswith("benchmark.harness")
                 for i in imps if i.startswith("benchmark.reports"))
    assert not bad, f"harness modules importing the reports: {bad}"


#: what composes a Hydra config: Hydra's compose API and the project's one place for it.
COMPOSERS = ("hydra.compose", "hydra.initialize_config_dir", "hydra.initialize", "benchmark.config.compose",
             "benchmark.config.compose_job", "benchmark.config.classifier_config",
             "benchmark.config.build_classifier")
#: the modules that may compose: the config module itself, and the layers above the algorithms.
MAY_COMPOSE = ("benchmark.config", "benchmark.cli", *UPPER)


def hydra_composers(path: Path) -> set[str]:
    """The composing names ``path`` imports (Hydra's own included)."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module:
            out.update(f"{node.module}.{a.name}" for a in node.names)
        elif isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
    return {n for n in out if n in COMPOSERS}


def composing_algorithms() -> list[tuple[str, str]]:
    files = [p for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py")]
    return sorted((module_name(p), c) for p in files
                  if not any(module_name(p) == u or module_name(p).startswith(u + ".") for u in MAY_COMPOSE)
                  for c in hydra_composers(p))


def test_algorithm_modules_never_compose_hydra_configs():
    """A stage gets its settings as arguments; composing a config is the commands' and the
    harness's job (benchmark/config.py is the one place that does it)."""
    bad = composing_algorithms()
    assert not bad, f"algorithm modules composing a Hydra config: {bad}"


def test_the_compose_rule_catches_a_composing_stage():
    fake = ROOT / "benchmark" / "aggregators" / "_layout_probe_tmp.py"
    try:
        fake.write_text("def f():\n    from benchmark.config import compose\n    return compose('config')\n")
        assert ("benchmark.aggregators._layout_probe_tmp", "benchmark.config.compose") in composing_algorithms()
    finally:
        fake.unlink(missing_ok=True)


#: the layers of ``envs``, lowest first: a module imports only its own layer and those below
#: (the first: standard-library helpers, such as the value ranges of envs.ranges that stage
#: classes of every layer annotate their parameters with).
ENVS_LAYERS = (("envs.atomic", "envs.digest", "envs.files", "envs.kernel_cache", "envs.memo", "envs.npz", "envs.ranges"), ("envs.world",), ("envs.maps",), ("envs.render",),
               ("envs.datasets", "envs.bags", "envs.logs"))


def envs_layer(name: str) -> int | None:
    for i, layer in enumerate(ENVS_LAYERS):
        if any(name == p or name.startswith(p + ".") for p in layer):
            return i
    return None


def envs_breaches(graph: dict[str, set[str]]) -> list[tuple[str, str]]:
    out = []
    for m, imps in graph.items():
        lm = envs_layer(m)
        if lm is None:
            continue
        out += [(m, i) for i in imps if (li := envs_layer(i)) is not None and li > lm]
    return sorted(out)


def test_no_layering_breach_inside_envs(graph):
    """world < maps < render < datasets/bags: the grid geometry (envs.maps.rays) sits with the map,
    so a map never imports the renderer."""
    assert all(envs_layer(m) is not None for m in graph if m.startswith("envs.") and m != "envs"), \
        [m for m in graph if m.startswith("envs.") and envs_layer(m) is None]
    bad = envs_breaches(graph)
    assert not bad, f"envs modules importing a layer above their own: {bad}"


def test_the_envs_rule_catches_a_map_importing_the_renderer():
    graph = {"envs.maps.scan": {"envs.render.floorplan"}, "envs.render.floorplan": {"envs.maps.rays"}}
    assert envs_breaches(graph) == [("envs.maps.scan", "envs.render.floorplan")]


def test_the_slow_check_names_an_unmarked_test_over_the_limit():
    """``make test-fast``'s check (tests/conftest.py, --max-unmarked-seconds): a test over the
    limit without ``@pytest.mark.slow`` is named, a marked one or a quick one is not."""
    from tests.conftest import unmarked_over

    durations = {"a::slow_one": [5.0, True], "a::quick": [0.1, False], "a::late": [2.5, False], "a::b": [3.0, False]}
    assert unmarked_over(durations, 2.0) == [("a::b", 3.0), ("a::late", 2.5)]
    assert unmarked_over(durations, 4.0) == []
