"""Build the net model (Eq. 1-5) and its folded initial state from a scene."""

from __future__ import annotations

import math
import os

import numpy as np

from ..common.errors import ScenarioError
from . import debris as debris_module
from .net import ElementKind, NetModel, NodeKind, thread_kinds
from .scenario import Scenario
from .state import NetState
from .topology import center_nodes, net_corners, node_kinds, perimeter, thread_pairs


def sphere_radius(mass: np.ndarray, density: float | np.ndarray) -> np.ndarray:
    """Radius of a solid sphere of the given mass [kg] and density [kg/m^3], in [m]."""
    return np.cbrt(3.0 * np.asarray(mass) / (4.0 * math.pi * np.asarray(density)))


def thread_parameters(s: Scenario, rest: np.ndarray, r_thread: np.ndarray,
                      m_ref: float) -> dict:
    """Axial (Eq. 3), transverse (Eq. 5) and angular (Eq. 4) stiffness and damping of threads
    of rest lengths ``rest`` [m] and radii ``r_thread`` [m], shape (P,). The bending dampers use
    omega_n1 = sqrt(k / m_ref) of the first thread, computed separately for t and b (MODEL.md:
    with the inner thread and the inner-node mass this reproduces Table 7), all scaled by
    ``bending.stiffness_scale``."""
    e, damp = s.materials.net.young_modulus, s.damping
    area = math.pi * r_thread**2
    second_moment = math.pi * r_thread**4 / 4.0          # I = pi r^4 / 4
    k_a = e * area / rest
    k_t = 3.0 * e * second_moment / rest**3
    k_b = e * second_moment / rest
    omega_t = math.sqrt(k_t[0] / m_ref)
    omega_b = math.sqrt(k_b[0] / m_ref)
    scale = s.bending.stiffness_scale
    return {
        "axial_stiffness": k_a,
        "axial_damping": 2.0 * damp.axial_ratio * k_a / damp.axial_reference_frequency,
        "transverse_stiffness": scale * k_t,
        "transverse_damping": scale * 2.0 * damp.bending_ratio * k_t / omega_t,
        "bending_stiffness": scale * k_b,
        "bending_damping": scale * 2.0 * damp.bending_ratio * k_b / omega_b,
    }


def breaking_tension(s: Scenario, kinds: np.ndarray, area: np.ndarray) -> np.ndarray:
    """Tension at which elements of :class:`~bulletnet.model.net.ElementKind` ``kinds`` and
    sections ``area`` [m^2], shape (E,) each, break [N], shape (E,): their kind's breaking
    stress (``[strength]``) times the section, times the knot efficiency for the knotted
    kinds (net and corner threads)."""
    st = s.strength
    stress = np.array([st.thread_breaking_stress, st.corner_thread_breaking_stress,
                       st.tether_breaking_stress, st.tether_breaking_stress,
                       st.closing_breaking_stress])  # by ElementKind
    knotted = np.isin(kinds, (ElementKind.NET, ElementKind.CORNER))
    return stress[kinds] * area * np.where(knotted, st.knot_efficiency, 1.0)


def lumped_masses(node_count: int, pairs: np.ndarray, thread_mass: np.ndarray) -> np.ndarray:
    """Eq. 2: each node gets half the mass of every thread it ends [kg], shape (N,)."""
    mass = np.zeros(node_count)
    np.add.at(mass, pairs[:, 0], thread_mass / 2.0)
    np.add.at(mass, pairs[:, 1], thread_mass / 2.0)
    return mass


BYTES_PER_NODE = 3000
"""Memory a net's node takes once its model and engine are built [bytes]: 2.4-2.9 KB a node
for the deployment and the capture at Ns = 60 and 120 (peak of Python's allocations while
building, ``tracemalloc``), rounded up."""


def check_memory(s: Scenario) -> None:
    """Refuse a net whose model and engine would not fit in this machine's memory
    (:data:`BYTES_PER_NODE` a node against the physical memory), before anything is built: a
    one-line :class:`ScenarioError` rather than hours of swapping or an out-of-memory kill.
    Not checked where the system does not tell its memory."""
    if s.scene.kind != "net":
        return
    try:
        have = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (AttributeError, ValueError, OSError):
        return
    ns = s.net.nodes_per_side
    need = BYTES_PER_NODE * ns * ns
    if need > have:
        raise ScenarioError(
            f"{s.source}: net.nodes_per_side = {ns} ({ns * ns} nodes) needs about "
            f"{need / 1e9:.0f} GB to build and run, more than this machine's "
            f"{have / 1e9:.0f} GB; lower net.nodes_per_side")


