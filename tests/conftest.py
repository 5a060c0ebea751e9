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
