"""Contact applied to the net each step: node spheres against the debris and against each
other, with each pair's parameters (Tables 5-6, friction of Sec. 5). The laws are in
:mod:`bulletnet.kernels.contact`, the debris' signed distances in
:mod:`bulletnet.kernels.geometry`; this module sets up their arrays and applies them after the
integrator's free step (operator splitting: the normal motion of a node in contact is
replaced by the exact solution of :func:`~bulletnet.kernels.contact.normal_step` with the
step's other forces, then friction acts on the slip).

Collision work is only done where something can touch: a node is tested against the debris
only when its step can reach the debris' bounding sphere and its cached distance, less its
motion since, allows it (:mod:`bulletnet.solver.debris_gap`), and node pairs come from a Verlet
list (pairs closer than their radii plus ``contact.skin``), rebuilt when a node has moved more
than 0.4 skin since the last build.

An overlap found at the start of a step that the last step's exact solution did not predict
(the step linearizes the geometry: a fixed normal, a node sliding into a concave corner, a
pair passing tangentially) is removed by moving the node (:func:`overlap_error`), not by the
contact spring; runs count these projections.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numba as nb
import numpy as np

from ..kernels.bending import integrate_rotation
from ..kernels.contact import friction_impulse, implicit_normal_step, normal_step
from ..kernels.geometry import BOX, FRUSTUM, MESH, PART_COLUMNS, SPHERE
from ..model.materials import BODY_CLASSES, contact_table
from ..model.mesh import MeshArrays, build, no_meshes
from ..model.net import NetModel, NodeKind
from ..model.scenario import Scenario
from .contact_solve import (
    SolveArrays,
    add_debris_impulse,
    carry_pairs,
    coupled_stage,
    grown,
    keep_pairs,
    solve_arrays,
)
from .debris_gap import debris_pose, start_gap, surface_speed

CLASS_OF_KIND = {NodeKind.CORNER_MASS: 1, NodeKind.CORNER: 2, NodeKind.EDGE: 3,
                 NodeKind.INNER: 4, NodeKind.TETHER: -1, NodeKind.CHASER: -1}
"""Index in :data:`~bulletnet.model.materials.BODY_CLASSES` of each node kind (0 is the debris); -1:
the node has no contact (the main tether and the chaser, which stay behind the net)."""

ALUMINIUM_CLASSES = (0, 1)
"""Classes made of aluminium (the debris and the corner masses); the rest is net material."""


class ContactArrays(NamedTuple):
    """The arrays of the compiled contact stage, for N nodes and a Verlet list of C pairs
    (:func:`setup`); empty where a kind of contact is off (same types: one compiled loop)."""

    node_class: np.ndarray
    """Body class of each node, an index in :data:`~bulletnet.model.materials.BODY_CLASSES` [-],
    shape (N,), int64."""
    stiffness: np.ndarray
    """k_c between body classes [N/m], shape (5, 5)."""
    damping: np.ndarray
    """c_c between body classes [N s/m], shape (5, 5)."""
    mu_static: np.ndarray
    """Static friction coefficients between body classes [-], shape (5, 5)."""
    mu_kinetic: np.ndarray
    """Kinetic friction coefficients between body classes [-], shape (5, 5)."""
    params: np.ndarray
    """Friction slip [s/kg], Verlet skin [m], normal law (1: implicit, 0: exact), shape (3,)."""
    parts: np.ndarray
    """Debris parts, one row each (:data:`~bulletnet.kernels.geometry.PART_COLUMNS`: shape
    code, pose in the body frame [-, m], dimensions [m]; :func:`debris_geometry`), shape
    (K, 17)."""
    mesh: MeshArrays
    """Triangles and hierarchies of the debris' mesh parts, in their part frames [m]."""
    com_body: np.ndarray
    """Debris centre of mass in its body frame [m], shape (3,)."""
    bound: np.ndarray
    """Radius of the debris' bounding sphere about its centre of mass [m], shape (1,)."""
    com: np.ndarray
    """Debris centre of mass [m], shape (3,)."""
    quat: np.ndarray
    """Debris orientation, quaternion x, y, z, w [-], shape (1, 4)."""
    velocity: np.ndarray
    """Debris velocity [m/s], shape (3,)."""
    omega: np.ndarray
    """Debris angular velocity, world frame [rad/s], shape (1, 3)."""
    impulse: np.ndarray
    """Impulse of the net on the debris since the chunk began: force [N s] (3), then moment
    about the centre of mass [N m s] (3), shape (6,)."""
    node_impulse: np.ndarray
    """Debris contact normal impulse on each node since last read [N s], shape (N,)."""
    self_impulse: np.ndarray
    """Node-node contact normal impulse on each node since last read [N s], shape (N,)."""
    pairs: np.ndarray
    """The Verlet list of node pairs [-], shape (C, 2), int64."""
    pair_meta: np.ndarray
    """Pairs in the list, overflow flag, builds so far [-], shape (3,), int64."""
    build_position: np.ndarray
    """Node positions at the last build of the list [m], shape (N, 3)."""
    first_contact: np.ndarray
    """Times of the first debris and the first node-node contact [s] (-1: none yet),
    shape (2,)."""
    flags: np.ndarray
    """Whether debris contact and self-contact are on [-], shape (2,), bool."""
    debris_gap: np.ndarray
    """Gap to the debris each node's last step predicted [m] (+inf: none), shape (N,)."""
    clear: np.ndarray
    """Lower bound of each node's gap to the debris at its last distance query [m] (-inf:
    none yet; :mod:`bulletnet.solver.debris_gap`), shape (N,)."""
    clear_at: np.ndarray
    """Where each node was at that query, in the debris' body frame [m], shape (N, 3)."""
    pair_gap: np.ndarray
    """Gap each listed pair's last step predicted [m] (+inf: none), shape (C,)."""
    projections: np.ndarray
    """Overlap projections: count [-], total distance [m], shape (2,) (with the coupled
    solve: overlaps absorbed into the contacts' references)."""
    solve: SolveArrays | None = None
    """The coupled solve's arrays (:mod:`bulletnet.solver.contact_solve`); None: the
    sequential stage (which then compiles no solve)."""