def build_model(s: Scenario) -> NetModel:
    """The scene's model: the square net (Eq. 1-5, Table 7) or the clamped beam (Fig. 2).
    A scene whose values are each valid but whose derived quantities overflow (a 1e300 m
    mesh, say), or whose net would not fit in memory (:func:`check_memory`), is a
    :class:`ScenarioError`."""
    check_memory(s)
    with np.errstate(all="ignore"):
        model = _build_beam(s) if s.scene.kind == "cantilever" else _build_net(s)
        state = initial_state(s, model)
    for name, value in [*vars(model).items(), ("initial position", state.position),
                        ("initial velocity", state.velocity)]:
        if isinstance(value, np.ndarray) and not np.isfinite(value).all():
            raise ScenarioError(
                f"{s.source}: derived {name.replace('_', ' ')} is not finite; "
                "check the magnitudes of the scene's values")
    return model


def _finish(s: Scenario, *, pairs, rest, r_thread, mass, kind, m_ref, fixed, load,
           nodes_per_side, bilateral, tether_threads=0, cables=None) -> NetModel:
    density = np.select([kind == NodeKind.CORNER_MASS, kind == NodeKind.CHASER,
                         kind == NodeKind.TETHER],
                        [s.materials.corner_mass.density, s.materials.corner_mass.density,
                         s.tether.density], s.materials.net.density)
    radius = sphere_radius(mass, density)
    pos = _layout(s)
    axis = pos[pairs[:, 1]] - pos[pairs[:, 0]]
    axis /= np.linalg.norm(axis, axis=1)[:, None]
    params = thread_parameters(s, rest, r_thread, m_ref)
    if tether_threads:  # the tether's own material; a rope: no bending springs
        tail = slice(pairs.shape[0] - tether_threads, None)
        k_a = s.tether.young_modulus * math.pi * r_thread[tail]**2 / rest[tail]
        params["axial_stiffness"][tail] = k_a
        params["axial_damping"][tail] = (2.0 * s.tether.damping_ratio * k_a
                                         / s.damping.axial_reference_frequency)
        for name in ("transverse_stiffness", "transverse_damping", "bending_stiffness",
                     "bending_damping"):
            params[name][tail] = 0.0
    return NetModel(
        nodes_per_side=nodes_per_side, mass=mass, radius=radius, kind=kind, pairs=pairs,
        rest_length=rest, thread_radius=r_thread, **params,
        inertia=0.4 * mass * radius**2, rest_axis=axis, fixed=fixed, load=load,
        breaking_tension=breaking_tension(s, thread_kinds(pairs, kind), math.pi * r_thread**2),
        bilateral=bilateral, **(cables or {}))


def _build_net(s: Scenario) -> NetModel:
    net, mat = s.net, s.materials.net
    ns = net.nodes_per_side
    pairs = thread_pairs(ns)
    corner = np.arange(pairs.shape[0]) >= 2 * ns * (ns - 1)
    rest = np.where(corner, net.corner_thread_length, net.mesh_length)
    r_thread = np.where(corner, net.corner_thread_radius, net.thread_radius)
    density = np.full(pairs.shape[0], mat.density)
    kind = node_kinds(ns)
    tether_threads = 0
    if s.tether.enabled:
        t_pairs, t_rest, t_kind = _tether(s, ns)
        tether_threads = t_pairs.shape[0]
        pairs = np.concatenate([pairs, t_pairs])
        rest = np.concatenate([rest, t_rest])
        r_thread = np.concatenate([r_thread, np.full(tether_threads, s.tether.diameter / 2)])
        density = np.concatenate([density, np.full(tether_threads, s.tether.density)])
        kind = np.concatenate([kind, t_kind])
    n = kind.shape[0]
    mass = lumped_masses(n, pairs, density * math.pi * r_thread**2 * rest)
    mass[ns * ns: ns * ns + 4] += net.corner_mass
    fixed = np.zeros(n, dtype=bool)
    if s.tether.enabled:
        mass[-1] += s.tether.chaser_mass
        fixed[-1] = s.tether.chaser_mass == 0.0
    cables = _closing(s, ns, mass) if s.closing.enabled else None
    # omega_n1 from the inner-node mass (the lightest net node if there is no inner node)
    inner = kind == NodeKind.INNER
    m_ref = mass[inner][0] if inner.any() else mass[: ns * ns].min()
    return _finish(s, pairs=pairs, rest=rest, r_thread=r_thread, mass=mass, kind=kind,
                   m_ref=m_ref, fixed=fixed, load=np.zeros((n, 3)), nodes_per_side=ns,
                   bilateral=False, tether_threads=tether_threads, cables=cables)


