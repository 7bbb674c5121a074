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
diagonal are independent), then every other node in index order; clamped nodes are left out
(their rows are the identity, z = 0 there), with their couplings.

Where the grid's nodes are coupled only to their row and column neighbours (and each to at
most one node past the grid), the sweeps run over them in a folded layout: slot row d, slot i
holds node (row i, column (d - i) mod Ns), so slot row d carries diagonal d in its slots 0 .. d
and diagonal d + Ns in the rest. Every node's earlier neighbours then lie one slot row back,
at the same slot (the left one) and the slot before (the lower one), the whole grid in Ns^2
slots with no gaps, and each diagonal's part of a slot row is one loop whose nodes are
independent: it vectorizes, the distances between the rows being compile-time constants
(the length of :attr:`DiluArrays.slots`). The nodes' terms are added in the order of the
sweeps by rank, so the layout changes no bit. Every other node is swept by rank.

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

Y, PAST, INV, LOW, LEFT = 0, 3, 6, 15, 24
"""The first row of each quantity in :attr:`DiluArrays.fold` (33 rows)."""


@nb.njit(cache=True, error_model="numpy", inline="always")
def fold_length(ns):
    """The length of a row of the folded layout for an Ns x Ns grid [-]: Ns + 2 padding slots
    before the Ns^2 nodes' (the lower neighbour of a first slot lies Ns + 1 back), Ns + 1
    after (the upper neighbour of a last slot lies Ns + 1 ahead)."""
    return ns * ns + 2 * ns + 3


@nb.njit(cache=True, error_model="numpy", inline="always")
def _fold_shape(dilu):
    """Ns of the folded grid (0 without a fold), the length of the folded layout's rows and F,
    the folded ranks' count, all compile-time constants (the length of dilu.slots)."""
    ns = U(len(dilu.slots))
    return ns, fold_length(ns), ns * ns


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
    """Each coupling's block B, row-major [kg], shape (E, 9) (zero for a coupling between two
    folded ranks: its block is kept in ``fold``)."""
    inv: np.ndarray
    """D^-1 at each rank, row-major [1/kg], shape (R, 9) (unused at the first F ranks: theirs
    is kept in ``fold``)."""
    slots: tuple
    """Ns zeros where the grid's nodes are swept in the folded layout (module doc), else ()
    (F = Ns^2 of the R ranks there, the first F; none without it): its length is a
    compile-time constant of the sweeps."""
    rank_slot: np.ndarray
    """Each rank's place: for the first F, its slot in the folded layout, for the others,
    its row of ``tail`` [-], shape (R,), int64."""
    coupling_row: np.ndarray
    """The first of the nine rows of ``fold`` that hold each coupling's block at its later
    node's slot (:data:`LOW` or :data:`LEFT`), -1 for a coupling not between two of the
    first F ranks [-], shape (E,), int64."""
    coupling_slot: np.ndarray
    """... and that slot [-], shape (E,), int64."""
    fold_columns: np.ndarray
    """For the grid path, at each folded slot (in slot order): the column of the grid's rows
    of its left neighbour's row thread, then of its lower neighbour's column thread, -1 for
    none [-], shape (2, F), int64."""
    past_grid: np.ndarray
    """Each of the first F ranks' entry in the upper lists of its coupling to a rank past
    them, -1 for none [-], shape (F,), int64."""
    fold: np.ndarray
    """The folded layout's rows, each :func:`fold_length` long, one after another: the vector
    being swept (3: :data:`Y`; [m/s once swept]), the terms from past the grid in the
    backward sweep (3: :data:`PAST`), D^-1 (9: :data:`INV`), the lower and the left
    neighbour's coupling block (9 each: :data:`LOW`, :data:`LEFT`); zero on the padding
    slots; shape (33 x fold_length,)."""
    tail: np.ndarray
    """The vector being swept at the other ranks, in rank order [m/s once swept], shape
    (R - F, 3)."""
    along: np.ndarray
    """The threads' implicit blocks along [kg], (P,) (on the grid path, the other threads'
    alone, gathered: :func:`gather_other_threads`)."""
    across: np.ndarray
    """... across [kg], (P,)."""
    axis: np.ndarray
    """... and their unit directions [-], shape (P, 3)."""
    w_fold: np.ndarray
    """W = M0^-1 g_c of each cable, its folded part as ``fold``'s first three rows [1/kg],
    shape (C, 3 x fold_length) (zero for a slack cable) ..."""
    w_tail: np.ndarray
    """... and its part at the other ranks, as ``tail`` [1/kg], shape (C, R - F, 3)."""
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
    fold = _fold(model, order, later, earlier, up)
    f_count, length = len(fold["slots"]) ** 2, fold_length(len(fold["slots"]))
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
        off=np.zeros((len(couplings), 9)), inv=np.zeros((r_count, 9)), **fold,
        fold=np.zeros(33 * length), tail=np.zeros((r_count - f_count, 3)),
        along=np.zeros(p), across=np.zeros(p), axis=np.zeros((p, 3)),
        w_fold=np.zeros((c_count, 3 * length)),
        w_tail=np.zeros((c_count, r_count - f_count, 3)), s=np.zeros((c_count, c_count)),
        t=np.zeros(c_count))