@dataclass
class ContactSetup:
    arrays: ContactArrays
    """The arrays the compiled stage reads (see :func:`setup`)."""
    has_debris: bool
    """Whether nodes collide with the debris."""
    self_contact: bool
    """Whether nodes collide with each other."""

    @property
    def enabled(self) -> bool:
        return self.has_debris or self.self_contact


def pair_tables(s: Scenario, model: NetModel) -> tuple[np.ndarray, ...]:
    """(k_c [N/m], c_c [N s/m], mu_s [-], mu_k [-]) between body classes, each (5, 5) and
    symmetric, in :data:`~bulletnet.model.materials.BODY_CLASSES` order (0 debris, 1 corner mass,
    2 corner node, 3 edge node, 4 inner node)."""
    k = np.zeros((5, 5))
    c = np.zeros((5, 5))
    for (a, b), (kc, cc) in contact_table(s, model).items():
        ia, ib = BODY_CLASSES.index(a), BODY_CLASSES.index(b)
        k[ia, ib] = k[ib, ia] = kc
        c[ia, ib] = c[ib, ia] = cc
    f = s.friction
    mu_s = np.full((5, 5), f.net_net)
    for a in range(5):
        for b in range(5):
            metal = (a in ALUMINIUM_CLASSES) + (b in ALUMINIUM_CLASSES)
            mu_s[a, b] = (f.net_net, f.aluminium_net, f.aluminium_aluminium)[metal]
    return k, c, mu_s, mu_s / f.kinetic_ratio


