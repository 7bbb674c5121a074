"""Build the net model (Eq. 1-5) and its folded initial state from a scene."""

from __future__ import annotations

import math

import numpy as np

from . import debris as debris_module
from .errors import ScenarioError
from .model import NetModel, NodeKind
from .scenario import Scenario
from .state import NetState
from .topology import net_corners, node_kinds, thread_pairs


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


def lumped_masses(node_count: int, pairs: np.ndarray, thread_mass: np.ndarray) -> np.ndarray:
    """Eq. 2: each node gets half the mass of every thread it ends [kg], shape (N,)."""
    mass = np.zeros(node_count)
    np.add.at(mass, pairs[:, 0], thread_mass / 2.0)
    np.add.at(mass, pairs[:, 1], thread_mass / 2.0)
    return mass


def build_model(s: Scenario) -> NetModel:
    """The scene's model: the square net (Eq. 1-5, Table 7) or the clamped beam (Fig. 2).
    A scene whose values are each valid but whose derived quantities overflow (a 1e300 m
    mesh, say) is a :class:`ScenarioError`."""
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
            nodes_per_side, bilateral) -> NetModel:
    density = np.where(kind == NodeKind.CORNER_MASS, s.materials.corner_mass.density,
                       s.materials.net.density)
    radius = sphere_radius(mass, density)
    pos = _layout(s)
    axis = pos[pairs[:, 1]] - pos[pairs[:, 0]]
    axis /= np.linalg.norm(axis, axis=1)[:, None]
    return NetModel(
        nodes_per_side=nodes_per_side, mass=mass, radius=radius, kind=kind, pairs=pairs,
        rest_length=rest, thread_radius=r_thread,
        **thread_parameters(s, rest, r_thread, m_ref),
        inertia=0.4 * mass * radius**2, rest_axis=axis, fixed=fixed, load=load,
        bilateral=bilateral)


def _build_net(s: Scenario) -> NetModel:
    net, mat = s.net, s.materials.net
    ns = net.nodes_per_side
    pairs = thread_pairs(ns)
    corner = np.zeros(pairs.shape[0], dtype=bool)
    corner[-4:] = True
    rest = np.where(corner, net.corner_thread_length, net.mesh_length)
    r_thread = np.where(corner, net.corner_thread_radius, net.thread_radius)
    mass = lumped_masses(ns * ns + 4, pairs, mat.density * math.pi * r_thread**2 * rest)
    mass[ns * ns:] += net.corner_mass
    kind = node_kinds(ns)
    # omega_n1 from the inner-node mass (the lightest net node if there is no inner node)
    inner = kind == NodeKind.INNER
    m_ref = mass[inner][0] if inner.any() else mass[: ns * ns].min()
    n = ns * ns + 4
    return _finish(s, pairs=pairs, rest=rest, r_thread=r_thread, mass=mass, kind=kind,
                   m_ref=m_ref, fixed=np.zeros(n, dtype=bool), load=np.zeros((n, 3)),
                   nodes_per_side=ns, bilateral=False)


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


def _layout(s: Scenario) -> np.ndarray:
    """Initial node positions [m], shape (N, 3): the folded planar net of Sec. 4 (adjacent
    nodes ``fold_ratio`` rest lengths apart, corner masses on the diagonals at ``fold_ratio``
    of their thread), or the straight beam along +x from the origin."""
    if s.scene.kind == "cantilever":
        return np.array([[0.0, 0, 0], [s.beam.length, 0, 0]])
    net = s.net
    ns = net.nodes_per_side
    n_net = ns * ns
    pos = np.zeros((n_net + 4, 3))
    spacing = net.fold_ratio * net.mesh_length
    r, c = np.divmod(np.arange(n_net), ns)
    half = (ns - 1) / 2.0
    pos[:n_net, 0] = (c - half) * spacing
    pos[:n_net, 1] = (r - half) * spacing
    for k, node in enumerate(net_corners(ns)):
        outward = pos[node, :2] / np.linalg.norm(pos[node, :2])
        pos[n_net + k, :2] = pos[node, :2] + outward * net.fold_ratio * net.corner_thread_length
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
    """The scene's :class:`~bulletnet.debris.Debris`, or None if it has none."""
    if not s.debris.asset:
        return None
    return debris_module.load_debris(s.debris.asset, s.debris.mass, s.debris.density)
