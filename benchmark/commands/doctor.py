"""``python -m benchmark.commands.doctor``: what is installed, what is missing, and what to do.

Checks the core packages, the optional model and simulator packages, a GPU, the AI2-THOR
Unity build for the pinned commit, Vulkan (CloudRendering) and an X display (Linux64), the
ai2thor-hab scenes, the ArchitecTHOR annotations, the ipa_room_segmentation build
(``make ipa-env``) and the shared data, and prints one row
per piece: OK, MISSING (core: nothing runs without it) or optional (only the paths that use
it need it), with one line of what to do. Exits 1 when a core piece is missing, else 0.
"""

from __future__ import annotations

import ctypes.util
import importlib.util
import os
from pathlib import Path

from benchmark.commands import cli
from benchmark.paths import data_dir

CORE = ("numpy", "scipy", "cv2", "skimage", "PIL", "shapely", "numba", "pandas", "matplotlib", "tqdm", "hydra",
        "omegaconf", "procthor")
OPTIONAL = {
    "torch": "pip install -e '.[models]' (CNN / DINOv2 / VLM classifiers)",
    "torchvision": "pip install -e '.[models]'",
    "transformers": "pip install -e '.[models]'",
    "bitsandbytes": "pip install -e '.[gpu]' (4-bit VLM, CUDA only)",
    "ai2thor": "pip install -e '.[thor]' (AI2-THOR renderer, ProcTHOR via prior)",
    "prior": "pip install -e '.[thor]' (downloads ProcTHOR-10k)",
    "habitat_sim": "conda install habitat-sim withbullet headless -c conda-forge -c aihabitat-nightly (no pip wheel for Linux)",
}
OK, MISSING, OPTIONAL_MISSING = "OK", "MISSING", "optional"
DEFAULT_HAB = "data/ai2thor-hab/ai2thor-hab/ai2thor-hab.scene_dataset_config.json"


def _has(module: str) -> bool:
    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):
        return False


def _gpu() -> str:
    if not _has("torch"):
        return ""
    import torch  # noqa: PLC0415

    return torch.cuda.get_device_name(0) if torch.cuda.is_available() else ""


def _thor_build(platform: str, commit_id: str | None) -> tuple[str, str]:
    if not _has("ai2thor"):
        return OPTIONAL_MISSING, "needs the ai2thor package first"
    from envs.render.thor import thor_build_dir  # noqa: PLC0415

    d = thor_build_dir(platform, commit_id)
    if d.is_dir():
        return OK, str(d)
    return OPTIONAL_MISSING, (f"not at {d}: ai2thor downloads it on the first Controller start (network), "
                              "or copy that folder there from another machine")


def _ipa_row() -> tuple[str, str, str]:
    """The ipa_room_segmentation build (``make ipa-env``; segmenter=ipa_*): where, which commit,
    with or without VRF."""
    from benchmark.segmenters.ipa import ipa_build  # noqa: PLC0415

    try:
        b = ipa_build()
    except FileNotFoundError as e:
        return "ipa_room_segmentation (segmenter=ipa_*)", OPTIONAL_MISSING, str(e)
    vrf = ("VRF with the OpenCV 2 weak hypotheses" if b["vrf_fix"] else "VRF as published (IPA_VRF_FIX=0)") \
        if b["vrf"] else "no VRF (built without OpenGM)"
    return ("ipa_room_segmentation (segmenter=ipa_*)", OK,
            f"{b['driver']} (ipa_coverage_planning {b['ipa_commit'][:8]}; {vrf})")