def no_fold(r_count: int, e_count: int) -> dict:
    """:func:`_fold`'s fields without a fold, for R ranks and E couplings: every rank swept by
    rank, in ``tail``."""
    return {"slots": (), "rank_slot": np.arange(r_count, dtype=np.int64),
            "coupling_row": np.full(e_count, -1, dtype=np.int64),
            "coupling_slot": np.zeros(e_count, dtype=np.int64),
            "fold_columns": np.zeros((2, 0), dtype=np.int64),
            "past_grid": np.zeros(0, dtype=np.int64)}


def _fold(model: NetModel, order: np.ndarray, later: np.ndarray, earlier: np.ndarray,
          up: np.ndarray) -> dict:
    """:class:`DiluArrays`' fields of the folded layout (slots, rank_slot, coupling_row,
    coupling_slot, fold_columns, past_grid): for a net whose first ranks are its Ns x Ns grid
    nodes, none clamped, coupled among themselves only to their row and column neighbours and
    each to at most one node past the grid; otherwise no fold (every rank swept by rank)."""
    ns, r_count = model.nodes_per_side, order.size
    none = no_fold(r_count, later.size)
    n = ns * ns
    if not grid_threads(ns, model.node_count, model.pairs) or model.fixed[:n].any():
        return none
    node = order[:n]
    row, col = node // ns, node % ns
    rank_slot = np.concatenate([ns + 2 + (row + col) % ns * ns + row,
                                np.arange(r_count - n)]).astype(np.int64)
    coupling_row = np.full(later.size, -1, dtype=np.int64)
    for q, (k, j) in enumerate(zip(later, earlier, strict=True)):
        if k >= n:
            continue
        if order[j] == order[k] - ns:
            coupling_row[q] = LOW
        elif order[j] == order[k] - 1 and order[k] % ns:
            coupling_row[q] = LEFT
        else:
            return none
    coupling_slot = np.where(later < n, rank_slot[later], 0)
    past_grid = np.full(n, -1, dtype=np.int64)
    for position, q in enumerate(up):
        if earlier[q] < n <= later[q]:
            if past_grid[earlier[q]] >= 0:
                return none
            past_grid[earlier[q]] = position
    at = np.empty(n, dtype=np.int64)  # the node at each folded slot
    at[rank_slot[:n] - ns - 2] = node
    fold_columns = np.stack([np.where(at % ns > 0, ns + at - 1, -1),  # grid_places' columns
                             np.where(at >= ns, at, -1)]).astype(np.int64)
    return {"slots": (0,) * ns, "rank_slot": rank_slot, "coupling_row": coupling_row,
            "coupling_slot": coupling_slot.astype(np.int64), "fold_columns": fold_columns,
            "past_grid": past_grid}


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


@nb.njit(cache=True, error_model="numpy", inline="always")
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
def gather_other_threads(dilu, o_along, o_across, o_axis):
    """The grid path's other threads' implicit blocks (Q,), past its grid threads, into dilu's
    along, across and axis, in the pair list's thread order."""
    along, across, axis = dilu.along, dilu.across, dilu.axis
    inner = dilu.grid_row.shape[0]
    for q in range(o_along.shape[0]):
        along[inner + q], across[inner + q] = o_along[q], o_across[q]
        axis[inner + q, 0], axis[inner + q, 1] = o_axis[q, 0], o_axis[q, 1]
        axis[inner + q, 2] = o_axis[q, 2]


