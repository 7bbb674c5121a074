"""Orbital relative motion: the Hill-Clohessy-Wiltshire (HCW) accelerations of a body near a
circular reference orbit, compiled with numba.

In the local-vertical-local-horizontal (LVLH) frame of the reference orbit (x radial, away
from the Earth; y along-track, the orbital velocity's direction; z cross-track, along the
orbit normal; origin on the reference orbit), a body at (x, y, z) moving at (x', y', z')
accelerates, to first order in its distance over the orbit's radius, by

    x'' = 3 n^2 x + 2 n y',   y'' = -2 n x',   z'' = -n^2 z

(n the orbit's mean motion [rad/s]): the gravity gradient and the centrifugal term (3 n^2 x,
-n^2 z) and the Coriolis term (2 n y', -2 n x') of the rotating frame. The scene's frame is
not turned: :class:`OrbitArrays` holds the LVLH axes as unit vectors of the scene's frame and
the scene point the reference orbit passes through, and the kernels take the same
accelerations in scene coordinates,

    a = (3 n^2 (r . e_x) + 2 n (v . e_y)) e_x - 2 n (v . e_x) e_y - n^2 (r . e_z) e_z,

r the position from that point. A rigid body's gravity-gradient torque about its centre of
mass is 3 n^2 e_x x (I e_x) (I its inertia tensor in the scene's frame); :func:`debris_load`
adds the rotating frame's torque, so that its attitude and angular velocity, like its
position and velocity, are relative to the LVLH frame.

A scene without an orbit passes None: each kernel's body is pruned by numba on the argument's
type, so it compiles none of this and its steps call nothing.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numba as nb
import numpy as np

EARTH_MU = 3.986004418e14
"""The Earth's gravitational parameter G M [m^3/s^2] (WGS 84)."""
EARTH_RADIUS = 6378137.0
"""The Earth's equatorial radius [m] (WGS 84)."""


def mean_motion(altitude: float) -> float:
    """Mean motion n = sqrt(mu / a^3) [rad/s] of a circular orbit ``altitude`` [m] above the
    equator's radius (a = R + altitude)."""
    return math.sqrt(EARTH_MU / (EARTH_RADIUS + altitude) ** 3)


class OrbitArrays(NamedTuple):
    """A circular reference orbit as the compiled kernels read it (:func:`orbit_arrays`)."""

    n: float
    """Mean motion [rad/s]."""
    radial: np.ndarray
    """LVLH x (radial, away from the Earth) in the scene's frame [-], shape (3,), unit."""
    along: np.ndarray
    """LVLH y (along-track) in the scene's frame [-], shape (3,), unit."""
    cross: np.ndarray
    """LVLH z (cross-track, radial x along-track) in the scene's frame [-], shape (3,), unit."""
    origin: np.ndarray
    """The scene point the reference orbit passes through (LVLH origin) [m], shape (3,)."""


def orbit_arrays(n: float, radial, along, origin) -> OrbitArrays:
    """The orbit of mean motion ``n`` [rad/s] whose LVLH x and y are the scene directions
    ``radial`` and ``along`` [-] (normalized here; orthogonal) through scene point ``origin``
    [m]."""
    x = np.asarray(radial, dtype=float) / np.linalg.norm(radial)
    y = np.asarray(along, dtype=float) / np.linalg.norm(along)
    return OrbitArrays(n=float(n), radial=x, along=y, cross=np.cross(x, y),
                       origin=np.asarray(origin, dtype=float).copy())


@nb.njit(cache=True, error_model="numpy")
def hcw_acceleration(orbit, px, py, pz, vx, vy, vz):
    """The HCW acceleration [m/s^2] (ax, ay, az) in the scene's frame of a body at (px, py,
    pz) [m] moving at (vx, vy, vz) [m/s] (module doc)."""
    n, ex, ey, ez, o = orbit.n, orbit.radial, orbit.along, orbit.cross, orbit.origin
    rx, ry, rz = px - o[0], py - o[1], pz - o[2]
    radial = 3.0 * n * n * (rx * ex[0] + ry * ex[1] + rz * ex[2]) \
        + 2.0 * n * (vx * ey[0] + vy * ey[1] + vz * ey[2])
    along = -2.0 * n * (vx * ex[0] + vy * ex[1] + vz * ex[2])
    cross = -n * n * (rx * ez[0] + ry * ez[1] + rz * ez[2])
    return (radial * ex[0] + along * ey[0] + cross * ez[0],
            radial * ex[1] + along * ey[1] + cross * ez[1],
            radial * ex[2] + along * ey[2] + cross * ez[2])


@nb.njit(cache=True, error_model="numpy")
def orbit_forces(pos, vel, mass, orbit, force):
    """Add each node's HCW force m a [N] to ``force`` (N, 3), from its position [m] and
    velocity [m/s] (N, 3) and mass [kg] (N,); explicit in the integrators (evaluated at the
    step's start). Without an orbit (None) nothing, and nothing is compiled."""
    if orbit is None:
        return
    for i in range(pos.shape[0]):
        ax, ay, az = hcw_acceleration(orbit, pos[i, 0], pos[i, 1], pos[i, 2], vel[i, 0],
                                      vel[i, 1], vel[i, 2])
        force[i, 0] += mass[i] * ax
        force[i, 1] += mass[i] * ay
        force[i, 2] += mass[i] * az


@nb.njit(cache=True, error_model="numpy")
def clear_orbit_nodes(orbit, force):
    """Zero every row of ``force`` (N, 3) if there is an orbit (it then writes every node's
    row: the grid's rows of the other elements' forces are otherwise cleared only where those
    elements act)."""
    if orbit is None:
        return
    for i in range(force.shape[0]):
        force[i, 0] = force[i, 1] = force[i, 2] = 0.0


def debris_load(orbit: OrbitArrays, mass: float, inertia: np.ndarray, com: np.ndarray,
                velocity: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """The load on a rigid body of ``mass`` [kg] in the LVLH frame, as shape (6,): the HCW
    force [N] at its centre of mass ``com`` [m], moving at ``velocity`` [m/s], and the torque
    [N m] about its centre of mass that turns a rigid body integrated in the scene's frame as
    if it were inertial (PyBullet's, I w' = T - w x I w) as a body turns relative to the
    rotating LVLH frame: with w its angular velocity relative to the frame (``omega``
    [rad/s]), W = n e_z the frame's and I its inertia tensor in the scene's frame (``inertia``
    [kg m^2] (3, 3)), Euler's equations of the inertial rate w + W read in the rotating frame
    (docs/tow.md derives it),

        I w' = T_gg - (w + W) x I (w + W) + I (w x W),

    T_gg = 3 n^2 e_x x (I e_x) the gravity-gradient torque; so the torque applied is
    T_gg - (w + W) x I (w + W) + I (w x W) + w x I w. (A body at rest in the frame turns at
    n in inertial space, as a body in a circular orbit keeping its face to the Earth; a
    body at rest in inertial space turns at -n about e_z in the frame.)"""
    a = hcw_acceleration(orbit, *com, *velocity)
    e = orbit.radial
    w = np.asarray(omega, dtype=float)
    inertial = w + orbit.n * orbit.cross
    torque = (3.0 * orbit.n ** 2 * np.cross(e, inertia @ e)
              - np.cross(inertial, inertia @ inertial)
              + inertia @ np.cross(w, orbit.n * orbit.cross) + np.cross(w, inertia @ w))
    return np.concatenate([mass * np.asarray(a), torque])