def checks(hab_dataset: str | None = None, shared: str | None = None, annotations: str | None = None,
           platform: str = "CloudRendering", commit_id: str | None = None) -> list[tuple[str, str, str]]:
    """(item, OK | MISSING | optional, what to do / where it is) rows."""
    rows = []
    for m in CORE:
        ok = _has(m)
        rows.append((f"core: {m}", OK if ok else MISSING, "" if ok else "pip install -e . (or make setup)"))
    for m, how in OPTIONAL.items():
        ok = _has(m)
        rows.append((f"package: {m}", OK if ok else OPTIONAL_MISSING, "" if ok else how))
    gpu = _gpu()
    rows.append(("GPU (CUDA via torch)", OK if gpu else OPTIONAL_MISSING,
                 gpu or "CPU only: the offline benchmark and tests run; image classifiers are slow, the VLM needs CUDA"))
    status, how = _thor_build(platform, commit_id)
    rows.append((f"AI2-THOR build ({platform})", status, how))
    vulkan = ctypes.util.find_library("vulkan") is not None  # the check ai2thor's CloudRendering makes
    rows.append(("Vulkan (CloudRendering)", OK if vulkan else OPTIONAL_MISSING,
                 "libvulkan found" if vulkan else "sudo apt-get install -y libvulkan1 (plus the NVIDIA driver's "
                                                  "Vulkan ICD) for headless AI2-THOR"))
    display = os.environ.get("DISPLAY", "")
    rows.append(("X display (Linux64)", OK if display else OPTIONAL_MISSING,
                 display or "none: use renderer.platform=CloudRendering, or start Xvfb / an X server"))
    hab = Path(hab_dataset or os.environ.get("ROOMSEG_HAB_DATASET", DEFAULT_HAB)).expanduser()
    rows.append(("ai2thor-hab scenes", OK if hab.is_file() else OPTIONAL_MISSING,
                 str(hab) if hab.is_file() else f"not at {hab}: download hssd/ai2thor-hab (Hugging Face, git-lfs) "
                                                "and set ROOMSEG_HAB_DATASET"))
    ann = Path(annotations or os.environ.get("ROOMSEG_ARCHITECTHOR_ANNOTATIONS", "data/architecthor")).expanduser()
    from envs.datasets.architecthor import ARCHITECTHOR_SCENES  # noqa: PLC0415

    have = [h for h in ARCHITECTHOR_SCENES if (ann / h / "labels.png").is_file()]
    rows.append(("ArchitecTHOR annotations", OK if len(have) == len(ARCHITECTHOR_SCENES) else OPTIONAL_MISSING,
                 f"{len(have)}/{len(ARCHITECTHOR_SCENES)} houses under {ann}" +
                 ("" if len(have) == len(ARCHITECTHOR_SCENES) else
                  ": python -m benchmark.commands.annotations import ... (docs/gpu.md), set ROOMSEG_ARCHITECTHOR_ANNOTATIONS")))
    rows.append(_ipa_row())
    data = Path(shared or data_dir()).expanduser()
    ok = (data / "procthor").is_dir()
    rows.append(("shared ProcTHOR/SeLRoS data", OK if ok else OPTIONAL_MISSING,
                 str(data) if ok else f"not at {data}: set ROOMSEG_SHARED_DATA (env=procthor_shared, SeLRoS tables)"))
    return rows


def format_table(rows: list[tuple[str, str, str]]) -> str:
    """The rows as an aligned text table."""
    w = max(len(r[0]) for r in rows)
    return "\n".join(f"{item:<{w}}  {status:<8}  {how}".rstrip() for item, status, how in rows)


def main(argv: list[str] | None = None) -> int:
    ap = cli.ArgumentParser(from_root=True, description=__doc__.split("\n\n")[0])
    ap.add_argument("--hab-dataset", default=None, help="ai2thor-hab scene dataset config (default: $ROOMSEG_HAB_DATASET)")
    ap.add_argument("--annotations", default=None, help="ArchitecTHOR annotation root")
    ap.add_argument("--shared", default=None, help="shared data folder")
    ap.add_argument("--platform", default="CloudRendering", help="AI2-THOR platform whose build to look for")
    ap.add_argument("--commit-id", default=None, help="AI2-THOR build (default: the one ai2thor pins)")
    a = ap.parse_args(argv)
    rows = checks(a.hab_dataset, a.shared, a.annotations, a.platform, a.commit_id)
    print(format_table(rows))
    missing = [r[0] for r in rows if r[1] == MISSING]
    print(f"\n{len(missing)} core piece(s) missing: {', '.join(missing)}" if missing else
          "\ncore OK; 'optional' rows are needed only by the paths that use them")
    return 1 if missing else 0


if __name__ == "__main__":
    raise SystemExit(main())
