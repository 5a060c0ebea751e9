"""The one place that composes the project's Hydra configs outside a Hydra app.

Commands that are not Hydra apps (``roomseg-segment``, ``evaluate``, ``train``, the scoring and
figure commands, ``gpu_check``) and the tests build their configuration here, from ``conf/``
(:data:`benchmark.paths.CONF_DIR`), with Hydra's compose API: the same groups, defaults and
``_target_`` plug-ins as ``roomseg-bench``, and no Hydra output folder.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from benchmark.paths import CONF_DIR

#: the longest sweep job folder name kept as Hydra writes it (longer names are shortened).
MAX_JOB_DIRNAME = 120


def job_dirname(name: str) -> str:
    """A sweep job's folder name from Hydra's ``override_dirname`` (the ``hydra.sweep.subdir``
    resolver ``job_dir``): unchanged when it is a plain name (no ``/``, quotes, braces, spaces or
    backslashes, at most :data:`MAX_JOB_DIRNAME` characters), so ordinary sweeps keep names such
    as ``aggregator=graph_knn,classifier=objects``; otherwise a readable part (a path value
    replaced by its last two parts, other characters by ``_``, at most 80 characters) then
    ``~`` and 10 hex digits of the name's SHA-1, so that overrides holding paths never nest
    folders and two different overrides never share a folder."""
    import hashlib
    import re

    if len(name) <= MAX_JOB_DIRNAME and not re.search(r"[/\\'\"{}\[\] ]", name) and not name.startswith("."):
        return name
    items = []
    for item in name.split(","):
        key, eq, value = item.partition("=")
        if "/" in value:  # a path: its last two parts
            value = "_".join(value.strip("'\"").rstrip("/").split("/")[-2:])
        items.append(f"{key}{eq}{value}")
    readable = re.sub(r"[^A-Za-z0-9_.,=@+-]+", "_", ",".join(items)).strip("._")[:80].rstrip(",_")
    return f"{readable}~{hashlib.sha1(name.encode('utf-8')).hexdigest()[:10]}"


def register_resolvers() -> None:
    """The ``job_dir`` resolver of ``conf/config.yaml``'s ``hydra.sweep.subdir`` (idempotent)."""
    from omegaconf import OmegaConf

    if not OmegaConf.has_resolver("job_dir"):
        OmegaConf.register_new_resolver("job_dir", job_dirname)


#: per process: the text of each YAML config Hydra read -> the config built from its parse, kept
#: untouched, so that composing many jobs parses and builds each config once (:func:`parse_configs_once`:
#: each load gets a deep copy of it)
_PARSED_CONFIGS: dict[str, Any] = {}


def resolved_body(cfg: Any) -> dict[str, Any]:
    """A job's config without Hydra's node, as a plain container with its interpolations resolved:
    ``OmegaConf.to_container(OmegaConf.masked_copy(cfg, [every key but hydra]), resolve=True)``.
    A config with no ``hydra`` node (the one a Hydra app's job receives) is resolved as it is,
    without the copy (the same content: a twentieth of a sweep job's set-up went to copying it)."""
    from omegaconf import OmegaConf

    body = OmegaConf.masked_copy(cfg, [k for k in cfg if k != "hydra"]) if "hydra" in cfg else cfg
    return OmegaConf.to_container(body, resolve=True)  # type: ignore[return-value]


def yaml_text(container: Any) -> str:
    """``OmegaConf.to_yaml``'s text of a plain container (``OmegaConf.to_container`` of a config:
    dicts, lists, scalars, no enums), emitted by libyaml where PyYAML was built with it (about a
    third of the pure-Python emitter's time: every job of a sweep writes four such files) with
    OmegaConf's representers (a string that would read back as a bool or number is quoted), else
    by OmegaConf's own dumper. The same text either way (tests/test_config_yaml.py compares them
    on every config ``conf/`` composes and on strings chosen to differ). libyaml writes only text
    whose strings are printable ASCII, tabs and newlines: it escapes some other characters that
    PyYAML's emitter writes as they are (a character beyond U+FFFF, measured), so any other
    string takes OmegaConf's dumper."""
    import yaml
    from omegaconf._utils import get_omega_conf_dumper

    fast = getattr(yaml, "__with_libyaml__", False) and _ascii_only(container)
    dumper = _libyaml_dumper() if fast else get_omega_conf_dumper()
    return yaml.dump(container, default_flow_style=False, allow_unicode=True, sort_keys=False, Dumper=dumper)


