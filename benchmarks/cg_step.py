"""Where the implicit step's time goes in the captures, against the machine's own bounds.

The capture with bending (``scenarios/capture.toml``, state at ``--capture-at``) and the
closing capture (``scenarios/capture_closing.toml``, at ``--closing-at``) run to their
snapshot; there, on the grid path and inside compiled loops (no Python call between calls):

1. the CG iterations a step of the run so far, and each part of a CG iteration, called
   5000 times on the snapshot's vectors: the product A d, the preconditioner's factor
   (once a step), the preconditioning with the residual's update and the sums r . z and
   r . r taken in its pass, the dot product d . A d (node by node, in node order: one
   sequential chain of additions each sum), the updates of dv and d (best of 5 loops);
2. two bounds measured beside them: the memory bandwidth of a triad over arrays as large as
   the iteration's working set (so from the same cache level: above L1, inside L2), which
   with the bytes an iteration's passes read and write (counted below, :data:`PASS_ROWS`)
   gives the iteration's traffic floor; and the latency of a sequential sum over the nodes,
   the floor of one dot product in node order (beside it the same sum left free to be
   reordered, as a vectorized reduction would be);
3. on the pair list at the same time (for the capture the same state: the two paths run bit
   for bit alike; for the closing capture a state of its own: the paths part at round-off
   once a closing cable is taut, tests/test_dilu.py, and the capture's chaos grows that),
   the system's matrix assembled column by column from the solver's own product, and plain PCG
   iteration counts to the scene's tolerance, from the solver's warm start and from zero,
   with block Jacobi (the solver's), symmetric Gauss-Seidel, incomplete Cholesky (IC(0), on
   the matrix's own pattern: two triangular sweeps an application, as Gauss-Seidel's), block
   D-ILU on the grid's threads alone (:func:`block_dilu` over :func:`grid_neighbours`: what a
   forward and a backward block sweep over the grid's stencils would apply), block D-ILU
   over every direct coupling (:func:`direct_neighbours`: the threads and the cables' spans)
   and the same on the system less its cables' rank-one parts, which the Woodbury identity
   adds back (:func:`woodbury_dilu`) and, if ``pyamg`` is installed,
   smoothed-aggregation AMG (a V-cycle, with pyamg's Gauss-Seidel smoothing and with block
   Jacobi's) as preconditioners; and, on the grid, one forward block Gauss-Seidel sweep in
   node order over the grid's threads (what symmetric Gauss-Seidel with Eisenstat's trick
   would run twice an iteration in place of the product and the preconditioning), and block
   D-ILU's factor in node order (a 3 x 3 product and inverse a node, a chain as the sweep),
   both also in wavefront order (:func:`wavefront`: by the grid's anti-diagonals, whose nodes
   are independent; checked to give the same results, bit for bit), and the sweep again on
   the anti-diagonals regathered into contiguous rows (:func:`diagonal_rows`, so that a
   diagonal's nodes go through the vector units together; its gather and scatter timed
   apart; checked the same, bit for bit), those rows also in one buffer at compile-time
   offsets (:func:`one_buffer`, the sweep and the factor; both checked the same); the
   solver's own block D-ILU (the ``block_dilu`` preconditioner, :func:`solver_dilu`: its
   factor and its preconditioning); with them, the CG step with block D-ILU estimated from
   the parts (:func:`dilu_estimate`);
4. the rest of the step at the grid path's state: the contact stages (node-debris and
   node-node, each called from a copy of the state) and then the whole step, the run's
   loop advanced over :data:`STEP_SPAN` (its CG iterations counted), so that the step's
   time splits into the CG (iterations x the iteration, plus the factor), the two contact
   stages and what is left (forces, the system's assembly, cables, winches, peaks, the
   returns to Python for the debris' dynamics); then, over four more spans, the scene's
   tolerance and one a hundred times tighter in turn: the step's time against its CG
   iterations, whose slope is what one iteration costs inside the run's loop (the marginal
   iterations, nothing else changed), against the passes' time alone above.

Also the frozen yardstick, timed at the start and the end. Writes ``OUT/cg_step.json``:

    python benchmarks/cg_step.py benchmarks/results [--capture-at 10] [--closing-at 30]
"""

from __future__ import annotations

import functools
import json
import time

import numba as nb
import numpy as np
from common import At, Yardsticks, best_us, machine, output_dir, parser, triad_bandwidth
from contact_cache import debris_stage_calls

import bulletnet as bn
from bulletnet.kernels.axial import block_product, invert3
from bulletnet.solver import grid as G
from bulletnet.solver import integrators, pcg
from bulletnet.solver.contact_stage import self_stage
from bulletnet.solver.dilu import dilu_arrays

PASS_ROWS = {"product": 35, "preconditioning_and_sums": 21, "dot_d_ad": 6, "updates": 15}
"""Rows of L doubles each pass of a CG iteration reads plus writes (grid layout): the product
(two thread stencils: d 3, the blocks' along and across 2, axes 3, products written 3, each
x2; the node pass: mass 1, d 3, both products 6, A d written 3), the preconditioning with
the residual's update, r . z and r . r (inverse blocks 9, r and A d 6, r and z written 6),
d . A d (6), the updates of dv and d (dv, d, z read, dv and d written)."""


STILL = 0.0
"""The CG's alpha and beta in the timed updates, passed at run time (a constant would be
folded into the compiled loop): 0 leaves the vectors as they are, and its products are
computed at full speed. A tiny step length such as 1e-300 would not: its products with the
state's small components are subnormal numbers, each operation on which takes this CPU
many cycles (the preconditioning with alpha 1e-300 on the capture's state timed 1.55-1.58 us
against 0.56)."""


@nb.njit(cache=True, error_model="numpy")
def _time_product(grid, d, ad, calls):
    for _ in range(calls):
        G._apply(grid, d, ad)


@nb.njit(cache=True, error_model="numpy")
def _time_factor(grid, calls):
    for _ in range(calls):
        G._block_jacobi(grid)


