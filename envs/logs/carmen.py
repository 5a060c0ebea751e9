"""CARMEN log reader (plain text or gzip): laser scans and odometry of a real robot.

API::

    from envs.logs.carmen import read_carmen, CarmenLogError
    log = read_carmen("intel-corrected.log.gz")      # path; gzip read by its magic bytes
    log.scans      # list[LaserScan], in file order
    log.odometry   # list[Odometry], in file order
    log.params     # dict name -> value (str) of the PARAM lines
    log.skipped    # dict message name -> count of lines of other messages (NEFF, SYNC, TRUEPOS, ...)

    s = log.scans[0]
    s.kind          # "FLASER" | "RLASER" | "ROBOTLASER1"
    s.ranges        # (n,) float64 metres, beam k at bearing s.angles()[k] in the laser's frame
    s.angle_min, s.angle_increment   # radians, counter-clockwise from the laser's heading
    s.max_range     # metres (ROBOTLASER1: the log's own; FLASER/RLASER: None, the log does not say)
    s.laser_pose    # (x, y, theta) of the laser in the world (metres, radians): in the corrected
                    # logs, the corrected pose
    s.robot_pose    # (x, y, theta) the robot's odometry pose logged with the scan
    s.timestamp     # seconds (the ipc timestamp)
    s.line          # line number in the file (1-based)
    s.endpoints()   # (n, 2) world x, y of each beam's end

    log.laser_poses(), log.scan_ranges()   # (N, 3) and (N, n) arrays over the scans of one kind

Line formats (CARMEN's logger, carmen/src/logger, "message formats" header of a CARMEN log)::

    FLASER num_readings [range_readings] x y theta odom_x odom_y odom_theta ipc_timestamp ipc_hostname logger_timestamp
    RLASER (as FLASER; the rear laser)
    ODOM x y theta tv rv accel ipc_timestamp ipc_hostname logger_timestamp
    ROBOTLASER1 laser_type start_angle field_of_view angular_resolution maximum_range accuracy remission_mode
        num_readings [range_readings] num_remissions [remissions] laser_x laser_y laser_theta
        robot_x robot_y robot_theta tv rv forward_safety_dist side_safety_dist turn_axis
        ipc_timestamp ipc_hostname logger_timestamp

FLASER / RLASER lines do not carry the scan's angles: ``num_readings`` beams spread evenly over
180 degrees starting at -90 degrees: ``angle_increment`` pi / num_readings for an even count
(180 beams: 1 degree apart, the SICK LMS of the Radish logs), pi / (num_readings - 1) for an odd
one (181, 361: both ends included). That is the convention of GMapping's CARMEN reader (180 / 181
beams 1 degree, 360 / 361 half a degree), stated here because the log cannot.

Lines starting with ``#`` and empty lines are ignored; lines of other messages are counted in
``skipped``. A line of FLASER / RLASER / ROBOTLASER1 / ODOM / PARAM with the wrong number of
fields or a field that is not a finite number raises :class:`CarmenLogError` naming the file, the
line number and what was expected.
"""

from __future__ import annotations

import gzip
import math
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

LASER_KINDS = ("FLASER", "RLASER", "ROBOTLASER1")


class CarmenLogError(ValueError):
    """A malformed line of a CARMEN log (one line: file, line number, what was expected)."""


@dataclass(frozen=True)
class LaserScan:
    """One laser scan of a CARMEN log (see the module docstring)."""

    kind: str
    ranges: np.ndarray
    angle_min: float
    angle_increment: float
    max_range: float | None
    laser_pose: tuple[float, float, float]
    robot_pose: tuple[float, float, float]
    timestamp: float
    line: int

    def angles(self) -> np.ndarray:
        """(n,) bearing of each beam in the laser's frame, radians counter-clockwise."""
        return self.angle_min + self.angle_increment * np.arange(len(self.ranges))

    def endpoints(self) -> np.ndarray:
        """(n, 2) world x, y of each beam's end point (at its range, max-range beams included)."""
        x, y, t = self.laser_pose
        a = t + self.angles()
        return np.column_stack([x + self.ranges * np.cos(a), y + self.ranges * np.sin(a)])


@dataclass(frozen=True)
class Odometry:
    """One ODOM line: pose (x, y, theta), velocities tv (m/s), rv (rad/s), accel, timestamp, line."""

    pose: tuple[float, float, float]
    tv: float
    rv: float
    accel: float
    timestamp: float
    line: int


@dataclass
class CarmenLog:
    """The messages of a CARMEN log (see the module docstring)."""

    path: str
    scans: list[LaserScan] = field(default_factory=list)
    odometry: list[Odometry] = field(default_factory=list)
    params: dict[str, str] = field(default_factory=dict)
    skipped: dict[str, int] = field(default_factory=dict)

    def of_kind(self, kind: str = "FLASER") -> list[LaserScan]:
        """The scans of one laser message, in file order."""
        return [s for s in self.scans if s.kind == kind]

    def laser_poses(self, kind: str = "FLASER") -> np.ndarray:
        """(N, 3) laser poses (x, y, theta) of the scans of ``kind``."""
        return np.array([s.laser_pose for s in self.of_kind(kind)], np.float64).reshape(-1, 3)

    def scan_ranges(self, kind: str = "FLASER") -> np.ndarray:
        """(N, n) ranges of the scans of ``kind``; one line when their beam counts differ."""
        scans = self.of_kind(kind)
        counts = sorted({len(s.ranges) for s in scans})
        if len(counts) > 1:
            raise CarmenLogError(f"{self.path}: {kind} scans have {counts} beams: expected one beam count")
        return np.array([s.ranges for s in scans], np.float64).reshape(len(scans), counts[0] if counts else 0)