def debris_geometry(parts) -> tuple[np.ndarray, MeshArrays]:
    """Debris parts (:class:`~bulletnet.model.debris.Part`) as the compiled contact loop reads
    them: rows (K, :data:`~bulletnet.kernels.geometry.PART_COLUMNS`) of shape code, rotation
    from the part frame to the body frame (row-major) [-], the part frame's origin [m] and
    the dimensions [m] (a box's as half edge lengths, a mesh's root node), and the mesh
    parts' :class:`~bulletnet.model.mesh.MeshArrays`."""
    from ..model.debris import part_mesh

    meshes = [part for part in parts if part.shape == "mesh"]
    mesh, roots = build([part_mesh(part, frame="part") for part in meshes])
    root_of = {id(part): root for part, root in zip(meshes, roots, strict=True)}
    rows = np.zeros((len(parts), PART_COLUMNS))
    for k, part in enumerate(parts):
        code, size = {"frustum": (FRUSTUM, part.size), "box": (BOX, 0.5 * np.asarray(part.size)),
                      "sphere": (SPHERE, part.size),
                      "mesh": (MESH, (root_of.get(id(part), 0),))}[part.shape]
        rows[k, 0] = code
        rows[k, 1:10] = part.matrix.ravel()
        rows[k, 10:13] = part.position
        rows[k, 13:13 + len(size)] = size
    return rows, mesh


def setup(s: Scenario, model: NetModel, debris=None, enabled: bool = True) -> ContactSetup:
    """The contact arrays of a scene: with ``debris`` (a :class:`~bulletnet.model.debris.Debris`)
    if the scene has one, self-contact if the scene asks for it; nothing with ``enabled``
    false. Without contact the arrays are empty (same types: the same compiled loop)."""
    n = model.node_count
    on = enabled and s.contact.enabled
    has_debris = bool(on and debris is not None)
    self_contact = bool(on and s.contact.self_contact)
    node_class = np.array([CLASS_OF_KIND[NodeKind(kd)] for kd in model.kind], dtype=np.int64)
    if on:
        k, c, mu_s, mu_k = pair_tables(s, model)
    else:
        k = c = mu_s = mu_k = np.zeros((5, 5))
    if has_debris:
        parts, mesh = debris_geometry(debris.parts)
        com_body = np.asarray(debris.center_of_mass, dtype=float)
        bound = max(p.reach(com_body) for p in debris.parts)
    else:
        parts, mesh, com_body, bound = np.zeros((0, PART_COLUMNS)), no_meshes(), np.zeros(3), 0.0
    capacity = 16 * n if self_contact else 0
    arrays = ContactArrays(
        node_class=node_class, stiffness=k, damping=c, mu_static=mu_s, mu_kinetic=mu_k,
        params=np.array([s.friction.slip, s.contact.skin, float(s.contact.model == "implicit")]),
        parts=parts, mesh=mesh, com_body=com_body, bound=np.array([bound]),
        com=np.zeros(3), quat=np.array([[0.0, 0.0, 0.0, 1.0]]), velocity=np.zeros(3),
        omega=np.zeros((1, 3)), impulse=np.zeros(6),
        node_impulse=np.zeros(n), self_impulse=np.zeros(n),
        pairs=np.zeros((capacity, 2), dtype=np.int64), pair_meta=np.zeros(3, dtype=np.int64),
        build_position=np.zeros((n, 3)), first_contact=np.full(2, -1.0),
        flags=np.array([has_debris, self_contact]),
        debris_gap=np.full(n, np.inf), clear=np.full(n, -np.inf), clear_at=np.zeros((n, 3)),
        pair_gap=np.full(capacity, np.inf),
        projections=np.zeros(2),
        solve=(solve_arrays(s.contact.tolerance, s.contact.sweeps, n, capacity)
               if on and s.contact.solver == "coupled" else None),
    )
    return ContactSetup(arrays=arrays, has_debris=has_debris, self_contact=self_contact)


def grow_pair_list(setup_: ContactSetup) -> ContactSetup:
    """The same setup with twice the Verlet list capacity (after an overflow)."""
    a = setup_.arrays
    pairs = np.zeros((2 * max(a.pairs.shape[0], 1), 2), dtype=np.int64)
    a.pair_meta[:] = 0
    solve = None if a.solve is None else grown(a.solve, a.node_class.shape[0], pairs.shape[0])
    return ContactSetup(arrays=a._replace(pairs=pairs, pair_gap=np.full(pairs.shape[0], np.inf),
                                          solve=solve),
                        has_debris=setup_.has_debris,
                        self_contact=setup_.self_contact)


@nb.njit(cache=True, error_model="numpy")
def _cross(a, b, out):
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]


@nb.njit(cache=True, error_model="numpy")
def _norm(a):
    return math.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])


