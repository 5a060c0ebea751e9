"""Pose and coordinate conversions between our convention, AI2-THOR and Habitat-Sim.

Pure functions (no simulator needed), tested both ways in ``tests/test_poses.py``.

* **Ours = AI2-THOR** (Unity: left-handed, y up): world (x, y, z) metres; a pose is
  (x, z, yaw) on the floor with yaw in degrees, 0 facing +z and 90 facing +x (clockwise
  seen from above), so forward = (sin yaw, 0, cos yaw). On our maps (:mod:`envs.maps.gridmap`)
  +x is right and +z is up. The camera height is a separate number (metres).
* **Habitat-Sim** (right-handed, y up, a camera with identity rotation looks along -z): a
  heading is a rotation by ``phi`` about +y (counter-clockwise seen from above, right-hand
  rule), forward = (-sin phi, 0, -cos phi); the rotation is the unit quaternion
  (w, x, y, z) = (cos(phi/2), 0, sin(phi/2), 0), which habitat_sim's
  ``utils.common.quat_from_coeffs`` takes in (x, y, z, w) order.
* **Between the two** a left-handed scene becomes a right-handed one by mirroring one
  horizontal axis. ``mirror="z"`` (the default; the Unity <-> Habitat convention):
  Habitat (x, y, z) = (x, y, -z) and ``phi = -yaw``. ``mirror="x"`` (what UnityGLTF
  exporters do): Habitat (x, y, z) = (-x, y, z) and ``phi = 180 - yaw``. Which one a
  converted scene dataset uses is a property of that dataset (``renderer.mirror``); the
  forward vectors agree in both cases (hand-checked in the tests).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

#: The horizontal axis that is mirrored between AI2-THOR and Habitat-Sim coordinates.
MIRRORS = ("z", "x")


def check_mirror(mirror: str) -> str:
    """Validate a mirror axis name ("z" or "x")."""
    if mirror not in MIRRORS:
        raise ValueError(f"mirror must be one of {MIRRORS} (the axis mirrored between AI2-THOR and Habitat), "
                         f"got {mirror!r}")
    return mirror


def _sign(mirror: str) -> np.ndarray:
    return np.array([1.0, 1.0, -1.0]) if check_mirror(mirror) == "z" else np.array([-1.0, 1.0, 1.0])


def thor_forward(yaw_deg: float) -> np.ndarray:
    """Unit forward vector (x, y, z) of a yaw (degrees) in AI2-THOR / our convention."""
    a = np.deg2rad(yaw_deg)
    return np.array([np.sin(a), 0.0, np.cos(a)])


def thor_to_habitat_position(x: float, y: float, z: float, mirror: str = "z") -> np.ndarray:
    """AI2-THOR world position (metres) -> Habitat-Sim world position (metres), shape (3,)."""
    return np.array([x, y, z], dtype=float) * _sign(mirror)


def habitat_to_thor_position(p: Sequence[float], mirror: str = "z") -> tuple[float, float, float]:
    """Habitat-Sim world position (metres) -> AI2-THOR world position (x, y, z)."""
    q = np.asarray(p, dtype=float)[:3] * _sign(mirror)  # the mirror is its own inverse
    return float(q[0]), float(q[1]), float(q[2])


def thor_yaw_to_habitat_phi(yaw_deg: float, mirror: str = "z") -> float:
    """AI2-THOR yaw (degrees) -> Habitat heading ``phi`` (degrees, about +y), in [0, 360)."""
    phi = -yaw_deg if check_mirror(mirror) == "z" else 180.0 - yaw_deg
    return float(np.mod(phi, 360.0))


def habitat_phi_to_thor_yaw(phi_deg: float, mirror: str = "z") -> float:
    """Habitat heading ``phi`` (degrees about +y) -> AI2-THOR yaw (degrees) in [0, 360)."""
    yaw = -phi_deg if check_mirror(mirror) == "z" else 180.0 - phi_deg
    return float(np.mod(yaw, 360.0))


def quat_about_y(phi_deg: float) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of a rotation by ``phi_deg`` degrees about +y."""
    h = np.deg2rad(phi_deg) / 2.0
    return np.array([np.cos(h), 0.0, np.sin(h), 0.0])