@nb.njit(cache=True, error_model="numpy")
def gather_grid_threads(dilu, blocks, eh, ev, o_along, o_across, o_axis):
    """The grid's threads' implicit blocks into dilu's along, across and axis in the pair
    list's thread order, where its nodes are not folded (:func:`_grid_couplings` reads them
    from the rows where they are): the grid threads' from their rows (``blocks`` (4, W), axes
    ``eh``, ``ev`` (3, W); a slack thread's across read as zero, as its diagonal entries are),
    then the other threads' (Q,)."""
    rows, columns = dilu.grid_row, dilu.grid_column
    along, across, axis = dilu.along, dilu.across, dilu.axis
    for p in range(rows.shape[0]):
        row, col = rows[p], columns[p]
        e = eh if row == 0 else ev
        on = blocks[row, col] != 0.0
        along[p] = blocks[row, col]
        across[p] = blocks[row + 1, col] if on else 0.0
        axis[p, 0], axis[p, 1], axis[p, 2] = e[0, col], e[1, col], e[2, col]
    gather_other_threads(dilu, o_along, o_across, o_axis)


@nb.njit(cache=True, error_model="numpy", inline="always")
def _slot_block(blocks, axis, row, col):
    """The coupling block of the grid thread at column ``col`` of ``blocks``' rows ``row``,
    ``row`` + 1 (along, across; axes ``axis``), zero for col < 0 (no such thread) or a slack
    thread (along 0: its across read as zero), as :func:`_couplings` adds it onto zeros."""
    zero = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    if col < 0 or blocks[row, col] == 0.0:
        return zero
    return add_block(zero, blocks[row, col], blocks[row + 1, col], axis[0, col], axis[1, col],
                     axis[2, col])


@nb.njit(cache=True, error_model="numpy")
def _grid_couplings(dilu, blocks, eh, ev):
    """The folded grid's couplings, slot after slot, from the grid's rows (``blocks`` (4, W):
    along and across of the row threads, then of the column threads; axes ``eh``, ``ev`` (3,
    W)): at each node's slot its left neighbour's row thread and its lower neighbour's column
    thread (:attr:`DiluArrays.fold_columns`), each as :func:`_couplings` adds a thread's."""
    b, columns = dilu.fold, dilu.fold_columns
    ns, length, _ = _fold_shape(dilu)
    first = ns + U(2)
    low, left = _rows(LOW, length), _rows(LEFT, length)
    for k in range(ns * ns):
        f = first + k
        m = _slot_block(blocks, eh, 0, columns[0, k])
        for a in range(9):
            b[left[a] + f] = m[a]
        m = _slot_block(blocks, ev, 2, columns[1, k])
        for a in range(9):
            b[low[a] + f] = m[a]


@nb.njit(cache=True, error_model="numpy", inline="always")
def _add_coupling(dilu, e, along, across, e0, e1, e2):
    """Add a thread's or a span's block (:func:`bulletnet.kernels.axial.add_block`) to
    coupling e's: in off, or at its later node's slot of the folded layout's rows."""
    first = dilu.coupling_row[e]
    if first < 0:
        _put(dilu.off, e, add_block(_row(dilu.off, e), along, across, e0, e1, e2))
        return
    b, f = dilu.fold, U(dilu.coupling_slot[e])
    rows = _rows(first, _fold_shape(dilu)[1])
    m = add_block(_at(b, rows, f), along, across, e0, e1, e2)
    for a in range(9):
        b[rows[a] + f] = m[a]


