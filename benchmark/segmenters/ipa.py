"""ipa_room_segmentation's five algorithms as segmenters (``segmenter=ipa_morphological``,
``ipa_distance``, ``ipa_voronoi``, ``ipa_semantic``, ``ipa_vrf``): the authors' C++ (Bormann et
al., ICRA 2016; public repository ipa320/ipa_coverage_planning, package ipa_room_segmentation),
built without ROS by ``make ipa-env`` into one driver executable (``native/ipa/``), run one
subprocess per map. The project contains none of the authors' code: the build compiles it from
the user's checkout.

What the driver gets: the occupancy map the other segmenters get (``grid.walkable``), **resampled
to 0.05 m/px** (nearest; the resolution of the authors' maps, for which their pixel parameters
such as ``voronoi_neighborhood_index`` were chosen; ``resolution`` sets another, e.g. the map's
own to run it unresampled) as their action server's input image: free
(255) = walkable, occupied (0) = the rest, with :data:`PAD_PX` occupied pixels around it. Its
rooms (a 16-bit label image) are sampled back onto the grid's walkable cells (nearest);
walkable cells no room took stay unlabelled (-1), as in the authors' output. Rooms under
``min_room_area`` then merge into the neighbour sharing the longest border
(:func:`benchmark.segmenters.common.merge_small_rooms`); the default 0 keeps the authors' output
as it is (their own room-area limits already apply).

Parameters are the authors' defaults (their ``room_segmentation_action_server_params.yaml``;
areas in square metres, the Voronoi and VRF neighbourhoods in pixels of the map the driver gets), set in
``conf/segmenter/ipa_*.yaml`` under ``params``. A map on which the driver fails (its one-line
message), or which takes longer than ``timeout`` seconds, raises one line: a failed row of that
map, never a crash of the sweep. The seconds the driver took go into the row (``t_ipa``).

VRF: a build of ``make ipa-env`` prints how the authors' inference labelled the field's nodes
(``native/ipa/roomseg_vrf_labels.h``); the segmenter keeps it in ``last_field_nodes`` (room,
hallway and doorway nodes of the last map; None from a build that does not print it).
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import tempfile
import time
from pathlib import Path
from typing import Annotated

import cv2
import numpy as np

from benchmark.guarded import run_guarded
from benchmark.interfaces import Segmenter
from benchmark.segmenters.common import check_room_area, clean_dead_tmp, merge_small_rooms
from envs.maps.gridmap import GridMap
from envs.ranges import NonNegative, Positive

#: metres per pixel of the authors' maps (their pixel parameters were chosen on these).
IPA_RESOLUTION = 0.05
#: occupied pixels drawn around the map (the algorithms' contour steps need a closed border).
PAD_PX = 5
#: the environment variable naming the build folder (``make ipa-env``) when the config does not.
ENV_VAR = "ROOMSEG_IPA_ENV"
DEFAULT_ENV = Path(__file__).resolve().parents[2] / ".ipa-env"
#: the algorithms and the parameters each takes (names of the authors' params YAML, without the
#: algorithm suffix; the driver holds the same list with the authors' default values).
ALGORITHMS: dict[str, tuple[str, ...]] = {
    "morphological": ("room_area_factor_lower_limit", "room_area_factor_upper_limit"),
    "distance": ("room_area_factor_lower_limit", "room_area_factor_upper_limit"),
    "voronoi": ("room_area_factor_lower_limit", "room_area_factor_upper_limit", "voronoi_neighborhood_index",
                "max_iterations", "min_critical_point_distance_factor", "max_area_for_merging"),
    "semantic": ("room_area_factor_lower_limit", "room_area_factor_upper_limit"),
    "vrf": ("room_area_lower_limit", "room_area_upper_limit", "voronoi_random_field_epsilon_for_neighborhood",
            "max_iterations", "min_neighborhood_size", "min_voronoi_random_field_node_distance",
            "max_voronoi_random_field_inference_iterations", "max_area_for_merging"),
}
#: name prefix of a driver's folder in the temporary folder: ``roomseg-ipa-<pid>-<random>``.
TMP_PREFIX = "roomseg-ipa-"
#: the VRF chatter line of ``native/ipa/roomseg_vrf_labels.h``: the inference's labels of the field's nodes.
FIELD_NODES_LINE = re.compile(r"^roomseg field nodes: room (\d+) hallway (\d+) doorway (\d+)", re.M)


def ipa_build(env_dir: str | Path | None = None) -> dict:
    """What ``make ipa-env`` built: ``{"env": folder, "driver": path, "models": folder,
    "ipa_commit": sha, "vrf": bool, "vrf_fix": bool}`` (``vrf_fix``: the VRF's AdaBoost weak
    hypotheses as OpenCV 2 gave them, ``native/ipa/roomseg_weak_responses.h``).

    Raises:
        FileNotFoundError: no build there (one line saying how to make it)."""
    env = Path(env_dir or os.environ.get(ENV_VAR) or DEFAULT_ENV).expanduser()
    driver, info_file = env / "bin" / "ipa_segment", env / "build.json"
    if not driver.is_file() or not info_file.is_file():
        raise FileNotFoundError(f"no ipa_room_segmentation build in {env} (no bin/ipa_segment or build.json): "
                                f"run `make ipa-env IPA_SRC=<ipa_coverage_planning checkout>` (docs/baselines.md)")
    try:
        info = json.loads(info_file.read_text())
        models = Path(info["ipa_src"]) / "ipa_room_segmentation" / "common" / "files" / "classifier_models"
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise FileNotFoundError(f"{info_file}: not a build record of make ipa-env ({e}); run make ipa-env again") from None
    return {"env": env, "driver": driver, "models": models, "ipa_commit": str(info.get("ipa_commit", "unknown")),
            "vrf": bool(info.get("vrf")), "vrf_fix": bool(info.get("vrf_fix"))}


def clean_ipa_tmp() -> list[Path]:
    """Remove the driver folders (``<tmp>/roomseg-ipa-<pid>-*``) of processes that are gone
    (killed before they could remove their own); returns the folders removed."""
    return clean_dead_tmp(TMP_PREFIX)


def ipa_image(walkable: np.ndarray, resolution: float, working: float = IPA_RESOLUTION) -> np.ndarray:
    """The map as the authors' action server takes it: (h, w) uint8 at ``working`` metres per
    pixel (nearest; default :data:`IPA_RESOLUTION`), 255 free (walkable), 0 occupied,
    :data:`PAD_PX` occupied pixels around it."""
    h, w = walkable.shape
    scale = resolution / working
    hh, ww = max(1, int(round(h * scale))), max(1, int(round(w * scale)))
    rows = np.minimum(((np.arange(hh) + 0.5) / scale).astype(np.int64), h - 1)
    cols = np.minimum(((np.arange(ww) + 0.5) / scale).astype(np.int64), w - 1)
    free = np.pad(walkable[rows][:, cols], PAD_PX)
    return np.where(free, 255, 0).astype(np.uint8)


def labels_to_instances(labels: np.ndarray, walkable: np.ndarray, resolution: float,
                        working: float = IPA_RESOLUTION) -> np.ndarray:
    """The driver's label image (0 none, 1..N rooms; :func:`ipa_image`'s pixels at ``working``
    metres per pixel) -> (H, W) int32 room ids on the grid's walkable cells (nearest pixel), -1
    elsewhere."""
    h, w = walkable.shape
    scale = resolution / working
    rr = np.minimum(((np.arange(h) + 0.5) * scale).astype(np.int64) + PAD_PX, labels.shape[0] - 1)
    cc = np.minimum(((np.arange(w) + 0.5) * scale).astype(np.int64) + PAD_PX, labels.shape[1] - 1)
    out = labels[rr][:, cc].astype(np.int32) - 1
    out[~walkable] = -1
    ids, inverse = np.unique(out, return_inverse=True)  # rooms no walkable cell kept: ids stay 0..K-1
    return (inverse.reshape(out.shape) - int(ids[0] < 0)).astype(np.int32)


class IpaSegmenter(Segmenter):
    """One of ipa_room_segmentation's algorithms on the grid's walkable map (module doc).

    Args:
        algorithm: morphological, distance, voronoi, semantic or vrf.
        params: the authors' parameters (names without the algorithm suffix, areas in square
            metres); a name left out takes the authors' default.
        env_dir: the ``make ipa-env`` folder; None: ``$ROOMSEG_IPA_ENV``, else ``.ipa-env``.
        timeout: seconds per map before it is stopped (a failed row).
        min_room_area: smaller rooms merge into a neighbour, square metres (0: none).
        resolution: metres per pixel of the map the driver gets (the grid resampled to it,
            nearest); the authors' 0.05 by default. Their pixel parameters keep their pixels.
    """

    def __init__(self, algorithm: str, params: dict | None = None, env_dir: str | None = None,
                 timeout: float = 300.0, min_room_area: Annotated[float, NonNegative()] = 0.0,
                 resolution: Annotated[float, Positive()] = IPA_RESOLUTION):
        if algorithm not in ALGORITHMS:
            raise ValueError(f"segmenter.algorithm={algorithm!r}: expected one of {', '.join(ALGORITHMS)}")
        params = dict(params or {})
        for key, value in params.items():
            if key not in ALGORITHMS[algorithm]:
                raise ValueError(f"segmenter.params.{key}: not a parameter of ipa {algorithm} "
                                 f"(expected one of {', '.join(ALGORITHMS[algorithm])})")
            if isinstance(value, bool) or not isinstance(value, int | float) or not np.isfinite(value) or value < 0:
                raise ValueError(f"segmenter.params.{key}={value!r}: expected a number >= 0")
        if isinstance(timeout, bool) or not (isinstance(timeout, int | float) and timeout > 0):
            raise ValueError(f"segmenter.timeout={timeout!r}: expected seconds > 0")
        if isinstance(resolution, bool) or not isinstance(resolution, int | float) or not (
                np.isfinite(resolution) and resolution > 0):
            raise ValueError(f"segmenter.resolution={resolution!r}: expected metres per pixel > 0")
        try:
            build = ipa_build(env_dir)
        except FileNotFoundError as e:
            raise ValueError(f"segmenter=ipa_{algorithm}: {e}") from None
        if algorithm == "vrf" and not build["vrf"]:
            raise ValueError(f"segmenter=ipa_vrf: the build in {build['env']} has no VRF (built without OpenGM); "
                             f"run `make ipa-env OPENGM_SRC=<opengm checkout>` (docs/baselines.md)")
        self.algorithm, self.params, self.build = algorithm, params, build
        self.timeout = float(timeout)
        self.resolution = float(resolution)
        self.min_room_area = check_room_area(min_room_area)
        self.last_info: dict[str, float] = {}
        #: VRF: the inference's labels of the last map's field nodes, {"room": n, "hallway": n,
        #: "doorway": n}; None when the build does not print them (or another algorithm).
        self.last_field_nodes: dict[str, int] | None = None

    def run_driver(self, image: np.ndarray) -> np.ndarray:
        """One subprocess of the driver on ``image`` (:func:`ipa_image`); its label image.

        The driver runs under :func:`benchmark.guarded.run_guarded`: in a process group of its
        own, killed whole on a timeout or when this process dies; its folder
        ``<tmp>/roomseg-ipa-<pid>-*`` goes with it, and folders of processes that are gone are
        removed first (:func:`clean_ipa_tmp`).

        Raises:
            RuntimeError: a timeout, or the driver failed (its last line)."""
        clean_ipa_tmp()
        tmp = Path(tempfile.mkdtemp(prefix=f"{TMP_PREFIX}{os.getpid()}-"))
        try:
            if not cv2.imwrite(str(tmp / "map.png"), image):
                raise RuntimeError(f"could not write the map for the ipa driver in {tmp}")
            cmd = [str(self.build["driver"]), "--map", str(tmp / "map.png"), "--resolution", repr(self.resolution),
                   "--algorithm", self.algorithm, "--models", str(self.build["models"]), "--work", str(tmp / "models"),
                   "--out", str(tmp / "labels.png")]
            for key, value in self.params.items():
                cmd += ["--param", f"{key}={value!r}"]
            if self.algorithm == "vrf":  # the algorithm's chatter on stderr: the field nodes' line
                cmd += ["--verbose", "1"]
            self.last_field_nodes = None
            try:
                r = run_guarded(cmd, timeout=self.timeout, remove=[str(tmp)])
            except subprocess.TimeoutExpired:
                raise RuntimeError(f"ipa {self.algorithm} timed out after {self.timeout:g} s (segmenter.timeout)") from None
            labels = cv2.imread(str(tmp / "labels.png"), cv2.IMREAD_UNCHANGED) if r.returncode == 0 else None
            if labels is None or labels.shape != image.shape:
                lines = r.stderr.strip().splitlines()
                last = ([x for x in lines if x.startswith("ipa_segment:")] or lines or ["no output"])[-1]
                raise RuntimeError(f"the ipa driver failed on {self.algorithm} (exit {r.returncode}): {last[:300]}")
            found = FIELD_NODES_LINE.search(r.stderr)
            if found:
                self.last_field_nodes = dict(zip(("room", "hallway", "doorway"), map(int, found.groups()), strict=True))
            return labels
        finally:
            shutil.rmtree(tmp, ignore_errors=True)

    def __call__(self, grid: GridMap) -> np.ndarray:
        t = time.perf_counter()
        walkable = np.asarray(grid.walkable, bool)
        labels = self.run_driver(ipa_image(walkable, grid.resolution, self.resolution))
        self.last_info = {"t_ipa": round(time.perf_counter() - t, 3)}
        rooms = labels_to_instances(labels, walkable, grid.resolution, self.resolution)
        if self.min_room_area <= 0:
            return rooms
        return merge_small_rooms(rooms, walkable, self.min_room_area / grid.resolution ** 2)


__all__ = ["IpaSegmenter", "ipa_build", "ipa_image", "labels_to_instances", "ALGORITHMS", "IPA_RESOLUTION", "ENV_VAR"]