@nb.njit(cache=True, error_model="numpy")
def _slip(rel, n):
    """Remove from the relative velocity ``rel`` [m/s] (3,) its component along the unit
    normal ``n``, in place; return the remaining slip speed [m/s]."""
    rel_n = rel[0] * n[0] + rel[1] * n[1] + rel[2] * n[2]
    for a in range(3):
        rel[a] -= rel_n * n[a]
    return _norm(rel)


@nb.njit(cache=True, error_model="numpy")
def normal_motion(params, s, u, a, k, c, m, dt):
    """The scene's normal law over one step: exact (:func:`normal_step`) or backward Euler
    (:func:`implicit_normal_step`, ``contact.model = "implicit"``)."""
    if params[2] == 1.0:
        return implicit_normal_step(s, u, a, k, c, m, dt)
    return normal_step(s, u, a, k, c, m, dt)


@nb.njit(cache=True, error_model="numpy")
def overlap_error(s0, predicted, stats):
    """The part of a measured start-of-step gap ``s0`` [m] that the contact dynamics do not
    explain: how far it lies below the gap the last step predicted (``predicted``, +inf if
    none) or below touching (0), whichever is deeper; 0 if none. Such overlap comes from
    geometry the step linearizes (a node sliding into a concave corner, a pair passing
    tangentially, the debris turning) and is removed by moving the node, not by the contact
    spring: at k_c ~ 4e9 N/m a 0.1 mm error would launch a 2 g node at 140 m/s. Counted in
    ``stats`` (number, total distance [m])."""
    target = min(predicted, 0.0)
    if s0 >= target:
        return 0.0
    stats[0] += 1.0
    stats[1] += target - s0
    return target - s0


@nb.njit(cache=True, error_model="numpy")
def debris_stage(pos, vel, dv, mass, radius, fixed, contact, dt, t):
    """Contact of every node with the debris over the step just taken: (pos, vel) hold the
    free step's end, dv its velocity increment [m/s]; the debris moves rigidly at its
    velocity over the step. Impulses on the debris are added to contact.impulse."""
    cls, kc, cc, mu_s, mu_k = (contact.node_class, contact.stiffness, contact.damping,
                               contact.mu_static, contact.mu_kinetic)
    params = contact.params
    slip = params[0]
    com, vd, wd = contact.com, contact.velocity, contact.omega
    imp, node_imp = contact.impulse, contact.node_impulse
    first, predicted, stats = contact.first_contact, contact.debris_gap, contact.projections
    rot, origin = debris_pose(com, contact.quat, contact.com_body)
    w = wd[0]
    speed = surface_speed(contact)
    p0, n, r, vs, acc, tmp = (np.empty(3), np.empty(3), np.empty(3), np.empty(3),
                              np.empty(3), np.empty(3))
    for i in range(pos.shape[0]):
        if fixed[i] or cls[i] < 0:
            continue
        s0, d = start_gap(i, pos, vel, dv, radius, contact, rot, origin, speed, dt, p0, n)
        if s0 == np.inf:
            predicted[i] = np.inf
            continue
        lift = overlap_error(s0, predicted[i], stats)
        if lift > 0.0:
            s0 += lift
            for a in range(3):
                pos[i, a] += lift * n[a]
        for a in range(3):
            r[a] = p0[a] - d * n[a] - com[a]  # contact point on the surface, from the COM
        _cross(w, r, vs)
        _cross(w, vs, acc)  # centripetal acceleration of the surface point
        for a in range(3):
            vs[a] += vd[a]
        u0 = dvn = acc_n = 0.0
        for a in range(3):
            u0 += (vel[i, a] - dv[i, a] - vs[a]) * n[a]
            dvn += dv[i, a] * n[a]
            acc_n += acc[a] * n[a]
        c = cls[i]
        m = mass[i]
        s1, u1, tc = normal_motion(params, s0, u0, dvn / dt - acc_n, kc[0, c], cc[0, c], m,
                                   dt)
        predicted[i] = s1
        if tc <= 0.0:
            continue
        u_free = u0 + dvn
        shift, du = s1 - (s0 + dt * u_free), u1 - u_free
        for a in range(3):
            pos[i, a] += shift * n[a]
            vel[i, a] += du * n[a]
        jn = m * du
        for a in range(3):
            tmp[a] = vel[i, a] - vs[a]
        slip_speed = _slip(tmp, n)
        jt = friction_impulse(slip_speed, max(jn, 0.0), tc, m, slip, mu_s[0, c], mu_k[0, c])
        for a in range(3):
            tangential = -jt * tmp[a] / slip_speed if jt > 0.0 else 0.0
            vel[i, a] += tangential / m
            pos[i, a] += dt * tangential / m
            tmp[a] = -(jn * n[a] + tangential)  # impulse on the debris
        add_debris_impulse(imp, r, tmp)
        node_imp[i] += jn
        if first[0] < 0.0:
            first[0] = t + dt