def _tether(s: Scenario, ns: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The main tether's threads (pairs (T, 2), rest lengths [m] (T,)) and its nodes' kinds
    (segments,): from the centre node, or from a junction node held by four bridle lines
    from the corner masses, through segments - 1 tether nodes to the chaser (the last)."""
    t = s.tether
    first = ns * ns + 4
    chain = np.arange(first, first + t.segments)  # tether nodes; the chaser last
    if t.attach == "bridle":
        chain = np.concatenate([[first], chain + 1])
        lines = [(ns * ns + k, first) for k in range(4)]
        line_rest = [t.bridle_length] * 4
    else:
        chain = np.concatenate([[center_nodes(ns)[0]], chain])
        lines, line_rest = [], []
    pairs = np.array(lines + list(zip(chain[:-1], chain[1:], strict=True)), dtype=np.int64)
    rest = np.array(line_rest + [t.length / t.segments] * t.segments)
    kind = np.full(pairs.max() + 1 - first, NodeKind.TETHER, dtype=np.int8)
    kind[-1] = NodeKind.CHASER
    return pairs, rest, kind


def closing_routes(route: str, ns: int) -> list[np.ndarray]:
    """Node polylines of the closing cables [-], each (V_c,): ``sides``, corner mass k ->
    the perimeter nodes of one side -> the next corner mass, for the four sides in order
    round the mouth; ``perimeter``, corner mass 0 -> every perimeter node -> net corner 0
    again -> corner mass 0."""
    ring = perimeter(ns)
    n = ns * ns
    mass_of = {int(c): n + k for k, c in enumerate(net_corners(ns))}
    if route == "perimeter":
        return [np.concatenate([[n], ring, [ring[0], n]])]
    sides = []
    for j in range(4):
        side = np.take(ring, np.arange(j * (ns - 1), (j + 1) * (ns - 1) + 1), mode="wrap")
        sides.append(np.concatenate([[mass_of[int(side[0])]], side, [mass_of[int(side[-1])]]]))
    return sides


def _closing(s: Scenario, ns: int, mass: np.ndarray) -> dict:
    """The closing cables' arrays (the :class:`NetModel` ``cable_*`` fields); each cable's
    mass, at its deployed length, is lumped on its vertices as Eq. 2 lumps a thread's (added
    into ``mass``)."""
    cl = s.closing
    routes = closing_routes(cl.route, ns)
    deployed = _layout(s, fold_ratio=1.0)
    area = math.pi * cl.diameter**2 / 4.0
    lengths = []
    for nodes in routes:
        spans = np.linalg.norm(np.diff(deployed[nodes], axis=0), axis=1)
        np.add.at(mass, nodes[:-1], 0.5 * cl.density * area * spans)
        np.add.at(mass, nodes[1:], 0.5 * cl.density * area * spans)
        lengths.append(spans.sum())
    count = len(routes)
    return {
        "cable_nodes": np.concatenate(routes).astype(np.int64),
        "cable_start": np.cumsum([0] + [r.size for r in routes]).astype(np.int64),
        "cable_rest_length": cl.length_ratio * np.array(lengths),
        "cable_rigidity": np.full(count, cl.young_modulus * area),
        "cable_damping_time": np.full(
            count, 2.0 * cl.damping_ratio / s.damping.axial_reference_frequency),
        "cable_breaking_tension": breaking_tension(s, np.full(count, ElementKind.CABLE),
                                                   np.full(count, area)),
    }


def _build_beam(s: Scenario) -> NetModel:
    """Fig. 2: two masses (half the beam each, Eq. 2) and one element; node 0 is clamped. The
    element is bilateral (a beam resists compression; a tension-only thread would let the tip
    slide in along the joint's free axis)."""
    beam = s.beam
    pairs = np.array([[0, 1]], dtype=np.int64)
    rest, r_thread = np.array([beam.length]), np.array([beam.radius])
    mass = lumped_masses(2, pairs, s.materials.net.density * math.pi * r_thread**2 * rest)
    load = np.zeros((2, 3))
    load[1] = beam.tip_load
    return _finish(s, pairs=pairs, rest=rest, r_thread=r_thread, mass=mass,
                   kind=np.zeros(2, dtype=np.int8), m_ref=mass[1],
                   fixed=np.array([True, False]), load=load, nodes_per_side=0,
                   bilateral=True)


def _layout(s: Scenario, fold_ratio: float | None = None) -> np.ndarray:
    """Initial node positions [m], shape (N, 3): the folded planar net of Sec. 4 (adjacent
    nodes ``fold_ratio`` rest lengths apart, corner masses on the diagonals at ``fold_ratio``
    of their thread; the scene's unless given), then the tether's nodes evenly on the straight
    line from its first node (the centre node, or the bridle's junction at ``fold_ratio`` of a
    line behind the centre) to the chaser, ``chaser_distance`` behind the net's centre (-z);
    or the straight beam along +x from the origin."""
    if s.scene.kind == "cantilever":
        return np.array([[0.0, 0, 0], [s.beam.length, 0, 0]])
    net = s.net
    fold = net.fold_ratio if fold_ratio is None else fold_ratio
    ns = net.nodes_per_side
    n_net = ns * ns
    pos = np.zeros((n_net + 4, 3))
    spacing = fold * net.mesh_length
    r, c = np.divmod(np.arange(n_net), ns)
    half = (ns - 1) / 2.0
    pos[:n_net, 0] = (c - half) * spacing
    pos[:n_net, 1] = (r - half) * spacing
    for k, node in enumerate(net_corners(ns)):
        outward = pos[node, :2] / np.linalg.norm(pos[node, :2])
        pos[n_net + k, :2] = pos[node, :2] + outward * fold * net.corner_thread_length
    if s.tether.enabled:
        t = s.tether
        chaser = pos[center_nodes(ns)].mean(axis=0) - np.array([0.0, 0.0, t.chaser_distance])
        start = pos[center_nodes(ns)[0]]
        steps = np.arange(1, t.segments + 1)
        if t.attach == "bridle":
            start = start - np.array([0.0, 0.0, fold * t.bridle_length])
            steps = np.arange(0, t.segments + 1)
        share = steps / t.segments
        pos = np.vstack([pos, start + share[:, None] * (chaser - start)])
    return pos + np.asarray(net.center)


def initial_state(s: Scenario, model: NetModel) -> NetState:
    """Nodes at :func:`_layout`, unrotated; a net's corner masses are launched at
    ``corner_speed``, radially out in plane and ``elevation`` above it (Sec. 4)."""
    pos = _layout(s)
    vel = np.zeros_like(pos)
    if s.scene.kind == "net":
        ns = s.net.nodes_per_side
        elev = math.radians(s.launch.elevation)
        for k, node in enumerate(net_corners(ns)):
            outward = pos[ns * ns + k, :2] - pos[node, :2]
            outward /= np.linalg.norm(outward)
            vel[ns * ns + k, :2] = s.launch.corner_speed * math.cos(elev) * outward
            vel[ns * ns + k, 2] = s.launch.corner_speed * math.sin(elev)
    state = NetState(time=0.0, position=pos, velocity=vel)
    debris = scene_debris(s)
    if debris is not None:
        state.debris = debris_module.initial_state(s.debris, debris)
    if s.bending.enabled:
        state.orientation = np.zeros((model.node_count, 4))
        state.orientation[:, 3] = 1.0
        state.angular_velocity = np.zeros((model.node_count, 3))
    return state


def scene_debris(s: Scenario):
    """The scene's :class:`~bulletnet.model.debris.Debris`, or None if it has none."""
    if not s.debris.asset:
        return None
    return debris_module.load_debris(s.debris.asset, s.debris.mass, s.debris.density)
