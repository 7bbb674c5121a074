"""Time integrators of the net, compiled with numba.

Each integrator computes the velocity increment dv [m/s] of one step from the state; the step
is then v <- v + dv, x <- x + dt v. The fast engine does both in compiled loops; the bullet
engine hands m dv / dt to PyBullet as an external force and lets PyBullet take the step (its
integrator is the same semi-implicit update), so both engines run the same method.

- ``symplectic_euler``: dv = dt F(x, v) / m. Explicit, first order; stable only while
  dt < ~2 m / c for the thread dampers (a few microseconds for the paper's nets).
- ``implicit_euler``: linearly implicit (one Newton step of) backward Euler,
  (M + dt C + dt^2 K) dv = dt F - dt^2 K v, solved by block-Jacobi preconditioned conjugate
  gradients, then shifted by the uniform velocity that makes the step conserve momentum
  exactly (the threads' blocks vanish on it). First order, stable on the damped threads.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from .forces.axial import axial_forces, axial_linearization

SYMPLECTIC_EULER = 0
IMPLICIT_EULER = 1
INTEGRATOR_IDS = {"symplectic_euler": SYMPLECTIC_EULER, "implicit_euler": IMPLICIT_EULER}


class Workspace:
    """Scratch arrays of the integrators for a net of N nodes and P threads."""

    def __init__(self, n: int, p: int):
        self.force = np.zeros((n, 3))
        """Force on each node [N], shape (N, 3)."""
        self.tension = np.zeros(p)
        """Thread tensions [N], shape (P,)."""
        self.along = np.zeros(p)
        """Implicit block along each thread [kg], shape (P,)."""
        self.across = np.zeros(p)
        """Implicit block across each thread [kg], shape (P,)."""
        self.axis = np.zeros((p, 3))
        """Thread unit directions [-], shape (P, 3)."""
        self.dv = np.zeros((n, 3))
        """Velocity increment of the last step [m/s], shape (N, 3); warm start of CG."""
        self.cg = np.zeros((4, n, 3))
        """CG vectors r, z, d, A d, shape (4, N, 3)."""
        self.block_inv = np.zeros((n, 3, 3))
        """Inverse block-Jacobi preconditioner [1/kg], shape (N, 3, 3)."""
        self.cg_iterations = np.zeros(1, dtype=np.int64)
        """CG iterations summed over all implicit steps [-]."""


@nb.njit(cache=True, error_model="numpy")
def _apply_blocks(x, pairs, along, across, axis, mass, out):
    """out = M x + sum_p B_p-Laplacian x, the implicit-Euler system matrix applied to x."""
    for i in range(x.shape[0]):
        for a in range(3):
            out[i, a] = mass[i] * x[i, a]
    for p in range(pairs.shape[0]):
        if along[p] == 0.0 and across[p] == 0.0:
            continue
        i, j = pairs[p, 0], pairs[p, 1]
        d0 = x[i, 0] - x[j, 0]
        d1 = x[i, 1] - x[j, 1]
        d2 = x[i, 2] - x[j, 2]
        s = (along[p] - across[p]) * (d0 * axis[p, 0] + d1 * axis[p, 1] + d2 * axis[p, 2])
        w0 = across[p] * d0 + s * axis[p, 0]
        w1 = across[p] * d1 + s * axis[p, 1]
        w2 = across[p] * d2 + s * axis[p, 2]
        out[i, 0] += w0
        out[i, 1] += w1
        out[i, 2] += w2
        out[j, 0] -= w0
        out[j, 1] -= w1
        out[j, 2] -= w2


@nb.njit(cache=True, error_model="numpy")
def _block_jacobi(pairs, along, across, axis, mass, inv):
    """Invert each node's 3x3 diagonal block of the implicit system into ``inv``."""
    n = mass.shape[0]
    for i in range(n):
        for a in range(3):
            for b in range(3):
                inv[i, a, b] = mass[i] if a == b else 0.0
    for p in range(pairs.shape[0]):
        if along[p] == 0.0 and across[p] == 0.0:
            continue
        for node in (pairs[p, 0], pairs[p, 1]):
            for a in range(3):
                for b in range(3):
                    inv[node, a, b] += (along[p] - across[p]) * axis[p, a] * axis[p, b]
                inv[node, a, a] += across[p]
    for i in range(n):
        m = inv[i]
        c00 = m[1, 1] * m[2, 2] - m[1, 2] * m[2, 1]
        c01 = m[1, 2] * m[2, 0] - m[1, 0] * m[2, 2]
        c02 = m[1, 0] * m[2, 1] - m[1, 1] * m[2, 0]
        det = m[0, 0] * c00 + m[0, 1] * c01 + m[0, 2] * c02
        c10 = m[0, 2] * m[2, 1] - m[0, 1] * m[2, 2]
        c11 = m[0, 0] * m[2, 2] - m[0, 2] * m[2, 0]
        c12 = m[0, 1] * m[2, 0] - m[0, 0] * m[2, 1]
        c20 = m[0, 1] * m[1, 2] - m[0, 2] * m[1, 1]
        c21 = m[0, 2] * m[1, 0] - m[0, 0] * m[1, 2]
        c22 = m[0, 0] * m[1, 1] - m[0, 1] * m[1, 0]
        m[0, 0], m[0, 1], m[0, 2] = c00 / det, c10 / det, c20 / det
        m[1, 0], m[1, 1], m[1, 2] = c01 / det, c11 / det, c21 / det
        m[2, 0], m[2, 1], m[2, 2] = c02 / det, c12 / det, c22 / det