@nb.njit(cache=True, error_model="numpy")
def _time_preconditioning(grid, r, z, ad, alpha, calls):
    """The preconditioning as :func:`bulletnet.solver.pcg.solve` calls it, with ``alpha``
    (:data:`STILL`: r stays as it is)."""
    s = 0.0
    for _ in range(calls):
        rz, rr = G._precondition(grid, r, z, ad, alpha)
        s += rz + rr
    return s


@nb.njit(cache=True, error_model="numpy")
def _time_dot(d, ad, count, calls):
    s = 0.0
    for _ in range(calls):
        s += pcg._dot(d, ad, nb.uint64(count))
    return s


@nb.njit(cache=True, error_model="numpy")
def _time_updates(dv, z, d, alpha, beta, calls):
    """The iteration's element-by-element updates of dv and d as
    :func:`bulletnet.solver.pcg.solve` writes them, with ``alpha`` and ``beta``
    (:data:`STILL`: dv stays as it is, d becomes z)."""
    dv_e, z_e, d_e = dv.reshape(-1), z.reshape(-1), d.reshape(-1)
    size = nb.uint64(d_e.shape[0])
    for _ in range(calls):
        for k in range(size):
            dv_e[k] += alpha * d_e[k]
            d_e[k] = z_e[k] + beta * d_e[k]


@nb.njit(cache=True, error_model="numpy")
def _time_sweep(grid, r, z, order, calls):
    """A forward block Gauss-Seidel sweep, (D + L) z = r, over the grid's threads alone (a full
    sweep adds the other threads and the cables): z_i = D_i^-1 (r_i + B_h z_(i-1) + B_v
    z_(i-Ns)), D_i^-1 the factor's inverse blocks, B a thread's block (its off-diagonal entry
    of A is -B), node by node in ``order`` (:func:`wavefront`: node order, a chain, each node
    waiting for its left neighbour; or the grid's anti-diagonals, whose nodes are
    independent: the same operations on the same values, so the same z)."""
    ns, blocks, eh, ev, inv = G.U(grid.ns), grid.blocks, grid.eh, grid.ev, grid.block_inv
    for _ in range(calls):
        for i in order:
            a0, a1, a2 = r[0, i], r[1, i], r[2, i]
            if i % ns > 0:  # the thread from node i - 1, at column Ns + i - 1
                c = ns + i - G.ONE
                w0, w1, w2 = block_product(z[0, i - 1], z[1, i - 1], z[2, i - 1],
                                           blocks[0, c], blocks[1, c], eh[0, c], eh[1, c],
                                           eh[2, c])
                a0, a1, a2 = a0 + w0, a1 + w1, a2 + w2
            if i >= ns:  # the thread from node i - Ns, at column i
                w0, w1, w2 = block_product(z[0, i - ns], z[1, i - ns], z[2, i - ns],
                                           blocks[2, i], blocks[3, i], ev[0, i], ev[1, i],
                                           ev[2, i])
                a0, a1, a2 = a0 + w0, a1 + w1, a2 + w2
            z[0, i] = inv[0, i] * a0 + inv[1, i] * a1 + inv[2, i] * a2
            z[1, i] = inv[3, i] * a0 + inv[4, i] * a1 + inv[5, i] * a2
            z[2, i] = inv[6, i] * a0 + inv[7, i] * a1 + inv[8, i] * a2


def diagonal_rows(grid, r) -> dict:
    """The forward sweep's operands (:func:`_time_sweep`) regathered by anti-diagonals: each
    row + column = d a row of Ns + 1 slots, node (row, column) at slot row + 1, slot 0 and
    the absent nodes zero, one zero diagonal first; so that a node's left neighbour sits in
    the diagonal before at the same slot and its lower neighbour at the slot before, and a
    diagonal's nodes are contiguous. ``rows``: r (3, D, S), the inverse blocks (9, D, S), the
    blocks of the thread from the left and from below, (along, across, e) (5, D, S) each;
    ``position``: each grid node's flat index in a (D, S) row, for the gather and the
    scatter (:func:`_time_regather`)."""
    ns = int(grid.ns)
    nodes = np.arange(ns * ns)
    row, col = nodes // ns, nodes % ns
    diagonals, slots = 2 * ns, ns + 1
    position = (row + col + 1) * slots + row + 1
    rd, inv = np.zeros((3, diagonals * slots)), np.zeros((9, diagonals * slots))
    left, low = np.zeros((5, diagonals * slots)), np.zeros((5, diagonals * slots))
    rd[:, position] = r[:, nodes]
    inv[:, position] = grid.block_inv[:, nodes]
    has = col > 0  # the thread from node i - 1 at column Ns + i - 1
    c = ns + nodes[has] - 1
    left[:, position[has]] = np.vstack([grid.blocks[0, c], grid.blocks[1, c], grid.eh[:, c]])
    has = row > 0  # the thread from node i - Ns at column i
    low[:, position[has]] = np.vstack([grid.blocks[2, nodes[has]], grid.blocks[3, nodes[has]],
                                       grid.ev[:, nodes[has]]])
    shape = (diagonals, slots)
    return {"rd": rd.reshape(3, *shape), "inv": inv.reshape(9, *shape),
            "left": left.reshape(5, *shape), "low": low.reshape(5, *shape),
            "position": position.astype(np.uint64)}


@nb.njit(cache=True, error_model="numpy")
def _time_sweep_diagonals(rd, inv, left, low, y, calls):
    """:func:`_time_sweep` on :func:`diagonal_rows`: diagonal after diagonal, each
    diagonal's slots in one loop over contiguous rows (which vectorizes); the same operations
    on each node in the same order (an absent neighbour's term is a zero block's product,
    and adding it changes nothing)."""
    diagonals, slots = G.U(rd.shape[1]), G.U(rd.shape[2])
    for _ in range(calls):
        for d in range(G.ONE, diagonals):
            p = d - G.ONE
            for k in range(G.ONE, slots):
                a0, a1, a2 = rd[0, d, k], rd[1, d, k], rd[2, d, k]
                w0, w1, w2 = block_product(y[0, p, k], y[1, p, k], y[2, p, k], left[0, d, k],
                                           left[1, d, k], left[2, d, k], left[3, d, k],
                                           left[4, d, k])
                a0, a1, a2 = a0 + w0, a1 + w1, a2 + w2
                j = k - G.ONE
                w0, w1, w2 = block_product(y[0, p, j], y[1, p, j], y[2, p, j], low[0, d, k],
                                           low[1, d, k], low[2, d, k], low[3, d, k],
                                           low[4, d, k])
                a0, a1, a2 = a0 + w0, a1 + w1, a2 + w2
                y[0, d, k] = inv[0, d, k] * a0 + inv[1, d, k] * a1 + inv[2, d, k] * a2
                y[1, d, k] = inv[3, d, k] * a0 + inv[4, d, k] * a1 + inv[5, d, k] * a2
                y[2, d, k] = inv[6, d, k] * a0 + inv[7, d, k] * a1 + inv[8, d, k] * a2


