"""Closing cables: one tension-only Kelvin-Voigt element along a polyline of nodes, compiled
with numba.

A cable runs from its first node (an end, at a winch) through ring nodes, where it slides
without friction, to its last node (the other end). With vertices x_0 .. x_m, span j from
x_j to x_(j+1) of length l_j and unit direction e_j, its length is L = sum_j l_j and its
rate L' = sum_v g_v . v_v, with g_v = dL/dx_v = e_(v-1) - e_v (the missing span omitted at
the ends). The tension is the thread law (Eq. 3) on the whole cable,

    T = k (L - L_0) + c (L' - L_0'),   k = E A / L_0,   c = tau k,

acting only while L > L_0 and T > 0. Vertex v feels -T g_v: a ring node T times the sum of
the unit vectors towards its two neighbours on the cable, an end T along its span. A node
that the cable passes twice (both ends at one corner mass) feels both. The forces are
internal (sum_v g_v = 0): momentum is conserved.

Implicit Euler takes the cable implicitly, as the threads: its block in
dt dF/dv + dt^2 dF/dx is (dt c + dt^2 k) g g^T (rank one over all its vertices) plus, per
span, the geometric stiffness dt^2 k max(L - L_0, 0) / l_j (I - e_j e_j^T) between the span's
two vertices (the threads' ``across`` block, with no ``along`` part). The explicit
integrators relax the cable's damper over the step instead (``share``,
:mod:`bulletnet.solver.exponential_damping`).

A winch shortens L_0 at the reel speed while the tension is below its stall tension (it holds
at stall and reels on when the tension drops). The damper acts on the cable's strain rate,
L' - L_0' (a cable reeled in at the speed its far end follows is not being stretched). The
winch's work is T times the length it reels: the elastic energy E A (L - L_0)^2 / (2 L_0) that
the change of L_0 adds at the current positions, plus the damper's force times that length;
the mechanical energy may rise by that work and no more.

A net without cables passes None for them: each kernel's body is then pruned by numba on the
argument's type, so a scene without cables compiles none of them and its steps call nothing.
"""

from __future__ import annotations

from typing import NamedTuple

import numba as nb
import numpy as np
from numba.core import types
from numba.extending import overload

from . import U
from .axial import add_block, add_pair, block_product, kelvin_voigt


class CableArrays(NamedTuple):
    """The closing cables as the compiled kernels read them, for C cables with V vertices in
    all (:func:`cable_arrays`). The first eight fields are the model's; the rest is written
    by the kernels."""

    nodes: np.ndarray
    """Node of each vertex, cable after cable [-], shape (V,), int64."""
    start: np.ndarray
    """First vertex of each cable, then V [-], shape (C + 1,), int64."""
    rigidity: np.ndarray
    """Axial rigidity E A [N], shape (C,)."""
    damping_time: np.ndarray
    """c / k, the Kelvin-Voigt relaxation time [s], shape (C,)."""
    reel_speed: np.ndarray
    """Speed at which the winch shortens the rest length [m/s], shape (C,)."""
    stall: np.ndarray
    """Tension at which the winch stops reeling and holds [N], shape (C,)."""
    min_rest: np.ndarray
    """Rest length at which the winch stops (its drum full) [m], shape (C,)."""
    start_time: np.ndarray
    """Time from which the winches reel [s], shape (1,); +inf until triggered."""
    rest: np.ndarray
    """Rest length L_0 [m], shape (C,)."""
    tension: np.ndarray
    """Tension T of the last evaluation [N], shape (C,)."""
    length: np.ndarray
    """Length L of the last evaluation [m], shape (C,)."""
    work: np.ndarray
    """Work done by the winch so far [J], shape (C,)."""
    rest_rate: np.ndarray
    """L_0' over the current step [m/s], shape (C,): minus the reel speed while reeling."""
    damper: np.ndarray
    """The damper's share c (L' - L_0') of the last tension [N], shape (C,) (0 if slack)."""
    grad: np.ndarray
    """g_v = dL/dx_v of each vertex at the last evaluation [-], shape (V, 3)."""
    axis: np.ndarray
    """Unit direction of the span from each vertex to the next [-], shape (V, 3)."""
    across: np.ndarray
    """Implicit geometric-stiffness block of each span, dt^2 k max(L - L_0, 0) / l [kg],
    shape (V,); 0 for a slack cable and for a cable's last vertex."""
    along: np.ndarray
    """Implicit rank-one coefficient dt c + dt^2 k [kg] of each cable, shape (C,); 0 when
    slack."""
    share: np.ndarray
    """Each vertex's node's share d / m [1/kg] of its dampers' relaxation, shape (V,): the
    cable's damper relaxes over the step (the explicit integrators,
    :mod:`bulletnet.solver.exponential_damping`); 0 on implicit Euler (in the solve)."""


