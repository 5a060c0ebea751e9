"""2D pose-graph reader: g2o (VERTEX_SE2 / EDGE_SE2) and TORO (VERTEX2 / EDGE2) files.

API::

    from envs.logs.g2o import read_pose_graph, read_g2o, read_toro, PoseGraphFileError, edge_errors
    g = read_pose_graph("input_INTEL_g2o.g2o")   # format from the line tags (g2o or TORO)
    g.ids          # (N,) int vertex ids as in the file, ascending
    g.initial      # (N, 3) the file's initial guess x, y, theta per vertex (row k: ids[k])
    g.i, g.j       # (E,) int ROW indices into ids of each edge's two vertices (j seen from i)
    g.z            # (E, 3) measurement dx, dy, dtheta (j in i's frame)
    g.information  # (E, 3, 3) symmetric information matrices (order x, y, theta) of g.errors
    g.format       # "g2o" | "toro"
    g.chi2(states) # sum over edges of e' I e with e = t2v(Z^-1 (X_i^-1 X_j)) (g2o's EdgeSE2 error)
    edge_errors(states, i, j, z)  # that error of any edges (i, j, z) at states, (E, 3)
    benchmark.conditions.pose_graph.graph_of_file(g)  # the back end's PoseGraph (square-root information)

Line formats and the order of the information entries (upper triangle of I)::

    VERTEX_SE2 id x y theta
    EDGE_SE2   i j dx dy dtheta  I11 I12 I13 I22 I23 I33        (g2o: row by row)
    VERTEX2    id x y theta
    EDGE2      i j dx dy dtheta  I11 I12 I22 I33 I13 I23        (TORO: inf_ff inf_fs inf_ss inf_rr
                                                                 inf_fr inf_sr)

The TORO order is the one of TORO's format page (openslam.org/toro.html, "EDGE2 ... inf_ff inf_fs
inf_ss inf_rr inf_fr inf_sr") and of GTSAM's TORO reading (gtsam/slam/dataset.cpp,
NoiseFormatTORO: ``[v1 v2 v5; v2 v3 v6; v5 v6 v4]``). Note that ``gtsam.readG2o`` reads every
file in g2o order, EDGE2 lines included, so it does not serve TORO files: read those here.

The frame of a TORO edge's information: ``information`` always belongs to g2o's error above, whose
translation part is in the MEASUREMENT's frame, ``e_z = R(dtheta)^T e_i`` with ``e_i`` the same
residual in pose i's frame. A TORO file's matrix ``I_toro`` belongs to ``e_i``, so the reader turns it
into ``I = R^T I_toro R``, R the 3x3 rotation by the edge's dtheta (xy block and the cross terms
rotated, I33 as read). TORO's own 2D error (``TreeOptimizer2::error`` in its treeoptimizer2.cpp)
weighs the world-frame residual ``X_i Z - X_j`` with ``R_i I_toro R_i^T``: ``I_toro`` on the residual
in pose i's frame. The datasets' own g2o versions by their author, L. Carlone (e.g.
``data/CSAIL.g2o`` and ``data/manhattan.g2o`` of david-m-rosen/SE-Sync at commit 9b631b6b), hold the
measurements of ``CSAIL_P_toro.graph`` and ``M3500_P_toro.graph`` with each information matrix so
rotated (relative difference <= 1e-9); unrotated, the solve weighs a different problem (CSAIL
chi2 39.13 instead of 40.55). GTSAM's TORO reading (NoiseFormatTORO above) reorders the six
numbers but does not rotate them.

Empty lines and ``#`` comments are ignored; other tags (FIX, VERTEX_XY, ...) are counted in
``skipped``. A malformed line (wrong field count, a value that is not a finite number, an edge to
an unknown vertex, a vertex twice, an information matrix that is not positive definite) raises
:class:`PoseGraphFileError` naming the file, the line number and what was expected.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

VERTEX_TAGS = {"VERTEX_SE2": "g2o", "VERTEX2": "toro"}
EDGE_TAGS = {"EDGE_SE2": "g2o", "EDGE2": "toro"}
#: position in the 3x3 information matrix of the 6 numbers of an edge line, per format
INFO_ORDER = {
    "g2o": ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)),
    "toro": ((0, 0), (0, 1), (1, 1), (2, 2), (0, 2), (1, 2)),
}


class PoseGraphFileError(ValueError):
    """A malformed pose-graph file (one line: file, line number, what was expected)."""


def _wrap(a):
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


def edge_errors(states: np.ndarray, i: np.ndarray, j: np.ndarray, z: np.ndarray) -> np.ndarray:
    """(E, 3) g2o's EdgeSE2 error t2v(Z^-1 (X_i^-1 X_j)) of edges ``(i, j, z)`` at ``states``
    (N, 3) x, y, theta: the translation part in the measurement's frame (metres), the rotation
    part wrapped to [-pi, pi) (radians)."""
    s = np.asarray(states, np.float64)
    z = np.asarray(z, np.float64).reshape(-1, 3)
    xi, xj = s[np.asarray(i)], s[np.asarray(j)]
    d = xj[:, :2] - xi[:, :2]
    c, sn = np.cos(xi[:, 2]), np.sin(xi[:, 2])
    rel = np.column_stack([c * d[:, 0] + sn * d[:, 1], -sn * d[:, 0] + c * d[:, 1], xj[:, 2] - xi[:, 2]])
    dt = rel[:, :2] - z[:, :2]
    cz, sz = np.cos(z[:, 2]), np.sin(z[:, 2])
    return np.column_stack([cz * dt[:, 0] + sz * dt[:, 1], -sz * dt[:, 0] + cz * dt[:, 1], _wrap(rel[:, 2] - z[:, 2])])


@dataclass
class PoseGraphFile:
    """A 2D pose graph read from a file (see the module docstring)."""

    path: str
    format: str
    ids: np.ndarray
    initial: np.ndarray
    i: np.ndarray
    j: np.ndarray
    z: np.ndarray
    information: np.ndarray
    skipped: dict[str, int] = field(default_factory=dict)

    @property
    def n(self) -> int:
        return len(self.ids)

    def errors(self, states: np.ndarray) -> np.ndarray:
        """(E, 3) g2o's EdgeSE2 error of each edge at ``states`` (N, 3): t2v(Z^-1 (X_i^-1 X_j))."""
        return edge_errors(states, self.i, self.j, self.z)

    def chi2(self, states: np.ndarray) -> float:
        """Sum over edges of e' I e (g2o's chi2) at ``states`` (N, 3)."""
        e = self.errors(states)
        return float(np.einsum("ei,eij,ej->", e, self.information, e))