@nb.njit(cache=True, error_model="numpy")
def _couplings(dilu, along, across, axis, cables, grid_rows):
    """Each coupling's block B [kg] into dilu's off or, between two folded grid nodes, the
    folded layout's rows (:func:`_add_coupling`): its threads' blocks (thread order; a slack
    one skipped; the grid threads' from the grid's rows ``grid_rows`` = (blocks, eh, ev) where
    its nodes are folded, :func:`_grid_couplings`; else gathered into ``along``, and the grid
    path's rows ignored, or None on the pair list), then its cable spans' (vertex order;
    span_edge has an entry, -1, for each cable's last vertex too)."""
    dilu.off[:] = 0.0
    thread_edge, first = dilu.thread_edge, 0
    if grid_rows is not None and len(dilu.slots) > 0:
        _grid_couplings(dilu, grid_rows[0], grid_rows[1], grid_rows[2])
        first = dilu.grid_row.shape[0]
    else:
        b, length = dilu.fold, _fold_shape(dilu)[1]
        for k in range(U(LOW) * length, U(LEFT + 9) * length):
            b[k] = 0.0
    for p in range(first, thread_edge.shape[0]):
        e = thread_edge[p]
        if e < 0 or (along[p] == 0.0 and across[p] == 0.0):
            continue
        _add_coupling(dilu, e, along[p], across[p], axis[p, 0], axis[p, 1], axis[p, 2])
    if cables is None:
        return
    span_edge, span_across, span_axis = dilu.span_edge, cables.across, cables.axis
    for v in range(span_edge.shape[0]):
        e = span_edge[v]
        if e < 0 or span_across[v] == 0.0:
            continue
        _add_coupling(dilu, e, 0.0, span_across[v], span_axis[v, 0], span_axis[v, 1],
                      span_axis[v, 2])


@nb.njit(cache=True, error_model="numpy", inline="always")
def _at(b, row, f):
    """The 9-tuple of slot f of the nine rows of ``b`` at offsets ``row``."""
    return (b[row[0] + f], b[row[1] + f], b[row[2] + f], b[row[3] + f], b[row[4] + f],
            b[row[5] + f], b[row[6] + f], b[row[7] + f], b[row[8] + f])


@nb.njit(cache=True, error_model="numpy", inline="always")
def _rows(first, length):
    """The offsets of nine rows from row ``first`` of the folded layout (rows ``length``
    long)."""
    return (U(first) * length, U(first + 1) * length, U(first + 2) * length,
            U(first + 3) * length, U(first + 4) * length, U(first + 5) * length,
            U(first + 6) * length, U(first + 7) * length, U(first + 8) * length)


@nb.njit(cache=True, error_model="numpy", inline="always")
def _forward_slots(b, first, last, shift, s, length):
    """The forward sweep over slots first .. last - 1 of the folded layout ``b``, nodes of one
    diagonal: y <- D^-1 (y + B_low y_low + B_left y_left), the left neighbour ``s`` - ``shift``
    slots back (shift is Ns^2 on the seam, where diagonal Ns reads diagonal Ns - 1 in the last
    slot row), the lower one a slot before it."""
    y0, y1, y2 = U(Y) * length, U(Y + 1) * length, U(Y + 2) * length
    inv, low, left = _rows(INV, length), _rows(LOW, length), _rows(LEFT, length)
    for f in range(first, last):
        g = f + shift - s
        h = g - ONE
        a0, a1, a2 = b[y0 + f], b[y1 + f], b[y2 + f]
        c0, c1, c2 = _times(_at(b, low, f), b[y0 + h], b[y1 + h], b[y2 + h])
        a0, a1, a2 = a0 + c0, a1 + c1, a2 + c2
        c0, c1, c2 = _times(_at(b, left, f), b[y0 + g], b[y1 + g], b[y2 + g])
        a0, a1, a2 = a0 + c0, a1 + c1, a2 + c2
        b[y0 + f], b[y1 + f], b[y2 + f] = _times(_at(b, inv, f), a0, a1, a2)


@nb.njit(cache=True, error_model="numpy", inline="always")
def _backward_slots(b, first, last, shift, s, length):
    """The backward sweep over slots first .. last - 1 of the folded layout ``b``: y <- y +
    D^-1 (B_right y_right + B_up y_up + the term from past the grid), the right neighbour
    ``s`` slots ahead (less ``shift``: Ns^2 on the seam), the upper one a slot after it; each
    block kept at the later node's slot."""
    y0, y1, y2 = U(Y) * length, U(Y + 1) * length, U(Y + 2) * length
    p0, p1, p2 = U(PAST) * length, U(PAST + 1) * length, U(PAST + 2) * length
    inv, low, left = _rows(INV, length), _rows(LOW, length), _rows(LEFT, length)
    for f in range(first, last):
        g = f + s - shift
        h = g + ONE
        a0 = a1 = a2 = 0.0
        c0, c1, c2 = _times(_at(b, left, g), b[y0 + g], b[y1 + g], b[y2 + g])
        a0, a1, a2 = a0 + c0, a1 + c1, a2 + c2
        c0, c1, c2 = _times(_at(b, low, h), b[y0 + h], b[y1 + h], b[y2 + h])
        a0, a1, a2 = a0 + c0, a1 + c1, a2 + c2
        a0, a1, a2 = a0 + b[p0 + f], a1 + b[p1 + f], a2 + b[p2 + f]
        c0, c1, c2 = _times(_at(b, inv, f), a0, a1, a2)
        b[y0 + f] += c0
        b[y1 + f] += c1
        b[y2 + f] += c2


