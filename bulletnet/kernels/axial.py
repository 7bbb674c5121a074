"""Tension-only Kelvin-Voigt threads (Eq. 3), compiled with numba.

For thread p from node i to node j: l = |x_j - x_i|, e = (x_j - x_i) / l,
v_r = (v_j - v_i) . e, T = k (l - l_0) + c (v_r - l_0'). The force +T e acts on i and -T e on
j only if l > l_0 and T > 0; otherwise the thread pushes nothing and its tension is exactly
zero. The rest length's rate l_0' is zero but for a tether reeled at the chaser
(:mod:`bulletnet.kernels.reel`): its damper acts on the strain rate, as a closing cable's
(kernels given None for the rates take them as zero and compile no reading of them).
With ``bilateral`` set (the cantilever's beam element) T acts whatever its sign. It is one
flag for all elements, so the compiled loop keeps a single branch-free path.
"""

from __future__ import annotations

import numba as nb
import numpy as np


@nb.njit(cache=True, error_model="numpy")
def add_pair(array, i, j, x, y, z):
    """array[i] += (x, y, z); array[j] -= (x, y, z): an action and its reaction."""
    array[i, 0] += x
    array[i, 1] += y
    array[i, 2] += z
    array[j, 0] -= x
    array[j, 1] -= y
    array[j, 2] -= z


@nb.njit(cache=True, error_model="numpy")
def kelvin_voigt(length, rate, rest, k, c, bilateral):
    """Eq. 3's tension [N] of an element of length ``length`` [m] straining at ``rate``
    [m/s] (its lengthening less its rest length's rate): k (l - l_0) + c (l' - l_0'), or
    0.0 if the element is slack (l <= l_0) or closing faster than its spring holds (T <= 0),
    unless ``bilateral``. Branch-free."""
    tension = k * (length - rest) + c * rate
    taut = bilateral | ((length > rest) & (tension > 0.0))
    return tension if taut else 0.0


@nb.njit(cache=True, error_model="numpy")
def tension_law(dx, dy, dz, du, dv, dw, rest, rest_rate, k, c, bilateral):
    """Eq. 3 for one thread from its end-to-end vector (dx, dy, dz) [m] and relative velocity
    (du, dv, dw) [m/s], rest length [m] and its rate [m/s], stiffness [N/m] and damping
    [N s/m].

    Returns (T [N], ex, ey, ez, l [m]); T is 0.0 for a slack thread or one closing faster than
    its spring holds (unless ``bilateral``). Branch-free, so loops over threads vectorize; the
    direction is computed for a slack thread too (and is not finite for l = 0: callers use it
    only where T != 0)."""
    return tension_at(np.sqrt(dx * dx + dy * dy + dz * dz), dx, dy, dz, du, dv, dw, rest,
                      rest_rate, k, c, bilateral)


@nb.njit(cache=True, error_model="numpy")
def tension_at(length, dx, dy, dz, du, dv, dw, rest, rest_rate, k, c, bilateral):
    """:func:`tension_law` of a thread whose length ``length`` [m] is known."""
    inv = 1.0 / length
    ex, ey, ez = dx * inv, dy * inv, dz * inv
    return (kelvin_voigt(length, du * ex + dv * ey + dw * ez - rest_rate, rest, k, c,
                         bilateral), ex, ey, ez, length)


@nb.njit(cache=True, error_model="numpy")
def _rest_rate(rest_rate, p):
    """Thread p's rest-length rate [m/s]: 0.0 without rates (None; nothing read)."""
    if rest_rate is None:
        return 0.0
    return rest_rate[p]


@nb.njit(cache=True, error_model="numpy")
def thread_tension(p, pos, vel, pairs, rest, rest_rate, k, c, bilateral):
    """Tension T [N] of thread p (:func:`tension_law`), its unit direction e (i -> j) and
    length l [m]: (T, ex, ey, ez, l)."""
    i, j = pairs[p, 0], pairs[p, 1]
    return tension_law(pos[j, 0] - pos[i, 0], pos[j, 1] - pos[i, 1], pos[j, 2] - pos[i, 2],
                       vel[j, 0] - vel[i, 0], vel[j, 1] - vel[i, 1], vel[j, 2] - vel[i, 2],
                       rest[p], _rest_rate(rest_rate, p), k[p], c[p], bilateral)


