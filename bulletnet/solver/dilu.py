"""Block D-ILU preconditioning of the implicit Euler step's system, the closing cables'
rank-one parts added back by the Woodbury identity: the ``block_dilu`` choice of
``simulation.preconditioner`` (:func:`bulletnet.solver.pcg.solve`; the default,
``block_jacobi``, inverts each node's diagonal block alone).

The system A = M + dt C + dt^2 K couples two nodes directly through a thread (its block B =
(along - across) e e^T + across I, A_ij = -B) or a cable's span (B = across (I - e e^T)), and
all of a cable's vertices at once through its rank-one part along_c g_c g_c^T (the cable's
length gradient, :mod:`bulletnet.kernels.cable`). Let A0 be A less those rank-one parts. Its
block D-ILU, in an elimination order of the nodes, is

    M0 = (D + L) D^-1 (D + L^T),   D_i = A0_ii - sum_(j < i) A_ij D_j^-1 A_ji,

L the strictly lower blocks of the direct couplings (j < i: earlier in the order). Applying
M0^-1 is a forward and a backward sweep, y_i = D_i^-1 (r_i + sum_(j<i) B_ij y_j), then z_i =
y_i + D_i^-1 sum_(j>i) B_ij z_j. The preconditioner is P = M0 + sum_c along_c g_c g_c^T,
applied exactly by Woodbury: P^-1 r = z0 - W S^-1 G^T z0 with z0 = M0^-1 r, W = M0^-1 G (one
pair of sweeps per taut cable, once a step) and S = diag(1 / along) + G^T W (C x C, by
Cholesky). P is symmetric positive definite where the D_i are; it is exact on a chain and
takes the net's closing capture from block Jacobi's 27 CG iterations to 4
(``benchmarks/cg_step.py``, docs/speed.md).

The order: a net's Ns x Ns grid nodes by anti-diagonals (row + column, then row; each node
after its left and lower neighbours, as in row-major order, but consecutive nodes of one
diagonal are independent, so the sweeps' chains overlap), then every other node in index
order; clamped nodes are left out (their rows are the identity, z = 0 there), with their
couplings.

Both layouts of the state call the same kernels on component rows (3, >= N), with the same
values in the same order: the grid's rows, the pair list's transposes; so the two paths keep
agreeing bit for bit.
"""

from __future__ import annotations

from typing import NamedTuple

import numba as nb
import numpy as np

from ..kernels import U
from ..kernels.axial import add_block, invert3
from ..kernels.cable import CableArrays
from ..model.net import NetModel
from ..model.topology import grid_places, grid_threads
from . import pcg

ONE = U(1)


class DiluArrays(NamedTuple):
    """The couplings of a net's implicit system in an elimination order (:func:`dilu_arrays`)
    and the preconditioner's scratch, for N nodes, R of them not clamped (ranked: their place
    in the order), E direct couplings, P threads, V cable vertices and C cables. A coupling is
    numbered by its entry in the lower lists, so the forward sweep reads the blocks in
    sequence."""

    rank_node: np.ndarray
    """The node at each rank [-], shape (R,), int64."""
    lower_start: np.ndarray
    """Each rank's first entry in lower_rank, then its length E [-], shape (R + 1,), int64."""
    lower_rank: np.ndarray
    """The ranks coupled to it earlier in the order, ascending [-], shape (E,), int64;
    entry q is coupling q."""
    upper_start: np.ndarray
    """Each rank's first entry in upper_rank, then E [-], shape (R + 1,), int64."""
    upper_rank: np.ndarray
    """The ranks coupled to it later in the order, ascending [-], shape (E,), int64."""
    upper_edge: np.ndarray
    """The coupling of each [-], shape (E,), int64."""
    thread_edge: np.ndarray
    """Each thread's coupling, -1 for none (an end clamped) [-], shape (P,), int64."""
    span_edge: np.ndarray
    """The coupling of the cable span from each vertex to the next, -1 for none (a cable's
    last vertex, an end clamped) [-], shape (V,), int64."""
    vertex_rank: np.ndarray
    """Each cable vertex's node's rank, -1 for a clamped node [-], shape (V,), int64."""
    grid_row: np.ndarray
    """For the grid's stencils: each of the first 2 Ns (Ns - 1) threads' row of the grid's
    blocks (0: a row thread, 2: a column thread) [-], shape (P_grid,), int64."""
    grid_column: np.ndarray
    """... and its column, Ns + its first node [-], shape (P_grid,), int64."""
    off: np.ndarray
    """Each coupling's block B, row-major [kg], shape (E, 9)."""
    inv: np.ndarray
    """D^-1 at each rank, row-major [1/kg], shape (R, 9)."""
    y: np.ndarray
    """The vector being swept, by rank [m/s once swept], shape (R, 3)."""
    along: np.ndarray
    """The threads' implicit blocks along [kg], (P,), gathered from the grid's rows."""
    across: np.ndarray
    """... across [kg], (P,)."""
    axis: np.ndarray
    """... and their unit directions [-], shape (P, 3)."""
    w: np.ndarray
    """W = M0^-1 g_c of each cable by rank [1/kg], shape (C, R, 3) (zero for a slack
    cable)."""
    s: np.ndarray
    """The lower Cholesky factor of S [kg^-1/2], shape (C, C)."""
    t: np.ndarray
    """Scratch: L^-1 G^T z0, then S^-1 G^T z0 [kg m/s], shape (C,)."""


