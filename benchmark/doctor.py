"""``python -m benchmark.doctor``: what is installed, what is missing, and what to do.

Checks the core packages, the optional model and simulator packages, a GPU, the AI2-THOR
build cache and display (CloudRendering needs Vulkan, Linux64 an X display), the
ai2thor-hab scenes and the shared data. Always exits 0: only the core is required.
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import shutil
from pathlib import Path

CORE = ("numpy", "scipy", "cv2", "skimage", "shapely", "numba", "pandas", "matplotlib", "hydra", "procthor")
OPTIONAL = {
    "torch": "pip install 'roomseg-bench[models]' (or make setup)",
    "torchvision": "pip install 'roomseg-bench[models]'",
    "transformers": "pip install 'roomseg-bench[models]'",
    "bitsandbytes": "pip install 'roomseg-bench[gpu]' (4-bit VLM on CUDA)",
    "ai2thor": "pip install 'roomseg-bench[thor]'",
    "prior": "pip install 'roomseg-bench[thor]' (ProcTHOR-10k download)",
    "habitat_sim": "conda install habitat-sim -c conda-forge -c aihabitat (no pip wheel for Linux)",
}


def checks(hab_dataset: str | None = None, shared: str | None = None) -> list[tuple[str, str, str]]:
    """(item, OK | MISSING | optional-MISSING, what to do) rows."""
    rows = []
    for m in CORE:
        ok = importlib.util.find_spec(m) is not None
        rows.append((f"core: {m}", "OK" if ok else "MISSING", "" if ok else "pip install -e . (make setup)"))
    for m, how in OPTIONAL.items():
        ok = importlib.util.find_spec(m) is not None
        rows.append((f"optional: {m}", "OK" if ok else "optional-MISSING", "" if ok else how))
    gpu = "no torch"
    if importlib.util.find_spec("torch") is not None:
        import torch  # noqa: PLC0415

        gpu = torch.cuda.get_device_name(0) if torch.cuda.is_available() else ""
    rows.append(("GPU (CUDA)", "OK" if gpu and gpu != "no torch" else "optional-MISSING",
                 gpu if gpu and gpu != "no torch" else "CPU only: offline benchmark and tests work; image classifiers are slow"))
    builds = Path.home() / ".ai2thor" / "releases"
    have = sorted(p.name for p in builds.glob("*")) if builds.exists() else []
    rows.append(("AI2-THOR build cache", "OK" if have else "optional-MISSING",
                 ", ".join(have[:2]) if have else "downloaded by ai2thor on first Controller start (network needed)"))
    vulkan = shutil.which("vulkaninfo") is not None
    rows.append(("Vulkan (CloudRendering)", "OK" if vulkan else "optional-MISSING",
                 "" if vulkan else "apt-get install vulkan-tools libvulkan1 (headless GPU rendering)"))
    rows.append(("X display (Linux64)", "OK" if os.environ.get("DISPLAY") else "optional-MISSING",
                 os.environ.get("DISPLAY", "") or "use platform=CloudRendering, or start Xvfb/an X server"))
    hab = Path(hab_dataset or os.environ.get("ROOMSEG_HAB_DATASET", "data/ai2thor-hab/ai2thor-hab.scene_dataset_config.json"))
    rows.append(("ai2thor-hab scenes", "OK" if hab.exists() else "optional-MISSING",
                 str(hab) if hab.exists() else f"not at {hab}: download the ai2thor-hab scene dataset and set ROOMSEG_HAB_DATASET"))
    data = Path(shared or os.environ.get("ROOMSEG_SHARED_DATA", "../shared/data"))
    ok = (data / "procthor").exists()
    rows.append(("shared ProcTHOR/SeLRoS data", "OK" if ok else "optional-MISSING",
                 str(data) if ok else f"not at {data}: set ROOMSEG_SHARED_DATA (only needed for env=procthor_shared and SeLRoS tables)"))
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--hab-dataset", default=None)
    ap.add_argument("--shared", default=None)
    a = ap.parse_args(argv)
    rows = checks(a.hab_dataset, a.shared)
    w = max(len(r[0]) for r in rows)
    for item, status, how in rows:
        print(f"{item:<{w}}  {status:<16}  {how}")
    missing = [r for r in rows if r[1] == "MISSING"]
    print(f"\n{len(missing)} required piece(s) missing" if missing else "\ncore OK")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
