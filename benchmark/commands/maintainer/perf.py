"""``make perf``: time the aggregators and post-processing against their references.

For each shared ProcTHOR house (first ``--houses``), each generated house (first
``--synthetic`` of :class:`envs.datasets.synthetic.SyntheticEnv`) and each resolution, autotrace poses
with random class probabilities are aggregated by the fast implementation and by its
slow reference (graph KNN: one SciPy csgraph BFS per viewpoint; vision cone: a per-ray
Python loop), on the *same* views, in the same process; the labels must be identical.
The per-ray Python reference is very slow, so it runs on the first ``--cone-ref-views``
views only and the fast version is timed again on exactly those views for the ratio.
The vision cone is also set against its floor: one vote added for each visible (view, cell)
pair, each pair once, from a precomputed list (what any cone implementation must at least
do); ``cone / floor`` is the ratio of the two times, each the best of 7 rounds of one call of
each (the order reversed every other round), so that the machine's changing speed meets both.
Euclidean KNN (no reference) is timed alongside. Prints per-house medians, the speed-up
ratios, and peak traced memory (tracemalloc: Python and NumPy allocations, including the
map-sized work arrays the numba kernels fill), also as bytes per map pixel: constant across
resolutions means linear in the map size.

Large maps (``--segment-rooms``): ``roomseg-segment`` (vision cone, post-processing, every
output file) on the example building of :mod:`benchmark.commands.segment_example` with N x N
rooms of 10 m at 0.05 m/px (16 views a room), each in a fresh process; its wall time and peak
RSS, and the bytes per map pixel between the two largest sizes (what each extra pixel costs).
N = 80 is the 16000 x 16000 px (800 m x 800 m) map of the 8 GB target, measured (16020 x
16020 px, 102,400 views, a few minutes); below that the peak is extrapolated to it. The
example's inputs are written by bands of rows, so this process stays small at any N.

Robot conditions (issue #25), per shared ProcTHOR house at 0.05 m/px (``--robot-houses``):
scan-map construction (:func:`envs.maps.scan.scan_map`, default :class:`ScanSettings`: plane
0.25 m, range 10 m, 1 degree beams, no noise; scans along the autotrace views' trajectory every
0.5 m) and, with range noise 0.02 m and dropout 0.05, against the pure-Python reference on the
first ``--scan-ref-scans`` scans (the fast mapper timed again on exactly those for the ratio);
frontier exploration (:class:`benchmark.conditions.exploration.Frontier` with its defaults, 40 m budget)
against its pure-Python reference on the whole exploration. Maps and poses must be identical.
"""

from __future__ import annotations

import time
import tracemalloc
from pathlib import Path

import numpy as np
import pandas as pd

from benchmark.commands import cli
from benchmark.paths import procthor_houses
from envs.kernel_cache import njit


def _timed(fn, *args, repeat: int = 3):
    """(result, best wall time in seconds over ``repeat`` calls)."""
    best = float("inf")
    out = None
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn(*args)
        best = min(best, time.perf_counter() - t)
    return out, best


def _timed_together(calls, repeat: int = 7, clock=time.perf_counter) -> list[float]:
    """Best wall time in seconds of each ``(fn, *args)`` of ``calls`` over ``repeat`` rounds, one
    call of each per round, in turn (forwards, then backwards in the next round): the times of
    a ratio taken side by side, so that a change in the machine's speed meets both. ``clock``:
    the timer, seconds."""
    best = [float("inf")] * len(calls)
    for k in range(repeat):
        order = range(len(calls)) if k % 2 == 0 else range(len(calls) - 1, -1, -1)
        for i in order:
            fn, *args = calls[i]
            t = clock()
            fn(*args)
            best[i] = min(best[i], clock() - t)
    return best


def _peak(fn, *args) -> int:
    tracemalloc.start()
    fn(*args)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return peak


