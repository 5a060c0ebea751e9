"""``python -m benchmark.commands.maintainer.gpu_check`` (``make gpu-check``): the first step on a GPU
workstation. Checks each real dependency of the paper's runs in order and prints a table:
one line per check, ``pass``, ``FAIL: why`` or ``skipped: why``, with its time in seconds.

0. ``roomseg-bench installed``: the core packages import (this module itself needs only the
   standard library, so the table prints on a bare Python too).
1. ``torch + CUDA``: torch imports, a CUDA GPU is there, a matrix product runs on it.
2. ``ai2thor render``: ai2thor starts its pinned Unity build (or ``--commit-id``), loads one
   ProcTHOR house (``--house``, else the first house of the shared ProcTHOR file, else
   ProcTHOR-10k train[0] through ``prior``) and renders one view at the house's agent start:
   an RGB frame and the visible objects.
3. ``habitat-sim scene`` (optional): habitat-sim imports and loads one ArchitecTHOR scene of
   the ai2thor-hab dataset, when the dataset is there; its navmesh map and one view.
4. ``classifier cnn`` / ``dinov2`` / ``vlm``: each image classifier loads its real weights
   (from ``conf/classifier``; the VLM in 4-bit) on the GPU and classifies the rendered view.
5. ``end to end``: the runner on that one house, rendered with AI2-THOR, classified by the
   first classifier that passed, aggregated with graph KNN and with the vision cone, scored.

Nothing missing is a traceback: a missing package, GPU, build, display, data set or weight
file is a ``skipped: why`` line, and a later check that needs it is skipped too. The exit
status is 0 only when every required check passed (all but the habitat-sim one).
"""

from __future__ import annotations

import ctypes.util
import importlib
import os
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from benchmark.commands import cli
from benchmark.commands.errors import one_line

PASS, FAIL, SKIP = "pass", "FAIL", "skipped"
CLASSIFIERS = ("cnn", "dinov2", "vlm")
AGGREGATORS = ("graph_knn", "vision_cone")


class Skip(Exception):
    """A check that cannot run here; the message says why, in one line."""


@dataclass
class Row:
    """One line of the table: check name, whether the exit status needs it, status
    (pass / FAIL / skipped), one-line detail, seconds taken."""

    name: str
    required: bool
    status: str = SKIP
    detail: str = ""
    seconds: float = 0.0


@dataclass
class Context:
    """What the checks hand on to the later ones, and the options."""

    house_file: str | None = None
    commit_id: str | None = None
    platform: str = "auto"
    hab_dataset: str | None = None
    hab_scene: str = "ArchitecTHOR-Val-00"
    out: Path | None = None
    device: str = "cuda"  # where the classifiers run (tests: cpu)
    classifier_overrides: dict = field(default_factory=dict)  # name -> ["key=value", ...] of its config
    installed: bool = False
    cuda: bool = False
    house: object = None
    house_path: str | None = None
    view: object = None  # (H, W, 3) uint8 RGB frame of the rendered view
    passed_classifiers: list[str] = field(default_factory=list)


def _short(e: BaseException) -> str:
    """An error as one line (:func:`benchmark.commands.errors.one_line`) cut to fit the table."""
    return one_line(e)[:240]


def first_line(e: BaseException) -> str:
    """An error's message as one line, without its type (for ``skipped:`` lines)."""
    return (str(e).strip().splitlines() or [type(e).__name__])[0].strip()[:240]


CORE = ("numpy", "scipy", "cv2", "PIL", "shapely", "pandas", "hydra", "omegaconf", "procthor")


def check_installed(ctx: Context) -> str:
    """The core packages import (``pip install -e '.[thor,models,gpu]'`` installs them)."""
    missing = []
    for m in CORE:
        try:
            importlib.import_module(m)
        except ImportError:
            missing.append(m)
    if missing:
        raise Skip(f"not installed: {', '.join(missing)}: pip install -e '.[thor,models,gpu]' in this environment")
    import numpy  # noqa: PLC0415

    ctx.installed = True
    return f"core packages import (numpy {numpy.__version__})"