def cable_arrays(nodes: np.ndarray, start: np.ndarray, rest: np.ndarray, rigidity: np.ndarray,
                 damping_time: np.ndarray, reel_speed: np.ndarray, stall: np.ndarray,
                 min_rest: np.ndarray) -> CableArrays:
    """Kernel arrays of cables with the given vertices, offsets and parameters (shapes as in
    :class:`CableArrays`), the winches not yet triggered."""
    c, v = rest.shape[0], nodes.shape[0]
    return CableArrays(
        nodes=nodes.astype(np.int64), start=start.astype(np.int64),
        rigidity=rigidity.astype(float), damping_time=damping_time.astype(float),
        reel_speed=reel_speed.astype(float), stall=stall.astype(float),
        min_rest=min_rest.astype(float), start_time=np.full(1, np.inf),
        rest=rest.astype(float).copy(), tension=np.zeros(c), length=np.zeros(c),
        work=np.zeros(c), rest_rate=np.zeros(c), damper=np.zeros(c), grad=np.zeros((v, 3)),
        axis=np.zeros((v, 3)), across=np.zeros(v), along=np.zeros(c), share=np.zeros(v))


def cable_energy(length: np.ndarray, rest: np.ndarray, rigidity: np.ndarray) -> np.ndarray:
    """:func:`elastic_energy` [J] of cables of length L [m], rest length L_0 [m] and rigidity
    E A [N], element by element (any broadcastable shapes)."""
    return np.vectorize(elastic_energy, otypes=[float])(length, rest, rigidity)


@nb.njit(cache=True, error_model="numpy")
def _span(pos, nodes, v):
    """Vector from vertex v to vertex v + 1 [m]."""
    a, b = nodes[v], nodes[v + 1]
    return pos[b, 0] - pos[a, 0], pos[b, 1] - pos[a, 1], pos[b, 2] - pos[a, 2]


@nb.njit(cache=True, error_model="numpy")
def cable_length(pos, cables, c):
    """Length L of cable c at positions ``pos`` [m]."""
    total = 0.0
    for v in range(cables.start[c], cables.start[c + 1] - 1):
        dx, dy, dz = _span(pos, cables.nodes, v)
        total += np.sqrt(dx * dx + dy * dy + dz * dz)
    return total