def quat_yaw_about_y(q: Sequence[float]) -> float:
    """Angle (degrees, in [0, 360)) of a unit quaternion (w, x, y, z) that rotates about +y only."""
    w, x, y, z = (float(v) for v in q)
    n = np.sqrt(w * w + x * x + y * y + z * z)
    if n < 1e-9 or abs(x) > 1e-6 * n or abs(z) > 1e-6 * n:
        raise ValueError(f"quaternion {tuple(q)} (w, x, y, z) is not a rotation about the vertical axis")
    return float(np.mod(np.rad2deg(2.0 * np.arctan2(y, w)), 360.0))


def thor_yaw_to_habitat_quat(yaw_deg: float, mirror: str = "z") -> np.ndarray:
    """AI2-THOR yaw (degrees) -> Habitat rotation quaternion (w, x, y, z) about +y."""
    return quat_about_y(thor_yaw_to_habitat_phi(yaw_deg, mirror))


def habitat_quat_to_thor_yaw(q: Sequence[float], mirror: str = "z") -> float:
    """Habitat rotation quaternion (w, x, y, z) about +y -> AI2-THOR yaw in [0, 360)."""
    return habitat_phi_to_thor_yaw(quat_yaw_about_y(q), mirror)


def habitat_forward(q: Sequence[float]) -> np.ndarray:
    """Forward vector (x, y, z) of a Habitat camera with rotation quaternion (w, x, y, z) about +y."""
    phi = np.deg2rad(quat_yaw_about_y(q))
    return np.array([-np.sin(phi), 0.0, -np.cos(phi)])


def wxyz_to_xyzw(q: Sequence[float]) -> list[float]:
    """(w, x, y, z) -> the (x, y, z, w) coefficient order of ``habitat_sim.utils.common.quat_from_coeffs``."""
    w, x, y, z = (float(v) for v in q)
    return [x, y, z, w]


def pose_to_habitat(pose: Sequence[float], floor_y: float = 0.0,
                    mirror: str = "z") -> tuple[np.ndarray, np.ndarray]:
    """Our (x, z, yaw) pose -> Habitat agent state: base position (3,) at ``floor_y`` metres
    and rotation quaternion (w, x, y, z). The camera height is the sensor's offset."""
    x, z, yaw = (float(v) for v in pose)
    return thor_to_habitat_position(x, floor_y, z, mirror), thor_yaw_to_habitat_quat(yaw, mirror)


def habitat_to_pose(position: Sequence[float], q: Sequence[float], mirror: str = "z") -> tuple[float, float, float]:
    """Habitat agent state (position, quaternion (w, x, y, z)) -> our (x, z, yaw) pose."""
    x, _, z = habitat_to_thor_position(position, mirror)
    return x, z, habitat_quat_to_thor_yaw(q, mirror)


def pose_to_thor_teleport(pose: Sequence[float], camera_y: float, horizon: float) -> dict:
    """Our (x, z, yaw) pose -> keyword arguments of AI2-THOR's ``TeleportFull`` action
    (``position`` metres with y = ``camera_y``, ``rotation`` degrees, ``horizon`` degrees
    down, ``standing``)."""
    x, z, yaw = (float(v) for v in pose)
    return {"action": "TeleportFull", "position": {"x": x, "y": float(camera_y), "z": z},
            "rotation": {"x": 0.0, "y": float(np.mod(yaw, 360.0)), "z": 0.0}, "horizon": float(horizon),
            "standing": True}


def thor_event_pose(agent: dict) -> tuple[float, float, float]:
    """Our (x, z, yaw) pose of AI2-THOR's ``event.metadata["agent"]`` (position, rotation.y)."""
    try:
        return float(agent["position"]["x"]), float(agent["position"]["z"]), float(np.mod(agent["rotation"]["y"], 360))
    except (KeyError, TypeError):
        raise ValueError(f"AI2-THOR agent metadata needs position.x/z and rotation.y, got {agent!r}") from None


def vertical_fov(hfov_deg: float, width: int, height: int) -> float:
    """Vertical field of view (degrees) of a pinhole camera with horizontal field of view
    ``hfov_deg`` and an image of ``width`` x ``height`` pixels (square pixels)."""
    if not 0.0 < hfov_deg < 180.0 or width <= 0 or height <= 0:
        raise ValueError(f"need 0 < fov < 180 degrees and a positive image size, got {hfov_deg}, {width} x {height}")
    return float(np.rad2deg(2.0 * np.arctan(np.tan(np.deg2rad(hfov_deg) / 2.0) * height / width)))


def horizontal_fov(vfov_deg: float, width: int, height: int) -> float:
    """Horizontal field of view (degrees) from the vertical one; the inverse of :func:`vertical_fov`."""
    return vertical_fov(vfov_deg, height, width)