@nb.njit(cache=True, error_model="numpy")
def _dot(a, b):
    s = 0.0
    for i in range(a.shape[0]):
        s += a[i, 0] * b[i, 0] + a[i, 1] * b[i, 1] + a[i, 2] * b[i, 2]
    return s


@nb.njit(cache=True, error_model="numpy")
def _precondition(inv, r, z):
    for i in range(r.shape[0]):
        for a in range(3):
            z[i, a] = inv[i, a, 0] * r[i, 0] + inv[i, a, 1] * r[i, 1] + inv[i, a, 2] * r[i, 2]


@nb.njit(cache=True, error_model="numpy")
def implicit_increment(pos, vel, mass, pairs, rest, k, c, gravity, external, dt, tol,
                       force, tension, along, across, axis, dv, cg, block_inv, iterations):
    """Velocity increment dv [m/s] of one linearly implicit Euler step (see module doc).

    ``external`` [N], shape (N, 3), is added to the thread forces and gravity. ``dv`` holds the
    previous increment on entry (the CG warm start) and the new one on exit."""
    n = pos.shape[0]
    for i in range(n):
        for a in range(3):
            force[i, a] = mass[i] * gravity[a] + external[i, a]
    axial_linearization(pos, vel, pairs, rest, k, c, dt, force, tension, along, across, axis)
    r, z, d, ad = cg[0], cg[1], cg[2], cg[3]
    # right-hand side dt F - dt^2 K v, in r
    for i in range(n):
        for a in range(3):
            r[i, a] = dt * force[i, a]
    for p in range(pairs.shape[0]):
        if along[p] == 0.0:
            continue
        i, j = pairs[p, 0], pairs[p, 1]
        kt = dt * dt * k[p]
        d0 = vel[i, 0] - vel[j, 0]
        d1 = vel[i, 1] - vel[j, 1]
        d2 = vel[i, 2] - vel[j, 2]
        s = (kt - across[p]) * (d0 * axis[p, 0] + d1 * axis[p, 1] + d2 * axis[p, 2])
        for a, da in ((0, d0), (1, d1), (2, d2)):
            w = across[p] * da + s * axis[p, a]
            r[i, a] -= w
            r[j, a] += w
    rhs_norm = np.sqrt(_dot(r, r))
    momentum = np.zeros(3)  # the step's exact momentum change: sum of dt F (internal forces cancel)
    for i in range(n):
        for a in range(3):
            momentum[a] += r[i, a]
    if rhs_norm == 0.0:
        dv[:] = 0.0
        return
    _block_jacobi(pairs, along, across, axis, mass, block_inv)
    # r <- rhs - A dv (warm start)
    _apply_blocks(dv, pairs, along, across, axis, mass, ad)
    for i in range(n):
        for a in range(3):
            r[i, a] -= ad[i, a]
    _precondition(block_inv, r, z)
    d[:] = z
    rz = _dot(r, z)
    for _ in range(4 * n):
        if np.sqrt(_dot(r, r)) <= tol * rhs_norm:
            break
        _apply_blocks(d, pairs, along, across, axis, mass, ad)
        alpha = rz / _dot(d, ad)
        for i in range(n):
            for a in range(3):
                dv[i, a] += alpha * d[i, a]
                r[i, a] -= alpha * ad[i, a]
        _precondition(block_inv, r, z)
        rz_new = _dot(r, z)
        beta = rz_new / rz
        rz = rz_new
        for i in range(n):
            for a in range(3):
                d[i, a] = z[i, a] + beta * d[i, a]
        iterations[0] += 1
    # The threads' blocks vanish on a uniform velocity, so adding one to dv changes only the
    # momentum residual: choose it so the step conserves momentum exactly, not to CG tolerance.
    total_mass = 0.0
    for i in range(n):
        total_mass += mass[i]
        for a in range(3):
            momentum[a] -= mass[i] * dv[i, a]
    for i in range(n):
        for a in range(3):
            dv[i, a] += momentum[a] / total_mass


@nb.njit(cache=True, error_model="numpy")
def symplectic_increment(pos, vel, mass, pairs, rest, k, c, gravity, external, dt,
                         force, tension, dv):
    """Velocity increment dv = dt F / m [m/s] of one symplectic Euler step."""
    n = pos.shape[0]
    for i in range(n):
        for a in range(3):
            force[i, a] = mass[i] * gravity[a] + external[i, a]
    axial_forces(pos, vel, pairs, rest, k, c, force, tension)
    for i in range(n):
        for a in range(3):
            dv[i, a] = dt * force[i, a] / mass[i]


@nb.njit(cache=True, error_model="numpy")
def advance(method, steps, pos, vel, mass, pairs, rest, k, c, gravity, external, dt, tol,
            force, tension, along, across, axis, dv, cg, block_inv, iterations):
    """Take ``steps`` steps of ``method`` in place on (pos, vel); stop early on a non-finite
    state and return the number of steps taken."""
    n = pos.shape[0]
    for step in range(steps):
        if method == SYMPLECTIC_EULER:
            symplectic_increment(pos, vel, mass, pairs, rest, k, c, gravity, external, dt,
                                 force, tension, dv)
        else:
            implicit_increment(pos, vel, mass, pairs, rest, k, c, gravity, external, dt, tol,
                               force, tension, along, across, axis, dv, cg, block_inv,
                               iterations)
        finite = True
        for i in range(n):
            for a in range(3):
                vel[i, a] += dv[i, a]
                pos[i, a] += dt * vel[i, a]
            if not (np.isfinite(pos[i, 0]) and np.isfinite(pos[i, 1])
                    and np.isfinite(pos[i, 2])):
                finite = False
        if not finite:
            return step + 1
    return steps