ONE_BUFFER_ROWS = {"sweep": 25, "factor": 28}
"""The rows of each :func:`one_buffer` pass's buffer: for the sweep r 0-2, the inverse
blocks 3-11, the left thread's block 12-16, the lower thread's 17-21 and the result y
22-24; for the factor the diagonal blocks A_ii 0-8, the left thread's block 9-13, the lower
thread's 14-18 and the inverse blocks D^-1 19-27."""


@functools.cache
def one_buffer(slots: int, diagonals: int, kind: str):
    """The forward sweep (``kind`` "sweep", :func:`_time_sweep_diagonals`) or block D-ILU's
    factor ("factor", :func:`_time_dilu_factor`: D = A_ii less the left and the lower
    thread's sandwich of their nodes' D^-1, inverted) on the diagonal rows
    (:func:`diagonal_rows`) in one flat buffer (:data:`ONE_BUFFER_ROWS`), each row
    ``diagonals`` x ``slots`` long, at offsets that are compile-time constants (numba freezes
    a closure's integers), so that the compiler knows every distance between the rows and
    between a slot and the two it waits for (one diagonal's row back) and needs no runtime
    check that the rows do not overlap: diagonal after diagonal, the same operations on each
    node in the same order as node order (an absent neighbour's block is zero, and so is its
    term; the factor's empty slots hold the identity, so every inverse stays finite)."""
    n, s, d_end = slots * diagonals, G.U(slots), G.U(diagonals)
    o = tuple(G.U(row * n) for row in range(max(ONE_BUFFER_ROWS.values())))  # row offsets
    sweep = kind == "sweep"

    @nb.njit(cache=True, error_model="numpy")
    def run(b, calls):
        for _ in range(calls):
            for d in range(G.ONE, d_end):
                for k in range(G.ONE, s):
                    f = d * s + k
                    g = f - s  # the left neighbour's slot
                    h = g - G.ONE  # the lower neighbour's
                    if sweep:
                        a0, a1, a2 = b[o[0] + f], b[o[1] + f], b[o[2] + f]
                        w0, w1, w2 = block_product(
                            b[o[22] + g], b[o[23] + g], b[o[24] + g], b[o[12] + f],
                            b[o[13] + f], b[o[14] + f], b[o[15] + f], b[o[16] + f])
                        a0, a1, a2 = a0 + w0, a1 + w1, a2 + w2
                        w0, w1, w2 = block_product(
                            b[o[22] + h], b[o[23] + h], b[o[24] + h], b[o[17] + f],
                            b[o[18] + f], b[o[19] + f], b[o[20] + f], b[o[21] + f])
                        a0, a1, a2 = a0 + w0, a1 + w1, a2 + w2
                        b[o[22] + f] = b[o[3] + f] * a0 + b[o[4] + f] * a1 + b[o[5] + f] * a2
                        b[o[23] + f] = b[o[6] + f] * a0 + b[o[7] + f] * a1 + b[o[8] + f] * a2
                        b[o[24] + f] = b[o[9] + f] * a0 + b[o[10] + f] * a1 + b[o[11] + f] * a2
                    else:
                        m = (b[o[0] + f], b[o[1] + f], b[o[2] + f], b[o[3] + f], b[o[4] + f],
                             b[o[5] + f], b[o[6] + f], b[o[7] + f], b[o[8] + f])
                        m = _sandwich(m, (b[o[19] + g], b[o[20] + g], b[o[21] + g],
                                          b[o[22] + g], b[o[23] + g], b[o[24] + g],
                                          b[o[25] + g], b[o[26] + g], b[o[27] + g]),
                                      b[o[9] + f], b[o[10] + f], b[o[11] + f], b[o[12] + f],
                                      b[o[13] + f])
                        m = _sandwich(m, (b[o[19] + h], b[o[20] + h], b[o[21] + h],
                                          b[o[22] + h], b[o[23] + h], b[o[24] + h],
                                          b[o[25] + h], b[o[26] + h], b[o[27] + h]),
                                      b[o[14] + f], b[o[15] + f], b[o[16] + f], b[o[17] + f],
                                      b[o[18] + f])
                        m = invert3(m)
                        b[o[19] + f], b[o[20] + f], b[o[21] + f] = m[0], m[1], m[2]
                        b[o[22] + f], b[o[23] + f], b[o[24] + f] = m[3], m[4], m[5]
                        b[o[25] + f], b[o[26] + f], b[o[27] + f] = m[6], m[7], m[8]

    return run


@nb.njit(cache=True, error_model="numpy")
def _time_regather(r, rd, y, z, position, calls):
    """What the diagonal layout costs a sweep if the CG's vectors stay in node order: r
    gathered into its diagonal rows and the result scattered back into z."""
    rf, yf = rd.reshape(3, -1), y.reshape(3, -1)
    for _ in range(calls):
        for a in range(3):
            for i in range(position.shape[0]):
                rf[a, position[i]] = r[a, i]
        for a in range(3):
            for i in range(position.shape[0]):
                z[a, i] = yf[a, position[i]]


def wavefront(ns: int, along_diagonals: bool) -> np.ndarray:
    """The grid's Ns^2 node indices (row-major) in node order, or by anti-diagonals (row +
    column = 0, 1, ..., 2 Ns - 2): an order in which node i still comes after i - 1 and
    i - Ns."""
    nodes = np.arange(ns * ns, dtype=np.uint64)
    if not along_diagonals:
        return nodes
    row, col = nodes // np.uint64(ns), nodes % np.uint64(ns)
    return nodes[np.lexsort((row, row + col))]


