"""The regular net's threads as stencils (Eq. 1) over a structure-of-arrays state.

An Ns x Ns net's inner threads join row neighbours (node i -> i + 1, the "horizontal"
threads h(i)) and column neighbours (i -> i + Ns, the "vertical" threads v(i)). Over
contiguous index ranges, with x, y, z (and u, v, w) in separate rows, every such thread is the
same arithmetic on shifted slices: the loops have no gathers and no scatter-adds, and numba
emits packed vector instructions for them. Each thread's result (T e, or a block product) is
stored once; each node then sums its four neighbours' entries, in the order in which the
pair-list kernels add them (v(i - Ns), h(i - 1), h(i), v(i), then every other element), so the
two paths give the same floating-point results, bit for bit.

Everything that is not a grid thread (the corner threads, and any element added later) stays
in the general pair-list kernels (:mod:`bulletnet.kernels.axial`), which read the same memory
through (N, 3) views of the rows (:attr:`GridViews`). The contact stage and the bending
springs read those views too. The implicit step solves its system with the pair list's
conjugate gradients (:func:`bulletnet.solver.pcg.solve`), given this module's product and
block-Jacobi preconditioner on the rows (or block D-ILU's, :mod:`bulletnet.solver.dilu`, on
the same rows).

Layout: :class:`Grid` holds rows of length L >= N (N nodes, padded to a multiple of 8), all
carved, with the threads' parameters, from one 64-byte aligned buffer (the placement of a
separately allocated array changed the plain step's time by up to 12 % from run to run); thread
rows have Ns leading zeros so that thread i - Ns and i - 1 of node i exist for every node,
and the explicit step's thread loops run over whole vectors (padding threads, never taut).
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import numba as nb
import numpy as np

from ..common import llvm_options
from ..kernels import U
from ..kernels.axial import (
    add_block,
    add_thread_blocks,
    add_thread_rhs,
    axial_forces,
    axial_linearization,
    block_entry,
    block_product,
    invert3,
    tension_law,
)
from ..kernels.bending import (
    angular_torque,
    bending_forces,
    relative_rotation_vector,
    transverse_force,
)
from ..kernels.breakage import fail_thread
from ..kernels.cable import (
    CableArrays,
    add_cable_blocks,
    add_cable_product,
    cable_forces,
    clear_cable_nodes,
)
from ..kernels.orbit import OrbitArrays, clear_orbit_nodes, orbit_forces
from ..kernels.peaks import track_cables, track_threads
from ..model.net import NetModel
from ..model.topology import grid_places, grid_threads
from . import dilu as dilu_kernels
from . import pcg
from .dilu import DiluArrays

ALIGN = 64
"""Alignment of every row [bytes] (a cache line; a whole AVX-512 register)."""


class Grid(NamedTuple):
    """The grid threads' parameters and the structure-of-arrays state and scratch of a net of
    Ns x Ns nodes, N nodes in all (the net, then the corner masses and any other nodes), and
    Q other (pair-list) threads. Rows of node quantities have length L >= N, a multiple of 8
    long enough for every padding thread's far node; rows of thread quantities, length W (Ns +
    L rounded up to a multiple of 8), hold thread t at column Ns + t, and column Ns begins a
    cache line in each of them (:func:`build`)."""

    ns: int
    """Ns, nodes per side [-]."""
    n: int
    """Ns^2, the net's nodes [-]; nodes n .. N - 1 have no grid thread."""
    count: int
    """N, all nodes [-]."""
    h_rest: np.ndarray
    """Rest length of thread i -> i + 1 [m], shape (H,): H is Ns^2 - 1 rounded up to a
    multiple of 8; +inf (never taut, every other parameter zero) at a row's end and on the
    padding threads i >= Ns^2 - 1."""
    h_k: np.ndarray
    """Its axial stiffness [N/m], shape (H,)."""
    h_c: np.ndarray
    """Its axial damping [N s/m], shape (H,)."""
    v_rest: np.ndarray
    """Rest length of thread i -> i + Ns [m], shape (V,): V is Ns^2 - Ns rounded up to a
    multiple of 8 (+inf on the padding threads)."""
    v_k: np.ndarray
    """Its axial stiffness [N/m], shape (V,)."""
    v_c: np.ndarray
    """Its axial damping [N s/m], shape (V,)."""
    h_bend: np.ndarray
    """Bending parameters of thread i -> i + 1 at column i: k_t [N/m], c_t [N s/m], k_b
    [N m/rad], c_b [N m s/rad], rest axis in node i's frame (3) [-], shape (7, H)
    (zero at a row's end and on the padding)."""
    v_bend: np.ndarray
    """The same for thread i -> i + Ns, shape (7, V)."""
    o_pairs: np.ndarray
    """The other threads' end nodes [-], shape (Q, 2), int64."""
    o_rest: np.ndarray
    """Their rest lengths [m], shape (Q,)."""
    o_k: np.ndarray
    """Their axial stiffness [N/m], shape (Q,)."""
    o_c: np.ndarray
    """Their axial damping [N s/m], shape (Q,)."""
    mass: np.ndarray
    """Node masses [kg], shape (L,) (zero on the padding columns N .. L - 1)."""
    inv_mass: np.ndarray
    """1 / mass [1/kg], shape (L,) (zero on the padding columns: they never move)."""
    x: np.ndarray
    """Positions [m], shape (3, L)."""
    v: np.ndarray
    """Velocities [m/s], shape (3, L)."""
    q: np.ndarray
    """Orientations, quaternions x, y, z, w [-], shape (4, L) (bending only)."""
    w: np.ndarray
    """Angular velocities [rad/s], shape (3, L) (bending only)."""
    dv: np.ndarray
    """Velocity increment of the last step [m/s], shape (3, L); CG's warm start."""
    base: np.ndarray
    """Gravity, loads and external forces, m g + load + external [N], shape (3, L)."""
    bend: np.ndarray
    """Bending forces of the last evaluation [N], shape (3, L)."""
    other: np.ndarray
    """Forces of the other threads [N], shape (3, L)."""
    th: np.ndarray
    """T e of thread h(i) at column Ns + i [N], shape (3, W)."""
    tv: np.ndarray
    """T e of thread v(i) at column Ns + i [N], shape (3, W)."""
    eh: np.ndarray
    """Unit direction of h(i) at column Ns + i [-], shape (3, W) (implicit Euler)."""
    ev: np.ndarray
    """Unit direction of v(i) [-], shape (3, W) (implicit Euler)."""
    blocks: np.ndarray
    """along, across of h(i), then of v(i), at column Ns + i [kg], shape (4, W):
    the implicit-Euler block along - across on e e^T plus across on the identity."""
    wh: np.ndarray
    """A block of h(i) times its nodes' difference [kg m/s], shape (3, W)."""
    wv: np.ndarray
    """The same for v(i), shape (3, W)."""
    cg: np.ndarray
    """CG vectors r, z, d, A d [kg m/s, m/s, m/s, kg m/s], shape (4, 3, L)."""
    block_inv: np.ndarray
    """Inverse block-Jacobi preconditioner, row-major 3 x 3 per node [1/kg], shape (9, L)
    (with block D-ILU, the diagonal blocks it is factored from [kg])."""
    o_tension: np.ndarray
    """Tension of the other threads [N], shape (Q,)."""
    o_along: np.ndarray
    """Their implicit block along the thread [kg], shape (Q,)."""
    o_across: np.ndarray
    """Their implicit block across the thread [kg], shape (Q,)."""
    o_axis: np.ndarray
    """Their unit directions [-], shape (Q, 3)."""
    o_bend: np.ndarray
    """Their bending parameters k_t, c_t, k_b, c_b (as h_bend), shape (4, Q)."""
    o_rest_axis: np.ndarray
    """Their rest axes in their first node's frame [-], shape (Q, 3)."""
    o_shear: np.ndarray
    """Their shear force magnitude [N], shape (Q,)."""
    bh: np.ndarray
    """Bending of thread h(i) at column Ns + i: force on node i [N] (3), r x that force
    [N m] (3), torque on node i [N m] (3), shape (9, W)."""
    bv: np.ndarray
    """The same for thread v(i), shape (9, W)."""
    peak_rows: np.ndarray
    """Each grid thread's running maximum of its squared |T e| [N^2], h(i) in row 0 and v(i)
    in row 1 at column Ns + i, shape (2, W) (the peaks' rows,
    :attr:`bulletnet.kernels.peaks.PeakArrays.rows`: carved here with the rows the peaks
    pass reads, so that their place relative to them holds from run to run; allocated apart,
    the heap's placement moved the plain deployment's step between 0.55 and 0.96 us,
    docs/speed.md)."""
    cables: CableArrays | None
    """The closing cables (pair-list kernels on the views); None without."""
    orbit: OrbitArrays | None = None
    """The reference orbit (HCW forces into the other rows, :mod:`bulletnet.kernels.orbit`);
    None without."""
    o_rest_rate: np.ndarray | None = None
    """The other threads' rest-length rates [m/s], shape (Q,) (a tether reeled at the chaser,
    :mod:`bulletnet.kernels.reel`); None without a reel (all zero)."""
    dilu: DiluArrays | None = None
    """Block D-ILU's couplings and scratch (:mod:`bulletnet.solver.dilu`); None: the
    block-Jacobi preconditioner."""