def _num(path: Path, no: int, tag: str, text: str, name: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise PoseGraphFileError(f"{path}: line {no} ({tag}): {name} = {text!r}: expected a number") from None
    if not math.isfinite(v):
        raise PoseGraphFileError(f"{path}: line {no} ({tag}): {name} = {text!r}: expected a finite number")
    return v


def _id(path: Path, no: int, tag: str, text: str, name: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise PoseGraphFileError(f"{path}: line {no} ({tag}): {name} = {text!r}: expected a whole number") from None
    return v


def toro_information_in_g2o_frame(info: np.ndarray, dtheta: float) -> np.ndarray:
    """The (3, 3) information ``info`` of a TORO edge (its residual in pose i's frame) for g2o's error
    in the measurement's frame (module docstring): ``R^T info R`` with R the rotation by ``dtheta``
    radians of x and y (theta kept)."""
    c, s = math.cos(dtheta), math.sin(dtheta)
    rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    out = rot.T @ np.asarray(info, np.float64) @ rot
    return (out + out.T) / 2


def read_pose_graph(path: str | Path, fmt: str | None = None) -> PoseGraphFile:
    """The pose graph in ``path``; ``fmt`` "g2o" or "toro" requires that format's tags, None takes
    the format of the first vertex or edge line (one file holds one format)."""
    path = Path(path)
    if fmt not in (None, "g2o", "toro"):
        raise PoseGraphFileError(f"pose-graph format {fmt!r}: expected g2o or toro")
    if not path.is_file():
        raise PoseGraphFileError(f"{path}: no such file (expected a g2o or TORO 2D pose graph)")
    vertices: dict[int, tuple[float, float, float]] = {}
    edges: list[tuple[int, int, int, list[float], np.ndarray]] = []
    skipped: Counter = Counter()
    with open(path, encoding="utf-8", errors="replace") as f:
        for no, text in enumerate(f, 1):
            fields = text.split()
            if not fields or fields[0].startswith("#"):
                continue
            tag = fields[0]
            kind = VERTEX_TAGS.get(tag) or EDGE_TAGS.get(tag)
            if kind is None:
                skipped[tag] += 1
                continue
            if fmt is None:
                fmt = kind
            elif kind != fmt:
                raise PoseGraphFileError(f"{path}: line {no} ({tag}): a {kind} line in a {fmt} file: expected "
                                         f"{' / '.join(t for t, k in {**VERTEX_TAGS, **EDGE_TAGS}.items() if k == fmt)}")
            if tag in VERTEX_TAGS:
                if len(fields) != 5:
                    raise PoseGraphFileError(f"{path}: line {no} ({tag}): {len(fields) - 1} fields: expected 4 "
                                             f"(id x y theta)")
                vid = _id(path, no, tag, fields[1], "id")
                if vid in vertices:
                    raise PoseGraphFileError(f"{path}: line {no} ({tag}): vertex {vid} a second time: expected each "
                                             f"vertex once")
                vertices[vid] = tuple(_num(path, no, tag, v, n) for v, n in zip(fields[2:], ("x", "y", "theta")))
            else:
                order = "I11 I12 I13 I22 I23 I33" if fmt == "g2o" else "I11 I12 I22 I33 I13 I23"
                if len(fields) != 12:
                    raise PoseGraphFileError(f"{path}: line {no} ({tag}): {len(fields) - 1} fields: expected 11 "
                                             f"(i j dx dy dtheta {order})")
                a, b = _id(path, no, tag, fields[1], "i"), _id(path, no, tag, fields[2], "j")
                z = [_num(path, no, tag, v, n) for v, n in zip(fields[3:6], ("dx", "dy", "dtheta"))]
                info = np.zeros((3, 3))
                for (r, c), v, n in zip(INFO_ORDER[fmt], fields[6:12], order.split()):
                    info[r, c] = info[c, r] = _num(path, no, tag, v, n)
                if np.linalg.eigvalsh(info)[0] <= 0:
                    raise PoseGraphFileError(f"{path}: line {no} ({tag}): information {fields[6:12]} ({order}) is not "
                                             f"positive definite: expected an information matrix ({fmt} order)")
                if fmt == "toro":
                    info = toro_information_in_g2o_frame(info, z[2])
                edges.append((no, a, b, z, info))
    if not vertices:
        raise PoseGraphFileError(f"{path}: no VERTEX_SE2 / VERTEX2 line: expected a 2D pose graph")
    ids = np.array(sorted(vertices), np.int64)
    row = {int(v): k for k, v in enumerate(ids)}
    for no, a, b, _, _ in edges:
        for v, name in ((a, "i"), (b, "j")):
            if v not in row:
                raise PoseGraphFileError(f"{path}: line {no} ({'EDGE_SE2' if fmt == 'g2o' else 'EDGE2'}): {name} = "
                                         f"{v}: expected the id of a vertex of the file")
    return PoseGraphFile(
        path=str(path), format=fmt or "g2o", ids=ids,
        initial=np.array([vertices[int(v)] for v in ids], np.float64).reshape(-1, 3),
        i=np.array([row[e[1]] for e in edges], np.int64), j=np.array([row[e[2]] for e in edges], np.int64),
        z=np.array([e[3] for e in edges], np.float64).reshape(-1, 3),
        information=np.array([e[4] for e in edges], np.float64).reshape(-1, 3, 3),
        skipped=dict(skipped))


def read_g2o(path: str | Path) -> PoseGraphFile:
    """A g2o file (VERTEX_SE2 / EDGE_SE2)."""
    return read_pose_graph(path, "g2o")


def read_toro(path: str | Path) -> PoseGraphFile:
    """A TORO file (VERTEX2 / EDGE2)."""
    return read_pose_graph(path, "toro")