@nb.njit(cache=True, error_model="numpy")
def _sandwich(d, x, along, across, e0, e1, e2):
    """d - B X B for 3 x 3 matrices as row-major 9-tuples, X symmetric, B a thread's block
    (along - across) e e^T + across I (:func:`block_product`, column by column, then row by
    row)."""
    y00, y10, y20 = block_product(x[0], x[3], x[6], along, across, e0, e1, e2)
    y01, y11, y21 = block_product(x[1], x[4], x[7], along, across, e0, e1, e2)
    y02, y12, y22 = block_product(x[2], x[5], x[8], along, across, e0, e1, e2)
    z00, z01, z02 = block_product(y00, y01, y02, along, across, e0, e1, e2)
    z10, z11, z12 = block_product(y10, y11, y12, along, across, e0, e1, e2)
    z20, z21, z22 = block_product(y20, y21, y22, along, across, e0, e1, e2)
    return (d[0] - z00, d[1] - z01, d[2] - z02, d[3] - z10, d[4] - z11, d[5] - z12,
            d[6] - z20, d[7] - z21, d[8] - z22)


@nb.njit(cache=True, error_model="numpy")
def _time_dilu_factor(grid, diagonal, out, order, calls):
    """Block D-ILU's factor over the grid's threads (:func:`block_dilu`): D_i = A_ii - B_h
    D_(i-1)^-1 B_h - B_v D_(i-Ns)^-1 B_v, each D_i inverted into ``out`` (9, L), A_ii from
    ``diagonal`` (9, L), node by node in ``order`` (as :func:`_time_sweep`)."""
    ns, blocks, eh, ev = G.U(grid.ns), grid.blocks, grid.eh, grid.ev
    for _ in range(calls):
        for i in order:
            d = (diagonal[0, i], diagonal[1, i], diagonal[2, i], diagonal[3, i],
                 diagonal[4, i], diagonal[5, i], diagonal[6, i], diagonal[7, i],
                 diagonal[8, i])
            if i % ns > 0:  # the thread from node i - 1, at column Ns + i - 1
                c, k = ns + i - G.ONE, i - G.ONE
                d = _sandwich(d, (out[0, k], out[1, k], out[2, k], out[3, k], out[4, k],
                                  out[5, k], out[6, k], out[7, k], out[8, k]),
                              blocks[0, c], blocks[1, c], eh[0, c], eh[1, c], eh[2, c])
            if i >= ns:  # the thread from node i - Ns, at column i
                k = i - ns
                d = _sandwich(d, (out[0, k], out[1, k], out[2, k], out[3, k], out[4, k],
                                  out[5, k], out[6, k], out[7, k], out[8, k]),
                              blocks[2, i], blocks[3, i], ev[0, i], ev[1, i], ev[2, i])
            m = invert3(d)
            for a in range(9):
                out[a, i] = m[a]


@nb.njit(cache=True, error_model="numpy")
def _time_copy(pos, vel, calls, work_pos, work_vel):
    """The state's copy that each timed contact stage starts from."""
    for _ in range(calls):
        work_pos[:] = pos
        work_vel[:] = vel


@nb.njit(cache=True, error_model="numpy")
def _time_self_stage(pos, vel, dv, mass, radius, contact, dt, t, calls, work_pos, work_vel):
    for _ in range(calls):
        work_pos[:] = pos
        work_vel[:] = vel
        self_stage(work_pos, work_vel, dv, mass, radius, contact, dt, t)


STEP_SPAN = 0.5
"""Simulated time [s] over which the whole step is timed, the run loop as a run takes it."""


def step_parts(e, state) -> dict:
    """At the engine's state: the two contact stages, each timed from a copy of the state
    (the copy's own time taken off), and then the whole step: the engine advanced over
    :data:`STEP_SPAN` (the compiled loop, its returns to Python for the debris' dynamics,
    no recording) [us]."""
    a, c, dv, t = e.arrays, e.contact.arrays, e.step_work.dv, state.time
    pos, vel = state.position.copy(), state.velocity.copy()
    work = (np.empty_like(pos), np.empty_like(vel))
    copy = best_us(lambda k: _time_copy(pos, vel, k, *work), 1000)
    debris = best_us(lambda k: debris_stage_calls(pos, vel, dv, a.mass, a.radius, a.fixed, c,
                                                  e.dt, t, k, *work), 1000)
    self_ = best_us(lambda k: _time_self_stage(pos, vel, dv, a.mass, a.radius, c, e.dt, t, k,
                                               *work), 1000)
    return {"debris_stage_us": debris - copy, "self_stage_us": self_ - copy,
            "self_contact_pairs": int(c.pair_meta[0]), **advance_span(e, state)}


def advance_span(e, state) -> dict:
    """The engine advanced over :data:`STEP_SPAN` from the state: its CG iterations a step and
    the step's wall time [us]."""
    steps, iterations, start = e.steps, int(e.work.cg_iterations[0]), time.perf_counter()
    e.advance(state, state.time + STEP_SPAN)
    wall, steps = time.perf_counter() - start, e.steps - steps
    return {"cg_iterations_per_step": (int(e.work.cg_iterations[0]) - iterations) / steps,
            "step_us": 1e6 * wall / steps}


def in_loop_iteration(e, state) -> dict:
    """What one CG iteration costs inside the run's loop [us]: the engine advanced over four
    spans of :data:`STEP_SPAN`, at the scene's tolerance and at one a hundred times tighter in
    turn; each pair of neighbouring spans gives (difference of their steps' times) /
    (difference of their iterations a step). Restores the tolerance."""
    tol, spans = e.cg_tolerance, []
    for tight in (False, True, False, True):
        e.cg_tolerance = tol / 100.0 if tight else tol
        spans.append({"tolerance": e.cg_tolerance, **advance_span(e, state)})
    e.cg_tolerance = tol
    slopes = [(b["step_us"] - a["step_us"])
              / (b["cg_iterations_per_step"] - a["cg_iterations_per_step"])
              for a, b in zip(spans, spans[1:], strict=False)]
    return {"spans": spans, "iteration_us": slopes,
            "iteration_us_median": float(np.median(slopes))}