@nb.njit(cache=True, error_model="numpy")
def cable_forces(pos, vel, cables, force, linearize, dt):
    """Add every cable's force [N] into ``force`` (N, 3); write tensions, lengths and the
    vertices' g into ``cables``; with ``linearize`` also the implicit blocks for a step of
    ``dt`` [s] (see the module doc)."""
    if cables is None:  # no cables: this specialization compiles to nothing
        return
    nodes, start, grad, axis = cables.nodes, cables.start, cables.grad, cables.axis
    for c in range(start.shape[0] - 1):
        first, last = start[c], start[c + 1] - 1
        length = rate = split = 0.0
        for v in range(first, last):
            dx, dy, dz = _span(pos, nodes, v)
            span = np.sqrt(dx * dx + dy * dy + dz * dz)
            axis[v, 0], axis[v, 1], axis[v, 2] = dx / span, dy / span, dz / span
            length += span
        for v in range(first, last + 1):
            for a in range(3):
                g = (axis[v - 1, a] if v > first else 0.0) - (axis[v, a] if v < last else 0.0)
                grad[v, a] = g
                rate += g * vel[nodes[v], a]
                split += g * g * cables.share[v]
        k = cables.rigidity[c] / cables.rest[c]
        damping = cables.damping_time[c] * k
        relax = damping * dt * split  # exponential Euler: the damper relaxed over the step
        if relax > 0.0:
            damping *= -np.expm1(-relax) / relax
        strain_rate = rate - cables.rest_rate[c]
        tension = kelvin_voigt(length, strain_rate, cables.rest[c], k, damping, False)
        cables.tension[c], cables.length[c] = tension, length
        cables.damper[c] = damping * strain_rate if tension != 0.0 else 0.0
        if tension != 0.0:
            for v in range(first, last + 1):
                i = nodes[v]
                for a in range(3):
                    force[i, a] -= tension * grad[v, a]
        if linearize:
            on = tension != 0.0
            cables.along[c] = dt * damping + dt * dt * k if on else 0.0
            elastic = dt * dt * k * max(length - cables.rest[c], 0.0)
            for v in range(first, last):
                dx, dy, dz = _span(pos, nodes, v)
                cables.across[v] = elastic / np.sqrt(dx * dx + dy * dy + dz * dz) if on else 0.0
            cables.across[last] = 0.0


@nb.njit(cache=True, error_model="numpy")
def clear_cable_nodes(cables, out):
    """Zero the rows of ``out`` (N, 3) of every cable vertex's node."""
    if cables is None:
        return
    for v in range(cables.nodes.shape[0]):
        for a in range(3):
            out[cables.nodes[v], a] = 0.0


@nb.njit(cache=True, error_model="numpy", inline="always")
def _rank_one(x, cables, c):
    """g . x over cable c's vertices (x (N, 3) by node)."""
    nodes, grad = cables.nodes, cables.grad
    s = 0.0
    for v in range(U(cables.start[c]), U(cables.start[c + 1])):
        i = U(nodes[v])
        s += grad[v, 0] * x[i, 0] + grad[v, 1] * x[i, 1] + grad[v, 2] * x[i, 2]
    return s


def add_cable_product(x, cables, out, along_scale, sign):
    """out += sign (the cables' implicit blocks applied to x) (N, 3): the rank-one part with
    coefficient ``along`` (or, with ``along_scale`` > 0, along_scale k: the right-hand side's
    stiffness part) and the spans' geometric part.

    In compiled code it is inlined into its callers once typed (:func:`_inline_cable_product`),
    its indices unsigned (no negative-index wraparound): the closing capture's product at
    30 s, 2.68 -> 2.02 us, its four cables' share (92 vertices) 1.07 -> 0.55 us."""
    if cables is None:
        return
    nodes, grad, axis, across = cables.nodes, cables.grad, cables.axis, cables.across
    for c in range(cables.start.shape[0] - 1):
        along = cables.along[c]
        if along == 0.0:
            continue
        if along_scale > 0.0:
            along = along_scale * cables.rigidity[c] / cables.rest[c]
        s = sign * along * _rank_one(x, cables, c)
        first, last = U(cables.start[c]), U(cables.start[c + 1] - 1)
        for v in range(first, last + U(1)):
            i = U(nodes[v])
            for a in range(U(3)):
                out[i, a] += s * grad[v, a]
        for v in range(first, last):
            i, j = U(nodes[v]), U(nodes[v + U(1)])
            w0, w1, w2 = block_product(x[i, 0] - x[j, 0], x[i, 1] - x[j, 1],
                                       x[i, 2] - x[j, 2], 0.0, across[v], axis[v, 0],
                                       axis[v, 1], axis[v, 2])
            add_pair(out, i, j, sign * w0, sign * w1, sign * w2)


@overload(add_cable_product, inline="always")
def _inline_cable_product(x, cables, out, along_scale, sign):
    """:func:`add_cable_product` in compiled code, inlined after typing (numba's
    ``inline="always"`` on a jitted function inlines before typing, where the ``cables is
    None`` branch is not yet pruned, and a scene without cables would not compile)."""
    if isinstance(cables, types.NoneType):  # no cables: nothing to add
        return lambda x, cables, out, along_scale, sign: None
    return add_cable_product