def _ascii_only(node: Any) -> bool:
    """Every string in a plain container (keys too) printable ASCII, tabs and newlines."""
    stack = [node]
    while stack:
        x = stack.pop()
        if isinstance(x, str):
            if not (x.isascii() and (x.isprintable() or all(c.isprintable() or c in "\t\n" for c in x))):
                return False
        elif isinstance(x, dict):
            stack.extend(x.keys())
            stack.extend(x.values())
        elif isinstance(x, list | tuple):
            stack.extend(x)
    return True


_LIBYAML_DUMPER: list[Any] = []


def _libyaml_dumper() -> Any:
    """PyYAML's libyaml dumper with OmegaConf's string representer (made once)."""
    if not _LIBYAML_DUMPER:
        import yaml
        from omegaconf._utils import OmegaConfDumper, get_omega_conf_dumper

        get_omega_conf_dumper()  # (OmegaConf adds its representer to its own dumper on first use)
        dumper = type("OmegaConfCDumper", (yaml.CDumper,), {})
        dumper.add_representer(str, OmegaConfDumper.str_representer)
        _LIBYAML_DUMPER.append(dumper)
    return _LIBYAML_DUMPER[0]


class _ConfigsParsedOnce:
    """``OmegaConf`` as Hydra's config sources (files and packages) see it after
    :func:`parse_configs_once`: its ``load`` parses each YAML text and builds its config once per
    process, everything else is ``OmegaConf``'s."""

    def __getattr__(self, name: str) -> Any:
        from omegaconf import OmegaConf

        return getattr(OmegaConf, name)

    @staticmethod
    def load(file_: Any) -> Any:
        """``OmegaConf.load`` of an open config file: a deep copy of the config built once from
        the parse of its text (kept by text: an edited file is parsed again; Hydra merges into
        the copy, the one kept stays as built). Copying a built config takes about half the time
        of building it from the parse (composing a robustness job: about 10 of 80 ms less). A
        text that does not parse is handed to ``OmegaConf.load`` itself, so its error is the one
        Hydra always gave."""
        import copy
        import io

        import yaml
        from omegaconf import OmegaConf
        from omegaconf._utils import get_yaml_loader

        if isinstance(file_, str | Path) or not callable(getattr(file_, "read", None)):
            return OmegaConf.load(file_)
        start = file_.tell()
        text = file_.read()
        text = text.decode("utf-8") if isinstance(text, bytes) else text
        if text not in _PARSED_CONFIGS:
            try:
                obj = yaml.load(io.StringIO(text), Loader=get_yaml_loader())
                parsed = obj is None or isinstance(obj, list | dict | str)
            except Exception:  # noqa: BLE001 - raised again below, as OmegaConf.load words it
                parsed = False
            if not parsed:  # the error as Hydra always gave it (naming the file), outside this handler
                file_.seek(start)
                return OmegaConf.load(file_)
            # (OmegaConf.create keeps no reference to the parse)
            _PARSED_CONFIGS[text] = OmegaConf.create() if obj is None else OmegaConf.create(obj)
        return copy.deepcopy(_PARSED_CONFIGS[text])