def _open(path: Path):
    with open(path, "rb") as f:
        magic = f.read(2)
    if magic == b"\x1f\x8b":
        return gzip.open(path, "rt", encoding="utf-8", errors="replace")
    return open(path, encoding="utf-8", errors="replace")


class _Line:
    def __init__(self, path: Path, no: int, fields: list[str]):
        self.path, self.no, self.fields = path, no, fields

    def error(self, what: str) -> CarmenLogError:
        return CarmenLogError(f"{self.path}: line {self.no} ({self.fields[0]}): {what}")

    def need(self, n: int, form: str) -> None:
        if len(self.fields) < n:
            raise self.error(f"{len(self.fields) - 1} fields: expected {form}")

    def num(self, k: int, name: str) -> float:
        try:
            v = float(self.fields[k])
        except (ValueError, IndexError):
            got = self.fields[k] if k < len(self.fields) else "nothing"
            raise self.error(f"{name} = {got!r}: expected a number") from None
        if not math.isfinite(v):
            raise self.error(f"{name} = {self.fields[k]!r}: expected a finite number")
        return v

    def count(self, k: int, name: str) -> int:
        v = self.num(k, name)
        if v != int(v) or v < 0:
            raise self.error(f"{name} = {self.fields[k]!r}: expected a whole number >= 0")
        return int(v)

    def nums(self, k: int, n: int, name: str) -> np.ndarray:
        return np.array([self.num(k + i, f"{name}[{i}]") for i in range(n)], np.float64)


_FLASER_FORM = "num_readings, the readings, x y theta odom_x odom_y odom_theta ipc_timestamp ipc_hostname " \
               "logger_timestamp"


def _flaser(ln: _Line) -> LaserScan:
    ln.need(2, _FLASER_FORM)
    n = ln.count(1, "num_readings")
    if len(ln.fields) != 2 + n + 9:
        raise ln.error(f"{len(ln.fields) - 1} fields with num_readings {n}: expected {n + 10} ({_FLASER_FORM})")
    ranges = ln.nums(2, n, "range")
    k = 2 + n
    laser = tuple(ln.nums(k, 3, "laser pose").tolist())
    robot = tuple(ln.nums(k + 3, 3, "odometry pose").tolist())
    inc = math.pi / (n - 1 if n % 2 else n) if n > 1 else 0.0
    return LaserScan(ln.fields[0], ranges, -math.pi / 2, inc, None, laser, robot, ln.num(k + 6, "ipc_timestamp"),
                     ln.no)


_ROBOTLASER_FORM = "laser_type start_angle field_of_view angular_resolution maximum_range accuracy remission_mode " \
                   "num_readings, the readings, num_remissions, the remissions, laser pose (3), robot pose (3), tv rv " \
                   "forward_safety_dist side_safety_dist turn_axis ipc_timestamp ipc_hostname logger_timestamp"


def _robotlaser(ln: _Line) -> LaserScan:
    ln.need(9, _ROBOTLASER_FORM)
    start, res, max_range = ln.num(2, "start_angle"), ln.num(4, "angular_resolution"), ln.num(5, "maximum_range")
    n = ln.count(8, "num_readings")
    ln.need(10 + n, _ROBOTLASER_FORM)
    ranges = ln.nums(9, n, "range")
    m = ln.count(9 + n, "num_remissions")
    k = 10 + n + m
    if len(ln.fields) != k + 14:
        raise ln.error(f"{len(ln.fields) - 1} fields with num_readings {n} and num_remissions {m}: expected "
                       f"{k + 13} ({_ROBOTLASER_FORM})")
    laser = tuple(ln.nums(k, 3, "laser pose").tolist())
    robot = tuple(ln.nums(k + 3, 3, "robot pose").tolist())
    return LaserScan("ROBOTLASER1", ranges, start, res, max_range, laser, robot, ln.num(k + 11, "ipc_timestamp"),
                     ln.no)


def _odom(ln: _Line) -> Odometry:
    form = "x y theta tv rv accel ipc_timestamp ipc_hostname logger_timestamp"
    if len(ln.fields) != 10:
        raise ln.error(f"{len(ln.fields) - 1} fields: expected 9 ({form})")
    v = ln.nums(1, 6, "x y theta tv rv accel")
    return Odometry((v[0], v[1], v[2]), v[3], v[4], v[5], ln.num(7, "ipc_timestamp"), ln.no)


def read_carmen(path: str | Path) -> CarmenLog:
    """The scans, odometry and parameters of the CARMEN log at ``path`` (see the module docstring)."""
    path = Path(path)
    if not path.is_file():
        raise CarmenLogError(f"{path}: no such file (expected a CARMEN log, plain or gzip)")
    log = CarmenLog(str(path))
    skipped: Counter = Counter()
    with _open(path) as f:
        for no, text in enumerate(f, 1):
            fields = text.split()
            if not fields or fields[0].startswith("#"):
                continue
            ln = _Line(path, no, fields)
            tag = fields[0]
            if tag in ("FLASER", "RLASER"):
                log.scans.append(_flaser(ln))
            elif tag == "ROBOTLASER1":
                log.scans.append(_robotlaser(ln))
            elif tag == "ODOM":
                log.odometry.append(_odom(ln))
            elif tag == "PARAM":
                if len(fields) < 3:
                    raise ln.error(f"{len(fields) - 1} fields: expected param_name param_value ...")
                log.params[fields[1]] = fields[2]
            else:
                skipped[tag] += 1
    log.skipped = dict(skipped)
    return log