class GridViews(NamedTuple):
    """(N, 3) views of a grid's rows, for the pair-list kernels, the contact stage and the
    bending springs (they write through to the rows)."""

    position: np.ndarray
    """Positions [m], shape (N, 3)."""
    velocity: np.ndarray
    """Velocities [m/s], shape (N, 3)."""
    dv: np.ndarray
    """Velocity increment of the last step [m/s], shape (N, 3)."""
    bend: np.ndarray
    """Bending forces [N], shape (N, 3)."""
    other: np.ndarray
    """Forces of the other threads [N], shape (N, 3)."""
    r: np.ndarray
    """CG residual (first the right-hand side) [kg m/s], shape (N, 3)."""
    quat: np.ndarray
    """Orientations [-], shape (N, 4)."""
    omega: np.ndarray
    """Angular velocities [rad/s], shape (N, 3)."""


def applies(model: NetModel) -> bool:
    """Whether ``model`` is a net the grid kernels cover: Eq. 1's threads first, tension-only,
    nothing clamped (the cantilever beam and any other model take the pair-list path)."""
    return (not model.bilateral and not model.fixed.any()
            and grid_threads(model.nodes_per_side, model.node_count, model.pairs) > 0)


def _rows(total: int) -> int:
    """Row length: ``total`` rounded up to a multiple of 8 float64 (64 bytes)."""
    return -(-total // 8) * 8


def _carve(shapes: list[tuple[int, ...]], leads: list[int]) -> list[np.ndarray]:
    """Zeroed float64 arrays of ``shapes``, each starting ``leads`` doubles after an
    :data:`ALIGN` boundary, all in one allocation (their relative placement then does not
    change from run to run)."""
    sizes = [_rows(int(np.prod(s)) + lead) for s, lead in zip(shapes, leads, strict=True)]
    buffer = np.zeros(sum(sizes) + ALIGN // 8)
    start = (-buffer.ctypes.data % ALIGN) // 8
    out = []
    for shape, size, lead in zip(shapes, sizes, leads, strict=True):
        begin = start + lead
        out.append(buffer[begin:begin + int(np.prod(shape))].reshape(shape))
        start += size
    return out


def build(model: NetModel, cables: CableArrays | None = None,
          orbit: OrbitArrays | None = None, rest_rate: np.ndarray | None = None,
          dilu: DiluArrays | None = None) -> Grid:
    """The grid of a net that :func:`applies`: its threads' parameters rearranged by stencil
    and zeroed state and scratch, its closing ``cables``, reference ``orbit``, the threads'
    rest-length rates ``rest_rate`` [m/s] (P,) and block D-ILU's arrays ``dilu``
    (:func:`bulletnet.solver.dilu.dilu_arrays`) (None: none; block Jacobi)."""
    ns, count, pairs, mass = model.nodes_per_side, model.node_count, model.pairs, model.mass
    per_thread = np.vstack([  # rows: rest, k, c, then the bending parameters (h_bend)
        model.rest_length, model.axial_stiffness, model.axial_damping,
        model.transverse_stiffness, model.transverse_damping, model.bending_stiffness,
        model.bending_damping, model.rest_axis.T])
    n, inner = ns * ns, 2 * ns * (ns - 1)
    o = np.ascontiguousarray(per_thread[:, inner:])
    q = o.shape[1]
    # thread rows padded to whole vectors (the stencils' loops then have no scalar remainder)
    # with threads that are never taut, as is the thread at a row's end: rest +inf, all else 0
    h_count, v_count = _rows(max(n - 1, 0)), _rows(n - ns)
    length = _rows(max(count, h_count + 1, v_count + ns))
    # the thread rows ("wide", column Ns + t for thread t) start Ns mod 8 doubles short of a
    # cache line and are whole lines long, so that column Ns of every row is line-aligned:
    # the stencils' and the peaks' vector stores then never split a line (the plain
    # deployment's step 0.55 -> 0.51 us, docs/speed.md)
    wide, lead = _rows(ns + length), -ns % 8
    shapes = ([(10, h_count), (10, v_count), (2, length)] + [(3, length)] * 6
              + [(3, wide)] * 4 + [(4, wide), (3, wide), (3, wide), (4, 3, length),
                                   (9, length), (q, 3), (9, wide), (9, wide), (4, length),
                                   (3, length), (2, wide)])
    (h, v, masses, x, vel, dv, base, bend, other, th, tv, eh, ev, blocks, wh, wv, cg, block_inv,
     o_axis, bh, bv, quat, omega, peak_rows) = _carve(
        shapes, [lead if s[-1] == wide else 0 for s in shapes])
    h[0] = v[0] = np.inf
    for p, (i, j) in enumerate(pairs[:inner]):
        (h if j == i + 1 else v)[:, i] = per_thread[:, p]
    masses[0, :count] = mass
    masses[1, :count] = 1.0 / mass
    return Grid(
        ns=ns, n=n, count=count, h_rest=h[0], h_k=h[1], h_c=h[2], v_rest=v[0], v_k=v[1],
        v_c=v[2], h_bend=h[3:], v_bend=v[3:], o_pairs=pairs[inner:].copy(), o_rest=o[0].copy(),
        o_k=o[1].copy(), o_c=o[2].copy(), mass=masses[0], inv_mass=masses[1], x=x, v=vel,
        q=quat, w=omega, dv=dv, base=base, bend=bend, other=other, th=th, tv=tv, eh=eh, ev=ev,
        blocks=blocks, wh=wh, wv=wv, cg=cg, block_inv=block_inv, o_tension=np.zeros(q),
        o_along=np.zeros(q), o_across=np.zeros(q), o_axis=o_axis, o_bend=o[3:7].copy(),
        o_rest_axis=o[7:].T.copy(), o_shear=np.zeros(q), bh=bh, bv=bv, peak_rows=peak_rows,
        cables=cables, orbit=orbit,
        o_rest_rate=None if rest_rate is None else rest_rate[inner:].copy(), dilu=dilu)


def views(grid: Grid) -> GridViews:
    """(N, 3) views of the grid's rows (see :class:`GridViews`), made once: a view made in a
    kernel compiled with numba's reference counting costs an atomic increment and decrement at
    every step (the grid's own kernels, compiled without it, make theirs: :func:`_apply`,
    :func:`_block_jacobi`)."""
    count = grid.count
    return GridViews(*(a[:, :count].T for a in (grid.x, grid.v, grid.dv, grid.bend,
                                                grid.other, grid.cg[0], grid.q, grid.w)))


def load(grid: Grid, state, base) -> None:
    """Copy a :class:`~bulletnet.model.state.NetState`'s nodes (positions [m], velocities [m/s],
    and orientations and angular velocities [rad/s] if it has them) and the constant forces
    ``base`` [N] (N, 3) into the grid's rows."""
    count = grid.count
    grid.x[:, :count] = state.position.T
    grid.v[:, :count] = state.velocity.T
    load_forces(grid, base)
    if state.oriented:
        grid.q[:, :count] = state.orientation.T
        grid.w[:, :count] = state.angular_velocity.T


def load_forces(grid: Grid, base) -> None:
    """Copy the constant forces ``base`` [N] (N, 3) into the grid's rows."""
    grid.base[:, :grid.count] = base.T


def store(grid: Grid, state) -> None:
    """Copy the grid's nodes back into a :class:`~bulletnet.model.state.NetState`."""
    count = grid.count
    state.position[:] = grid.x[:, :count].T
    state.velocity[:] = grid.v[:, :count].T
    if state.oriented:
        state.orientation[:] = grid.q[:, :count].T
        state.angular_velocity[:] = grid.w[:, :count].T


ONE = U(1)


@nb.njit(cache=True, error_model="numpy")
def _neighbours(start, h, v, a, i, ns, sign):
    """``start`` plus component a of node i's four grid-thread entries in the pair-list
    kernels' order and signs, - v(i - Ns) - h(i - 1) + h(i) + v(i) (all four negated with
    ``sign`` -1); h and v hold thread t at column Ns + t. (x - (-w) is x + w exactly, so one
    order serves both signs bit for bit.)"""
    return (((start - sign * v[a, i]) - sign * h[a, i + ns - ONE]) + sign * h[a, i + ns]) \
        + sign * v[a, i + ns]


@nb.njit(cache=True, error_model="numpy")
def _row_tension(x, v, t, j, rest, k, c):
    """:func:`~bulletnet.kernels.axial.tension_law` of thread t, from node t to node j of the
    (3, L) rows x [m] and v [m/s]: (T [N], ex, ey, ez, l [m]) (a grid thread's rest length
    never changes: its rate is 0)."""
    return tension_law(x[0, j] - x[0, t], x[1, j] - x[1, t], x[2, j] - x[2, t],
                       v[0, j] - v[0, t], v[1, j] - v[1, t], v[2, j] - v[2, t], rest[t], 0.0,
                       k[t], c[t], False)


@nb.njit(cache=True, error_model="numpy")
def _store_tension(tension_e, col, tension, ex, ey, ez):
    """Column ``col`` of ``tension_e`` <- T e [N] (zero for a slack thread, whose direction
    may not be finite)."""
    on = tension != 0.0
    tension_e[0, col] = tension * ex if on else 0.0
    tension_e[1, col] = tension * ey if on else 0.0
    tension_e[2, col] = tension * ez if on else 0.0


@nb.njit(cache=True, error_model="numpy", inline="always")
def _tension_stencil(x, v, off, rest, k, c, tension_e, count, ns):
    """Eq. 3 for threads t < ``count`` from node t to node t + ``off``: T e [N] into
    column Ns + t of ``tension_e`` (3, W); x [m] and v [m/s] are (3, L) rows."""
    for t in range(count):
        tension, ex, ey, ez, _ = _row_tension(x, v, t, t + off, rest, k, c)
        _store_tension(tension_e, t + ns, tension, ex, ey, ez)


@nb.njit(cache=True, error_model="numpy", inline="always")
def _linearize_stencil(x, v, off, rest, k, c, tension_e, axis, blocks, row, dt, count, ns):
    """:func:`_tension_stencil`, plus each thread's e into ``axis`` and its implicit block's
    along and across [kg] into blocks[row], blocks[row + 1] (see
    :func:`~bulletnet.kernels.axial.axial_linearization`). Three loops, each computing the
    tension law afresh: one loop writing all eight rows stayed scalar (too many rows for
    LLVM's runtime alias checks), and so did the direction and the blocks in one loop after
    the tension stencil; three vectorize (the capture's 840 threads, stretched at random:
    6.1 -> 4.0 us, the same bits)."""
    _tension_stencil(x, v, off, rest, k, c, tension_e, count, ns)
    for t in range(count):
        _, ex, ey, ez, _ = _row_tension(x, v, t, t + off, rest, k, c)
        col = t + ns
        axis[0, col], axis[1, col], axis[2, col] = ex, ey, ez
    for t in range(count):
        tension, _, _, _, length = _row_tension(x, v, t, t + off, rest, k, c)
        col = t + ns
        on = tension != 0.0
        blocks[row, col] = dt * c[t] + dt * dt * k[t] if on else 0.0
        blocks[row + ONE, col] = (dt * dt * k[t] * max(length - rest[t], 0.0) / length
                                  if on else 0.0)


@nb.njit(cache=True, error_model="numpy", inline="always")
def _other_threads(grid, views, dt, linearize):
    """The other threads', the cables' and the orbit's forces [N] into ``other`` (pair-list
    kernels on the views); with ``linearize`` also the threads' and cables' directions and
    implicit blocks."""
    other, pairs, cables = views.other, grid.o_pairs, grid.cables
    for q in range(pairs.shape[0]):
        for end in range(2):
            for a in range(3):
                other[pairs[q, end], a] = 0.0
    clear_cable_nodes(cables, other)
    clear_orbit_nodes(grid.orbit, other)
    if linearize:
        axial_linearization(views.position, views.velocity, pairs, grid.o_rest,
                            grid.o_rest_rate, grid.o_k, grid.o_c, False, dt, other,
                            grid.o_tension, grid.o_along, grid.o_across, grid.o_axis)
    else:
        axial_forces(views.position, views.velocity, pairs, grid.o_rest, grid.o_rest_rate,
                     grid.o_k, grid.o_c, False, other, grid.o_tension)
    cable_forces(views.position, views.velocity, cables, other, linearize, dt)
    orbit_forces(views.position, views.velocity, grid.mass, grid.orbit, other)


@nb.njit(cache=True, error_model="numpy", inline="always")
def thread_forces(grid, views, dt):
    """T e of every grid thread into th and tv, the other threads' forces [N] into other."""
    ns, x, v = U(grid.ns), grid.x, grid.v
    _tension_stencil(x, v, ONE, grid.h_rest, grid.h_k, grid.h_c, grid.th,
                     U(grid.h_rest.shape[0]), ns)
    _tension_stencil(x, v, ns, grid.v_rest, grid.v_k, grid.v_c, grid.tv,
                     U(grid.v_rest.shape[0]), ns)
    _other_threads(grid, views, dt, False)


@nb.njit(cache=True, error_model="numpy", inline="always")
def _net_force(grid, base, a, i, ns, bending_scale):
    """Component a of node i's force [N]: base + bending_scale bend + its grid threads
    (:func:`_neighbours`) + the other threads; zero on a padding column. ``bending_scale``
    None: no bending, bend not read (base + 0 bend is base: the same bits, a row less to read
    a step); ``base`` None: no base forces, 0.0 in their place (the same operations on the
    same values as a zero row: the same bits, a row less; a net in 0 g with no load)."""
    start = 0.0 if base is None else base[a, i]
    if bending_scale is not None:
        start = start + bending_scale * grid.bend[a, i]
    return _neighbours(start, grid.th, grid.tv, a, i, ns, 1.0) + grid.other[a, i]


@nb.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def symplectic_step(grid, views, dt, bending_scale, increment, base):
    """One symplectic Euler step of every node: :func:`thread_forces`, then dv = dt F / m with
    F = :func:`_net_force` (``base``: the grid's base rows, or None where they are all zero),
    v <- v + dv, x <- x + dt v, in one pass over the rows (padding columns included: they
    have no force and no mass, and stay at rest); dv is kept in its rows only with
    ``increment`` (the contact stage reads it).

    Inlined into the loops that call it, as :func:`track_peaks` is: a call passes the grid's
    arrays field by field (195 words pushed on the stack, read with ``inspect_asm``) and the
    callee reads them afresh, every step; the plain deployment's ~1 us step took 0.76-0.83
    of its time inlined (benchmarks/grid_step.py, docs/speed.md)."""
    thread_forces(grid, views, dt)
    node_pass(grid, dt, bending_scale, increment, base)


@nb.njit(cache=True, error_model="numpy", inline="always")
def node_pass(grid, dt, bending_scale, increment, base):
    """The node pass of :func:`symplectic_step`, after :func:`thread_forces`: dv = dt F / m
    with F = :func:`_net_force`, v <- v + dv, x <- x + dt v over the rows, dv kept only with
    ``increment``."""
    ns, length = U(grid.ns), U(grid.x.shape[1])
    x, v, dv, inv_mass = grid.x, grid.v, grid.dv, grid.inv_mass
    for a in range(U(3)):
        if increment:  # two loops written out: one loop with this test inside is 5-10 % slower
            for i in range(length):
                dv[a, i] = dt * inv_mass[i] * _net_force(grid, base, a, i, ns, bending_scale)
                v[a, i] += dv[a, i]
                x[a, i] += dt * v[a, i]
        else:
            for i in range(length):
                v[a, i] += dt * inv_mass[i] * _net_force(grid, base, a, i, ns, bending_scale)
                x[a, i] += dt * v[a, i]


@nb.njit(cache=True, error_model="numpy", inline="always")
def _move(x, v, dv, dt, count):
    """v <- v + dv, x <- x + dt v for the first ``count`` columns."""
    for a in range(U(3)):
        for i in range(count):
            v[a, i] += dv[a, i]
            x[a, i] += dt * v[a, i]


@nb.njit(cache=True, error_model="numpy", inline="always")
def _block_stencil(rows, off, k, scale, blocks, row, axis, products, count, ns):
    """Each thread's (t < ``count``, node t to node t + ``off``)
    :func:`~bulletnet.kernels.axial.block_product` of rows_t - rows_(t + off), with across =
    blocks[row + 1] and along = blocks[row] or, where ``scale`` > 0, scale k [kg] (the
    right-hand side's stiffness part), into column Ns + t of ``products``; zero for a slack
    thread (blocks[row] 0)."""
    for t in range(count):
        j, col = t + off, t + ns
        along = blocks[row, col]
        w0, w1, w2 = block_product(rows[0, t] - rows[0, j], rows[1, t] - rows[1, j],
                                   rows[2, t] - rows[2, j],
                                   scale * k[t] if scale > 0.0 else along,
                                   blocks[row + ONE, col], axis[0, col], axis[1, col],
                                   axis[2, col])
        on = along != 0.0
        products[0, col] = w0 if on else 0.0
        products[1, col] = w1 if on else 0.0
        products[2, col] = w2 if on else 0.0


@nb.njit(cache=True, error_model="numpy", _nrt=False)
def _block_products(grid, rows, scale):
    """Every grid thread's block times its nodes' difference of ``rows`` (3, L), into wh and
    wv: the system's blocks (``scale`` 0) or, for the right-hand side, the blocks with
    along = scale k (scale dt^2 [s^2])."""
    ns, n, blocks = U(grid.ns), U(grid.n), grid.blocks
    _block_stencil(rows, ONE, grid.h_k, scale, blocks, U(0), grid.eh, grid.wh, n - ONE, ns)
    _block_stencil(rows, ns, grid.v_k, scale, blocks, U(2), grid.ev, grid.wv, n - ns, ns)


@nb.njit(cache=True, error_model="numpy", _nrt=False)
def _apply(grid, rows, out):
    """out = M rows + the threads' blocks applied to rows (the implicit system's product
    A x of :func:`bulletnet.solver.pcg.solve`; rows [m/s] and out [kg m/s] (3, L)), in the
    pair-list kernels' order."""
    ns, n, count, mass = U(grid.ns), U(grid.n), U(grid.count), grid.mass
    wh, wv = grid.wh, grid.wv
    _block_products(grid, rows, 0.0)
    for a in range(U(3)):
        for i in range(n):
            out[a, i] = _neighbours(mass[i] * rows[a, i], wh, wv, a, i, ns, 1.0)
        for i in range(n, count):
            out[a, i] = mass[i] * rows[a, i]
    rows_view, out_view = rows[:, :count].T, out[:, :count].T  # free: no reference counts
    add_thread_blocks(rows_view, grid.o_pairs, grid.o_along, grid.o_across, grid.o_axis,
                      out_view)
    add_cable_product(rows_view, grid.cables, out_view, 0.0, 1.0)


@nb.njit(cache=True, error_model="numpy")
def _thread_entry(m, blocks, row, axis, col, a, b):
    """m + entry (a, b) of the implicit block of the thread at column ``col`` of blocks[row],
    axis (its along, across, e), or m itself for a slack thread (its terms are zeroed, not
    skipped, so that the loop over nodes has no branch; m + 0.0 is m)."""
    on = blocks[row, col] != 0.0
    along = blocks[row, col] if on else 0.0
    across = blocks[row + ONE, col] if on else 0.0
    return block_entry(m, along - across, across, axis[a, col] if on else 0.0,
                       axis[b, col] if on else 0.0, a == b)


@nb.njit(cache=True, error_model="numpy", inline="always")
def _block_entry(grid, i, ns, a, b):
    """Entry (a, b) of node i's 3 x 3 diagonal block [kg]: its mass on the diagonal, plus its
    four grid threads' blocks in the pair-list order, v(i - Ns), h(i - 1), h(i), v(i)."""
    blocks, eh, ev = grid.blocks, grid.eh, grid.ev
    m = grid.mass[i] if a == b else 0.0
    m = _thread_entry(m, blocks, U(2), ev, i, a, b)
    m = _thread_entry(m, blocks, U(0), eh, ns + i - ONE, a, b)
    m = _thread_entry(m, blocks, U(0), eh, ns + i, a, b)
    return _thread_entry(m, blocks, U(2), ev, ns + i, a, b)


@nb.njit(cache=True, error_model="numpy")
def _store(rows, i, m):
    """Column i of (9, L) ``rows`` <- the 9-tuple m (stored entry by entry: a tuple indexed
    in a loop would compile to a jump table and keep the node loop from vectorizing)."""
    rows[0, i], rows[1, i], rows[2, i] = m[0], m[1], m[2]
    rows[3, i], rows[4, i], rows[5, i] = m[3], m[4], m[5]
    rows[6, i], rows[7, i], rows[8, i] = m[6], m[7], m[8]


@nb.njit(cache=True, error_model="numpy", _nrt=False)
def _block_jacobi(grid):
    """Each node's 3 x 3 diagonal block of the implicit system, inverted, into block_inv (the
    preconditioner of :func:`bulletnet.solver.pcg.solve`); with block D-ILU (grid.dilu) the
    blocks without the cables' rank-one parts, not inverted, and from them D-ILU's factor
    (:func:`bulletnet.solver.dilu.factor`)."""
    ns, n, count, mass, inv = U(grid.ns), U(grid.n), U(grid.count), grid.mass, grid.block_inv
    # three passes of three entries each: one pass writing all nine rows stayed scalar (too
    # many rows for LLVM's runtime alias checks; the capture's 441 grid nodes, 4.4 -> 3.6 us)
    for i in range(n):
        inv[0, i] = _block_entry(grid, i, ns, U(0), U(0))
        inv[4, i] = _block_entry(grid, i, ns, U(1), U(1))
        inv[8, i] = _block_entry(grid, i, ns, U(2), U(2))
    for i in range(n):
        inv[1, i] = _block_entry(grid, i, ns, U(0), U(1))
        inv[2, i] = _block_entry(grid, i, ns, U(0), U(2))
        inv[5, i] = _block_entry(grid, i, ns, U(1), U(2))
    for i in range(n):
        inv[3, i] = _block_entry(grid, i, ns, U(1), U(0))
        inv[6, i] = _block_entry(grid, i, ns, U(2), U(0))
        inv[7, i] = _block_entry(grid, i, ns, U(2), U(1))
    for i in range(n, count):
        for a in range(9):
            inv[a, i] = mass[i] if a % 4 == 0 else 0.0
    pairs, along, across, axis = grid.o_pairs, grid.o_along, grid.o_across, grid.o_axis
    for q in range(pairs.shape[0]):
        if along[q] == 0.0 and across[q] == 0.0:
            continue
        for node in (pairs[q, 0], pairs[q, 1]):
            m = add_block((inv[0, node], inv[1, node], inv[2, node], inv[3, node], inv[4, node],
                           inv[5, node], inv[6, node], inv[7, node], inv[8, node]), along[q],
                          across[q], axis[q, 0], axis[q, 1], axis[q, 2])
            for a in range(9):
                inv[a, node] = m[a]
    add_cable_blocks(grid.cables, inv[:, :count].T, grid.dilu is None)
    if _dilu_factor(grid.dilu, grid):
        return
    for i in range(count):
        _store(inv, i, invert3((inv[0, i], inv[1, i], inv[2, i], inv[3, i], inv[4, i],
                                inv[5, i], inv[6, i], inv[7, i], inv[8, i])))


@nb.njit(cache=True, error_model="numpy")
def _dilu_factor(dilu, grid):
    """Block D-ILU's factor from the diagonal blocks in grid's block_inv
    (:func:`bulletnet.solver.dilu.factor`), the grid threads' blocks read from the rows where
    the grid's nodes are folded (else gathered), the other threads' gathered; False, and
    nothing compiled, without block D-ILU (``dilu`` None)."""
    if dilu is None:
        return False
    if len(dilu.slots) == 0:
        dilu_kernels.gather_grid_threads(dilu, grid.blocks, grid.eh, grid.ev, grid.o_along,
                                         grid.o_across, grid.o_axis)
    else:
        dilu_kernels.gather_other_threads(dilu, grid.o_along, grid.o_across, grid.o_axis)
    # one specialization of the factor whether folded or not (each is compiled in a first run)
    dilu_kernels.factor(dilu, grid.block_inv, dilu.along, dilu.across, dilu.axis, grid.cables,
                        (grid.blocks, grid.eh, grid.ev))
    return True


@nb.njit(cache=True, error_model="numpy", inline="always")
def _precondition(grid, r, z, ad, alpha):
    """:func:`_preconditioned` with the grid's block D-ILU arrays (None: block Jacobi)."""
    return _preconditioned(grid.dilu, grid, r, z, ad, alpha)


@nb.njit(cache=True, error_model="numpy")
def _preconditioned(dilu, grid, r, z, ad, alpha):
    """r [kg m/s] <- r - ``alpha`` [-] ad [kg m/s], then z [m/s] = the inverse diagonal blocks
    times r, node by node ((3, L) rows; the padding columns, zeros, untouched); returns r . z
    [kg m^2/s^2] and r . r [kg^2 m^2/s^2] summed in node order
    (:func:`bulletnet.solver.pcg.dot_terms`); with block D-ILU (grid.dilu), z = its
    preconditioner times r (:func:`bulletnet.solver.dilu.precondition`)."""
    count, inv = U(grid.count), grid.block_inv
    if dilu is not None:
        return dilu_kernels.precondition(dilu, r, z, ad, alpha, count, grid.cables)
    rz = rr = 0.0
    for i in range(count):
        r0, r1, r2 = r[0, i] - alpha * ad[0, i], r[1, i] - alpha * ad[1, i], \
            r[2, i] - alpha * ad[2, i]
        r[0, i], r[1, i], r[2, i] = r0, r1, r2
        z0 = inv[0, i] * r0 + inv[1, i] * r1 + inv[2, i] * r2
        z1 = inv[3, i] * r0 + inv[4, i] * r1 + inv[5, i] * r2
        z2 = inv[6, i] * r0 + inv[7, i] * r1 + inv[8, i] * r2
        z[0, i], z[1, i], z[2, i] = z0, z1, z2
        tz, tr = pcg.dot_terms(r0, r1, r2, z0, z1, z2)
        rz += tz
        rr += tr
    return rz, rr


@nb.njit(cache=True, error_model="numpy", inline="always")
def _components(rows):
    """The rows (3, L) themselves: the grid's vectors are component rows already."""
    return rows


@nb.njit(cache=True, error_model="numpy", _nrt=False)
def implicit_step(grid, views, dt, tol, iterations):
    """One linearly implicit Euler step (:func:`bulletnet.solver.integrators.implicit_increment`,
    the same arithmetic in the same order) on the rows: the right-hand side and the system's
    blocks by stencil, dv by :func:`bulletnet.solver.pcg.solve` (its product
    :func:`_apply`, preconditioner :func:`_block_jacobi`, :func:`_precondition`; its updates
    run over whole rows, padding included) from its last value to the relative residual
    ``tol`` [-], v <- v + dv, x <- x + dt v (``dt`` [s]). base and bend hold the non-axial
    forces [N]; ``iterations`` (1,) int64 counts CG iterations."""
    ns, n, count = U(grid.ns), U(grid.n), U(grid.count)
    x, v, dv, blocks, r = grid.x, grid.v, grid.dv, grid.blocks, grid.cg[0]
    base, bend, other, th, tv = grid.base, grid.bend, grid.other, grid.th, grid.tv
    _linearize_stencil(x, v, ONE, grid.h_rest, grid.h_k, grid.h_c, th, grid.eh, blocks, U(0),
                       dt, n - ONE, ns)
    _linearize_stencil(x, v, ns, grid.v_rest, grid.v_k, grid.v_c, tv, grid.ev, blocks, U(2),
                       dt, n - ns, ns)
    _other_threads(grid, views, dt, True)
    # right-hand side dt F - dt^2 K v, in r
    _block_products(grid, v, dt * dt)
    wh, wv = grid.wh, grid.wv
    for a in range(U(3)):
        for i in range(n):
            f = _neighbours(base[a, i] + bend[a, i], th, tv, a, i, ns, 1.0) + other[a, i]
            r[a, i] = _neighbours(dt * f, wh, wv, a, i, ns, -1.0)
        for i in range(n, count):
            r[a, i] = dt * (base[a, i] + bend[a, i] + other[a, i])
    add_thread_rhs(views.velocity, grid.o_pairs, grid.o_k, grid.o_along, grid.o_across,
                   grid.o_axis, dt, views.r)
    add_cable_product(views.velocity, grid.cables, views.r, dt * dt, -1.0)
    pcg.solve(_apply, _block_jacobi, _precondition, _components, grid, dv, r, grid.cg[1],
              grid.cg[2], grid.cg[3], grid.mass, grid.count, tol, iterations, True)
    _move(x, v, dv, dt, count)


@functools.cache
def free_steps(implicit: bool):
    """The compiled loop ``(grid, views, steps, dt, tol, iterations, peaks, base)`` that takes
    ``steps`` steps of implicit Euler (``implicit``: CG to the relative residual ``tol``,
    ``iterations`` (1,) counting) or of symplectic Euler of a net with no bending, no contact
    and no cables: the threads, gravity, loads and external forces only (``base``: the grid's
    base rows, or None where they are all zero, :func:`base_rows`; symplectic Euler then
    reads no base row); after each step the threads' largest tensions (:func:`track_peaks`;
    ``peaks`` None: none, nothing compiled). (One compiled loop around the step kernels: no
    per-step bookkeeping. ``implicit`` is a constant of the loop, so numba prunes the other
    integrator's branch and compiles only the step in use.)"""

    @nb.njit(cache=True, error_model="numpy", _nrt=False)
    def free_loop(grid, views, steps, dt, tol, iterations, peaks, base):
        for _ in range(steps):
            if implicit:
                implicit_step(grid, views, dt, tol, iterations)
            else:
                symplectic_step(grid, views, dt, None, False, base)
            if peaks is not None:
                track_peaks(grid, peaks)

    # the symplectic loop's stencils run faster interleaved (:mod:`bulletnet.common.llvm_options`)
    return free_loop if implicit else llvm_options.interleave(free_loop)


def base_rows(grid: Grid) -> np.ndarray | None:
    """The grid's base rows for :func:`free_steps`, or None where every base force is zero (a
    net in 0 g with no load or external force)."""
    return grid.base if grid.base.any() else None


@nb.njit(cache=True, error_model="numpy", inline="always")
def _bending_stencil(x, v, q, w, off, params, out, count, ns):
    """The bending springs of threads t < ``count`` from node t to node t + ``off``
    (:func:`~bulletnet.kernels.bending.bending_forces`' arithmetic) into column Ns + t of
    ``out`` (see :attr:`Grid.bh`), from the rows x [m], v [m/s], q [-] and w [rad/s]. Three
    loops (the transverse force, its moment r x f, the angular spring): LLVM vectorizes each,
    not two fused; the force and its moment in one loop read and write too many rows for
    its runtime alias checks and stayed scalar (read with ``inspect_asm``: the capture's 840
    threads took 11.5 us there, 3.5 us in the two loops, the same bits)."""
    for t in range(count):
        j, col = t + off, t + ns
        out[0, col], out[1, col], out[2, col] = transverse_force(
            x[0, j] - x[0, t], x[1, j] - x[1, t], x[2, j] - x[2, t], v[0, j] - v[0, t],
            v[1, j] - v[1, t], v[2, j] - v[2, t], q[0, t], q[1, t], q[2, t], q[3, t], w[0, t],
            w[1, t], w[2, t], params[4, t], params[5, t], params[6, t], params[0, t],
            params[1, t])
    for t in range(count):
        j, col = t + off, t + ns
        rx, ry, rz = x[0, j] - x[0, t], x[1, j] - x[1, t], x[2, j] - x[2, t]
        fx, fy, fz = out[0, col], out[1, col], out[2, col]
        out[3, col], out[4, col], out[5, col] = ry * fz - rz * fy, rz * fx - rx * fz, \
            rx * fy - ry * fx
    for t in range(count):
        j, col = t + off, t + ns
        px, py, pz = relative_rotation_vector(q[0, t], q[1, t], q[2, t], q[3, t], q[0, j],
                                              q[1, j], q[2, j], q[3, j])
        out[6, col], out[7, col], out[8, col] = angular_torque(
            px, py, pz, w[0, j] - w[0, t], w[1, j] - w[1, t], w[2, j] - w[2, t], params[2, t],
            params[3, t])


@nb.njit(cache=True, error_model="numpy", _nrt=False)
def bending(grid, views, torque):
    """The bending springs afresh (as :func:`~bulletnet.solver.integrators.evaluate_bending`, in the
    pair-list order): forces [N] into the bend rows, torques [N m] into ``torque`` (N, 3)."""
    ns, n, count = U(grid.ns), U(grid.n), U(grid.count)
    x, v, q, w, bh, bv, bend = grid.x, grid.v, grid.q, grid.w, grid.bh, grid.bv, grid.bend
    _bending_stencil(x, v, q, w, ONE, grid.h_bend, bh, n - ONE, ns)
    _bending_stencil(x, v, q, w, ns, grid.v_bend, bv, n - ns, ns)
    for a in range(U(3)):
        for i in range(n):
            bend[a, i] = _neighbours(0.0, bh, bv, a, i, ns, 1.0)
        for i in range(n, count):
            bend[a, i] = 0.0
    for a in range(U(3)):
        for i in range(n):
            torque[i, a] = (((((0.0 - bv[a + U(6), i]) - bh[a + U(6), i + ns - ONE])
                              + bh[a + U(3), i + ns]) + bh[a + U(6), i + ns])
                            + bv[a + U(3), i + ns]) + bv[a + U(6), i + ns]
        for i in range(n, count):
            torque[i, a] = 0.0
    p = grid.o_bend
    bending_forces(views.position, views.velocity, views.quat, views.omega, grid.o_pairs,
                   grid.o_rest_axis, p[0], p[1], p[2], p[3], views.bend, torque, grid.o_shear)


@nb.njit(cache=True, error_model="numpy")
def break_threads(grid, views, pairs, rest, k_a, c_a, k_t, c_t, k_b, c_b, breakage, t):
    """Breakage on the grid (:mod:`bulletnet.kernels.breakage`): every intact thread whose
    tension of the step from ``t`` [s] reached its breaking tension fails. A grid thread's
    tension is the length of its T e (th, tv: the step's own, to round-off), another
    thread's its o_tension. A failed thread's parameters are zeroed both in the grid's rows
    (k, c and the bending springs) and in the model's pair-list arrays ``pairs`` (P, 2),
    ``rest`` [m], ``k_a`` .. ``c_b`` (P,) (which the recorded tensions read), by
    :func:`~bulletnet.kernels.breakage.fail_thread` at the rows' positions. Nothing without
    breakage (``breakage`` None)."""
    if breakage is None:
        return
    ns, limit, failed = grid.ns, breakage.limit, breakage.failure_time
    inner = pairs.shape[0] - grid.o_pairs.shape[0]
    pos = views.position
    for p in range(inner):
        if failed[p] >= 0.0:
            continue
        i = pairs[p, 0]
        across = pairs[p, 1] == i + 1  # h(i), else v(i)
        e = grid.th if across else grid.tv
        col = ns + i
        if np.sqrt(e[0, col] ** 2 + e[1, col] ** 2 + e[2, col] ** 2) < limit[p]:
            continue
        fail_thread(p, pos, pairs, rest, k_a, c_a, k_t, c_t, k_b, c_b, breakage, t)
        if across:
            _cut(grid.h_k, grid.h_c, grid.h_bend, i)
        else:
            _cut(grid.v_k, grid.v_c, grid.v_bend, i)
    for q in range(grid.o_pairs.shape[0]):
        p = inner + q
        if failed[p] >= 0.0 or grid.o_tension[q] < limit[p]:
            continue
        fail_thread(p, pos, pairs, rest, k_a, c_a, k_t, c_t, k_b, c_b, breakage, t)
        _cut(grid.o_k, grid.o_c, grid.o_bend, q)


@nb.njit(cache=True, error_model="numpy")
def _cut(k, c, bend, i):
    """Thread i of a stencil's (or the other threads') rows carries nothing: its axial
    stiffness k [N/m], damping c [N s/m] and bending parameters bend[0..3] zeroed."""
    k[i] = 0.0
    c[i] = 0.0
    for r in range(4):
        bend[r, i] = 0.0


@nb.njit(cache=True, error_model="numpy", inline="always")
def _square_peaks(tension_e, rows, row, count, ns):
    """rows[row, Ns + t] <- the larger of it and |T e|^2 [N^2] of column Ns + t of
    ``tension_e`` (3, W), for t < ``count``."""
    for t in range(count):
        col = t + ns
        square = tension_e[0, col] * tension_e[0, col] + tension_e[1, col] * tension_e[1, col] \
            + tension_e[2, col] * tension_e[2, col]
        rows[row, col] = np.maximum(rows[row, col], square)  # not max(): masked stores


@nb.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def track_peaks(grid, peaks):
    """Each element's running maximum of its tension (:mod:`bulletnet.kernels.peaks`) after a
    step on the grid: a grid thread's squared |T e| (th, tv: the step's own, as
    :func:`break_threads` reads it) into the peaks' rows, another thread's o_tension and each
    cable's tension [N] into their places. Nothing without peaks (``peaks`` None)."""
    if peaks is None:
        return
    ns, rows = U(grid.ns), peaks.rows
    _square_peaks(grid.th, rows, U(0), U(grid.h_rest.shape[0]), ns)
    _square_peaks(grid.tv, rows, ONE, U(grid.v_rest.shape[0]), ns)
    track_threads(grid.o_tension, peaks, peaks.thread.shape[0] - grid.o_tension.shape[0])
    track_cables(grid.cables, peaks)


def scale_damping(grid: Grid, pairs: np.ndarray, factor: np.ndarray) -> None:
    """Multiply each thread's axial damping by ``factor`` [-], shape (P,) in the order of
    ``pairs`` (P, 2) (the pair list's; the grid's rows and its other threads)."""
    inner = pairs.shape[0] - grid.o_pairs.shape[0]
    i, j = pairs[:inner, 0], pairs[:inner, 1]
    along = j == i + 1
    grid.h_c[i[along]] *= factor[:inner][along]
    grid.v_c[i[~along]] *= factor[:inner][~along]
    grid.o_c[:] *= factor[inner:]


def peak_columns(grid: Grid, pairs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where the grid keeps each grid thread's running maximum in the peaks' rows: (row,
    column) of the first 2 Ns (Ns - 1) threads of ``pairs`` (P, 2), each shape (2 Ns (Ns -
    1),) (:func:`track_peaks`)."""
    return grid_places(pairs[:pairs.shape[0] - grid.o_pairs.shape[0]], grid.ns)
