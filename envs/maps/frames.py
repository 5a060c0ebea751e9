"""Frame conversion between ROS ``map_server`` maps / poses and the project's grid and yaw.

ROS (REP 103, ``map_server``): a map's ``origin: [x, y, yaw]`` is the pose of the
*bottom-left corner* of the bottom-left pixel of the image; ``x`` grows to the right, ``y``
grows up; a heading ``theta`` is in radians, counter-clockwise from ``+x``. Image row 0 is
the *top* of the picture.

Project (:mod:`envs.maps.gridmap`): world ``(x, z)`` in metres, ``GridMap.origin`` is the
world ``(x, z)`` of the *top-left corner* of pixel (0, 0); row grows as ``z`` decreases;
yaw in degrees, 0 faces ``+z`` (up on the map), 90 faces ``+x`` (right), i.e. clockwise
from up.

The mapping is ROS ``(x, y)`` -> project ``(x, z) = (x, y)``: no mirroring, so the ROS
image drawn as is equals the project's map drawn with row 0 on top::

          ROS                                    project
      y ^                                    z ^   origin (x0, z0) = top-left corner
        |   theta (rad, CCW from +x)           | * ------------- +    row 0
        |   .                                  | |   yaw (deg, CW  |
        |  .                                   | |   from +z)      |
        | . theta                              | |      ^ 0        |
        +---------> x                          | |      |          |
     origin (ox, oy) = bottom-left corner      | |      +--> 90    |
     of the bottom-left pixel                  | + ------------- +    row H-1
                                               +------------------> x
      x0 = ox,   z0 = oy + H * resolution     (H = image height in pixels)
      yaw_deg = (90 - degrees(theta)) mod 360,   theta = radians(90 - yaw_deg) in (-pi, pi]

Examples: theta = 0 (facing +x) is yaw 90; theta = pi/2 (facing +y) is yaw 0; theta = pi
(facing -x) is yaw 270; theta = -pi/2 (facing -y) is yaw 180.
"""

from __future__ import annotations

import numpy as np


def ros_to_world(x, y, theta):
    """ROS pose(s) -> project world pose(s).

    Args:
        x, y: ROS position(s), metres (scalars or arrays of one shape).
        theta: ROS heading(s), radians, counter-clockwise from +x.

    Returns:
        (x, z, yaw_deg): float arrays (0-d for scalar input); ``z = y``; ``yaw_deg`` in
        [0, 360), clockwise from +z.
    """
    x = np.asarray(x, dtype=float)
    z = np.asarray(y, dtype=float).copy()
    yaw = np.mod(90.0 - np.rad2deg(np.asarray(theta, dtype=float)), 360.0)
    yaw = np.where(yaw >= 360.0, 0.0, yaw)  # mod of a tiny negative can round to 360.0
    return x.copy(), z, yaw


def world_to_ros(x, z, yaw_deg):
    """Project world pose(s) -> ROS pose(s); the inverse of :func:`ros_to_world`.

    Args:
        x, z: world position(s), metres.
        yaw_deg: project yaw(s), degrees clockwise from +z.

    Returns:
        (x, y, theta): float arrays; ``y = z``; ``theta`` in radians in (-pi, pi],
        counter-clockwise from +x.
    """
    x = np.asarray(x, dtype=float)
    y = np.asarray(z, dtype=float).copy()
    deg = np.mod(90.0 - np.asarray(yaw_deg, dtype=float), 360.0)  # [0, 360)
    deg = np.where(deg > 180.0, deg - 360.0, deg)  # (-180, 180]
    return x.copy(), y, np.deg2rad(deg)


def ros_origin_to_grid_origin(origin_xy, height_px: int, resolution: float) -> tuple[float, float]:
    """ROS map origin (bottom-left corner of the bottom-left pixel) -> ``GridMap.origin``.

    Args:
        origin_xy: ROS ``origin`` ``(x, y)`` in metres (a third yaw entry is ignored here;
            :func:`envs.maps.ros.read_ros_map` refuses a non-zero yaw).
        height_px: image height H in pixels.
        resolution: metres per pixel.

    Returns:
        (x0, z0): world (x, z) in metres of the top-left corner of pixel (0, 0):
        ``x0 = ox``, ``z0 = oy + H * resolution``.
    """
    ox, oy = float(origin_xy[0]), float(origin_xy[1])
    return ox, oy + int(height_px) * float(resolution)


def grid_origin_to_ros_origin(grid_origin, height_px: int, resolution: float) -> tuple[float, float]:
    """``GridMap.origin`` (top-left corner of pixel (0, 0)) -> ROS map origin ``(x, y)``.

    Args:
        grid_origin: ``(x0, z0)`` in metres.
        height_px: image height H in pixels.
        resolution: metres per pixel.

    Returns:
        (x, y): ROS ``origin`` in metres (bottom-left corner of the bottom-left pixel):
        ``x = x0``, ``y = z0 - H * resolution``. The ROS origin yaw is 0.
    """
    x0, z0 = float(grid_origin[0]), float(grid_origin[1])
    return x0, z0 - int(height_px) * float(resolution)


__all__ = ["grid_origin_to_ros_origin", "ros_origin_to_grid_origin", "ros_to_world", "world_to_ros"]
