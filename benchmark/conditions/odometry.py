"""Wheel odometry on SE(2): the motion model of Thrun, Burgard and Fox (Probabilistic Robotics,
ch. 5.4, Table 5.6), integrated along the path a robot actually drives.

A move between two poses is three numbers: a turn ``rot1`` towards the new position, a straight
``trans`` (metres), a turn ``rot2`` to the new heading. Odometry reports each with zero-mean
Gaussian noise whose *variance* couples rotation and translation:

* ``rot1``  variance ``alpha1 * rot1**2 + alpha2 * trans**2``   (rad^2)
* ``trans`` variance ``alpha3 * trans**2 + alpha4 * (rot1**2 + rot2**2)``   (m^2)
* ``rot2``  variance ``alpha1 * rot2**2 + alpha2 * trans**2``   (rad^2)

(``alpha1`` rad^2 per rad^2 turned, ``alpha2`` rad^2 per m^2 driven, ``alpha3`` m^2 per m^2
driven, ``alpha4`` m^2 per rad^2 turned.) Integrating the noisy moves from the start pose gives
the dead-reckoning estimate: a heading error turns every later move, so the position error
grows faster than linearly with the distance driven. A move shorter than 1e-9 m is a turn in
place (``rot1 = 0``, ``rot2`` the whole turn), as the book advises.

Poses here are the project's (x, z metres, yaw degrees; yaw 0 faces +z, 90 faces +x,
:mod:`envs.maps.gridmap`). Internally a pose is (x, z, phi) with the standard angle
``phi = pi/2 - yaw`` (radians, counter-clockwise from +x in the x-z plane), so that SE(2)
composition is the textbook one.
"""

from __future__ import annotations

import numpy as np

#: a move shorter than this (metres) is a turn in place
TURN_IN_PLACE = 1e-9


def wrap(a):
    """Angles (radians) wrapped to [-pi, pi)."""
    return np.mod(np.asarray(a, np.float64) + np.pi, 2.0 * np.pi) - np.pi


def to_se2(poses: np.ndarray) -> np.ndarray:
    """(N, 3) x, z (m), yaw (deg) -> (N, 3) x, z (m), phi (rad, counter-clockwise from +x)."""
    p = np.asarray(poses, np.float64).reshape(-1, 3)
    return np.column_stack([p[:, 0], p[:, 1], wrap(np.pi / 2 - np.deg2rad(p[:, 2]))])


def from_se2(states: np.ndarray) -> np.ndarray:
    """(N, 3) x, z, phi (rad) -> (N, 3) x, z (m), yaw (deg, [0, 360))."""
    s = np.asarray(states, np.float64).reshape(-1, 3)
    return np.column_stack([s[:, 0], s[:, 1], np.mod(90.0 - np.rad2deg(s[:, 2]), 360.0)])


def increments(states: np.ndarray) -> np.ndarray:
    """(K, 3) SE(2) states -> (K-1, 3) moves (rot1 rad, trans m, rot2 rad) between consecutive ones."""
    s = np.asarray(states, np.float64).reshape(-1, 3)
    d = np.diff(s, axis=0)
    trans = np.hypot(d[:, 0], d[:, 1])
    turn = trans < TURN_IN_PLACE
    rot1 = np.where(turn, 0.0, wrap(np.arctan2(d[:, 1], d[:, 0]) - s[:-1, 2]))
    rot2 = wrap(d[:, 2] - rot1)
    return np.column_stack([rot1, np.where(turn, 0.0, trans), rot2])


def move_sigmas(moves: np.ndarray, alphas) -> np.ndarray:
    """(K, 3) moves -> (K, 3) standard deviations of rot1 (rad), trans (m), rot2 (rad) (module docstring)."""
    a1, a2, a3, a4 = (float(a) for a in alphas)
    m = np.asarray(moves, np.float64).reshape(-1, 3)
    r1, t, r2 = m[:, 0] ** 2, m[:, 1] ** 2, m[:, 2] ** 2
    return np.sqrt(np.column_stack([a1 * r1 + a2 * t, a3 * t + a4 * (r1 + r2), a1 * r2 + a2 * t]))


def noisy_moves(moves: np.ndarray, alphas, normals: np.ndarray) -> np.ndarray:
    """The moves odometry reports: ``moves - sigmas * normals``.

    Args:
        moves: (K, 3) true rot1, trans, rot2.
        alphas: (alpha1, alpha2, alpha3, alpha4), module docstring.
        normals: (K, 3) standard normal draws (drawn by the caller, whatever the alphas, so
            that severities share their random numbers).
    """
    return np.asarray(moves, np.float64) - move_sigmas(moves, alphas) * np.asarray(normals, np.float64)


def integrate(start: np.ndarray, moves: np.ndarray) -> np.ndarray:
    """Dead reckoning: (3,) start state and (K, 3) moves -> (K + 1, 3) states (start first)."""
    m = np.asarray(moves, np.float64).reshape(-1, 3)
    out = np.empty((len(m) + 1, 3))
    out[0] = start
    # the heading before each move is the start heading plus every earlier turn
    turns = np.concatenate([[0.0], np.cumsum(m[:, 0] + m[:, 2])])
    heading = start[2] + turns[:-1] + m[:, 0]
    out[1:, 0] = start[0] + np.cumsum(m[:, 1] * np.cos(heading))
    out[1:, 1] = start[1] + np.cumsum(m[:, 1] * np.sin(heading))
    out[1:, 2] = wrap(start[2] + turns[1:])
    return out


__all__ = ["wrap", "to_se2", "from_se2", "increments", "move_sigmas", "noisy_moves", "integrate", "TURN_IN_PLACE"]