def _sums(a, count, calls):
    """``calls`` sums of a[:count], in order (compiled as :data:`_chain`) or with the
    additions free to be reordered, vectorized (:data:`_reordered`)."""
    s = 0.0
    for _ in range(calls):
        t = 0.0
        for i in range(count):
            t += a[i]
        s += t
    return s


_chain = nb.njit(error_model="numpy")(_sums)
_reordered = nb.njit(error_model="numpy", fastmath={"reassoc"})(_sums)


def bounds(working_set_bytes: int, count: int) -> dict:
    """The triad's bandwidth over three arrays of ``working_set_bytes`` in all [GB/s], a
    sequential sum's time over ``count`` terms [us] and the same sum's, reordered."""
    bandwidth, arrays = triad_bandwidth(working_set_bytes)
    terms = np.random.default_rng(3).random(count)
    return {"triad_arrays_bytes": arrays, "bandwidth_GB_s": bandwidth,
            "sequential_sum_us": best_us(lambda k: _chain(terms, count, k)),
            "reordered_sum_us": best_us(lambda k: _reordered(terms, count, k))}


def diagonal_parts(grid, r, diagonal, z_node_order, dilu_node_order) -> dict:
    """The forward sweep and block D-ILU's factor on the grid's anti-diagonal rows
    (:func:`diagonal_rows`), timed [us] and checked against node order's results
    (``z_node_order`` (3, L) from :func:`_time_sweep`, ``dilu_node_order`` (9, L) from
    :func:`_time_dilu_factor` on the diagonal blocks ``diagonal``): the sweep on separate
    rows (:func:`_time_sweep_diagonals`) with its gather and scatter
    (:func:`_time_regather`), then the sweep and the factor in one buffer
    (:func:`one_buffer`)."""
    rows, nodes = diagonal_rows(grid, r), int(grid.ns) ** 2
    position = rows["position"]
    diagonals, slots = rows["rd"].shape[1:]
    y, z = np.zeros_like(rows["rd"]), np.zeros_like(r)
    sweep = best_us(lambda k: _time_sweep_diagonals(rows["rd"], rows["inv"], rows["left"],
                                                    rows["low"], y, k))
    regather = best_us(lambda k: _time_regather(r, rows["rd"], y, z, position, k))
    buffer = np.concatenate([rows[name].reshape(k, -1) for name, k in (
        ("rd", 3), ("inv", 9), ("left", 5), ("low", 5))] + [np.zeros((3, diagonals * slots))])
    sweep_flat = one_buffer(slots, diagonals, "sweep")
    flat_us = best_us(lambda k: sweep_flat(buffer.reshape(-1), k))
    identity = np.tile(np.eye(3).reshape(9, 1), diagonals * slots)  # in every empty slot
    blocks = identity.copy()
    blocks[:, position] = diagonal[:, :nodes]
    factor_buffer = np.concatenate([blocks, rows["left"].reshape(5, -1),
                                    rows["low"].reshape(5, -1), identity])
    factor_flat = one_buffer(slots, diagonals, "factor")
    factor_us = best_us(lambda k: factor_flat(factor_buffer.reshape(-1), k))
    expected_z, expected_dilu = z_node_order[:, :nodes], dilu_node_order[:, :nodes]
    return {"gauss_seidel_sweep_us": sweep, "regather_us": regather,
            "same_results_as_node_order": bool(np.array_equal(z[:, :nodes], expected_z)),
            "one_buffer_sweep_us": flat_us,
            "one_buffer_same_results_as_node_order": bool(
                np.array_equal(buffer[-3:][:, position], expected_z)),
            "one_buffer_dilu_factor_us": factor_us,
            "one_buffer_factor_same_as_node_order": bool(
                np.array_equal(factor_buffer[-9:][:, position], expected_dilu))}


def solver_dilu(e, g, r, z, ad) -> dict:
    """The solver's own block D-ILU (``simulation.preconditioner = "block_dilu"``,
    :mod:`bulletnet.solver.dilu`) on the grid's state: its factor (the diagonal blocks, the
    couplings, D^-1, and W and S for the taut cables) and one preconditioning with its sums,
    timed as the solver calls them [us]. Leaves block_inv as block D-ILU's factor wrote it
    (the run's next step factors anew)."""
    grid = g._replace(dilu=dilu_arrays(e.model, g.cables))
    return {"factor_us": best_us(lambda k: _time_factor(grid, k)),
            "preconditioning_and_sums_us": best_us(
                lambda k: _time_preconditioning(grid, r, z, ad, STILL, k)),
            "taut_cables": 0 if g.cables is None else int((g.cables.along > 0).sum())}


