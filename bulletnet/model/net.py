"""The immutable net model: topology, masses and thread parameters as arrays.

N = Ns**2 + 4 nodes (net nodes row by row, then the four corner masses), then, with a main
tether, its nodes from the net to the chaser (the last); P = 2 Ns (Ns - 1) + 4 threads (inner
threads in Eq. 1's order, then the four corner threads), then the tether's (the bridle's four
lines first). Indices are 0-based: the paper's node k is index k - 1. Closing cables are
polylines over these nodes (C cables, V vertices in all).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import IntEnum

import numpy as np


class NodeKind(IntEnum):
    """Kind of a node, as used in the contact tables (Tables 5-6)."""

    INNER = 0
    EDGE = 1
    CORNER = 2
    CORNER_MASS = 3
    TETHER = 4
    CHASER = 5


class ElementKind(IntEnum):
    """Kind of a load-carrying element, for its strength: a thread of the model (by its end
    nodes' kinds, :func:`thread_kinds`) or a closing cable."""

    NET = 0
    """A thread between two net nodes (Eq. 1's inner threads; the cantilever's beam)."""
    CORNER = 1
    """A corner thread: a net corner to its corner mass (Fig. 1)."""
    BRIDLE = 2
    """A bridle line: a corner mass to the tether's junction node."""
    TETHER = 3
    """A thread of the main tether (from the net's centre or the bridle's junction to the
    chaser)."""
    CABLE = 4
    """A closing cable (one element however many rings it runs through)."""


ELEMENT_NAMES = {ElementKind.NET: "net thread", ElementKind.CORNER: "corner thread",
                 ElementKind.BRIDLE: "bridle line", ElementKind.TETHER: "tether thread",
                 ElementKind.CABLE: "closing cable"}
"""Each :class:`ElementKind` in words."""


def thread_kinds(pairs: np.ndarray, kind: np.ndarray) -> np.ndarray:
    """:class:`ElementKind` of each thread of ``pairs`` (P, 2) of nodes of ``kind`` (N,) [-],
    shape (P,), int8: found by its ends' kinds, not by position (a tether's threads follow
    the corner threads, a bridle's lines first)."""
    ends = kind[pairs]
    mass = (ends == NodeKind.CORNER_MASS).any(axis=1)
    rope = ((ends == NodeKind.TETHER) | (ends == NodeKind.CHASER)).any(axis=1)
    return np.select([mass & rope, mass, rope],
                     [ElementKind.BRIDLE, ElementKind.CORNER, ElementKind.TETHER],
                     ElementKind.NET).astype(np.int8)


def corner_threads(pairs: np.ndarray, kind: np.ndarray) -> np.ndarray:
    """Indices of the corner threads (Fig. 1's threads from a net corner to its corner mass)
    among threads ``pairs`` (P, 2) of nodes of ``kind`` (N,) [-], in thread order
    (:func:`thread_kinds`: a bridle's lines, which also end on corner masses, are not)."""
    return np.flatnonzero(thread_kinds(pairs, kind) == ElementKind.CORNER)


@dataclass(frozen=True)
class NetModel:
    nodes_per_side: int
    """Ns [-]."""
    mass: np.ndarray
    """Node masses [kg], shape (N,) (Eq. 2; corner masses include m_CM)."""
    radius: np.ndarray
    """Node sphere radii [m], shape (N,): (3 m / 4 pi rho)^(1/3) with the node's material."""
    kind: np.ndarray
    """Node kinds (:class:`NodeKind` values) [-], shape (N,), int8."""
    pairs: np.ndarray
    """Thread end nodes (i, j), i -> j [-], shape (P, 2), int64."""
    rest_length: np.ndarray
    """Thread rest lengths l_0 [m], shape (P,)."""
    thread_radius: np.ndarray
    """Thread section radii [m], shape (P,)."""
    axial_stiffness: np.ndarray
    """k_a = E A / l_0 [N/m], shape (P,) (Eq. 3)."""
    axial_damping: np.ndarray
    """c_a = 2 xi_a k_a / omega_ref [N s/m], shape (P,)."""
    transverse_stiffness: np.ndarray
    """k_t = 3 E I / l_0^3 [N/m], shape (P,) (Eq. 5)."""
    transverse_damping: np.ndarray
    """c_t = 2 xi_b k_t / omega_t [N s/m], shape (P,)."""
    bending_stiffness: np.ndarray
    """k_b = E I / l_0 [N m/rad], shape (P,) (Eq. 4)."""
    bending_damping: np.ndarray
    """c_b = 2 xi_b k_b / omega_b [N m s/rad], shape (P,)."""
    inertia: np.ndarray
    """Node moments of inertia, solid spheres 2 m r^2 / 5 [kg m^2], shape (N,)."""
    rest_axis: np.ndarray
    """Thread rest direction in node i's body frame (nodes start unrotated) [-], shape (P, 3)."""
    fixed: np.ndarray
    """Clamped nodes: position and orientation held [-], shape (N,), bool."""
    load: np.ndarray
    """Constant external force on each node (e.g. a tip load) [N], shape (N, 3)."""
    breaking_tension: np.ndarray
    """Tension at which each thread breaks [N], shape (P,) (``[strength]``; measured against,
    never acting)."""
    bilateral: bool
    """Whether the elements also resist compression (a beam, not threads)."""
    cable_nodes: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    """Node of each closing-cable vertex, cable after cable, ends first and last [-],
    shape (V,), int64."""
    cable_start: np.ndarray = field(default_factory=lambda: np.zeros(1, np.int64))
    """First vertex of each cable, then V [-], shape (C + 1,), int64."""
    cable_rest_length: np.ndarray = field(default_factory=lambda: np.zeros(0))
    """Initial rest length L_0 of each cable [m], shape (C,)."""
    cable_rigidity: np.ndarray = field(default_factory=lambda: np.zeros(0))
    """Axial rigidity E A of each cable [N], shape (C,)."""
    cable_damping_time: np.ndarray = field(default_factory=lambda: np.zeros(0))
    """c / k of each cable, 2 xi / omega_ref [s], shape (C,)."""
    cable_breaking_tension: np.ndarray = field(default_factory=lambda: np.zeros(0))
    """Tension at which each cable breaks [N], shape (C,)."""

    def __post_init__(self):
        for name in self.__dataclass_fields__:
            value = getattr(self, name)
            if isinstance(value, np.ndarray):
                value.setflags(write=False)

    @property
    def node_count(self) -> int:
        """N, nodes including the four corner masses [-]."""
        return self.mass.shape[0]

    @property
    def cable_count(self) -> int:
        """C, closing cables [-]."""
        return self.cable_rest_length.shape[0]

    @property
    def thread_count(self) -> int:
        """P, threads including the four corner threads [-]."""
        return self.pairs.shape[0]
