"""Tension-only Kelvin-Voigt threads (Eq. 3), compiled with numba.

For thread p from node i to node j: l = |x_j - x_i|, e = (x_j - x_i) / l,
v_r = (v_j - v_i) . e, T = k (l - l_0) + c v_r. The force +T e acts on i and -T e on j only
if l > l_0 and T > 0; otherwise the thread pushes nothing and its tension is exactly zero.
With ``bilateral`` set (the cantilever's beam element) T acts whatever its sign. It is one
flag for all elements, so the compiled loop keeps a single branch-free path.
"""

from __future__ import annotations

import numba as nb
import numpy as np


@nb.njit(cache=True, error_model="numpy", inline="always")
def add_pair(array, i, j, x, y, z):
    """array[i] += (x, y, z); array[j] -= (x, y, z): an action and its reaction."""
    array[i, 0] += x
    array[i, 1] += y
    array[i, 2] += z
    array[j, 0] -= x
    array[j, 1] -= y
    array[j, 2] -= z


@nb.njit(cache=True, error_model="numpy", inline="always")
def thread_tension(p, pos, vel, pairs, rest, k, c, bilateral):
    """Tension T [N] of thread p and its unit direction e (i -> j) and length l [m].

    Returns (T, ex, ey, ez, l); T is 0.0 for a slack thread or one closing faster than its
    spring holds (Eq. 3)."""
    i, j = pairs[p, 0], pairs[p, 1]
    dx = pos[j, 0] - pos[i, 0]
    dy = pos[j, 1] - pos[i, 1]
    dz = pos[j, 2] - pos[i, 2]
    length = np.sqrt(dx * dx + dy * dy + dz * dz)
    if length <= rest[p] and not bilateral:
        return 0.0, 0.0, 0.0, 0.0, length
    inv = 1.0 / length
    ex, ey, ez = dx * inv, dy * inv, dz * inv
    vr = ((vel[j, 0] - vel[i, 0]) * ex + (vel[j, 1] - vel[i, 1]) * ey
          + (vel[j, 2] - vel[i, 2]) * ez)
    tension = k[p] * (length - rest[p]) + c[p] * vr
    if tension <= 0.0 and not bilateral:
        return 0.0, ex, ey, ez, length
    return tension, ex, ey, ez, length


@nb.njit(cache=True, error_model="numpy")
def axial_forces(pos, vel, pairs, rest, k, c, bilateral, force, tension):
    """Add every thread's force [N] into ``force`` (N, 3); write tensions [N] into ``tension``
    (P,); with ``bilateral`` set the elements also push."""
    for p in range(pairs.shape[0]):
        t, ex, ey, ez, _ = thread_tension(p, pos, vel, pairs, rest, k, c, bilateral)
        tension[p] = t
        if t != 0.0:
            add_pair(force, pairs[p, 0], pairs[p, 1], t * ex, t * ey, t * ez)


@nb.njit(cache=True, error_model="numpy")
def axial_linearization(pos, vel, pairs, rest, k, c, bilateral, dt, force, tension, along,
                        across, axis):
    """Thread forces as :func:`axial_forces`, plus each taut thread's implicit-Euler block.

    The block of thread p in dt * dF/dv + dt^2 * dF/dx (with the non-symmetric d(v_r)/dx term
    dropped) is ``across[p] * I + (along[p] - across[p]) * e e^T``, e = ``axis[p]``:
    along = dt c + dt^2 k [kg], across = dt^2 k max(l - l_0, 0) / l [kg] (geometric
    stiffness, kept >= 0 so the system stays positive definite). Slack threads get zero blocks."""
    for p in range(pairs.shape[0]):
        t, ex, ey, ez, length = thread_tension(p, pos, vel, pairs, rest, k, c, bilateral)
        tension[p] = t
        axis[p, 0], axis[p, 1], axis[p, 2] = ex, ey, ez
        if t != 0.0:
            add_pair(force, pairs[p, 0], pairs[p, 1], t * ex, t * ey, t * ez)
            along[p] = dt * c[p] + dt * dt * k[p]
            across[p] = dt * dt * k[p] * max(length - rest[p], 0.0) / length
        else:
            along[p] = 0.0
            across[p] = 0.0


def axial_energy(pos: np.ndarray, pairs: np.ndarray, rest: np.ndarray, k: np.ndarray) -> float:
    """Elastic energy [J] stored in the stretched threads: sum of k (l - l_0)^2 / 2 over l > l_0.

    ``pos`` may be (N, 3) or (T, N, 3); the result is then a scalar or shape (T,)."""
    d = pos[..., pairs[:, 1], :] - pos[..., pairs[:, 0], :]
    stretch = np.maximum(np.linalg.norm(d, axis=-1) - rest, 0.0)
    return 0.5 * np.sum(k * stretch**2, axis=-1)