def elimination_order(model: NetModel) -> np.ndarray:
    """The nodes in the preconditioner's elimination order (see the module doc), clamped
    nodes left out [-], shape (R,), int64."""
    ns, nodes = model.nodes_per_side, np.arange(model.node_count)
    if grid_threads(ns, model.node_count, model.pairs):
        grid = np.arange(ns * ns)
        row, col = grid // ns, grid % ns
        nodes = np.concatenate([grid[np.lexsort((row, row + col))], nodes[ns * ns:]])
    return nodes[~model.fixed[nodes]].astype(np.int64)


def dilu_arrays(model: NetModel, cables: CableArrays | None) -> DiluArrays:
    """The couplings of ``model``'s threads and ``cables``' spans (None: none) in
    :func:`elimination_order`, and zeroed scratch."""
    order = elimination_order(model)
    rank = np.full(model.node_count, -1)
    rank[order] = np.arange(order.size)
    pairs = [(int(i), int(j)) for i, j in model.pairs]
    spans = [] if cables is None else [
        (int(cables.nodes[v]), int(cables.nodes[v + 1])) if v + 1 < cables.start[c + 1] else (0, 0)
        for c in range(cables.start.size - 1) for v in range(cables.start[c], cables.start[c + 1])]
    # each coupling as (later rank, earlier rank): the lower lists sorted
    couplings = sorted({tuple(sorted((int(rank[i]), int(rank[j])), reverse=True))
                        for i, j in pairs + spans if i != j and rank[i] >= 0 and rank[j] >= 0})
    entry = {pair: q for q, pair in enumerate(couplings)}

    def edge(i: int, j: int) -> int:
        if i == j or rank[i] < 0 or rank[j] < 0:
            return -1
        return entry[tuple(sorted((int(rank[i]), int(rank[j])), reverse=True))]

    later = np.array([k for k, _ in couplings], dtype=np.int64)
    earlier = np.array([k for _, k in couplings], dtype=np.int64)
    up = np.lexsort((later, earlier))  # the upper lists: by earlier rank, then later
    r_count = order.size
    inner = grid_threads(model.nodes_per_side, model.node_count, model.pairs)
    direction, column = grid_places(model.pairs[:inner], model.nodes_per_side)
    c_count = 0 if cables is None else cables.rest.size
    p = model.thread_count
    return DiluArrays(
        rank_node=order.astype(np.int64),
        lower_start=np.searchsorted(later, np.arange(r_count + 1)).astype(np.int64),
        lower_rank=earlier,
        upper_start=np.searchsorted(earlier[up], np.arange(r_count + 1)).astype(np.int64),
        upper_rank=later[up], upper_edge=up.astype(np.int64),
        thread_edge=np.array([edge(i, j) for i, j in pairs], dtype=np.int64),
        span_edge=np.array([edge(i, j) for i, j in spans], dtype=np.int64),
        vertex_rank=(np.zeros(0, dtype=np.int64) if cables is None
                     else rank[cables.nodes].astype(np.int64)),
        grid_row=2 * direction, grid_column=column,
        off=np.zeros((len(couplings), 9)), inv=np.zeros((r_count, 9)),
        y=np.zeros((r_count, 3)), along=np.zeros(p), across=np.zeros(p), axis=np.zeros((p, 3)),
        w=np.zeros((c_count, r_count, 3)), s=np.zeros((c_count, c_count)),
        t=np.zeros(c_count))


