"""Where the configs and the shared data live, read from ``conf/paths/default.yaml``.

The data root has one default, written once in that file
(``${oc.env:ROOMSEG_SHARED_DATA,../shared/data}``); Hydra apps read it as
``${paths.data_dir}`` and plain commands through :func:`data_dir` here.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

from omegaconf import OmegaConf

#: the Hydra config directory of the project.
CONF_DIR = str(Path(__file__).resolve().parents[1] / "conf")


@lru_cache(maxsize=1)
def _paths_node():
    return OmegaConf.load(Path(CONF_DIR) / "paths" / "default.yaml")


def _get(key: str) -> Path:
    node = OmegaConf.create({"paths": _paths_node()})
    return Path(str(OmegaConf.select(node, f"paths.{key}", throw_on_resolution_failure=True)))


def data_dir() -> Path:
    """The shared-data root (``$ROOMSEG_SHARED_DATA``, default ``../shared/data``)."""
    return _get("data_dir")


def procthor_houses() -> Path:
    """The 150 shared ProcTHOR houses (``.jsonl.gz``) under :func:`data_dir`."""
    return _get("procthor_houses")


def selros_dir() -> Path:
    """The SeLRoS release folder under :func:`data_dir`."""
    return _get("selros_dir")