@nb.njit(cache=True, error_model="numpy", inline="always")
def _at_rank(dilu, y_fold, y_tail, k):
    """A vector's value at rank k (unsigned), the vector in the folded layout's rows
    ``y_fold`` (as fold's first three) and the tail ``y_tail`` (as tail)."""
    _, length, n = _fold_shape(dilu)
    f = U(dilu.rank_slot[k])
    if k >= n:
        return y_tail[f, 0], y_tail[f, 1], y_tail[f, 2]
    return y_fold[f], y_fold[length + f], y_fold[U(2) * length + f]


@nb.njit(cache=True, error_model="numpy")
def _sweeps(dilu):
    """The vector in dilu's fold (its first three rows) and tail <- M0^-1 times it: the
    forward sweep over the folded grid, diagonal after diagonal (:func:`_forward_slots`),
    then by rank over the tail; the backward sweep by rank over the tail, then each grid
    node's term from past the grid, then the folded grid back (indices unsigned: no
    wraparound checks, :data:`bulletnet.kernels.U`)."""
    s, length, n = _fold_shape(dilu)
    b, tail = dilu.fold, dilu.tail
    p = s + U(2)  # the first node's slot
    for d in range(s):  # diagonals 0 .. Ns - 1: slots 0 .. d of slot row d
        _forward_slots(b, p + d * s, p + d * s + d + ONE, U(0), s, length)
    if s > 0:  # diagonal Ns: slot row 0's slots 1 .. Ns - 1, its neighbours in slot row Ns - 1
        _forward_slots(b, p + ONE, p + s, s * s, s, length)
    for d in range(ONE, s):  # diagonals Ns + 1 ..: slots d + 1 .. Ns - 1 of slot row d
        _forward_slots(b, p + d * s + d + ONE, p + d * s + s, U(0), s, length)
    off, inv = dilu.off, dilu.inv
    start, earlier = dilu.lower_start, dilu.lower_rank
    ranks = U(dilu.rank_slot.shape[0])
    for k in range(n, ranks):
        t = k - n
        a0, a1, a2 = tail[t, 0], tail[t, 1], tail[t, 2]
        for q in range(U(start[k]), U(start[k + ONE])):
            b0, b1, b2 = _at_rank(dilu, b, tail, U(earlier[q]))
            b0, b1, b2 = _times(_row(off, q), b0, b1, b2)
            a0, a1, a2 = a0 + b0, a1 + b1, a2 + b2
        tail[t, 0], tail[t, 1], tail[t, 2] = _times(_row(inv, k), a0, a1, a2)
    start, later, edge = dilu.upper_start, dilu.upper_rank, dilu.upper_edge
    for step in range(ranks - n):
        k = ranks - ONE - step
        first, last = U(start[k]), U(start[k + ONE])
        if first == last:
            continue
        a0 = a1 = a2 = 0.0
        for q in range(first, last):
            j = U(later[q]) - n
            b0, b1, b2 = _times(_row(off, U(edge[q])), tail[j, 0], tail[j, 1], tail[j, 2])
            a0, a1, a2 = a0 + b0, a1 + b1, a2 + b2
        b0, b1, b2 = _times(_row(inv, k), a0, a1, a2)
        t = k - n
        tail[t, 0] += b0
        tail[t, 1] += b1
        tail[t, 2] += b2
    past = dilu.past_grid
    for k in range(n):
        q = past[k]
        if q >= 0:
            j = U(later[q]) - n
            c0, c1, c2 = _times(_row(off, U(edge[q])), tail[j, 0], tail[j, 1], tail[j, 2])
            f = U(dilu.rank_slot[k])
            b[U(PAST) * length + f] = 0.0 + c0
            b[U(PAST + 1) * length + f] = 0.0 + c1
            b[U(PAST + 2) * length + f] = 0.0 + c2
    for step in range(ONE, s):  # diagonals 2 Ns - 2 .. Ns + 1
        d = s - step
        _backward_slots(b, p + d * s + d + ONE, p + d * s + s, U(0), s, length)
    if s > 0:  # diagonal Ns
        _backward_slots(b, p + ONE, p + s, U(0), s, length)
        d = s - ONE  # diagonal Ns - 1: its neighbours on diagonal Ns, in slot row 0
        _backward_slots(b, p + d * s, p + d * s + d + ONE, s * s, s, length)
    for step in range(U(2), s + ONE):  # diagonals Ns - 2 .. 0
        d = s - step
        _backward_slots(b, p + d * s, p + d * s + d + ONE, U(0), s, length)


