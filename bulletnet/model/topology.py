"""Net topology by index (Eq. 1, Fig. 1), 0-based: the paper's node k is index k - 1.

Nodes 0 .. Ns^2 - 1 are the net, row by row; Ns^2 .. Ns^2 + 3 are the corner masses, hanging
on net corners 0, Ns - 1, Ns^2 - Ns, Ns^2 - 1 in that order.
"""

from __future__ import annotations

import numpy as np

from .net import NodeKind


def thread_pairs(ns: int) -> np.ndarray:
    """Inner threads by Eq. 1 in the paper's order, then the four corner threads
    (net corner -> corner mass) [-], shape (2 Ns (Ns - 1) + 4, 2), int64."""
    pairs = []
    n = ns * ns
    for i in range(1, n + 1):  # the paper's 1-based loop, verbatim
        if i % ns != 0:
            pairs.append((i - 1, i))          # j = i + 1
        if i + ns <= n:
            pairs.append((i - 1, i + ns - 1))  # j = i + Ns
    pairs.extend((c, n + k) for k, c in enumerate(net_corners(ns)))
    return np.array(pairs, dtype=np.int64)


def grid_threads(ns: int, node_count: int, pairs: np.ndarray) -> int:
    """How many of a model's first threads ``pairs`` (P, 2) are an Ns x Ns net's grid threads,
    Eq. 1's in its order, in a model of ``node_count`` nodes: 2 Ns (Ns - 1), or 0 if the
    model does not begin with them."""
    inner = 2 * ns * (ns - 1)
    return inner if (ns >= 2 and node_count >= ns * ns and pairs.shape[0] >= inner
                     and np.array_equal(pairs[:inner], thread_pairs(ns)[:inner])) else 0


def grid_places(pairs: np.ndarray, ns: int) -> tuple[np.ndarray, np.ndarray]:
    """Where the grid kernels keep each of the grid threads ``pairs`` (G, 2) (their first G,
    :func:`grid_threads`): 0 for a row thread i -> i + 1, 1 for a column thread i -> i + Ns,
    and the column Ns + i of its rows [-], each shape (G,), int64."""
    i, j = pairs[:, 0], pairs[:, 1]
    return np.where(j == i + 1, 0, 1).astype(np.int64), (ns + i).astype(np.int64)


def node_kinds(ns: int) -> np.ndarray:
    """Kind of every node (:class:`NodeKind`) [-], shape (Ns^2 + 4,), int8."""
    r, c = np.divmod(np.arange(ns * ns), ns)
    on_edge_r = (r == 0) | (r == ns - 1)
    on_edge_c = (c == 0) | (c == ns - 1)
    kind = np.full(ns * ns + 4, NodeKind.INNER, dtype=np.int8)
    kind[: ns * ns][on_edge_r | on_edge_c] = NodeKind.EDGE
    kind[: ns * ns][on_edge_r & on_edge_c] = NodeKind.CORNER
    kind[ns * ns:] = NodeKind.CORNER_MASS
    return kind


def net_corners(ns: int) -> np.ndarray:
    """The four net corners, in the corner masses' order [-], shape (4,)."""
    return np.array([0, ns - 1, ns * ns - ns, ns * ns - 1])


def perimeter(ns: int) -> np.ndarray:
    """The net's edge nodes in order around the mouth [-], shape (4 Ns - 4,)."""
    grid = np.arange(ns * ns).reshape(ns, ns)
    return np.concatenate([grid[0, :-1], grid[:-1, -1], grid[-1, :0:-1], grid[:0:-1, 0]])


def center_nodes(ns: int) -> np.ndarray:
    """The innermost node(s) [-]: the centre (Ns^2 - 1) / 2 for odd Ns, the four central nodes
    for even Ns. (Eq. 13 prints Ns (Ns + 1) / 2, an edge node for Ns = 11; see MODEL.md.)"""
    if ns % 2:
        return np.array([(ns * ns - 1) // 2])
    a, b = ns // 2 - 1, ns // 2
    return np.array([a * ns + a, a * ns + b, b * ns + a, b * ns + b])