def parse_configs_once() -> None:
    """Make Hydra's file and package config sources parse each YAML config once per process
    (idempotent). Every job of a sweep composes its config from the same files; Hydra parses
    them again for each (PyYAML in pure Python: about a quarter of a job's composition). The
    configs built are new objects each time, equal to ``OmegaConf.load``'s (Hydra's
    composition merges into them). Hydra 1.3's sources read a config with ``OmegaConf.load``
    of the open file; nothing else changes. Call it after Hydra's plugin scan (it runs those
    modules again): the sweep launcher does, before each job's composition."""
    from hydra._internal.core_plugins import file_config_source, importlib_resources_config_source

    for module in (file_config_source, importlib_resources_config_source):
        if not isinstance(getattr(module, "OmegaConf", None), _ConfigsParsedOnce):
            module.OmegaConf = _ConfigsParsedOnce()


def compose(config_name: str = "config", overrides: Sequence[str] = (), *, hydra: bool = False):
    """``conf/<config_name>.yaml`` composed with Hydra ``overrides`` (``key=value`` strings).

    Args:
        config_name: ``config`` (the bench app), ``segment`` or ``score``.
        overrides: Hydra overrides, as on the command line.
        hydra: keep the ``hydra`` node (its ``runtime.choices`` name the chosen options).

    Returns:
        The composed ``DictConfig``.

    Raises:
        hydra.errors.HydraException, omegaconf.errors.OmegaConfBaseException: a bad override.
    """
    from hydra import compose as hydra_compose  # noqa: PLC0415
    from hydra import initialize_config_dir  # noqa: PLC0415

    register_resolvers()
    config_dir, extra = config_location(config_name)
    with initialize_config_dir(config_dir=config_dir, version_base="1.3"):
        parse_configs_once()  # (after Hydra's plugin scan, which runs its config sources' modules again)
        return hydra_compose(config_name=config_name, overrides=[*extra, *overrides], return_hydra_config=hydra)


#: primary configs that live in a folder of their own, with the groups only they use (so that
#: ``roomseg-bench --help`` lists only the groups the bench app accepts): name -> subfolder.
OWN_FOLDER = {"score": "scoring"}


def config_location(config_name: str) -> tuple[str, list[str]]:
    """(config folder, overrides it needs) of a primary config: ``conf/`` for the bench app and
    ``roomseg-segment``; ``conf/scoring/`` for the scoring app, which finds the shared groups
    (``paths``, ``metrics``) in ``conf/`` through Hydra's search path."""
    sub = OWN_FOLDER.get(config_name)
    if sub is None:
        return CONF_DIR, []
    return str(Path(CONF_DIR) / sub), [f"hydra.searchpath=[file://{CONF_DIR}]"]


def compose_job(overrides: Sequence[str] = (), config_name: str = "config"):
    """A job's config as the bench app sees it, and the options chosen per group.

    Returns:
        (config without the ``hydra`` node, {group: chosen option name} without Hydra's own
        groups), what :func:`benchmark.harness.runner.run` takes.
    """
    from omegaconf import OmegaConf  # noqa: PLC0415

    full = compose(config_name, overrides, hydra=True)
    choices = {k: (str(v) if v is not None else "") for k, v in full.hydra.runtime.choices.items()
               if not k.startswith("hydra")}
    return OmegaConf.masked_copy(full, [k for k in full if k != "hydra"]), choices




def quote_braces(overrides: Sequence[str]) -> list[str]:
    """Overrides as users type them, made readable by Hydra's parser: an unquoted value holding
    a ``{name}`` placeholder (``external.pred_pattern={id}_rooms.png``,
    ``viewpoints.path=poses/{house_id}.csv``), which Hydra would parse as a dictionary, is
    quoted; everything else passes unchanged.

    Returns:
        The overrides, in order."""
    import re  # noqa: PLC0415

    out = []
    for o in overrides:
        key, eq, value = o.partition("=")
        if (eq and not key.startswith("-") and re.search(r"\{[A-Za-z_][A-Za-z0-9_]*\}", value)
                and value[:1] not in ("'", '"') and not re.match(r"^\{\s*[A-Za-z_]\w*\s*:", value)):
            value = "'" + value.replace("\\", "\\\\").replace("'", "\\'") + "'"
        out.append(f"{key}{eq}{value}")
    return out


