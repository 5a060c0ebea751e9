"""Shared fixtures. Tests that need ../shared/data skip with a reason when it is absent."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from benchmark.config import register_resolvers

register_resolvers()  # conf/config.yaml's job_dir resolver, for the tests that compose with Hydra directly

ROOT = Path(__file__).resolve().parents[1]
SHARED_DATA = Path(os.environ.get("ROOMSEG_SHARED_DATA", ROOT.parent / "shared" / "data"))
PROCTHOR_FILE = SHARED_DATA / "procthor" / "procthor-10k-uniform-hard-val.jsonl.gz"
SELROS_DIR = SHARED_DATA / "selros"


def _need(path: Path) -> Path:
    if not path.exists():
        pytest.skip(f"shared data not found at {path} (set ROOMSEG_SHARED_DATA or place ../shared/data)")
    return path


@pytest.fixture(scope="session")
def procthor_file() -> Path:
    return _need(PROCTHOR_FILE)


@pytest.fixture(scope="session")
def selros_dir() -> Path:
    return _need(SELROS_DIR)


@pytest.fixture(scope="session")
def shared_houses(procthor_file):
    from envs.datasets.house_files import load_houses

    return load_houses(procthor_file)


@pytest.fixture(scope="session")
def shared_scenes(shared_houses):
    from envs.maps.scene import rasterise_house

    return [rasterise_house(h) for h in shared_houses]


# ---- the developer loop: `make test-fast` fails a test over N seconds that is not marked slow
_DURATIONS: dict[str, list] = {}


def pytest_addoption(parser):
    parser.addoption("--max-unmarked-seconds", type=float, default=None, metavar="S",
                     help="fail the session when a test not marked slow takes longer than S seconds "
                          "(its call; shared fixtures' setup is not charged to it); make test-fast sets 2")


def pytest_runtest_logreport(report):
    # the test's own call: a session-scoped fixture's setup (150 rasterised houses) is shared
    # by every test that uses it, not the cost of the first one
    if report.when == "call":
        _DURATIONS[report.nodeid] = [report.duration, "slow" in report.keywords]


def unmarked_over(durations: dict[str, list], limit: float) -> list[tuple[str, float]]:
    """(test id, seconds) of the tests over ``limit`` seconds that carry no ``slow`` mark, slowest first."""
    return sorted(((k, v[0]) for k, v in durations.items() if v[0] > limit and not v[1]), key=lambda t: -t[1])


def pytest_sessionfinish(session, exitstatus):
    limit = session.config.getoption("--max-unmarked-seconds", default=None)
    if limit is None:
        return
    over = unmarked_over(_DURATIONS, limit)
    if over:
        tr = session.config.pluginmanager.get_plugin("terminalreporter")
        if tr is not None:
            tr.write_line(f"{len(over)} test(s) took over {limit:g} s without @pytest.mark.slow:", red=True)
            for k, s in over:
                tr.write_line(f"  {s:6.2f} s  {k}")
        session.exitstatus = 1