@nb.njit(cache=True, error_model="numpy", _nrt=True)
def build_pairs(pos, radius, contact):
    """Rebuild the Verlet list of node pairs closer than their radii plus the skin (sweep
    along x; nodes without contact left out). Returns False if the list's capacity is too
    small. Compiled with reference counting (``_nrt=True``), which the step loop that calls
    it goes without: its sort allocates."""
    skin = contact.params[1]
    pairs, meta, ref = contact.pairs, contact.pair_meta, contact.build_position
    cls = contact.node_class
    old_count = meta[0]
    keep_pairs(contact.solve, pairs, old_count, contact.pair_gap)
    order = np.argsort(pos[:, 0])
    largest = 0.0
    for i in range(pos.shape[0]):
        if cls[i] >= 0:
            largest = max(largest, radius[i])
    reach = 2.0 * largest + skin
    count = 0
    for a in range(order.shape[0]):
        i = order[a]
        if cls[i] < 0:
            continue
        for b in range(a + 1, order.shape[0]):
            j = order[b]
            if pos[j, 0] - pos[i, 0] > reach:
                break
            if cls[j] < 0:
                continue
            dx, dy, dz = pos[j, 0] - pos[i, 0], pos[j, 1] - pos[i, 1], pos[j, 2] - pos[i, 2]
            cut = radius[i] + radius[j] + skin
            if dx * dx + dy * dy + dz * dz < cut * cut:
                if count == pairs.shape[0]:
                    meta[1] = 1
                    return False
                pairs[count, 0], pairs[count, 1] = i, j
                count += 1
    meta[0] = count
    meta[2] += 1
    for i in range(pos.shape[0]):  # (a loop: `ref[:] = pos` compiles numba's shape checks)
        for a in range(3):
            ref[i, a] = pos[i, a]
    contact.pair_gap[:] = np.inf
    carry_pairs(contact.solve, pairs, count, old_count, contact.pair_gap, pos.shape[0])
    return True


@nb.njit(cache=True, error_model="numpy")
def ensure_pairs(pos, radius, contact):
    """Before a step: rebuild the Verlet list if no list exists or a node has moved more
    than 0.4 skin since the last build (two nodes then close at most 0.8 skin, leaving 0.2
    skin for the step itself). Returns False if the list's capacity is too small."""
    if not contact.flags[1]:
        return True
    skin, meta, ref = contact.params[1], contact.pair_meta, contact.build_position
    moved = 0.0
    for i in range(pos.shape[0]):
        d2 = 0.0
        for a in range(3):
            d2 += (pos[i, a] - ref[i, a]) ** 2
        moved = max(moved, d2)
    if meta[2] == 0 or moved > (0.4 * skin) ** 2:
        return build_pairs(pos, radius, contact)
    return True