@nb.njit(cache=True, error_model="numpy", inline="always")
def _row(a, i):
    """Row i of a (., 9) array as a 9-tuple."""
    return (a[i, 0], a[i, 1], a[i, 2], a[i, 3], a[i, 4], a[i, 5], a[i, 6], a[i, 7], a[i, 8])


@nb.njit(cache=True, error_model="numpy", inline="always")
def _put(a, i, m):
    """Row i of a (., 9) array <- the 9-tuple m."""
    a[i, 0], a[i, 1], a[i, 2], a[i, 3], a[i, 4] = m[0], m[1], m[2], m[3], m[4]
    a[i, 5], a[i, 6], a[i, 7], a[i, 8] = m[5], m[6], m[7], m[8]


@nb.njit(cache=True, error_model="numpy", inline="always")
def _times(m, x0, x1, x2):
    """The 3 x 3 matrix m (row-major 9-tuple) times (x0, x1, x2)."""
    return (m[0] * x0 + m[1] * x1 + m[2] * x2, m[3] * x0 + m[4] * x1 + m[5] * x2,
            m[6] * x0 + m[7] * x1 + m[8] * x2)


@nb.njit(cache=True, error_model="numpy")
def _less_sandwich(m, b, d):
    """m - b d b for 3 x 3 matrices as row-major 9-tuples (b symmetric: A_ij D_j^-1 A_ji)."""
    c0, c1, c2 = _times(d, b[0], b[3], b[6])  # d times b's columns
    c3, c4, c5 = _times(d, b[1], b[4], b[7])
    c6, c7, c8 = _times(d, b[2], b[5], b[8])
    r0, r1, r2 = _times(b, c0, c1, c2)  # b times them: the columns of b d b
    r3, r4, r5 = _times(b, c3, c4, c5)
    r6, r7, r8 = _times(b, c6, c7, c8)
    return (m[0] - r0, m[1] - r3, m[2] - r6, m[3] - r1, m[4] - r4, m[5] - r7,
            m[6] - r2, m[7] - r5, m[8] - r8)


@nb.njit(cache=True, error_model="numpy")
def gather_grid_threads(dilu, blocks, eh, ev, o_along, o_across, o_axis):
    """The grid's threads' implicit blocks into dilu's along, across and axis in the pair
    list's thread order: the grid threads' from their rows (``blocks`` (4, W), axes ``eh``,
    ``ev`` (3, W); a slack thread's across read as zero, as its diagonal entries are), then the
    other threads' (Q,)."""
    rows, columns = dilu.grid_row, dilu.grid_column
    along, across, axis = dilu.along, dilu.across, dilu.axis
    inner = rows.shape[0]
    for p in range(inner):
        row, col = rows[p], columns[p]
        e = eh if row == 0 else ev
        on = blocks[row, col] != 0.0
        along[p] = blocks[row, col]
        across[p] = blocks[row + 1, col] if on else 0.0
        axis[p, 0], axis[p, 1], axis[p, 2] = e[0, col], e[1, col], e[2, col]
    for q in range(o_along.shape[0]):
        along[inner + q], across[inner + q] = o_along[q], o_across[q]
        axis[inner + q, 0], axis[inner + q, 1] = o_axis[q, 0], o_axis[q, 1]
        axis[inner + q, 2] = o_axis[q, 2]