def check_cuda(ctx: Context) -> str:
    """torch imports and a CUDA GPU multiplies two 1024 x 1024 matrices."""
    try:
        import torch  # noqa: PLC0415
    except ImportError:
        raise Skip("torch is not installed: pip install -e '.[models]'") from None
    if not torch.cuda.is_available():
        raise Skip(f"no CUDA GPU visible to torch {torch.__version__} (CUDA build {torch.version.cuda or 'none'})")
    x = torch.randn(1024, 1024, device="cuda")
    float((x @ x).sum())
    torch.cuda.synchronize()
    ctx.cuda = True
    return f"torch {torch.__version__}, CUDA {torch.version.cuda}, {torch.cuda.get_device_name(0)}"


def _house_source(ctx: Context):
    """(House, where it came from) for the AI2-THOR check: --house, the shared file, prior."""
    from envs.world.house import House  # noqa: PLC0415

    if ctx.house_file:
        from envs.datasets.procthor import ProcTHOREnv  # noqa: PLC0415

        env = ProcTHOREnv(path=str(ctx.house_file), stop=1)
        return env.house(env.house_ids()[0]), str(ctx.house_file)
    from benchmark.paths import data_dir  # noqa: PLC0415

    shared = sorted((Path(data_dir()) / "procthor").glob("*.jsonl.gz"))
    if shared:
        from envs.datasets.procthor import ProcTHOREnv  # noqa: PLC0415

        env = ProcTHOREnv(path=str(shared[0]), stop=1)
        return env.house(env.house_ids()[0]), str(shared[0])
    try:
        import prior  # noqa: PLC0415
    except ImportError:
        raise Skip("no ProcTHOR house: pass --house FILE.json, set ROOMSEG_SHARED_DATA, or pip install -e '.[thor]' "
                   "for prior") from None
    try:
        ds = prior.load_dataset("procthor-10k")
        data = ds["train"][0]
    except Exception as e:  # noqa: BLE001  network, git-lfs
        raise Skip(f"no ProcTHOR house: prior.load_dataset('procthor-10k') failed ({_short(e)})") from None
    return House("procthor-10k-train-0", data), "prior procthor-10k train[0]"


def _start_pose(house):
    """(1, 3) pose [x, z, yaw_deg] of the house's agent start (``metadata.agent``)."""
    import numpy as np  # noqa: PLC0415

    agent = (house.data.get("metadata") or {}).get("agent") or {}
    pos, rot = agent.get("position") or {}, agent.get("rotation") or {}
    if "x" not in pos or "z" not in pos:
        raise ValueError(f"house {house.id!r} has no metadata.agent.position to render from")
    return np.array([[float(pos["x"]), float(pos["z"]), float(rot.get("y", 0.0))]])


def check_ai2thor(ctx: Context) -> str:
    """ai2thor starts its pinned build, loads one ProcTHOR house and renders one view."""
    if not ctx.installed:
        raise Skip("needs the roomseg-bench installed check to pass")
    try:
        from envs.render.thor import AI2THORRenderer, default_commit_id, resolve_platform  # noqa: PLC0415

        commit = ctx.commit_id or default_commit_id()
    except ImportError as e:
        raise Skip(first_line(e)) from None
    platform = resolve_platform(ctx.platform)
    if platform == "CloudRendering" and ctypes.util.find_library("vulkan") is None:
        raise Skip("no Vulkan library for CloudRendering (sudo apt-get install -y libvulkan1 and the NVIDIA "
                   "driver) and no X display for Linux64")
    if platform == "Linux64" and not os.environ.get("DISPLAY"):
        raise Skip("Linux64 needs an X display ($DISPLAY is not set)")
    house, where = _house_source(ctx)
    r = AI2THORRenderer(platform=platform, commit_id=ctx.commit_id)
    try:
        obs = r.render(house, None, _start_pose(house))[0]
    finally:
        r.close()
    if obs.meta.get("refused"):
        raise RuntimeError(f"the view at the agent start was refused: {obs.meta.get('error')}")
    if obs.image is None:
        raise RuntimeError("the view has no RGB frame")
    ctx.house, ctx.house_path, ctx.view = house, where, obs.image
    h, w = obs.image.shape[:2]
    return (f"build {commit[:12]} ({platform}), house {house.id} from {where}: RGB {w}x{h}, "
            f"{len(obs.objects)} visible object types")