@nb.njit(cache=True, error_model="numpy")
def _load(dilu, x):
    """dilu's fold (its first three rows) and tail <- x (3, >= N) at each rank's node."""
    order, rank_slot, b, tail = dilu.rank_node, dilu.rank_slot, dilu.fold, dilu.tail
    _, length, n = _fold_shape(dilu)
    for k in range(n):
        i, f = U(order[k]), U(rank_slot[k])
        b[f], b[length + f], b[U(2) * length + f] = x[0, i], x[1, i], x[2, i]
    for k in range(n, U(order.shape[0])):
        i, t = U(order[k]), U(rank_slot[k])
        tail[t, 0], tail[t, 1], tail[t, 2] = x[0, i], x[1, i], x[2, i]


@nb.njit(cache=True, error_model="numpy")
def _gradient_dot(dilu, cables, c, y_fold, y_tail):
    """g_c . y over cable c's vertices, y in the folded layout's rows ``y_fold`` and the tail
    ``y_tail`` (a node passed twice counted twice, as g_c sums its shares; a clamped node not
    at all)."""
    grad, vertex_rank = cables.grad, dilu.vertex_rank
    s = 0.0
    for v in range(cables.start[c], cables.start[c + 1]):
        k = vertex_rank[v]
        if k >= 0:
            y0, y1, y2 = _at_rank(dilu, y_fold, y_tail, U(k))
            s += grad[v, 0] * y0 + grad[v, 1] * y1 + grad[v, 2] * y2
    return s


@nb.njit(cache=True, error_model="numpy", inline="always")
def _factor_slots(b, first, last, shift, s, length):
    """D^-1 over slots first .. last - 1 of the folded layout ``b``, nodes of one diagonal,
    its neighbours as in :func:`_forward_slots`: D = A0_ii (in the D^-1 rows on entry) less the
    lower, then the left neighbour's B D^-1 B, inverted."""
    inv, low, left = _rows(INV, length), _rows(LOW, length), _rows(LEFT, length)
    for f in range(first, last):
        g = f + shift - s
        h = g - ONE
        m = _less_sandwich(_at(b, inv, f), _at(b, low, f), _at(b, inv, h))
        m = invert3(_less_sandwich(m, _at(b, left, f), _at(b, inv, g)))
        for a in range(9):
            b[inv[a] + f] = m[a]