def _scenes(path: Path, houses: int, synthetic: int, res: float):
    """(dataset, house id, Scene) for the shared ProcTHOR houses and the generated ones."""
    from envs.datasets.house_files import load_houses
    from envs.datasets.synthetic import SyntheticEnv
    from envs.maps.scene import rasterise_house

    if houses > 0:
        for h in load_houses(path, 0, houses):
            yield "procthor shared", h.id, rasterise_house(h, resolution=res)
    if synthetic > 0:
        env = SyntheticEnv(n_houses=synthetic, resolution=res)
        for hid in env.house_ids():
            yield "synthetic", hid, env.scene(hid)


@njit(cache=True)
def _add_votes(flat, labels, counts):
    for k in range(flat.shape[0]):
        counts[labels[k], flat[k]] += 1.0


def cone_pairs(grid, poses: np.ndarray, proba: np.ndarray, cone) -> tuple[np.ndarray, np.ndarray]:
    """Every (view, cell) pair ``cone`` votes for, each once, in view order: ((P,) int64 flat
    cell indices, (P,) int64 the view's label), found with :func:`envs.maps.rays.cast_rays`
    per view and :func:`numpy.unique` per view (no code shared with the cone's kernel)."""
    from benchmark.aggregators.common import view_cells
    from envs.maps.rays import cast_rays, cone_thetas

    r, c, yaw, p, _ = view_cells(grid, poses, proba)
    blocked, max_px = ~grid.walkable, cone.max_range_m / grid.resolution
    flats, labs = [], []
    for i in range(len(r)):
        *_, hit = cast_rays(blocked, int(r[i]), int(c[i]), np.deg2rad([yaw[i]]), cone.blocked_ray_m / grid.resolution)
        if hit[0, 0] >= 0:
            continue
        rr, cc, _, _ = cast_rays(blocked, int(r[i]), int(c[i]), cone_thetas(yaw[i], cone.fov, max_px, cone.ray_density),
                                 max_px)
        flats.append(np.unique(rr.astype(np.int64) * grid.shape[1] + cc))
        labs.append(np.full(len(flats[-1]), int(np.argmax(p[i])), np.int64))
    return np.concatenate(flats), np.concatenate(labs)


def cone_floor(grid, flat: np.ndarray, labels: np.ndarray, n_classes: int) -> np.ndarray:
    """The floor of the vision cone: one vote per visible pair into (C, H * W) float32 counts."""
    counts = np.zeros((n_classes, grid.shape[0] * grid.shape[1]), np.float32)
    _add_votes(flat, labels, counts)
    return counts