class GridParts(At):
    """At the first frame at or after ``at`` [s]: a CG iteration's parts timed on the grid
    path (see the module doc); then stops the run."""

    def act(self, e, state):
        g = e.grid
        per_step = e.work.cg_iterations[0] / e.steps  # the run so far
        count, length = g.count, g.x.shape[1]
        r, z, d, ad = g.cg[0], g.cg[1], g.cg[2], g.cg[3]
        parts = {
            "product": best_us(lambda k: _time_product(g, d, ad, k)),
            "preconditioning_and_sums": best_us(
                lambda k: _time_preconditioning(g, r, z, ad, STILL, k)),
            "dot_d_ad": best_us(lambda k: _time_dot(d, ad, count, k)),
            "updates": best_us(lambda k: _time_updates(g.dv, z, d, STILL, STILL, k)),
        }
        iteration = sum(parts.values())
        traffic = 8 * length * sum(PASS_ROWS.values())
        measured = bounds(traffic, count)
        floor = {"traffic_us": traffic / measured["bandwidth_GB_s"] * 1e-3,
                 "two_sums_us": 2 * measured["sequential_sum_us"]}
        factor = best_us(lambda k: _time_factor(g, k))
        inverse = g.block_inv[:, :count].T.reshape(count, 3, 3)  # (the factor's, just timed)
        diagonal = np.zeros_like(g.block_inv)
        diagonal[:, :count] = np.linalg.inv(inverse).reshape(count, 9).T
        sweeps, factors, results = {}, {}, {}
        for name, along in (("node_order", False), ("wavefront", True)):
            order = wavefront(int(g.ns), along)
            zs, dilu = np.zeros_like(z), np.zeros_like(g.block_inv)
            sweeps[name] = best_us(lambda k, zs=zs, order=order: _time_sweep(g, r, zs, order, k))
            factors[name] = best_us(lambda k, dilu=dilu, order=order: _time_dilu_factor(
                g, diagonal, dilu, order, k))
            results[name] = (zs, dilu)
        same = all(np.array_equal(a, b)
                   for a, b in zip(results["node_order"], results["wavefront"], strict=True))
        in_rows = diagonal_parts(g, r, diagonal, *results["node_order"])
        sweep, dilu_factor = sweeps["node_order"], factors["node_order"]
        in_solver = solver_dilu(e, g, r, z, ad)  # (last of the timings on this state)
        taken = {
            "t_s": state.time, "nodes": count, "row_length": length,
            "cg_iterations_per_step": per_step, "factor_us": factor,
            "iteration_parts_us": parts, "iteration_us": iteration,
            "iteration_bytes": traffic, "bounds": measured, "iteration_floor_us": floor,
            "gauss_seidel_sweep_us": sweep, "dilu_factor_us": dilu_factor,
            "wavefront": {"gauss_seidel_sweep_us": sweeps["wavefront"],
                          "dilu_factor_us": factors["wavefront"],
                          "same_results_as_node_order": same},
            "diagonal_rows": in_rows, "solver_block_dilu": in_solver,
            "cg_per_step_us": iteration * per_step}
        step = step_parts(e, state)  # (last: it advances the run)
        step["cg_us"] = iteration * step["cg_iterations_per_step"] + factor
        step["rest_us"] = (step["step_us"] - step["cg_us"] - step["debris_stage_us"]
                           - step["self_stage_us"])
        return {**taken, "step": step, "in_loop": in_loop_iteration(e, state)}


class PairSystemAt(At):
    """At the first frame at or after ``at`` [s] on the pair list: one implicit increment,
    then the system's matrix [kg] (3N x 3N, node-major) assembled from the solver's product
    (:func:`bulletnet.solver.integrators._apply_blocks` on unit vectors), the warm start and
    the solution; then stops the run."""

    def act(self, e, s):
        a, w = e.arrays, e.step_work
        warm, before = w.dv.copy(), int(w.cg_iterations[0])
        quat, omega = e.rotations(s)  # the bending forces held, as the loop holds them
        integrators.external_forces(s.position, s.velocity, quat, omega, a, w,
                                    e.base_forces(), 0.0, True)
        integrators.implicit_increment(s.position, s.velocity, a, w, e.dt, e.cg_tolerance)
        system = integrators.PairSystem(a.mass, a.fixed, a.pairs, w.along, w.across, w.axis,
                                        w.block_inv, a.cables, None)
        n = s.position.shape[0]
        matrix = np.zeros((3 * n, 3 * n))
        unit, column = np.zeros((n, 3)), np.zeros((n, 3))
        for k in range(3 * n):
            unit.reshape(-1)[k] = 1.0
            integrators._apply_blocks(system, unit, column)
            matrix[:, k] = column.reshape(-1)
            unit.reshape(-1)[k] = 0.0
        cables = a.cables
        return {"matrix": matrix, "warm": warm.reshape(-1),
                "solver_iterations": int(w.cg_iterations[0]) - before,
                "solution": w.dv.copy().reshape(-1), "tol": e.cg_tolerance,
                "nodes_per_side": e.model.nodes_per_side,
                "live_pairs": a.pairs[(w.along != 0.0) | (w.across != 0.0)].copy(),
                "cables": None if cables is None else {
                    name: np.array(getattr(cables, name)) for name in
                    ("nodes", "start", "grad", "along")}}


def pcg_iterations(matrix, b, x0, tol: float, precondition) -> int:
    """Plain preconditioned CG's iterations from x0 to |b - A x| <= tol |b| (at most 5000)."""
    return plain_pcg(matrix, b, x0, tol, precondition)[1]


def plain_pcg(matrix, b, x0, tol: float, precondition) -> tuple:
    """Plain preconditioned CG from x0 to |b - A x| <= tol |b| (at most 5000 iterations):
    the iterate it stops at and its iterations."""
    x = x0.copy()
    r = b - matrix @ x
    z = precondition(r)
    d = z.copy()
    rz, k, goal = r @ z, 0, tol * np.linalg.norm(b)
    while np.linalg.norm(r) > goal and k < 5000:
        ad = matrix @ d
        alpha = rz / (d @ ad)
        x += alpha * d
        r -= alpha * ad
        z = precondition(r)
        rz, previous = r @ z, rz
        d = z + rz / previous * d
        k += 1
    return x, k


def incomplete_cholesky(a) -> np.ndarray:
    """IC(0) of the symmetric positive definite ``a`` (scipy CSR): the lower triangular L,
    dense, with L L^T = a on a's own sparsity pattern (no fill-in)."""
    lower = np.tril(a.toarray())
    pattern = lower != 0.0
    for k in range(lower.shape[0]):
        lower[k, k] = np.sqrt(lower[k, k])
        below = k + 1 + np.nonzero(pattern[k + 1:, k])[0]
        lower[below, k] /= lower[k, k]
        for j in below:  # the update of column j, kept to the pattern
            rows = below[below >= j]
            lower[rows, j] -= np.where(pattern[rows, j], lower[rows, k] * lower[j, k], 0.0)
    return lower


def grid_neighbours(n: int, ns: int) -> list[list[int]]:
    """Each node's lower neighbours over the net grid's threads alone: i - 1 in a row and
    i - Ns (the first Ns^2 nodes, row by row); none for the nodes past the grid."""
    return [[] if i >= ns * ns else
            [k for k in (i - 1, i - ns) if k >= 0 and (k == i - ns or i % ns)]
            for i in range(n)]