@nb.njit(cache=True, error_model="numpy")
def thread_tensions(pos, vel, pairs, rest, rest_rate, k, c, bilateral, tension):
    """Every thread's tension [N] into ``tension`` (P,) (:func:`thread_tension`) and nothing
    else: the values :func:`axial_forces` writes there at the same state (the same
    operations; a slack thread's 0.0 from the law instead of its shortcut)."""
    for p in range(pairs.shape[0]):
        tension[p] = thread_tension(p, pos, vel, pairs, rest, rest_rate, k, c, bilateral)[0]


@nb.njit(cache=True, error_model="numpy")
def axial_forces(pos, vel, pairs, rest, rest_rate, k, c, bilateral, force, tension):
    """Add every thread's force [N] into ``force`` (N, 3); write tensions [N] into ``tension``
    (P,), from the threads' rest lengths [m] and their rates [m/s] (None: zero), stiffness
    [N/m] and damping [N s/m] (P,) each; with ``bilateral`` set the elements also push. A
    slack thread (l <= l_0) is known
    from its length alone: it gets its zero tension without a direction (over a pair list
    nothing vectorizes, so the branch saves a division and the rest of the law; every other
    thread's tension is :func:`tension_law`'s, the same operations in the same order)."""
    for p in range(pairs.shape[0]):
        i, j = pairs[p, 0], pairs[p, 1]
        dx, dy, dz = pos[j, 0] - pos[i, 0], pos[j, 1] - pos[i, 1], pos[j, 2] - pos[i, 2]
        length = np.sqrt(dx * dx + dy * dy + dz * dz)
        if length <= rest[p] and not bilateral:
            tension[p] = 0.0
            continue
        t, ex, ey, ez, _ = tension_at(length, dx, dy, dz, vel[j, 0] - vel[i, 0],
                                      vel[j, 1] - vel[i, 1], vel[j, 2] - vel[i, 2], rest[p],
                                      _rest_rate(rest_rate, p), k[p], c[p], bilateral)
        tension[p] = t
        if t != 0.0:
            add_pair(force, i, j, t * ex, t * ey, t * ez)


@nb.njit(cache=True, error_model="numpy")
def axial_linearization(pos, vel, pairs, rest, rest_rate, k, c, bilateral, dt, force, tension,
                        along, across, axis):
    """Thread forces as :func:`axial_forces`, plus each taut thread's implicit-Euler block.

    The block of thread p in dt * dF/dv + dt^2 * dF/dx (with the non-symmetric d(v_r)/dx term
    dropped) is ``across[p] * I + (along[p] - across[p]) * e e^T``, e = ``axis[p]``:
    along = dt c + dt^2 k [kg], across = dt^2 k max(l - l_0, 0) / l [kg] (geometric
    stiffness, kept >= 0 so the system stays positive definite). Slack threads get zero blocks."""
    for p in range(pairs.shape[0]):
        t, ex, ey, ez, length = thread_tension(p, pos, vel, pairs, rest, rest_rate, k, c,
                                               bilateral)
        tension[p] = t
        axis[p, 0], axis[p, 1], axis[p, 2] = ex, ey, ez
        if t != 0.0:
            add_pair(force, pairs[p, 0], pairs[p, 1], t * ex, t * ey, t * ez)
            along[p] = dt * c[p] + dt * dt * k[p]
            across[p] = dt * dt * k[p] * max(length - rest[p], 0.0) / length
        else:
            along[p] = 0.0
            across[p] = 0.0


@nb.njit(cache=True, error_model="numpy")
def block_product(d0, d1, d2, along, across, e0, e1, e2):
    """A thread's block, (along - across) e e^T + across I [kg], times the difference d of its
    end nodes' vectors: across d + (along - across) (d . e) e."""
    s = (along - across) * (d0 * e0 + d1 * e1 + d2 * e2)
    return across * d0 + s * e0, across * d1 + s * e1, across * d2 + s * e2


@nb.njit(cache=True, error_model="numpy", inline="always")
def block_entry(m, g, across, ea, eb, diagonal):
    """m + entry (a, b) of a thread's implicit block (along - across) e e^T + across I [kg],
    from g = along - across [kg], across [kg] and e's components a and b; ``diagonal``:
    a == b."""
    return m + g * ea * eb + across if diagonal else m + g * ea * eb