def run(houses: int, synthetic: int, resolutions: list[float], cone_ref_views: int, path: Path) -> pd.DataFrame:
    from benchmark.aggregators.euclidean_knn import EuclideanKNN
    from benchmark.aggregators.graph_knn import GraphKNN
    from benchmark.aggregators.reference import graph_knn_reference, vision_cone_reference
    from benchmark.aggregators.vision_cone import VisionCone
    from benchmark.postprocess import PostProcess
    from benchmark.viewpoints import Autotrace

    rows = []
    knn, cone, eu, pp = GraphKNN(k=5), VisionCone(), EuclideanKNN(k=5), PostProcess()
    for res in resolutions:
        for dataset, hid, s in _scenes(path, houses, synthetic, res):
            poses = Autotrace().generate(s)
            proba = np.random.default_rng(0).dirichlet(np.ones(7), len(poses))
            knn(s.grid, poses[:5], proba[:5])  # compile once
            lab, t_knn = _timed(knn, s.grid, poses, proba)
            ref, t_knn_ref = _timed(graph_knn_reference, s.grid, poses, proba, 5, repeat=1)
            cone_lab, t_cone = _timed(cone, s.grid, poses, proba)
            flat, labs = cone_pairs(s.grid, poses, proba, cone)
            floor_counts = cone_floor(s.grid, flat, labs, proba.shape[1])
            t_votes, t_floor = _timed_together([(cone.votes, s.grid, poses, proba),
                                                (cone_floor, s.grid, flat, labs, proba.shape[1])])
            # the floor's counts are the cone's votes: the same pairs, each once
            floor_equal = bool(np.array_equal(floor_counts.reshape(-1, *s.grid.shape), cone.votes(s.grid, poses, proba)))
            sub = slice(0, cone_ref_views)
            small, t_cone_sub = _timed(cone, s.grid, poses[sub], proba[sub])
            cref, t_cone_ref = _timed(vision_cone_reference, s.grid, poses[sub], proba[sub], repeat=1)
            _, t_eu = _timed(eu, s.grid, poses, proba)
            post, t_pp = _timed(pp, cone_lab, s.grid)
            h_, w_ = s.grid.shape
            knn_peak, cone_peak = _peak(knn, s.grid, poses, proba), _peak(cone, s.grid, poses, proba)
            rows.append({
                "dataset": dataset, "resolution": res, "house": hid, "pixels": h_ * w_, "views": len(poses),
                "knn_ms": 1e3 * t_knn, "knn_ref_ms": 1e3 * t_knn_ref, "knn_speedup": t_knn_ref / t_knn,
                "knn_equal": bool(np.array_equal(lab, ref)),
                "cone_ms": 1e3 * t_cone, "cone_speedup": t_cone_ref / t_cone_sub, "cone_pairs": len(flat),
                "cone_votes_ms": 1e3 * t_votes, "cone_floor_ms": 1e3 * t_floor, "cone_over_floor": t_votes / t_floor,
                "floor_equal": floor_equal,
                "cone_equal": bool(np.array_equal(small, cref)), "eu_ms": 1e3 * t_eu, "postprocess_ms": 1e3 * t_pp,
                "knn_peak_MB": knn_peak / 2**20, "cone_peak_MB": cone_peak / 2**20,
                "knn_B_px": knn_peak / (h_ * w_), "cone_B_px": cone_peak / (h_ * w_),
                "pp_peak_MB": _peak(pp, cone_lab, s.grid) / 2**20,
            })
            print(f"{res} m/px {hid}: knn {1e3 * t_knn:.1f} ms (x{t_knn_ref / t_knn:.0f}), "
                  f"cone {1e3 * t_cone:.1f} ms (x{t_cone_ref / t_cone_sub:.0f}; votes {1e3 * t_votes:.1f} ms = "
                  f"{t_votes / t_floor:.1f} x the floor's {1e3 * t_floor:.2f} ms for {len(flat)} pairs), euclidean {1e3 * t_eu:.1f} ms, "
                  f"post {1e3 * t_pp:.1f} ms", flush=True)
    return pd.DataFrame(rows)