def valid_keys_hint(error: BaseException, overrides: Sequence[str], config_name: str = "config") -> str:
    """A hint for an override Hydra refused: the valid keys of the node a misspelt key sits in
    (``aggregator.kk=3`` -> the aggregator's keys), or the options of a group that has no such
    option (``segmenter=distanc`` -> the segmenters). "" when the error is of another kind.

    Args:
        error: what composing raised.
        overrides: the overrides given (those naming other things are kept to compose the rest).
        config_name: the primary config.
    """
    import re  # noqa: PLC0415
    from pathlib import Path  # noqa: PLC0415

    chain, e = [], error
    while e is not None and len(chain) < 5:
        chain.append(str(e))
        e = e.__cause__ or e.__context__
    text = "\n".join(chain)
    group = re.search(r"Could not find '([\w/]+)/([^']+)'", text)
    if group:
        folder = Path(CONF_DIR) / group.group(1)
        options = sorted(p.stem for p in folder.glob("*.yaml")) if folder.is_dir() else []
        return f"; {group.group(1)} options: {', '.join(options)}" if options else ""
    full = re.search(r"Could not override '([^']+)'", text)
    key = re.search(r"Key '([^']+)' is not in struct", text)
    if not (full or key):
        return ""
    dotted = full.group(1) if full else key.group(1)
    bad = dotted.split(".")[-1]
    parent = ".".join(dotted.split(".")[:-1])  # the node where the valid keys live
    rest = [o for o in overrides if "=" in o and o.split("=", 1)[0].lstrip("+~").split(".")[-1] != bad
            and not o.split("=", 1)[1].startswith("???")]
    try:
        cfg = compose(config_name, [o for o in rest if not o.startswith(("+", "~"))])
    except Exception:  # noqa: BLE001 - the hint is a courtesy: other overrides may be bad too
        try:
            cfg = compose(config_name)
        except Exception:  # noqa: BLE001
            return ""
    from omegaconf import DictConfig, OmegaConf  # noqa: PLC0415

    node = OmegaConf.select(cfg, parent) if parent else cfg
    if not isinstance(node, DictConfig):
        return ""
    keys = [k for k in node.keys() if k not in ("hydra", "_target_")]
    return f"; valid keys{' of ' + parent if parent else ''}: {', '.join(map(str, keys))}"


#: the robot-condition stages (null: the perfect robot): the map the robot builds, and the
#: view transforms between the classifier and the aggregator, in order.
ROBOT_STAGES = ("mapping", "pose_error", "label_noise")
#: per view-transform group, the amounts that are all zero in its identity setting.
IDENTITY_AMOUNTS = {"pose_error": ("sigma_xy", "sigma_yaw", "drift_xy", "drift_yaw"), "label_noise": ("share",)}


def _plain_node(node):
    from omegaconf import DictConfig, OmegaConf  # noqa: PLC0415

    return OmegaConf.to_container(node, resolve=True) if isinstance(node, DictConfig) else node


def robot_settings(cfg) -> dict:
    """The robot-condition stages that change anything, as plain configs: a stage that is
    unset, or set to its identity (a pose error or label noise whose every amount is 0), is
    left out, so that severity 0 of every condition has the clean run's keys and rows.

    Args:
        cfg: a composed config, or a plain mapping of group -> config."""
    out = {}
    for g in ROBOT_STAGES:
        node = _plain_node(cfg.get(g))
        if node is None:
            continue
        amounts = IDENTITY_AMOUNTS.get(g)
        if g == "pose_error" and shapes_map({g: node}):
            amounts = ("alpha1", "alpha2", "alpha3", "alpha4", "kidnap_m")
        if amounts and all(not node.get(k) for k in amounts):
            continue
        out[g] = node
    return out