@nb.njit(cache=True, error_model="numpy", inline="always")
def add_block(m, along, across, ex, ey, ez):
    """m + a thread's implicit block, (along - across) e e^T + across I [kg], with m a 3 x 3
    matrix as a row-major 9-tuple (:func:`block_entry` by entry)."""
    g = along - across
    return (block_entry(m[0], g, across, ex, ex, True),
            block_entry(m[1], g, across, ex, ey, False),
            block_entry(m[2], g, across, ex, ez, False),
            block_entry(m[3], g, across, ey, ex, False),
            block_entry(m[4], g, across, ey, ey, True),
            block_entry(m[5], g, across, ey, ez, False),
            block_entry(m[6], g, across, ez, ex, False),
            block_entry(m[7], g, across, ez, ey, False),
            block_entry(m[8], g, across, ez, ez, True))


@nb.njit(cache=True, error_model="numpy", inline="always")
def invert3(m):
    """The inverse of a 3 x 3 matrix given and returned as a row-major 9-tuple (cofactors times
    the determinant's reciprocal: one division, not nine)."""
    c00 = m[4] * m[8] - m[5] * m[7]
    c01 = m[5] * m[6] - m[3] * m[8]
    c02 = m[3] * m[7] - m[4] * m[6]
    det = m[0] * c00 + m[1] * c01 + m[2] * c02
    c10 = m[2] * m[7] - m[1] * m[8]
    c11 = m[0] * m[8] - m[2] * m[6]
    c12 = m[1] * m[6] - m[0] * m[7]
    c20 = m[1] * m[5] - m[2] * m[4]
    c21 = m[2] * m[3] - m[0] * m[5]
    c22 = m[0] * m[4] - m[1] * m[3]
    r = 1.0 / det
    return (c00 * r, c10 * r, c20 * r, c01 * r, c11 * r, c21 * r, c02 * r, c12 * r, c22 * r)


@nb.njit(cache=True, error_model="numpy")
def add_thread_blocks(x, pairs, along, across, axis, out):
    """out += the threads' implicit blocks applied to x (each thread's
    :func:`block_product` of x_i - x_j, +on i and -on j); slack threads are skipped."""
    for p in range(pairs.shape[0]):
        if along[p] == 0.0 and across[p] == 0.0:
            continue
        i, j = pairs[p, 0], pairs[p, 1]
        w0, w1, w2 = block_product(x[i, 0] - x[j, 0], x[i, 1] - x[j, 1], x[i, 2] - x[j, 2],
                                   along[p], across[p], axis[p, 0], axis[p, 1], axis[p, 2])
        add_pair(out, i, j, w0, w1, w2)


@nb.njit(cache=True, error_model="numpy")
def add_thread_rhs(vel, pairs, k, along, across, axis, dt, r):
    """r -= dt^2 K v, the threads' stiffness part of implicit Euler's right-hand side: each
    taut thread's block with along = dt^2 k [kg] applied to v_i - v_j [m/s], -on i, +on j."""
    for p in range(pairs.shape[0]):
        if along[p] == 0.0:
            continue
        i, j = pairs[p, 0], pairs[p, 1]
        w0, w1, w2 = block_product(vel[i, 0] - vel[j, 0], vel[i, 1] - vel[j, 1],
                                   vel[i, 2] - vel[j, 2], dt * dt * k[p], across[p],
                                   axis[p, 0], axis[p, 1], axis[p, 2])
        add_pair(r, j, i, w0, w1, w2)


def thread_energies(pos: np.ndarray, pairs: np.ndarray, rest: np.ndarray,
                    k: np.ndarray) -> np.ndarray:
    """Elastic energy [J] stored in each thread: k (l - l_0)^2 / 2 if l > l_0, else 0.

    ``pos`` may be (N, 3) or (T, N, 3); the result is then shape (P,) or (T, P)."""
    d = pos[..., pairs[:, 1], :] - pos[..., pairs[:, 0], :]
    stretch = np.maximum(np.linalg.norm(d, axis=-1) - rest, 0.0)
    return 0.5 * k * stretch**2


def axial_energy(pos: np.ndarray, pairs: np.ndarray, rest: np.ndarray, k: np.ndarray) -> float:
    """Elastic energy [J] stored in the stretched threads: the sum of :func:`thread_energies`.

    ``pos`` may be (N, 3) or (T, N, 3); the result is then a scalar or shape (T,)."""
    return np.sum(thread_energies(pos, pairs, rest, k), axis=-1)