def direct_neighbours(n: int, taken: dict) -> list[list[int]]:
    """Each node's lower neighbours over every direct coupling of the system: the threads with
    a live block (the grid's, the corner threads, the tether) and the cables' spans (their
    vertices in a row), not the cables' rank-one couplings between all their vertices."""
    lower = [set() for _ in range(n)]
    edges = [tuple(p) for p in taken["live_pairs"]]
    cables = taken["cables"]
    if cables is not None:
        nodes, start = cables["nodes"], cables["start"]
        edges += [(nodes[v], nodes[v + 1]) for c in range(len(start) - 1)
                  for v in range(start[c], start[c + 1] - 1)]
    for i, j in edges:
        if i != j:
            lower[max(i, j)].add(min(i, j))
    return [sorted(k) for k in lower]


def cable_rank_one(taken: dict, n: int) -> list[tuple[float, np.ndarray]]:
    """The cables' rank-one parts of the system, along_c g_c g_c^T: (along_c [kg], g_c (3N,))
    of each taut cable, g_c its length's gradient over the nodes (a node passed twice gets
    both shares)."""
    cables = taken["cables"]
    if cables is None:
        return []
    parts = []
    for c in range(len(cables["start"]) - 1):
        if cables["along"][c] == 0.0:
            continue
        g = np.zeros((n, 3))
        for v in range(cables["start"][c], cables["start"][c + 1]):
            g[cables["nodes"][v]] += cables["grad"][v]
        parts.append((float(cables["along"][c]), g.reshape(-1)))
    return parts


def block_dilu(matrix, lower: list[list[int]]):
    """Block D-ILU over the couplings ``lower`` (each node's lower neighbours k < i):
    (D + L) D^-1 (D + L^T), L the 3 x 3 blocks of ``matrix`` (3N x 3N, node-major) between
    those neighbours, D_i = A_ii - sum over them of A_ik D_k^-1 A_ki (every other coupling
    only through A_ii): what one forward and one backward block sweep would apply. Returns
    the preconditioner as a function of r."""
    import scipy.sparse as sp
    from scipy.sparse.linalg import splu

    n = matrix.shape[0] // 3
    block = matrix.reshape(n, 3, n, 3)
    diagonal, inverse = np.zeros((n, 3, 3)), np.zeros((n, 3, 3))
    strict = sp.lil_matrix(matrix.shape)
    for i in range(n):
        d = block[i, :, i, :].copy()
        for k in lower[i]:
            d -= block[i, :, k, :] @ inverse[k] @ block[k, :, i, :]
            strict[3 * i:3 * i + 3, 3 * k:3 * k + 3] = block[i, :, k, :]
        diagonal[i], inverse[i] = d, np.linalg.inv(d)
    d = sp.block_diag(list(diagonal), format="csc")
    forward, backward = splu((d + strict).tocsc()), splu((d + strict.T).tocsc())
    return lambda r: backward.solve(d @ forward.solve(r))


def woodbury_dilu(matrix, lower: list[list[int]], rank_one: list[tuple[float, np.ndarray]]):
    """Block D-ILU (:func:`block_dilu`) of the system less its cables' rank-one parts,
    A0 = A - sum_c along_c g_c g_c^T, with those parts added back exactly by the Woodbury
    identity: P^-1 = M0^-1 - W S^-1 W^T, W = M0^-1 G (one forward and backward sweep per taut
    cable, once a step), S = diag(1 / along) + G^T W (C x C). An application is M0^-1's two
    sweeps plus C dot products and C updates over the nodes."""
    if not rank_one:
        return block_dilu(matrix, lower)
    g = np.stack([vector for _, vector in rank_one], axis=1)
    along = np.array([value for value, _ in rank_one])
    base = block_dilu(matrix - g @ np.diag(along) @ g.T, lower)
    w = np.stack([base(g[:, c]) for c in range(g.shape[1])], axis=1)
    s_inv = np.linalg.inv(np.diag(1.0 / along) + g.T @ w)
    return lambda r: (lambda z: z - w @ (s_inv @ (g.T @ z)))(base(r))


def block_jacobi(matrix):
    """Block Jacobi, the solver's preconditioner, as a function of r: each node's 3 x 3
    diagonal block of ``matrix`` (3N x 3N, node-major) inverted."""
    n = matrix.shape[0] // 3
    blocks = np.linalg.inv(matrix.reshape(n, 3, n, 3)[np.arange(n), :, np.arange(n), :])
    return lambda r: np.einsum("nab,nb->na", blocks, r.reshape(n, 3)).reshape(-1)


def preconditioners(taken: dict) -> dict:
    """Iterations by preconditioner, from the warm start and from zero (see module doc)."""
    import scipy.sparse as sp
    from scipy.sparse.linalg import spsolve_triangular

    a = sp.csr_matrix(taken["matrix"])
    b, warm, tol = a @ taken["solution"], taken["warm"], taken["tol"]
    n = a.shape[0] // 3
    lower, upper, diagonal = sp.tril(a, format="csr"), sp.triu(a, format="csr"), a.diagonal()
    factor = sp.csr_matrix(incomplete_cholesky(a))
    direct = direct_neighbours(n, taken)
    factor_t = factor.T.tocsr()
    methods = {
        "block_jacobi": block_jacobi(taken["matrix"]),
        "symmetric_gauss_seidel": lambda r: spsolve_triangular(
            upper, diagonal * spsolve_triangular(lower, r, lower=True), lower=False),
        "incomplete_cholesky": lambda r: spsolve_triangular(
            factor_t, spsolve_triangular(factor, r, lower=True), lower=False),
        "block_dilu_grid_threads": block_dilu(taken["matrix"],
                                              grid_neighbours(n, taken["nodes_per_side"])),
        "block_dilu_direct_couplings": block_dilu(taken["matrix"], direct),
        "block_dilu_direct_couplings_woodbury_cables": woodbury_dilu(
            taken["matrix"], direct, cable_rank_one(taken, n)),
    }
    try:
        import pyamg
    except ImportError:
        pyamg = None
    if pyamg is not None:  # pyamg's smoothing (Gauss-Seidel), and block Jacobi's (vectorizes)
        for name, smoother in (("smoothed_aggregation_amg", {}),
                               ("smoothed_aggregation_amg_block_jacobi_smoothing", {
                                   "presmoother": ("block_jacobi", {"blocksize": 3}),
                                   "postsmoother": ("block_jacobi", {"blocksize": 3})})):
            solver = pyamg.smoothed_aggregation_solver(
                a, B=np.kron(np.ones((n, 1)), np.eye(3)), max_coarse=30, **smoother)
            methods[name] = solver.aspreconditioner(cycle="V").matvec
    relative = np.linalg.norm(b - a @ warm) / np.linalg.norm(b)
    return {"warm_start_relative_residual": relative, "tolerance": tol,
            "solver_iterations": taken["solver_iterations"], "iterations": {
        name: {"warm": pcg_iterations(a, b, warm, tol, f),
               "zero": pcg_iterations(a, b, np.zeros_like(b), tol, f)}
        for name, f in methods.items()}}