#: pose-error stages whose one estimate also places the robot's scans (benchmark/conditions/slam.py)
MAP_POSE_ERRORS = ("benchmark.conditions.slam.OdometrySlam",)


def shapes_map(robot) -> bool:
    """True when the robot's pose error is a SLAM estimate that its map is built at too.

    Args:
        robot: group -> plain config (:func:`robot_settings`' output, or a config's groups)."""
    node = robot.get("pose_error")
    return isinstance(node, dict) and node.get("_target_") in MAP_POSE_ERRORS


def build_method(cfg, stage=None, transforms=(), names=None):
    """The :class:`benchmark.method.Method` of a config: the one function that turns the
    ``classifier``, ``pose_error``, ``label_noise``, ``aggregator`` and ``postprocess`` groups
    into a Method, for every command that segments (the harness, ``roomseg-segment``, the
    figures, the confusion command).

    Args:
        cfg: a composed config (or a plain mapping of group -> config).
        stage: group -> the built stage (None: absent); default ``instantiate(cfg[group])``.
            Stages are built when the Method first needs them (:class:`benchmark.method.Lazy`),
            so a run whose steps are cached builds none.
        transforms: more view transforms, after the robot conditions' (``roomseg-segment``'s
            off-map rule).
        names: stage -> name in messages (default: the ``_target_``).

    Returns:
        The Method; its view transforms are the robot conditions that change anything
        (:func:`robot_settings`): pose error, then label noise.
    """
    from benchmark.method import LabelNoiseTransform, Lazy, Method, PoseErrorTransform  # noqa: PLC0415

    if stage is None:
        def stage(group):
            from hydra.utils import instantiate  # noqa: PLC0415

            node = cfg.get(group)
            return instantiate(node) if node is not None else None

    def lazy(group):
        return Lazy(lambda: stage(group))

    robot = robot_settings(cfg)
    steps = []
    if "pose_error" in robot:
        steps.append(PoseErrorTransform(lazy("pose_error")))
    if "label_noise" in robot:
        steps.append(LabelNoiseTransform(lazy("label_noise")))
    if names is None:
        names = {g: str((_plain_node(cfg.get(g)) or {}).get("_target_", "")) for g in ("classifier", "aggregator")}
    return Method(lazy("classifier"), lazy("aggregator"), lazy("postprocess"), [*steps, *transforms], names)


def _scoped(override: str) -> str:
    """``key=value`` -> ``classifier.key=value`` (also ``+key``/``~key``); ``classes=...``
    and ``classifier.*`` pass unchanged."""
    prefix = override[0] if override[:1] in ("+", "~") else ""
    body = override[len(prefix):]
    if body.startswith(("classifier.", "classes=", "classes.", "run.")):
        return override
    return f"{prefix}classifier.{body}"


def classifier_config(model: str, overrides: Sequence[str] = ()):
    """The root config composed with ``classifier=<model>`` and the overrides (keys of the
    classifier config, e.g. ``device=cpu``); ``cfg.classifier`` is what the runner builds."""
    from benchmark.classifiers.evaluate import MODELS  # noqa: PLC0415

    if model not in MODELS:
        raise ValueError(f"unknown model {model!r}; expected one of {', '.join(MODELS)}")
    return compose("config", [f"classifier={model}", *(_scoped(o) for o in overrides)])


def build_classifier(model: str, overrides: Sequence[str] = ()):
    """(classifier, root config) for ``model`` with the overrides."""
    from hydra.utils import instantiate  # noqa: PLC0415

    cfg = classifier_config(model, overrides)
    return instantiate(cfg.classifier), cfg


__all__ = ["build_method", "shapes_map", "MAP_POSE_ERRORS", "classifier_config", "build_classifier", "robot_settings", "ROBOT_STAGES", "compose", "compose_job", "parse_configs_once", "yaml_text", "resolved_body", "job_dirname", "quote_braces", "register_resolvers", "valid_keys_hint", "CONF_DIR"]