def run_robot(houses: int, scan_ref_scans: int, path: Path) -> pd.DataFrame:
    """Scan-map and frontier-exploration timings per shared house at 0.05 m/px (module docstring)."""
    from benchmark.conditions.exploration import Frontier, explore_frontier_reference
    from benchmark.viewpoints import Autotrace
    from envs.datasets.house_files import load_houses
    from envs.maps.scan import (
        ScanSettings,
        house_wall_height,
        scan_map,
        scan_map_reference,
        scan_obstacles,
    )
    from envs.maps.scene import rasterise_house
    from envs.maps.trajectory import trajectory

    rows = []
    clean, noisy = ScanSettings(), ScanSettings(range_noise=0.02, dropout=0.05)
    frontier = Frontier()
    for house in load_houses(path, 0, houses):
        s = rasterise_house(house, resolution=0.05)
        traj = trajectory(s.grid.walkable, s.grid, Autotrace().generate(s), clean.spacing)
        obstacles = scan_obstacles(s, clean.height, house_wall_height(house))
        scan_map(obstacles, s.grid, traj[:2], clean)  # compile once
        frontier.explore(s)
        _, t_scan = _timed(scan_map, obstacles, s.grid, traj, clean)
        _, t_noisy = _timed(scan_map, obstacles, s.grid, traj, noisy)
        sub = traj[:scan_ref_scans]
        eq = True
        t_sub = t_ref = 0.0
        for settings in (clean, noisy):
            fast_sub, t = _timed(scan_map, obstacles, s.grid, sub, settings)
            ref_sub, tr = _timed(scan_map_reference, obstacles, s.grid, sub, settings, repeat=1)
            eq &= bool(np.array_equal(fast_sub.log_odds, ref_sub.log_odds)
                       and np.array_equal(fast_sub.occupancy, ref_sub.occupancy))
            t_sub, t_ref = t_sub + t, t_ref + tr
        exp, t_front = _timed(frontier.explore, s)
        ref, t_front_ref = _timed(explore_frontier_reference, s, frontier, repeat=1)
        same = bool(len(exp.poses) == len(ref.poses) and np.allclose(exp.poses, ref.poses, rtol=0, atol=1e-9)
                    and np.array_equal(exp.scan_map.occupancy, ref.scan_map.occupancy))
        h_, w_ = s.grid.shape
        rows.append({
            "house": house.id, "pixels": h_ * w_, "scans": len(traj), "scan_ms": 1e3 * t_scan,
            "scan_noisy_ms": 1e3 * t_noisy, "scan_speedup": t_ref / t_sub, "scan_equal": eq,
            "frontier_ms": 1e3 * t_front, "frontier_ref_s": t_front_ref, "frontier_speedup": t_front_ref / t_front,
            "frontier_equal": same, "frontier_views": len(exp.poses), "frontier_m": exp.length,
        })
        print(f"0.05 m/px {house.id}: scan map {1e3 * t_scan:.1f} ms ({len(traj)} scans, x{t_ref / t_sub:.0f} "
              f"vs reference), noisy {1e3 * t_noisy:.1f} ms; frontier {1e3 * t_front:.1f} ms "
              f"(x{t_front_ref / t_front:.0f}, {exp.length:.1f} m, {len(exp.poses)} views)", flush=True)
    return pd.DataFrame(rows)


#: a child process that segments and prints its own peak RSS in KiB as its last line: VmHWM of
#: its memory after exec (getrusage's ru_maxrss would also count the forking parent's pages)
_SEGMENT_CHILD = ("import sys; from benchmark.commands.segment import main; rc = main(sys.argv[1:]); "
                  "print([ln.split()[1] for ln in open('/proc/self/status') if ln.startswith('VmHWM:')][0]); "
                  "sys.exit(rc)")


#: the map the large-map target is about: 800 m x 800 m at 0.05 m/px
TARGET_PIXELS = 16000 * 16000


def run_segment_memory(rooms: list[int], workdir: Path) -> pd.DataFrame:
    """Peak RSS of ``roomseg-segment`` on the N x N room example, per N (module docstring).
    The inputs are written by bands of rows (:func:`write_example_inputs`: tens of MB at any
    size), so this process stays small beside the child it measures."""
    import subprocess
    import sys

    from benchmark.commands.segment_example import write_example_inputs

    rows = []
    for n in rooms:
        d = workdir / f"rooms{n}"
        ex = write_example_inputs(d, n, n, room_m=10.0, resolution=0.05)
        h, w = ex.shape
        t = time.perf_counter()
        p = subprocess.run([sys.executable, "-c", _SEGMENT_CHILD, f"map={ex.map_yaml}", f"poses={ex.poses}",
                            "frame=ros", f"labels={ex.labels}", f"out={d / 'segmented'}",
                            f"max_map_pixels={h * w + 1}"], capture_output=True, text=True)
        wall = time.perf_counter() - t
        if p.returncode != 0:
            raise RuntimeError(f"roomseg-segment on {ex.map_yaml} failed: {p.stderr.strip()[-500:]}")
        peak = int(p.stdout.strip().splitlines()[-1]) * 1024
        rows.append({"rooms": f"{n} x {n}", "pixels": h * w, "views": ex.views, "wall s": wall,
                     "peak RSS MB": peak / 2**20})
        print(f"roomseg-segment {w} x {h} px, {ex.views} views: {wall:.1f} s, peak RSS {peak / 2**20:.0f} MB",
              flush=True)
    df = pd.DataFrame(rows)
    if len(df) >= 2:
        a, b = df.iloc[-2], df.iloc[-1]
        per_px = (b["peak RSS MB"] - a["peak RSS MB"]) * 2**20 / (b["pixels"] - a["pixels"])
        df["B/px (marginal)"] = [float("nan")] * (len(df) - 1) + [per_px]
        if b["pixels"] < TARGET_PIXELS:  # measured at the target size: nothing to extrapolate
            df["16000^2 px extrapolated GB"] = [float("nan")] * (len(df) - 1) + [
                (b["peak RSS MB"] * 2**20 + per_px * (TARGET_PIXELS - b["pixels"])) / 1e9]
    return df


