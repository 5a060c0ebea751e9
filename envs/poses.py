"""Pose and coordinate conversions between our convention, AI2-THOR and Habitat-Sim.

* **Ours / AI2-THOR** (Unity, left-handed, y up): world (x, y, z) metres; yaw in degrees,
  0 faces +z, 90 faces +x (clockwise seen from above); forward = (sin yaw, 0, cos yaw).
  Our poses are (x, z, yaw) on the floor; the camera height is a separate number.
* **Habitat-Sim** (right-handed, y up, the camera looks along -z): scenes converted from
  AI2-THOR keep x and y and mirror z (``z_hab = -z``). A heading is a rotation by ``phi``
  about +y (counter-clockwise seen from above), forward = (-sin phi, 0, -cos phi). Matching
  the two forwards gives ``phi = -yaw``. The rotation is the unit quaternion
  (w, x, y, z) = (cos(phi/2), 0, sin(phi/2), 0).
"""

from __future__ import annotations

import numpy as np


def thor_forward(yaw_deg: float) -> np.ndarray:
    """Unit forward vector (x, y, z) of a yaw in AI2-THOR."""
    a = np.deg2rad(yaw_deg)
    return np.array([np.sin(a), 0.0, np.cos(a)])


def thor_to_habitat_position(x: float, y: float, z: float) -> np.ndarray:
    """AI2-THOR world position -> Habitat-Sim world position (z mirrored)."""
    return np.array([x, y, -z], dtype=float)


def habitat_to_thor_position(p) -> tuple[float, float, float]:
    """Habitat-Sim world position -> AI2-THOR world position."""
    return float(p[0]), float(p[1]), float(-p[2])


def thor_yaw_to_habitat_quat(yaw_deg: float) -> np.ndarray:
    """AI2-THOR yaw (degrees) -> Habitat rotation quaternion (w, x, y, z) about +y."""
    phi = -np.deg2rad(yaw_deg)
    return np.array([np.cos(phi / 2), 0.0, np.sin(phi / 2), 0.0])


def habitat_quat_to_thor_yaw(q) -> float:
    """Habitat rotation quaternion (w, x, y, z), a rotation about +y -> AI2-THOR yaw in [0, 360)."""
    w, x, y, z = (float(v) for v in q)
    if abs(x) > 1e-6 or abs(z) > 1e-6:
        raise ValueError(f"quaternion {q} is not a pure rotation about the vertical axis")
    phi = 2.0 * np.arctan2(y, w)
    return float(np.mod(-np.rad2deg(phi), 360.0))


def habitat_forward(q) -> np.ndarray:
    """Forward vector (x, y, z) of a Habitat camera with rotation quaternion (w, x, y, z) about +y."""
    w, _, y, _ = (float(v) for v in q)
    phi = 2.0 * np.arctan2(y, w)
    return np.array([-np.sin(phi), 0.0, -np.cos(phi)])


def pose_to_thor_teleport(pose, camera_y: float, horizon: float) -> dict:
    """Our (x, z, yaw) pose -> keyword arguments of AI2-THOR's ``TeleportFull`` action."""
    x, z, yaw = (float(v) for v in pose)
    return {"action": "TeleportFull", "position": {"x": x, "y": float(camera_y), "z": z},
            "rotation": {"x": 0.0, "y": yaw, "z": 0.0}, "horizon": float(horizon), "standing": True}
