"""Build the net model (Eq. 1-5) and its folded initial state from a scene."""

from __future__ import annotations

import math

import numpy as np

from .model import NetModel, NodeKind
from .scenario import Scenario
from .state import NetState
from .topology import net_corners, node_kinds, thread_pairs


def sphere_radius(mass: np.ndarray, density: float | np.ndarray) -> np.ndarray:
    """Radius of a solid sphere of the given mass [kg] and density [kg/m^3], in [m]."""
    return np.cbrt(3.0 * np.asarray(mass) / (4.0 * math.pi * np.asarray(density)))


def build_model(s: Scenario) -> NetModel:
    """Topology, masses (Eq. 2), radii and thread stiffness/damping (Eq. 3-5, Table 7)."""
    net, mat, damp = s.net, s.materials.net, s.damping
    ns = net.nodes_per_side
    n_net = ns * ns
    pairs = thread_pairs(ns)
    p_count = pairs.shape[0]
    corner = np.zeros(p_count, dtype=bool)
    corner[-4:] = True

    rest = np.where(corner, net.corner_thread_length, net.mesh_length)
    r_thread = np.where(corner, net.corner_thread_radius, net.thread_radius)
    area = math.pi * r_thread**2
    second_moment = math.pi * r_thread**4 / 4.0          # I = pi r^4 / 4
    thread_mass = mat.density * area * rest              # m_p = rho A l_0

    mass = np.zeros(n_net + 4)
    np.add.at(mass, pairs[:, 0], thread_mass / 2.0)      # Eq. 2
    np.add.at(mass, pairs[:, 1], thread_mass / 2.0)
    mass[n_net:] += net.corner_mass

    kind = node_kinds(ns)
    density = np.where(kind == NodeKind.CORNER_MASS, s.materials.corner_mass.density, mat.density)
    radius = sphere_radius(mass, density)

    e = mat.young_modulus
    k_a = e * area / rest
    c_a = 2.0 * damp.axial_ratio * k_a / damp.axial_reference_frequency
    k_t = 3.0 * e * second_moment / rest**3
    k_b = e * second_moment / rest
    # omega_n1 from the inner thread and the inner-node mass, reused for the corner threads
    # (MODEL.md: this reproduces Table 7). A net with no inner node uses its lightest node.
    inner = kind[:n_net] == NodeKind.INNER
    m_ref = mass[:n_net][inner][0] if inner.any() else mass[:n_net].min()
    omega_t = math.sqrt(k_t[0] / m_ref)
    omega_b = math.sqrt(k_b[0] / m_ref)
    c_t = 2.0 * damp.bending_ratio * k_t / omega_t
    c_b = 2.0 * damp.bending_ratio * k_b / omega_b

    return NetModel(
        nodes_per_side=ns, mass=mass, radius=radius, kind=kind, pairs=pairs,
        rest_length=rest, thread_radius=r_thread, axial_stiffness=k_a, axial_damping=c_a,
        transverse_stiffness=k_t, transverse_damping=c_t,
        bending_stiffness=k_b, bending_damping=c_b)


def initial_state(s: Scenario, model: NetModel) -> NetState:
    """The folded, planar start of Sec. 4: net parallel to x-y, adjacent nodes ``fold_ratio``
    rest lengths apart, corner masses on the diagonals at ``fold_ratio`` of their thread, and the
    corner masses launched at ``corner_speed``, radially out, ``elevation`` above the plane."""
    net, launch = s.net, s.launch
    ns = net.nodes_per_side
    n_net = ns * ns
    pos = np.zeros((n_net + 4, 3))
    vel = np.zeros_like(pos)
    spacing = net.fold_ratio * net.mesh_length
    r, c = np.divmod(np.arange(n_net), ns)
    half = (ns - 1) / 2.0
    pos[:n_net, 0] = (c - half) * spacing
    pos[:n_net, 1] = (r - half) * spacing
    elev = math.radians(launch.elevation)
    for k, node in enumerate(net_corners(ns)):
        outward = pos[node, :2] / np.linalg.norm(pos[node, :2])
        pos[n_net + k, :2] = pos[node, :2] + outward * net.fold_ratio * net.corner_thread_length
        vel[n_net + k, :2] = launch.corner_speed * math.cos(elev) * outward
        vel[n_net + k, 2] = launch.corner_speed * math.sin(elev)
    pos += np.asarray(net.center)
    return NetState(time=0.0, position=pos, velocity=vel)