@nb.njit(cache=True, error_model="numpy")
def _couplings(dilu, along, across, axis, cables):
    """Each coupling's block B [kg] into dilu's off: its threads' blocks (thread order; a slack
    one skipped), then its cable spans' (vertex order; span_edge has an entry, -1, for each
    cable's last vertex too)."""
    off = dilu.off
    off[:] = 0.0
    thread_edge = dilu.thread_edge
    for p in range(thread_edge.shape[0]):
        e = thread_edge[p]
        if e < 0 or (along[p] == 0.0 and across[p] == 0.0):
            continue
        _put(off, e, add_block(_row(off, e), along[p], across[p], axis[p, 0], axis[p, 1],
                               axis[p, 2]))
    if cables is None:
        return
    span_edge, span_across, span_axis = dilu.span_edge, cables.across, cables.axis
    for v in range(span_edge.shape[0]):
        e = span_edge[v]
        if e < 0 or span_across[v] == 0.0:
            continue
        _put(off, e, add_block(_row(off, e), 0.0, span_across[v], span_axis[v, 0],
                               span_axis[v, 1], span_axis[v, 2]))


@nb.njit(cache=True, error_model="numpy")
def _sweeps(dilu, y):
    """y <- M0^-1 y, by rank (R, 3): the forward sweep, then the backward, in place (indices
    unsigned: no wraparound checks, :data:`bulletnet.kernels.U`)."""
    off, inv = dilu.off, dilu.inv
    start, earlier = dilu.lower_start, dilu.lower_rank
    ranks = U(y.shape[0])
    for k in range(ranks):
        a0, a1, a2 = y[k, 0], y[k, 1], y[k, 2]
        for q in range(U(start[k]), U(start[k + ONE])):
            j = U(earlier[q])
            b0, b1, b2 = _times(_row(off, q), y[j, 0], y[j, 1], y[j, 2])
            a0, a1, a2 = a0 + b0, a1 + b1, a2 + b2
        y[k, 0], y[k, 1], y[k, 2] = _times(_row(inv, k), a0, a1, a2)
    start, later, edge = dilu.upper_start, dilu.upper_rank, dilu.upper_edge
    for step in range(ranks):
        k = ranks - ONE - step
        first, last = U(start[k]), U(start[k + ONE])
        if first == last:
            continue
        a0 = a1 = a2 = 0.0
        for q in range(first, last):
            j = U(later[q])
            b0, b1, b2 = _times(_row(off, U(edge[q])), y[j, 0], y[j, 1], y[j, 2])
            a0, a1, a2 = a0 + b0, a1 + b1, a2 + b2
        b0, b1, b2 = _times(_row(inv, k), a0, a1, a2)
        y[k, 0] += b0
        y[k, 1] += b1
        y[k, 2] += b2


@nb.njit(cache=True, error_model="numpy")
def _gradient_dot(dilu, cables, c, y):
    """g_c . y over cable c's vertices (y by rank; a node passed twice counted twice, as g_c
    sums its shares; a clamped node not at all)."""
    grad, vertex_rank = cables.grad, dilu.vertex_rank
    s = 0.0
    for v in range(cables.start[c], cables.start[c + 1]):
        k = vertex_rank[v]
        if k >= 0:
            s += grad[v, 0] * y[k, 0] + grad[v, 1] * y[k, 1] + grad[v, 2] * y[k, 2]
    return s