@nb.njit(cache=True, error_model="numpy")
def self_stage(pos, vel, dv, mass, radius, contact, dt, t):
    """Contact between node spheres over the step just taken (see :func:`debris_stage`),
    for the pairs of the Verlet list (:func:`ensure_pairs`)."""
    cls, kc, cc, mu_s, mu_k = (contact.node_class, contact.stiffness, contact.damping,
                               contact.mu_static, contact.mu_kinetic)
    params = contact.params
    self_imp, pairs, meta = contact.self_impulse, contact.pairs, contact.pair_meta
    first = contact.first_contact
    predicted, stats = contact.pair_gap, contact.projections
    skin, slip = params[1], params[0]
    n, tmp = np.empty(3), np.empty(3)
    for q in range(meta[0]):
        i, j = pairs[q, 0], pairs[q, 1]
        dist = 0.0
        for a in range(3):
            n[a] = (pos[j, a] - dt * vel[j, a]) - (pos[i, a] - dt * vel[i, a])
            dist += n[a] * n[a]
        dist = math.sqrt(dist)
        s0 = dist - radius[i] - radius[j]
        if s0 > skin:
            predicted[q] = np.inf
            continue
        for a in range(3):
            n[a] /= dist
        mc = mass[i] * mass[j] / (mass[i] + mass[j])
        lift = overlap_error(s0, predicted[q], stats)
        if lift > 0.0:
            s0 += lift
            for a in range(3):
                pos[j, a] += mc / mass[j] * lift * n[a]
                pos[i, a] -= mc / mass[i] * lift * n[a]
        u0 = dvn = 0.0
        for a in range(3):
            u0 += ((vel[j, a] - dv[j, a]) - (vel[i, a] - dv[i, a])) * n[a]
            dvn += (dv[j, a] - dv[i, a]) * n[a]
        ci, cj = cls[i], cls[j]
        s1, u1, tc = normal_motion(params, s0, u0, dvn / dt, kc[ci, cj], cc[ci, cj], mc, dt)
        predicted[q] = s1
        if tc <= 0.0:
            continue
        u_free = u0 + dvn
        shift, du = s1 - (s0 + dt * u_free), u1 - u_free
        for a in range(3):
            pos[j, a] += mc / mass[j] * shift * n[a]
            pos[i, a] -= mc / mass[i] * shift * n[a]
            vel[j, a] += mc / mass[j] * du * n[a]
            vel[i, a] -= mc / mass[i] * du * n[a]
        for a in range(3):
            tmp[a] = vel[j, a] - vel[i, a]
        slip_speed = _slip(tmp, n)
        jn = mc * du
        jt = friction_impulse(slip_speed, max(jn, 0.0), tc, mc, slip, mu_s[ci, cj],
                              mu_k[ci, cj])
        if jt > 0.0:
            for a in range(3):
                tangential = -jt * tmp[a] / slip_speed  # on j; -tangential on i
                vel[j, a] += tangential / mass[j]
                pos[j, a] += dt * tangential / mass[j]
                vel[i, a] -= tangential / mass[i]
                pos[i, a] -= dt * tangential / mass[i]
        self_imp[i] += jn
        self_imp[j] += jn
        if first[1] < 0.0:
            first[1] = t + dt


@nb.njit(cache=True, error_model="numpy", _nrt=True)
def contact_stage(pos, vel, dv, mass, radius, fixed, contact, dt, t):
    """Self-contact, debris contact (sequentially, or together with the coupled solve:
    ``contact.solve``), then the debris' rigid motion over the step (constant velocity).
    Compiled with reference counting (``_nrt=True``), as are the stages it calls, whatever
    the caller: they allocate small scratch vectors, and the step loop that calls it goes
    without (:func:`bulletnet.solver.integrators.advance`)."""
    _stages(pos, vel, dv, mass, radius, fixed, contact, contact.solve, dt, t)


@nb.njit(cache=True, error_model="numpy")
def _stages(pos, vel, dv, mass, radius, fixed, contact, solve, dt, t):
    """:func:`contact_stage` with its solve as an argument (None: the sequential stages;
    numba prunes the other branch, so a scene compiles only its own)."""
    flags = contact.flags
    if solve is None:
        if flags[1]:
            self_stage(pos, vel, dv, mass, radius, contact, dt, t)
        if flags[0]:
            debris_stage(pos, vel, dv, mass, radius, fixed, contact, dt, t)
    else:
        coupled_stage(pos, vel, dv, mass, radius, fixed, contact, solve, dt, t)
    if flags[0]:
        com, quat, vd, wd = contact.com, contact.quat, contact.velocity, contact.omega
        for a in range(3):
            com[a] += dt * vd[a]
        integrate_rotation(quat, wd, dt)
