"""Bending stiffness (Sec. 3.2, Eq. 4-5): the relaxed prismatic joint of every thread.

Nodes carry an orientation q (unit quaternion x, y, z, w) and an angular velocity w [rad/s].
For thread p from node i to node j, with r = x_j - x_i and the joint axis a = R(q_i) a0 fixed
in node i's frame (a0: the thread's rest direction, in i's body frame):

- transverse spring and damper: the offset of node j from the axis, d = r - (a . r) a, and its
  rate seen from node i's frame, P u with u = (v_j - v_i) - w_i x r and P = I - a a^T, give
  the shear force f = k_t d + c_t P u on i and -f on j, and the torque r x f on i (the axis
  turns with i). f derives from E_t = k_t |d|^2 / 2 and D_t = c_t |P u|^2 / 2.
- angular spring and damper: the relative rotation phi = log(q_j q_i^*) (rotation vector, world
  frame; the rest relative rotation is the identity) and the relative angular velocity give the
  torque k_b phi + c_b (w_j - w_i) on i and its opposite on j. E_b = k_b |phi|^2 / 2.

Forces and moments balance per thread; a straight, unrotated net feels nothing.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from .axial import add_pair


@nb.njit(cache=True, error_model="numpy", inline="always")
def rotate(qx, qy, qz, qw, vx, vy, vz):
    """Rotate the vector v by the unit quaternion q = (x, y, z, w)."""
    tx = 2.0 * (qy * vz - qz * vy)
    ty = 2.0 * (qz * vx - qx * vz)
    tz = 2.0 * (qx * vy - qy * vx)
    return (vx + qw * tx + qy * tz - qz * ty,
            vy + qw * ty + qz * tx - qx * tz,
            vz + qw * tz + qx * ty - qy * tx)


@nb.njit(cache=True, error_model="numpy", inline="always")
def relative_quaternion(ix, iy, iz, iw, jx, jy, jz, jw):
    """q_j q_i^* (x, y, z, w) with w >= 0 (the shorter of the two rotations), and the norm s
    of its vector part."""
    x = -jw * ix + jx * iw - jy * iz + jz * iy
    y = -jw * iy + jy * iw - jz * ix + jx * iz
    z = -jw * iz + jz * iw - jx * iy + jy * ix
    w = jw * iw + jx * ix + jy * iy + jz * iz
    if w < 0.0:
        x, y, z, w = -x, -y, -z, -w
    return x, y, z, w, np.sqrt(x * x + y * y + z * z)


@nb.njit(cache=True, error_model="numpy", inline="always")
def small_rotation_vector(x, y, z, w, s):
    """Rotation vector [rad] of the unit quaternion (x, y, z, w), w > 0, valid where the
    vector part's norm s < 1e-2 w: angle / s = 2 atan(s / w) / s by its series (next term
    ~ (s/w)^10: below round-off). Branch-free."""
    r2 = (s / w) ** 2
    g = 2.0 / w * (1.0 - r2 * (1.0 / 3.0 - r2 * (0.2 - r2 * (1.0 / 7.0 - r2 / 9.0))))
    return g * x, g * y, g * z


ATAN_P = (-8.750608600031904122785e-1, -1.615753718733365076637e1, -7.500855792314704667340e1,
          -1.228866684490136173410e2, -6.485021904942025371773e1)
ATAN_Q = (2.485846490142306297962e1, 1.650270098316988542046e2, 4.328810604912902668951e2,
          4.853903996359136964868e2, 1.945506571482613964425e2)
"""Cephes' rational approximation of atan on [0, 0.66] (numerator, denominator without its
leading 1): relative error below 2.2e-16 (Moshier, *Methods and Programs for Mathematical
Functions*, 1989)."""


@nb.njit(cache=True, error_model="numpy", inline="always")
def atan_nonnegative(x):
    """atan(x) [rad] for x >= 0 (+inf included), branch-free so that loops over threads
    vectorize (libm's atan2 is a call): Cephes' range reduction to [0, 0.66] and
    :data:`ATAN_P` / :data:`ATAN_Q`; within an ulp or two of libm."""
    big = x > 2.414213562373095  # tan(3 pi / 8)
    mid = (x > 0.66) & ~big
    y0 = 1.5707963267948966 if big else (0.7853981633974483 if mid else 0.0)
    extra = 6.123233995736766e-17 if big else (3.061616997868383e-17 if mid else 0.0)
    t = -1.0 / x if big else ((x - 1.0) / (x + 1.0) if mid else x)
    z = t * t
    p = (((ATAN_P[0] * z + ATAN_P[1]) * z + ATAN_P[2]) * z + ATAN_P[3]) * z + ATAN_P[4]
    q = ((((z + ATAN_Q[0]) * z + ATAN_Q[1]) * z + ATAN_Q[2]) * z + ATAN_Q[3]) * z + ATAN_Q[4]
    return y0 + ((t * (z * p / q) + t) + extra)


@nb.njit(cache=True, error_model="numpy", inline="always")
def relative_rotation_vector(ix, iy, iz, iw, jx, jy, jz, jw):
    """Rotation vector [rad] of q_j q_i^* (world frame), the shortest of the two:
    2 atan(s / w) times the unit vector part, by its series for small rotations
    (:func:`small_rotation_vector`). Branch-free."""
    x, y, z, w, s = relative_quaternion(ix, iy, iz, iw, jx, jy, jz, jw)
    sx, sy, sz = small_rotation_vector(x, y, z, w, s)
    g = 2.0 * atan_nonnegative(s / w) / s
    small = s < 1e-2 * w
    return (sx if small else g * x), (sy if small else g * y), (sz if small else g * z)


@nb.njit(cache=True, error_model="numpy", inline="always")
def transverse_force(rx, ry, rz, dvx, dvy, dvz, qx, qy, qz, qw, wx, wy, wz, ax0, ay0, az0,
                     k_t, c_t):
    """The transverse spring and damper of one thread (module doc): its force f [N] on node
    i (-f on j), from r = x_j - x_i [m], v_j - v_i [m/s], node i's orientation q and angular
    velocity w [rad/s], the rest axis a0 in i's frame, k_t [N/m] and c_t [N s/m]."""
    ax, ay, az = rotate(qx, qy, qz, qw, ax0, ay0, az0)
    s = ax * rx + ay * ry + az * rz
    dx, dy, dz = rx - s * ax, ry - s * ay, rz - s * az
    ux = dvx - (wy * rz - wz * ry)
    uy = dvy - (wz * rx - wx * rz)
    uz = dvz - (wx * ry - wy * rx)
    au = ax * ux + ay * uy + az * uz
    return (k_t * dx + c_t * (ux - au * ax), k_t * dy + c_t * (uy - au * ay),
            k_t * dz + c_t * (uz - au * az))


@nb.njit(cache=True, error_model="numpy", inline="always")
def angular_torque(px, py, pz, dwx, dwy, dwz, k_b, c_b):
    """The angular spring and damper of one thread: its torque [N m] on node i (minus on j),
    from the relative rotation vector phi [rad], w_j - w_i [rad/s], k_b [N m/rad] and c_b
    [N m s/rad]."""
    return k_b * px + c_b * dwx, k_b * py + c_b * dwy, k_b * pz + c_b * dwz


@nb.njit(cache=True, error_model="numpy")
def bending_forces(pos, vel, quat, omega, pairs, rest_axis, k_t, c_t, k_b, c_b,
                   force, torque, shear):
    """Add every thread's bending forces [N] and torques [N m] into ``force`` and ``torque``
    (N, 3); write the shear force magnitude |f| [N] of each thread into ``shear`` (P,)."""
    for p in range(pairs.shape[0]):
        i, j = pairs[p, 0], pairs[p, 1]
        rx = pos[j, 0] - pos[i, 0]
        ry = pos[j, 1] - pos[i, 1]
        rz = pos[j, 2] - pos[i, 2]
        fx, fy, fz = transverse_force(
            rx, ry, rz, vel[j, 0] - vel[i, 0], vel[j, 1] - vel[i, 1], vel[j, 2] - vel[i, 2],
            quat[i, 0], quat[i, 1], quat[i, 2], quat[i, 3], omega[i, 0], omega[i, 1],
            omega[i, 2], rest_axis[p, 0], rest_axis[p, 1], rest_axis[p, 2], k_t[p], c_t[p])
        shear[p] = np.sqrt(fx * fx + fy * fy + fz * fz)
        add_pair(force, i, j, fx, fy, fz)
        torque[i, 0] += ry * fz - rz * fy
        torque[i, 1] += rz * fx - rx * fz
        torque[i, 2] += rx * fy - ry * fx
        px, py, pz = relative_rotation_vector(quat[i, 0], quat[i, 1], quat[i, 2], quat[i, 3],
                                              quat[j, 0], quat[j, 1], quat[j, 2], quat[j, 3])
        tx, ty, tz = angular_torque(px, py, pz, omega[j, 0] - omega[i, 0],
                                    omega[j, 1] - omega[i, 1], omega[j, 2] - omega[i, 2],
                                    k_b[p], c_b[p])
        add_pair(torque, i, j, tx, ty, tz)


def bending_energy(pos, quat, pairs, rest_axis, k_t, k_b) -> float:
    """Elastic bending energy [J]: sum of k_t |d|^2 / 2 + k_b |phi|^2 / 2 over threads."""
    energy = 0.0
    for p in range(pairs.shape[0]):
        i, j = pairs[p]
        r = pos[j] - pos[i]
        a = np.array(rotate(*quat[i], *rest_axis[p]))
        d = r - (a @ r) * a
        phi = np.array(relative_rotation_vector(*quat[i], *quat[j]))
        energy += 0.5 * k_t[p] * (d @ d) + 0.5 * k_b[p] * (phi @ phi)
    return float(energy)


SMALL_ANGLE2 = 1e-6
"""Squared rotation angle [rad^2] below which a turn takes the series of sin(a/2)/a and
cos(a/2) (exact to round-off there)."""


@nb.njit(cache=True, error_model="numpy", inline="always")
def _series(a2):
    """(sin(a/2)/a, cos(a/2)) for a squared angle a2 < :data:`SMALL_ANGLE2` [rad^2], by their
    series (no call: a loop of it vectorizes)."""
    return 0.5 - a2 * (1.0 / 48.0 - a2 / 3840.0), 1.0 - a2 * (0.125 - a2 / 384.0)


@nb.njit(cache=True, error_model="numpy", inline="always")
def _turned(qx, qy, qz, qw, wx, wy, wz, s, dw):
    """exp(w / 2) q for the orientation q (x, y, z, w) [-] and the rotation vector w [rad],
    with s = sin(a/2)/a and dw = cos(a/2), renormalized: (x, y, z, w) [-]."""
    dx, dy, dz = wx * s, wy * s, wz * s
    nx = dw * qx + dx * qw + dy * qz - dz * qy
    ny = dw * qy + dy * qw + dz * qx - dx * qz
    nz = dw * qz + dz * qw + dx * qy - dy * qx
    nw = dw * qw - dx * qx - dy * qy - dz * qz
    norm = np.sqrt(nx * nx + ny * ny + nz * nz + nw * nw)
    return nx / norm, ny / norm, nz / norm, nw / norm


@nb.njit(cache=True, error_model="numpy", inline="always")
def turn(quat, i, wx, wy, wz):
    """q_i <- exp(w / 2) q_i: node i turned by the rotation vector w [rad] (exactly; the
    result renormalized)."""
    a2 = wx * wx + wy * wy + wz * wz
    if a2 < SMALL_ANGLE2:  # angle < 1e-3 rad: the series, exact to round-off
        s, dw = _series(a2)
    else:
        angle = np.sqrt(a2)
        s = np.sin(0.5 * angle) / angle
        dw = np.cos(0.5 * angle)
    quat[i, 0], quat[i, 1], quat[i, 2], quat[i, 3] = _turned(quat[i, 0], quat[i, 1], quat[i, 2],
                                                             quat[i, 3], wx, wy, wz, s, dw)


@nb.njit(cache=True, error_model="numpy")
def integrate_rotation(quat, omega, dt):
    """q <- exp(dt w / 2) q for every node: the exact rotation by w dt [rad], renormalized."""
    for i in range(quat.shape[0]):
        turn(quat, i, omega[i, 0] * dt, omega[i, 1] * dt, omega[i, 2] * dt)


@nb.njit(cache=True, error_model="numpy")
def advance_rotation(q, w, gain, torque, held, steps, dt, rotation, turned):
    """``steps`` steps of dt [s] of every node's rotation: with ``held`` 1, under a held torque
    [N m] (N, 3), each step w <- w + gain tau (``gain`` [rad/(N m s)], (N,)) then
    q <- exp(dt w / 2) q; taken at once, since w grows linearly: q turns by
    steps dt w_0 + dt steps (steps + 1) / 2 gain tau (exact up to the commutator of the step
    rotations, O((dt |w|)^2 steps^2)). With ``held`` 0 the torque is ignored and q turns by
    steps dt w exactly. The orientations q [-] and angular velocities w [rad/s] as component
    rows, (4, >= N) and (3, >= N): the grid's rows, or a pair-list array's transpose;
    ``rotation`` (3, >= N) and ``turned`` (4, >= N) are scratch rows.

    Each node turns as :func:`turn` turns it: the rotation vectors into ``rotation``; every
    node by the small-angle series into ``turned`` (a node turning further keeps its q
    there), copied into q; the nodes turning further by sine and cosine (few: a scalar loop,
    run only if there are any); then w. Node by node the same arithmetic as one loop calling
    :func:`turn`, so the same bits; that loop stayed scalar (a call in it), 7.2 us a step for
    the capture's 470 nodes. The series' loop vectorizes only as written: reading rows (unit
    stride: not the (N, 3) torque), writing other arrays than it reads, choosing between
    values already loaded."""
    ramp = 0.5 * steps * (steps + 1) * dt * held
    span = steps * dt
    n = gain.shape[0]
    for a in range(3):
        for i in range(n):
            g = gain[i] * ramp
            rotation[a, i] = span * w[a, i] + g * torque[i, a]
    large = 0
    for i in range(n):
        wx, wy, wz = rotation[0, i], rotation[1, i], rotation[2, i]
        a2 = wx * wx + wy * wy + wz * wz
        small = a2 < SMALL_ANGLE2
        s, dw = _series(a2)
        qx, qy, qz, qw = q[0, i], q[1, i], q[2, i], q[3, i]
        nx, ny, nz, nw = _turned(qx, qy, qz, qw, wx, wy, wz, s, dw)
        turned[0, i] = nx if small else qx
        turned[1, i] = ny if small else qy
        turned[2, i] = nz if small else qz
        turned[3, i] = nw if small else qw
        large += 0 if small else 1
    for a in range(4):
        for i in range(n):
            q[a, i] = turned[a, i]
    if large:
        quat = q.T
        for i in range(n):
            wx, wy, wz = rotation[0, i], rotation[1, i], rotation[2, i]
            if not wx * wx + wy * wy + wz * wz < SMALL_ANGLE2:
                turn(quat, i, wx, wy, wz)
    for a in range(3):
        for i in range(n):
            g = gain[i] * steps * held
            w[a, i] += g * torque[i, a]