def segment_memory_note(df: pd.DataFrame) -> str:
    """The caption under the large-map table: measured at 16000^2 px or extrapolated to it."""
    head = ("roomseg-segment (vision cone, post-processing, all outputs) on N x N rooms of 10 m at 0.05 m/px, "
            "16 views a room, a fresh process each: wall time and peak RSS (VmHWM); bytes per pixel between the "
            "two largest maps. Target: a 16000 x 16000 px map within 8 GB")
    big = df[df["pixels"] >= TARGET_PIXELS]
    if len(big):
        return head + f"; measured at {int(big['pixels'].iloc[0])} px: {big['peak RSS MB'].iloc[0] * 2**20 / 1e9:.2f} GB."
    if "16000^2 px extrapolated GB" in df:
        return head + (": extrapolated from the two largest maps, not run at that size (--segment-rooms ... 80 runs "
                       "it: 16020^2 px).")
    return head + "."


def robot_table(df: pd.DataFrame) -> pd.DataFrame:
    """The robot-conditions summary: medians and maxima over houses."""
    return pd.DataFrame([{
        "houses": len(df), "median pixels": df["pixels"].median(), "median scans": df["scans"].median(),
        "scan map ms (median)": df["scan_ms"].median(), "scan map ms (max)": df["scan_ms"].max(),
        "noisy scan map ms (median)": df["scan_noisy_ms"].median(), "scan speed-up": df["scan_speedup"].median(),
        "scan identical": df["scan_equal"].all(),
        "frontier ms (median)": df["frontier_ms"].median(), "frontier ms (max)": df["frontier_ms"].max(),
        "frontier ref s (median)": df["frontier_ref_s"].median(), "frontier speed-up": df["frontier_speedup"].median(),
        "frontier identical": df["frontier_equal"].all(), "median path m": df["frontier_m"].median(),
    }])