@nb.njit(cache=True, error_model="numpy", inline="always")
def add_vertex_block(m, cables, c, v, rank_one):
    """m (a row-major 9-tuple) + vertex v's share of cable c's diagonal block: along g_v g_v^T
    (with ``rank_one``) plus the geometric blocks of the spans on either side (for the
    preconditioners; a node passed twice gets each pass's share)."""
    if rank_one:
        g0, g1, g2 = cables.grad[v, 0], cables.grad[v, 1], cables.grad[v, 2]
        u0, u1, u2 = _unit(g0, g1, g2)
        m = add_block(m, cables.along[c] * (g0 * g0 + g1 * g1 + g2 * g2), 0.0, u0, u1, u2)
    axis, across = cables.axis, cables.across
    if v > cables.start[c]:
        m = add_block(m, 0.0, across[v - 1], axis[v - 1, 0], axis[v - 1, 1], axis[v - 1, 2])
    return add_block(m, 0.0, across[v], axis[v, 0], axis[v, 1], axis[v, 2])


@nb.njit(cache=True, error_model="numpy")
def add_cable_blocks(cables, flat, rank_one):
    """Add each cable vertex's share of its cable's diagonal block
    (:func:`add_vertex_block`; its rank-one part only with ``rank_one``) to its node's row of
    ``flat`` (nodes, 9): the 3 x 3 blocks row-major."""
    if cables is None:  # no cables: this specialization compiles to nothing
        return
    for c in range(cables.start.shape[0] - 1):
        if cables.along[c] == 0.0:
            continue
        for v in range(cables.start[c], cables.start[c + 1]):
            i = cables.nodes[v]
            m = add_vertex_block((flat[i, 0], flat[i, 1], flat[i, 2], flat[i, 3], flat[i, 4],
                                  flat[i, 5], flat[i, 6], flat[i, 7], flat[i, 8]), cables, c, v,
                                 rank_one)
            for a in range(9):
                flat[i, a] = m[a]


@nb.njit(cache=True, error_model="numpy")
def _unit(x, y, z):
    """(x, y, z) / |(x, y, z)|, or zero for the zero vector."""
    norm = np.sqrt(x * x + y * y + z * z)
    inv = 1.0 / norm if norm > 0.0 else 0.0
    return x * inv, y * inv, z * inv


@nb.njit(cache=True, error_model="numpy")
def elastic_energy(length, rest, ea):
    """Elastic energy E A (L - L_0)^2 / (2 L_0) [J] of one cable of length L [m], rest length
    L_0 [m] and rigidity E A [N]; 0 if slack."""
    return 0.5 * ea * (length - rest) ** 2 / rest if length > rest else 0.0


@nb.njit(cache=True, error_model="numpy")
def reel(pos, cables, t, dt):
    """The winches over a step from ``t`` [s] of ``dt`` [s]: from the trigger time, each
    shortens its cable's rest length by reel_speed dt (not below min_rest) while the cable's
    last tension is below stall, and sets its rest_rate; its work [J] is the elastic energy
    that adds at ``pos`` plus the last damper force times the length reeled."""
    if cables is None:  # no cables: this specialization compiles to nothing
        return
    for c in range(cables.rest.shape[0]):
        cables.rest_rate[c] = 0.0
        old = cables.rest[c]
        if (t < cables.start_time[0] or cables.tension[c] >= cables.stall[c]
                or old <= cables.min_rest[c]):
            continue
        new = max(old - cables.reel_speed[c] * dt, cables.min_rest[c])
        cables.rest_rate[c] = (new - old) / dt
        length, ea = cable_length(pos, cables, c), cables.rigidity[c]
        cables.rest[c] = new
        cables.work[c] += (elastic_energy(length, new, ea) - elastic_energy(length, old, ea)
                           + cables.damper[c] * (old - new))