@nb.njit(cache=True, error_model="numpy")
def factor(dilu, diagonal, along, across, axis, cables):
    """Block D-ILU's factor: the couplings' blocks from the threads' ``along``, ``across`` [kg]
    and ``axis`` [-] (P,) and the cables' spans, then D_i^-1 node after node in the order
    from A0's diagonal blocks ``diagonal`` [kg] (9, >= N) (row-major entries by component
    row); then, with taut cables, W and S's Cholesky factor (see the module doc)."""
    _couplings(dilu, along, across, axis, cables)
    order, off, inv = dilu.rank_node, dilu.off, dilu.inv
    start, earlier = dilu.lower_start, dilu.lower_rank
    for k in range(U(order.shape[0])):
        i = U(order[k])
        m = (diagonal[0, i], diagonal[1, i], diagonal[2, i], diagonal[3, i], diagonal[4, i],
             diagonal[5, i], diagonal[6, i], diagonal[7, i], diagonal[8, i])
        for q in range(U(start[k]), U(start[k + ONE])):
            m = _less_sandwich(m, _row(off, q), _row(inv, U(earlier[q])))
        _put(inv, k, invert3(m))
    if cables is None:
        return
    w, s, vertex_rank = dilu.w, dilu.s, dilu.vertex_rank
    count = cables.rest.shape[0]
    w[:] = 0.0
    for c in range(count):
        if cables.along[c] == 0.0:
            continue
        g = w[c]  # g_c, then M0^-1 g_c in its place
        for v in range(cables.start[c], cables.start[c + 1]):
            k = vertex_rank[v]
            if k >= 0:
                for a in range(3):
                    g[k, a] += cables.grad[v, a]
        _sweeps(dilu, g)
    for c in range(count):  # S = diag(1 / along) + G^T W, then its Cholesky factor
        for d in range(count):
            if cables.along[c] == 0.0 or cables.along[d] == 0.0:
                s[c, d] = 1.0 if c == d else 0.0
            else:
                s[c, d] = _gradient_dot(dilu, cables, c, w[d]) + (1.0 / cables.along[c]
                                                                  if c == d else 0.0)
    for c in range(count):
        for d in range(c + 1):
            x = s[c, d]
            for e in range(d):
                x -= s[c, e] * s[d, e]
            s[c, d] = np.sqrt(x) if c == d else x / s[d, d]


@nb.njit(cache=True, error_model="numpy")
def precondition(dilu, r, z, ad, alpha, count, cables):
    """r [kg m/s] <- r - ``alpha`` [-] ad, then z [m/s] = P^-1 r (zero on clamped nodes),
    over nodes 0 .. ``count`` - 1 of component rows (3, >= N); returns r . z and r . r summed
    in node order (:func:`bulletnet.solver.pcg.dot_terms`)."""
    count = U(count)
    for a in range(U(3)):
        for i in range(count):
            r[a, i] = r[a, i] - alpha * ad[a, i]
    order, y = dilu.rank_node, dilu.y
    ranks = U(order.shape[0])
    for k in range(ranks):
        i = U(order[k])
        y[k, 0], y[k, 1], y[k, 2] = r[0, i], r[1, i], r[2, i]
    _sweeps(dilu, y)
    if cables is not None:
        w, s, t = dilu.w, dilu.s, dilu.t
        n_c = t.shape[0]
        for c in range(n_c):  # t = L^-1 G^T z0 (forward substitution)
            x = _gradient_dot(dilu, cables, c, y) if cables.along[c] != 0.0 else 0.0
            for e in range(c):
                x -= s[c, e] * t[e]
            t[c] = x / s[c, c]
        for c in range(n_c - 1, -1, -1):  # t = L^-T t: S^-1 G^T z0
            x = t[c]
            for e in range(c + 1, n_c):
                x -= s[e, c] * t[e]
            t[c] = x / s[c, c]
        flat = y.reshape(-1)
        for c in range(n_c):
            if cables.along[c] == 0.0:
                continue
            u, wc = t[c], w[c].reshape(-1)
            for k in range(U(flat.shape[0])):
                flat[k] -= u * wc[k]
    if ranks < count:
        for a in range(U(3)):
            for i in range(count):
                z[a, i] = 0.0
    for k in range(ranks):
        i = U(order[k])
        z[0, i], z[1, i], z[2, i] = y[k, 0], y[k, 1], y[k, 2]
    rz = rr = 0.0
    for i in range(count):
        tz, tr = pcg.dot_terms(r[0, i], r[1, i], r[2, i], z[0, i], z[1, i], z[2, i])
        rz += tz
        rr += tr
    return rz, rr