def check_habitat(ctx: Context) -> str:
    """habitat-sim imports and loads one ArchitecTHOR scene of ai2thor-hab."""
    if not ctx.installed:
        raise Skip("needs the roomseg-bench installed check to pass")
    import numpy as np  # noqa: PLC0415

    try:
        from envs.render.habitat import (  # noqa: PLC0415
            DEFAULT_DATASET,
            HabitatRenderer,
            check_dataset,
            require_habitat,
        )

        require_habitat()
    except ImportError as e:
        raise Skip(first_line(e)) from None
    try:
        dataset = check_dataset(ctx.hab_dataset or os.environ.get("ROOMSEG_HAB_DATASET", DEFAULT_DATASET))
    except FileNotFoundError as e:
        raise Skip(first_line(e)) from None
    r = HabitatRenderer(str(dataset))
    try:
        g = r.navmesh_grid(ctx.hab_scene, 0.05)
        rr, cc = np.nonzero(g.walkable)
        if not len(rr):
            raise RuntimeError(f"{ctx.hab_scene}: the navmesh has no walkable cell")
        i = len(rr) // 2
        x, z = g.pixel_to_world(rr[i], cc[i])
        from envs.world.house import House  # noqa: PLC0415

        obs = r.render(House(ctx.hab_scene, {"scene": ctx.hab_scene}), None, np.array([[float(x), float(z), 0.0]]))[0]
    finally:
        r.close()
    area = float(g.walkable.sum()) * g.resolution ** 2
    frame = "no frame" if obs.image is None else f"RGB {obs.image.shape[1]}x{obs.image.shape[0]}"
    return f"{ctx.hab_scene}: navmesh {area:.1f} m2 walkable, one view: {frame}, {len(obs.objects)} object types"


def classifier_check(name: str) -> Callable[[Context], str]:
    """The check that classifier ``name`` loads its real weights on the GPU and classifies the view."""

    def check(ctx: Context) -> str:
        import numpy as np  # noqa: PLC0415

        if ctx.device.startswith("cuda") and not ctx.cuda:
            raise Skip("needs the CUDA check to pass")
        if ctx.view is None:
            raise Skip("no rendered view (the ai2thor check did not pass)")
        try:
            from benchmark.config import build_classifier  # noqa: PLC0415

            clf, _ = build_classifier(name, [f"device={ctx.device}", *ctx.classifier_overrides.get(name, [])])
        except Exception as e:  # noqa: BLE001  Hydra wraps the constructor's error
            msg = _short(e)
            if any(k in msg for k in ("FileNotFoundError", "ImportError", "ModuleNotFoundError", "could not load",
                                      "not found")):
                raise Skip(msg) from None
            raise RuntimeError(msg) from None
        p = np.asarray(clf.predict_images([ctx.view]))
        if p.shape != (1, len(clf.classes)) or not np.isfinite(p).all() or abs(float(p.sum()) - 1.0) > 1e-3:
            raise RuntimeError(f"classifier {name} returned {p.shape} {p.tolist()}, not one probability vector")
        ctx.passed_classifiers.append(name)
        k = int(p[0].argmax())
        extra = ", 4-bit" if name == "vlm" and getattr(clf, "model", None) is not None and \
            getattr(clf.model, "is_loaded_in_4bit", False) else ""
        return f"{name}{extra}: the view is {clf.classes[k]} (p={float(p[0, k]):.2f})"

    check.__doc__ = f"classifier {name} loads its weights and classifies the rendered view"
    return check


def check_end_to_end(ctx: Context) -> str:
    """The runner on the one house: AI2-THOR, the first classifier that passed, two aggregators."""
    if ctx.view is None or ctx.house_path is None:
        raise Skip("needs the ai2thor check to pass")
    if not ctx.passed_classifiers:
        raise Skip("needs an image classifier check to pass")
    from benchmark.config import compose_job  # noqa: PLC0415
    from benchmark.harness.runner import run  # noqa: PLC0415

    name = ctx.passed_classifiers[0]
    out = Path(ctx.out or tempfile.mkdtemp(prefix="roomseg-gpu-check-"))
    env = (["env=procthor", f"env.path={ctx.house_path}", "env.stop=1"] if Path(ctx.house_path).is_file()
           else ["env=procthor", "env.stop=1"])
    parts = []
    for agg in AGGREGATORS:
        overrides = [*env, "renderer=ai2thor", f"renderer.platform={ctx.platform}", f"classifier={name}",
                     f"classifier.device={ctx.device}",
                     *(f"classifier.{o}" for o in ctx.classifier_overrides.get(name, [])),
                     f"aggregator={agg}", f"run.results_dir={out / 'results'}", "run.progress=false"]
        if ctx.commit_id:
            overrides.append(f"renderer.commit_id={ctx.commit_id}")
        cfg, choices = compose_job(overrides)
        df = run(cfg, out / agg, choices)
        row = df.iloc[0]
        if row["status"] != "ok":
            raise RuntimeError(f"{agg}: house {row.get('house_id', '?')} failed: {row.get('error')}")
        parts.append(f"{agg} IoU {100 * float(row['iou']):.1f} acc {100 * float(row['accuracy']):.1f}")
    return f"1 house, {name}: " + "; ".join(parts) + f" (rows under {out})"