def main(argv: list[str] | None = None) -> int:
    default = procthor_houses()
    ap = cli.ArgumentParser(from_root=True, description=__doc__.split("\n\n")[0])
    ap.add_argument("--houses", type=int, default=5, help="shared ProcTHOR houses (0: none)")
    ap.add_argument("--synthetic", type=int, default=3, help="generated houses (0: none)")
    ap.add_argument("--resolutions", type=float, nargs="+", default=[0.05, 0.02])
    ap.add_argument("--cone-ref-views", type=int, default=20)
    ap.add_argument("--data", type=Path, default=default)
    ap.add_argument("--robot-houses", type=int, default=5,
                    help="shared ProcTHOR houses for the scan-map and frontier timings (0: none)")
    ap.add_argument("--scan-ref-scans", type=int, default=40, help="scans the scan-map reference runs on")
    ap.add_argument("--segment-rooms", type=int, nargs="*", default=[],
                    help="large maps: roomseg-segment's peak memory on N x N rooms of 10 m (e.g. 10 20: "
                         "2020^2 and 4020^2 px), extrapolated to 16000^2 px; 80 measures it there (16020^2 px)")
    ap.add_argument("--out", type=Path, default=None,
                    help="also write the tables here (Markdown, with the date, machine, commit and command)")
    a = ap.parse_args(argv)
    parts: list[str] = []
    if (a.houses > 0 or a.robot_houses > 0) and not a.data.exists():
        print(f"error: shared ProcTHOR houses not found at {a.data} (pass --houses 0 for generated houses only)")
        return 2
    if a.robot_houses > 0:
        robot = run_robot(a.robot_houses, a.scan_ref_scans, a.data)
        parts += [robot_table(robot).to_markdown(index=False, floatfmt=".1f"),
                  f"Robot conditions at 0.05 m/px, shared houses. Times: best of 3 calls per house (references: 1 "
                  f"call; the scan-map reference on the first {a.scan_ref_scans} scans, clean and noisy). Targets: "
                  f"scan map <= 50 ms, frontier <= 200 ms per house."]
        print("\n" + "\n\n".join(parts[-2:]) + "\n")
    if a.segment_rooms:
        import tempfile

        with tempfile.TemporaryDirectory(prefix="roomseg-perf-") as d:
            seg = run_segment_memory(a.segment_rooms, Path(d))
        blank = seg.astype(object).where(seg.notna(), None)  # a cell with no value is empty, not "nan"
        parts += [blank.to_markdown(index=False, floatfmt=".1f", missingval=""), segment_memory_note(seg)]
        print("\n" + "\n\n".join(parts[-2:]) + "\n")
    if a.houses == 0 and a.synthetic == 0:
        return _write(a.out, parts, argv)
    df = run(a.houses, a.synthetic, a.resolutions, a.cone_ref_views, a.data)
    g = df.groupby(["dataset", "resolution"])
    table = pd.DataFrame({
        "houses": g.size(), "median pixels": g["pixels"].median(), "median views": g["views"].median(),
        "graph KNN ms": g["knn_ms"].median(), "csgraph BFS ref ms": g["knn_ref_ms"].median(),
        "KNN speed-up": g["knn_speedup"].median(), "KNN identical": g["knn_equal"].all(),
        "vision cone ms": g["cone_ms"].median(), "cone speed-up": g["cone_speedup"].median(),
        "cone identical": g["cone_equal"].all(), "cone votes ms": g["cone_votes_ms"].median(),
        "cone floor ms": g["cone_floor_ms"].median(), "cone / floor": g["cone_over_floor"].median(),
        "floor identical": g["floor_equal"].all(), "Euclidean KNN ms": g["eu_ms"].median(),
        "post-process ms": g["postprocess_ms"].median(),
        "KNN peak MB": g["knn_peak_MB"].median(), "cone peak MB": g["cone_peak_MB"].median(),
        "KNN B/px": g["knn_B_px"].median(), "cone B/px": g["cone_B_px"].median(),
        "post peak MB": g["pp_peak_MB"].median(),
    }).reset_index()
    table["resolution"] = table["resolution"].map(lambda r: f"{r:g} m/px")
    parts += [table.to_markdown(index=False, floatfmt=".1f"),
              f"Medians over houses. Speed-ups measured in this run on the same inputs (cone: the first "
              f"{a.cone_ref_views} views). Cone / floor: the cone's voting (before the window mode) over one vote "
              f"per visible (view, cell) pair from a precomputed list, same views; floor identical: those "
              f"votes equal the cone's. Times: best of 3 calls per house; cone votes and floor: best of 7, "
              f"called in turn. Peak: tracemalloc (Python/NumPy "
              f"allocations, incl. the numba kernels' work arrays)."]
    print("\n" + "\n\n".join(parts[-2:]))
    return _write(a.out, parts, argv)


def _write(out: Path | None, parts: list[str], argv: list[str] | None) -> int:
    """The tables to ``out`` (when given) under a line saying when, where and by which command."""
    if out is None:
        return 0

    from benchmark.reports.published import write_measured

    write_measured(out, "benchmark.commands.maintainer.perf", argv, "\n\n".join(parts))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