@nb.njit(cache=True, error_model="numpy")
def factor(dilu, diagonal, along, across, axis, cables, grid_rows):
    """Block D-ILU's factor: the couplings' blocks from the threads' ``along``, ``across`` [kg]
    and ``axis`` [-] (P,) (the grid threads' from ``grid_rows`` on the grid path:
    :func:`_couplings`) and the cables' spans, then D_i^-1 node after node in the order from
    A0's diagonal blocks ``diagonal`` [kg] (9, >= N) (row-major entries by component row);
    then, with taut cables, W and S's Cholesky factor (see the module doc)."""
    _couplings(dilu, along, across, axis, cables, grid_rows)
    order, off, inv, rank_slot = dilu.rank_node, dilu.off, dilu.inv, dilu.rank_slot
    ns, length, n = _fold_shape(dilu)
    b = dilu.fold
    for k in range(n):  # the folded grid's: A0's diagonal blocks into the D^-1 rows, then D^-1
        i, f = U(order[k]), U(rank_slot[k])
        for a in range(U(9)):
            b[(U(INV) + a) * length + f] = diagonal[a, i]
    p = ns + U(2)
    for d in range(ns):
        _factor_slots(b, p + d * ns, p + d * ns + d + ONE, U(0), ns, length)
    if ns > 0:
        _factor_slots(b, p + ONE, p + ns, ns * ns, ns, length)
    for d in range(ONE, ns):
        _factor_slots(b, p + d * ns + d + ONE, p + d * ns + ns, U(0), ns, length)
    start, earlier = dilu.lower_start, dilu.lower_rank
    rows = _rows(INV, length)
    for k in range(n, U(order.shape[0])):  # the others' by rank
        i = U(order[k])
        m = (diagonal[0, i], diagonal[1, i], diagonal[2, i], diagonal[3, i], diagonal[4, i],
             diagonal[5, i], diagonal[6, i], diagonal[7, i], diagonal[8, i])
        for q in range(U(start[k]), U(start[k + ONE])):
            j = U(earlier[q])
            d_inv = _at(b, rows, U(rank_slot[j])) if j < n else _row(inv, j)
            m = _less_sandwich(m, _row(off, q), d_inv)
        _put(inv, k, invert3(m))
    if cables is None:
        return
    s, vertex_rank, tail = dilu.s, dilu.vertex_rank, dilu.tail
    w_fold, w_tail = dilu.w_fold, dilu.w_tail
    count = cables.rest.shape[0]
    w_fold[:] = 0.0
    w_tail[:] = 0.0
    for c in range(count):
        if cables.along[c] == 0.0:
            continue
        for k in range(U(3) * length):  # g_c, then M0^-1 g_c in its place
            b[k] = 0.0
        tail[:] = 0.0
        for v in range(cables.start[c], cables.start[c + 1]):
            k = vertex_rank[v]
            if k < 0:
                continue
            f = U(rank_slot[k])
            for a in range(U(3)):
                if U(k) < n:
                    b[a * length + f] += cables.grad[v, a]
                else:
                    tail[f, a] += cables.grad[v, a]
        _sweeps(dilu)
        for k in range(U(3) * length):
            w_fold[c, k] = b[k]
        for k in range(U(tail.shape[0])):
            for a in range(U(3)):
                w_tail[c, k, a] = tail[k, a]
    for c in range(count):  # S = diag(1 / along) + G^T W, then its Cholesky factor
        for d in range(count):
            if cables.along[c] == 0.0 or cables.along[d] == 0.0:
                s[c, d] = 1.0 if c == d else 0.0
            else:
                s[c, d] = (_gradient_dot(dilu, cables, c, w_fold[d], w_tail[d])
                           + (1.0 / cables.along[c] if c == d else 0.0))
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
    _load(dilu, r)
    _sweeps(dilu)
    b, tail = dilu.fold, dilu.tail
    _, length, n = _fold_shape(dilu)
    if cables is not None:
        w_fold, w_tail, s, t = dilu.w_fold, dilu.w_tail, dilu.s, dilu.t
        n_c = t.shape[0]
        for c in range(n_c):  # t = L^-1 G^T z0 (forward substitution)
            x = _gradient_dot(dilu, cables, c, b, tail) if cables.along[c] != 0.0 else 0.0
            for e in range(c):
                x -= s[c, e] * t[e]
            t[c] = x / s[c, c]
        for c in range(n_c - 1, -1, -1):  # t = L^-T t: S^-1 G^T z0
            x = t[c]
            for e in range(c + 1, n_c):
                x -= s[e, c] * t[e]
            t[c] = x / s[c, c]
        flat = tail.reshape(-1)
        for c in range(n_c):
            if cables.along[c] == 0.0:
                continue
            u, wc, wt = t[c], w_fold[c], w_tail[c].reshape(-1)
            for k in range(U(3) * length):
                b[k] -= u * wc[k]
            for k in range(U(flat.shape[0])):
                flat[k] -= u * wt[k]
    order, rank_slot = dilu.rank_node, dilu.rank_slot
    ranks = U(order.shape[0])
    if ranks < count:
        for a in range(U(3)):
            for i in range(count):
                z[a, i] = 0.0
    for k in range(n):
        i, f = U(order[k]), U(rank_slot[k])
        z[0, i], z[1, i], z[2, i] = b[f], b[length + f], b[U(2) * length + f]
    for k in range(n, ranks):
        i, f = U(order[k]), U(rank_slot[k])
        z[0, i], z[1, i], z[2, i] = tail[f, 0], tail[f, 1], tail[f, 2]
    rz = rr = 0.0
    for i in range(count):
        tz, tr = pcg.dot_terms(r[0, i], r[1, i], r[2, i], z[0, i], z[1, i], z[2, i])
        rz += tz
        rr += tr
    return rz, rr
