"""Pose conversions between our convention / AI2-THOR and Habitat-Sim, against hand-computed cases."""

import numpy as np
import pytest

from envs.maps.gridmap import GridMap, yaw_to_pixel_direction
from envs.maps.poses import (
    habitat_forward,
    habitat_phi_to_thor_yaw,
    habitat_quat_to_thor_yaw,
    habitat_to_pose,
    habitat_to_thor_position,
    pose_to_habitat,
    pose_to_thor_teleport,
    quat_about_y,
    thor_event_pose,
    thor_forward,
    thor_to_habitat_position,
    thor_yaw_to_habitat_phi,
    thor_yaw_to_habitat_quat,
    wxyz_to_xyzw,
)

S = np.sqrt(0.5)


def _rotate(q, v):
    """v rotated by unit quaternion q = (w, x, y, z): q v q*, written out (independent of envs.maps.poses)."""
    w, x, y, z = q

    def mul(a, b):
        aw, ax, ay, az = a
        bw, bx, by, bz = b
        return (aw * bw - ax * bx - ay * by - az * bz, aw * bx + ax * bw + ay * bz - az * by,
                aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw)

    r = mul(mul((w, x, y, z), (0.0, *v)), (w, -x, -y, -z))
    return np.array(r[1:])


# yaw, THOR forward, Habitat phi, Habitat quaternion (w, x, y, z), Habitat forward -- by hand
Z_CASES = [
    (0, (0, 0, 1), 0, (1, 0, 0, 0), (0, 0, -1)),        # THOR +z is Habitat -z
    (90, (1, 0, 0), 270, (-S, 0, S, 0), (1, 0, 0)),     # THOR +x stays +x
    (180, (0, 0, -1), 180, (0, 0, 1, 0), (0, 0, 1)),
    (270, (-1, 0, 0), 90, (S, 0, S, 0), (-1, 0, 0)),
    (45, (S, 0, S), 315, (np.cos(np.pi * 315 / 360), 0, np.sin(np.pi * 315 / 360), 0), (S, 0, -S)),
]
X_CASES = [
    (0, (0, 0, 1), 180, (0, 0, 1, 0), (0, 0, 1)),       # THOR +z stays +z
    (90, (1, 0, 0), 90, (S, 0, S, 0), (-1, 0, 0)),      # THOR +x is Habitat -x
    (180, (0, 0, -1), 0, (1, 0, 0, 0), (0, 0, -1)),
    (270, (-1, 0, 0), 270, (-S, 0, S, 0), (1, 0, 0)),
]


@pytest.mark.parametrize("mirror,case", [("z", c) for c in Z_CASES] + [("x", c) for c in X_CASES])
def test_heading_by_hand(mirror, case):
    yaw, thor_fwd, phi, quat, hab_fwd = case
    assert np.allclose(thor_forward(yaw), thor_fwd, atol=1e-12)
    assert np.isclose(thor_yaw_to_habitat_phi(yaw, mirror), phi)
    assert np.allclose(thor_yaw_to_habitat_quat(yaw, mirror), quat, atol=1e-12)
    assert np.allclose(habitat_forward(quat), hab_fwd, atol=1e-12)
    # Habitat's camera looks along -z: the quaternion rotates (0, 0, -1) onto the forward
    assert np.allclose(_rotate(quat, (0.0, 0.0, -1.0)), hab_fwd, atol=1e-12)
    # the Habitat forward is the THOR forward with the mirrored axis flipped
    assert np.allclose(hab_fwd, thor_to_habitat_position(*thor_fwd, mirror=mirror), atol=1e-12)
    # and back
    assert np.isclose(habitat_quat_to_thor_yaw(quat, mirror), yaw)
    assert np.isclose(habitat_phi_to_thor_yaw(phi, mirror), yaw)


def test_positions_by_hand():
    assert thor_to_habitat_position(1.0, 0.9, 2.0).tolist() == [1.0, 0.9, -2.0]
    assert thor_to_habitat_position(1.0, 0.9, 2.0, mirror="x").tolist() == [-1.0, 0.9, 2.0]
    assert habitat_to_thor_position([1.0, 0.9, -2.0]) == (1.0, 0.9, 2.0)
    assert habitat_to_thor_position([-1.0, 0.9, 2.0], mirror="x") == (1.0, 0.9, 2.0)
    pos, q = pose_to_habitat((3.0, -1.5, 90.0), floor_y=0.1)
    assert pos.tolist() == [3.0, 0.1, 1.5] and np.allclose(q, (-S, 0, S, 0))
    assert wxyz_to_xyzw(q) == pytest.approx([0.0, S, 0.0, -S])


@pytest.mark.parametrize("mirror", ["z", "x"])
def test_round_trips(mirror):
    rng = np.random.default_rng(0)
    for _ in range(100):
        x, y, z, yaw = rng.uniform(-10, 10), rng.uniform(0, 2), rng.uniform(-10, 10), rng.uniform(-360, 720)
        assert np.allclose(habitat_to_thor_position(thor_to_habitat_position(x, y, z, mirror), mirror), (x, y, z))
        assert np.isclose(habitat_quat_to_thor_yaw(thor_yaw_to_habitat_quat(yaw, mirror), mirror), yaw % 360)
        pos, q = pose_to_habitat((x, z, yaw), 0.0, mirror)
        back = habitat_to_pose(pos, q, mirror)
        assert np.allclose(back[:2], (x, z)) and np.isclose(back[2], yaw % 360)
        # a quaternion and its negative are the same rotation
        assert np.isclose(habitat_quat_to_thor_yaw(-q, mirror), yaw % 360)
        # forward vectors agree through the mirror for any yaw
        assert np.allclose(habitat_forward(q), thor_to_habitat_position(*thor_forward(yaw), mirror=mirror), atol=1e-9)


def test_yaw_on_the_map_matches_the_simulator_heading():
    """1 m ahead of a pose in THOR coordinates is the pixel the map heading points to."""
    grid = GridMap(np.ones((100, 100), bool), 0.05, (0.0, 5.0))
    for yaw in (0, 30, 90, 135, 200, 270, 333):
        x, z = 2.5, 2.5
        f = thor_forward(yaw)
        r0, c0 = grid.world_to_pixel(x, z)
        r1, c1 = grid.world_to_pixel(x + f[0], z + f[2])
        d = np.array([r1 - r0, c1 - c0]) * grid.resolution
        assert np.allclose(d, yaw_to_pixel_direction(yaw), atol=1e-9)


def test_bad_input():
    with pytest.raises(ValueError, match="vertical axis"):
        habitat_quat_to_thor_yaw([S, S, 0.0, 0.0])
    with pytest.raises(ValueError, match="vertical axis"):
        habitat_quat_to_thor_yaw([0.0, 0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="mirror must be one of"):
        thor_to_habitat_position(0, 0, 0, mirror="y")
    with pytest.raises(ValueError, match="rotation.y"):
        thor_event_pose({"position": {"x": 1}})
    assert np.allclose(quat_about_y(360.0), (-1, 0, 0, 0))


def test_thor_teleport_and_event_pose():
    args = pose_to_thor_teleport((1.5, -2.0, -90.0), 0.95, 30.0)
    assert args == {"action": "TeleportFull", "position": {"x": 1.5, "y": 0.95, "z": -2.0},
                    "rotation": {"x": 0.0, "y": 270.0, "z": 0.0}, "horizon": 30.0, "standing": True}
    agent = {"position": {"x": 1.5, "y": 0.9, "z": -2.0}, "rotation": {"x": 0, "y": 270.0, "z": 0}}
    assert thor_event_pose(agent) == (1.5, -2.0, 270.0)