def checks() -> list[tuple[str, bool, Callable[[Context], str]]]:
    """(name, required, check) in the order they run."""
    return [("roomseg-bench installed", True, check_installed), ("torch + CUDA", True, check_cuda), ("ai2thor render", True, check_ai2thor),
            ("habitat-sim scene", False, check_habitat),
            *((f"classifier {c}", True, classifier_check(c)) for c in CLASSIFIERS),
            ("end to end (1 house, 2 aggregators)", True, check_end_to_end)]


def run_checks(ctx: Context, items=None) -> list[Row]:
    """Run the checks in order; each becomes a Row (never raises for a check's failure)."""
    rows = []
    for name, required, fn in (items if items is not None else checks()):
        row = Row(name, required)
        t = time.perf_counter()
        try:
            row.detail, row.status = fn(ctx), PASS
        except Skip as e:
            row.status, row.detail = SKIP, (str(e).strip().splitlines() or [""])[0]
        except Exception as e:  # noqa: BLE001  every failure is one line in the table
            row.status, row.detail = FAIL, _short(e)
        row.seconds = time.perf_counter() - t
        rows.append(row)
    return rows


def format_rows(rows: list[Row]) -> str:
    """The table: check, status (``pass`` / ``FAIL: why`` / ``skipped: why``), seconds."""
    names = [r.name + ("" if r.required else " (optional)") for r in rows]
    w = max(len(n) for n in names)
    lines = [f"{'check':<{w}}  {'seconds':>7}  result", "-" * (w + 40)]
    for name, r in zip(names, rows):
        result = r.status if r.status == PASS and not r.detail else f"{r.status}: {r.detail}"
        lines.append(f"{name:<{w}}  {r.seconds:7.1f}  {result}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """Run the checks, print the table and a summary; exit 0 only if every required check passed."""
    ap = cli.ArgumentParser(from_root=True, description="check each real dependency of the paper's GPU runs, in order")
    ap.add_argument("--house", default=None, help="a ProcTHOR house file (.json/.jsonl.gz) to render; default: the "
                                                  "shared ProcTHOR file, else prior's procthor-10k train[0]")
    ap.add_argument("--commit-id", default=None, help="AI2-THOR build (default: the one ai2thor pins)")
    ap.add_argument("--platform", default="auto", help="AI2-THOR platform: auto | CloudRendering | Linux64")
    ap.add_argument("--hab-dataset", default=None, help="ai2thor-hab scene dataset config ($ROOMSEG_HAB_DATASET)")
    ap.add_argument("--hab-scene", default="ArchitecTHOR-Val-00")
    ap.add_argument("--out", type=Path, default=None, help="where the end-to-end run writes (default: a temp folder)")
    a = ap.parse_args(argv)
    ctx = Context(house_file=a.house, commit_id=a.commit_id, platform=a.platform, hab_dataset=a.hab_dataset,
                  hab_scene=a.hab_scene, out=a.out)
    rows = run_checks(ctx)
    print(format_rows(rows))
    n = {s: sum(r.status == s for r in rows) for s in (PASS, FAIL, SKIP)}
    missing = [r.name for r in rows if r.required and r.status != PASS]
    print(f"\n{n[PASS]} passed, {n[FAIL]} failed, {n[SKIP]} skipped; " +
          (f"required and not passed: {', '.join(missing)}" if missing else "every required check passed"))
    return 1 if missing else 0


if __name__ == "__main__":
    raise SystemExit(main())