def dilu_estimate(case: dict, cables: int) -> dict:
    """A CG step with block D-ILU on the grid's threads, estimated from the parts timed
    alone [us]: an iteration is a forward and a backward sweep (each the forward sweep's
    time), the product, d . A d, the updates and the sums r . z and r . r (two sequential
    chains); a step, the iterations from the warm start times that plus the factor; the same
    with the sweeps and the factor in wavefront order. Beside it the block-Jacobi step from
    the same parts, and the step with the ``cables`` taut cables' rank-one parts added back by
    Woodbury (:func:`woodbury_dilu`, its iterations): each cable adds two sweeps to the factor
    and to an iteration a dot product over its vertices (a few dozen) and an update of z over
    every node, counted as half of the iteration's two updates; that step also with each
    sweep on the diagonal rows (:func:`_time_sweep_diagonals`; the factor in wavefront
    order, scalar), and on them in one buffer (:func:`one_buffer`, the factor too), each
    sweep plus its gather and scatter; first, the step with the solver's own block D-ILU
    (``solver_step_us``: :func:`solver_dilu`'s factor, and per iteration its
    preconditioning, the product, d . A d and the updates)."""
    parts, bound = case["iteration_parts_us"], case["bounds"]["sequential_sum_us"]
    rest = parts["product"] + parts["dot_d_ad"] + parts["updates"] + 2 * bound
    iteration = 2 * case["gauss_seidel_sweep_us"] + rest
    wave = case["wavefront"]
    wave_iteration = 2 * wave["gauss_seidel_sweep_us"] + rest
    rows = case["diagonal_rows"]
    vector = rows["gauss_seidel_sweep_us"] + rows["regather_us"]
    one_buffer = rows["one_buffer_sweep_us"] + rows["regather_us"]
    taken = case["preconditioners"]["iterations"]
    dilu, jacobi = taken["block_dilu_grid_threads"]["warm"], taken["block_jacobi"]["warm"]
    woodbury = taken["block_dilu_direct_couplings_woodbury_cables"]["warm"]
    extra = cables * parts["updates"] / 2.0
    solver = case["solver_block_dilu"]
    return {"solver_step_us": woodbury * (solver["preconditioning_and_sums_us"]
                                          + parts["product"] + parts["dot_d_ad"]
                                          + parts["updates"]) + solver["factor_us"],
            "iteration_us": iteration, "iterations": dilu,
            "step_us": dilu * iteration + case["dilu_factor_us"],
            "wavefront_iteration_us": wave_iteration,
            "wavefront_step_us": dilu * wave_iteration + wave["dilu_factor_us"],
            "block_jacobi_iterations": jacobi,
            "block_jacobi_step_us": jacobi * case["iteration_us"] + case["factor_us"],
            "woodbury_cables": cables, "woodbury_iterations": woodbury,
            "woodbury_step_us": woodbury * (iteration + extra) + case["dilu_factor_us"]
            + 2 * cables * case["gauss_seidel_sweep_us"],
            "woodbury_wavefront_step_us": woodbury * (wave_iteration + extra)
            + wave["dilu_factor_us"] + 2 * cables * wave["gauss_seidel_sweep_us"],
            "woodbury_diagonal_rows_step_us": woodbury * (2 * vector + rest + extra)
            + wave["dilu_factor_us"] + 2 * cables * vector,
            "woodbury_one_buffer_step_us": woodbury * (2 * one_buffer + rest + extra)
            + rows["one_buffer_dilu_factor_us"] + 2 * cables * one_buffer}


def main() -> int:
    p = parser(__doc__.split("\n\n")[0])
    p.add_argument("--capture-at", type=float, default=10.0, help="snapshot time [s]")
    p.add_argument("--closing-at", type=float, default=30.0, help="snapshot time [s]")
    args = p.parse_args()
    out = output_dir(args)
    yard = Yardsticks()
    yard.time()
    # the run, its iteration parts and its step timed with block Jacobi whatever the scene's
    # preconditioner; block D-ILU is timed on the same state beside it (solver_dilu)
    jacobi = {"simulation.preconditioner": "block_jacobi"}
    cases = {"capture_bending": ("capture", {"bending.enabled": True, **jacobi},
                                 args.capture_at),
             "capture_closing": ("capture_closing", jacobi, args.closing_at)}
    doc = {"machine": machine(), "cases": {}}
    for name, (scene_name, overrides, at) in cases.items():
        scene = bn.load_scenario(scene_name, {**overrides, "scene.duration": at + 3.0})
        parts = GridParts(at)
        bn.run(scene, None, observers=[parts])
        system = PairSystemAt(at)
        bn.run(scene.with_overrides({"simulation.kernels": "pairs"}), None,
               observers=[system])
        doc["cases"][name] = {"scene": scene_name, "overrides": overrides, **parts.taken,
                              "preconditioners": preconditioners(system.taken)}
        cables = len(cable_rank_one(system.taken, system.taken["warm"].size // 3))
        doc["cases"][name]["block_dilu_estimate"] = dilu_estimate(doc["cases"][name], cables)
        print(f"{name}: {json.dumps(doc['cases'][name], indent=1)}", flush=True)
    yard.time()
    doc["yardsticks"] = yard.doc()
    (out / "cg_step.json").write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
