"""Time integrators of the net, compiled with numba.

Each integrator computes the velocity increment dv [m/s] of one step from the state; the step
is then v <- v + dv, x <- x + dt v (and, with bending, w <- w + dt tau / J, q <- exp(dt w / 2) q;
the soft bending springs are evaluated every n steps, see :func:`advance`).
The fast engine does this in compiled loops; the bullet engine hands m dv / dt and tau to
PyBullet as external force and torque and lets PyBullet take the step (its integrator is the
same semi-implicit update), so both engines run the same method.

- ``symplectic_euler``: dv = dt F(x, v) / m. Explicit, first order; stable only while
  dt < ~2 m / c for the thread dampers (a few microseconds for the paper's nets).
- ``exponential_euler``: symplectic Euler with each thread's damper relaxing its rate
  exactly over the step (its two ends' masses shared among the threads that meet there):
  the dampers no longer limit the step, the springs do (about sqrt(2) / omega_max;
  :mod:`bulletnet.solver.exponential_damping`).
- ``implicit_euler``: linearly implicit (one Newton step of) backward Euler on the axial
  threads, (M + dt C + dt^2 K) dv = dt F - dt^2 K v, solved by preconditioned conjugate
  gradients (block Jacobi, or block D-ILU: :mod:`bulletnet.solver.dilu`;
  :func:`bulletnet.solver.pcg.solve`, shared with the grid's stencils),
  then shifted by the uniform velocity that makes the step conserve momentum exactly (the
  threads' blocks vanish on it). Bending forces enter F explicitly; the node rotations take
  dw = h tau / (J + h C_g + h^2 K_g) with C_g, K_g the Gershgorin bounds of their angular
  damping and stiffness (:func:`rotational_bounds`; h the bending interval): a diagonally
  implicit step, stable at any step. First order, stable on the damped threads.

Clamped nodes (``model.fixed``) never move or turn.
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import numba as nb
import numpy as np

from ..kernels.axial import (
    add_block,
    add_thread_blocks,
    add_thread_rhs,
    axial_forces,
    axial_linearization,
    invert3,
)
from ..kernels.bending import advance_rotation, bending_forces
from ..kernels.breakage import break_cables, break_threads
from ..kernels.cable import (
    CableArrays,
    add_cable_blocks,
    add_cable_product,
    cable_forces,
    reel,
)
from ..kernels.orbit import OrbitArrays, orbit_forces
from ..kernels.peaks import track_cables, track_threads
from ..kernels.reel import ReelArrays, reel_tether
from ..model.net import NetModel
from . import dilu as dilu_kernels
from . import grid as grid_kernels
from . import pcg
from .contact_stage import contact_stage, ensure_pairs

SYMPLECTIC_EULER = 0
IMPLICIT_EULER = 1
INTEGRATOR_IDS = {"symplectic_euler": SYMPLECTIC_EULER, "implicit_euler": IMPLICIT_EULER,
                  "exponential_euler": SYMPLECTIC_EULER}
"""The kernels of each integrator: exponential Euler is symplectic Euler's step with the
dampers' coefficients set for the step (:mod:`bulletnet.solver.exponential_damping`)."""


def rotational_bounds(model: NetModel) -> tuple[np.ndarray, np.ndarray]:
    """Gershgorin bounds of each node's row of the bending system's angular damping and
    stiffness: 2 sum over its threads of (c_b + c_t l^2) [N m s/rad] and of (k_b + k_t l^2)
    [N m/rad], each shape (N,). They bound the eigenvalues of the coupled rotations."""
    stiffness = model.bending_stiffness + model.transverse_stiffness * model.rest_length**2
    damping = model.bending_damping + model.transverse_damping * model.rest_length**2
    k_sum = np.zeros(model.node_count)
    c_sum = np.zeros(model.node_count)
    for end in (0, 1):
        np.add.at(k_sum, model.pairs[:, end], stiffness)
        np.add.at(c_sum, model.pairs[:, end], damping)
    return 2.0 * c_sum, 2.0 * k_sum


class ModelArrays(NamedTuple):
    """The net model as the compiled kernels read it (:class:`~bulletnet.model.net.NetModel`'s
    arrays, plus derived ones), for N nodes and P threads."""

    mass: np.ndarray
    """Node masses [kg], shape (N,)."""
    pairs: np.ndarray
    """Thread end nodes (i, j) [-], shape (P, 2), int64."""
    rest: np.ndarray
    """Thread rest lengths [m], shape (P,)."""
    k_a: np.ndarray
    """Axial stiffness [N/m], shape (P,)."""
    c_a: np.ndarray
    """Axial damping [N s/m], shape (P,)."""
    k_t: np.ndarray
    """Transverse stiffness [N/m], shape (P,)."""
    c_t: np.ndarray
    """Transverse damping [N s/m], shape (P,)."""
    k_b: np.ndarray
    """Bending stiffness [N m/rad], shape (P,)."""
    c_b: np.ndarray
    """Bending damping [N m s/rad], shape (P,)."""
    inertia: np.ndarray
    """Node moments of inertia [kg m^2], shape (N,)."""
    rest_axis: np.ndarray
    """Thread rest direction in node i's body frame [-], shape (P, 3)."""
    fixed: np.ndarray
    """Clamped nodes [-], shape (N,), bool."""
    load: np.ndarray
    """Constant external force on each node [N], shape (N, 3)."""
    bilateral: bool
    """Whether the elements also resist compression."""
    inv_mass: np.ndarray
    """1 / mass, 0 for clamped nodes [1/kg], shape (N, 3): each node's value in each
    component, so that symplectic Euler's increment runs over the flat arrays (vectorized)."""
    radius: np.ndarray
    """Node sphere radii [m], shape (N,)."""
    rot_c: np.ndarray
    """Gershgorin bound of each node's angular damping [N m s/rad], shape (N,)
    (:func:`rotational_bounds`)."""
    rot_k: np.ndarray
    """Gershgorin bound of each node's angular stiffness [N m/rad], shape (N,)."""
    cables: CableArrays | None
    """The closing cables and their winches (:mod:`bulletnet.kernels.cable`); None without
    (the cable kernels then compile to nothing)."""
    orbit: OrbitArrays | None = None
    """The reference orbit whose HCW accelerations every node feels
    (:mod:`bulletnet.kernels.orbit`); None without (nothing compiled)."""
    reel: ReelArrays | None = None
    """The reel at the chaser, which sets the tether's rest lengths, their rates, stiffness
    and damping in ``rest``, ``rest_rate``, ``k_a`` and ``c_a`` (:mod:`bulletnet.kernels.reel`;
    they must then be writable); None without (nothing compiled)."""
    rest_rate: np.ndarray | None = None
    """Thread rest-length rates l_0' [m/s], shape (P,), which the dampers subtract (the
    reeled tether's; :mod:`bulletnet.kernels.axial`); None without a reel (all zero, nothing
    read)."""
    dilu: dilu_kernels.DiluArrays | None = None
    """Block D-ILU's couplings and scratch, the implicit step's preconditioner
    (:mod:`bulletnet.solver.dilu`); None: block Jacobi."""


def model_arrays(model: NetModel, cables: CableArrays | None = None,
                 orbit: OrbitArrays | None = None, reel: ReelArrays | None = None,
                 preconditioner: str = "block_jacobi") -> ModelArrays:
    """The model's arrays as the compiled kernels read them, with the closing ``cables``
    (:func:`~bulletnet.kernels.cable.cable_arrays`; None, or none in them: no cables), the
    reference ``orbit`` and the ``reel`` at the chaser (None: none; with one, the threads'
    rest-length rates, zero), and the implicit step's ``preconditioner`` (block_jacobi or
    block_dilu)."""
    m = model
    cables = cables if cables is not None and cables.rest.shape[0] else None
    rot_c, rot_k = rotational_bounds(m)
    return ModelArrays(
        mass=m.mass, pairs=m.pairs, rest=m.rest_length, k_a=m.axial_stiffness,
        c_a=m.axial_damping, k_t=m.transverse_stiffness, c_t=m.transverse_damping,
        k_b=m.bending_stiffness, c_b=m.bending_damping, inertia=m.inertia,
        rest_axis=m.rest_axis, fixed=m.fixed, load=m.load, bilateral=m.bilateral,
        # clamped nodes: no velocity change
        inv_mass=np.repeat(np.where(m.fixed, 0.0, 1.0 / m.mass)[:, None], 3, axis=1),
        radius=m.radius, rot_c=rot_c, rot_k=rot_k,
        cables=cables, orbit=orbit, reel=reel,
        rest_rate=None if reel is None else np.zeros(m.thread_count),
        dilu=dilu_kernels.dilu_arrays(m, cables) if preconditioner == "block_dilu" else None)


class Workspace(NamedTuple):
    """Scratch arrays of the integrators for a net of N nodes and P threads
    (:func:`workspace`)."""

    force: np.ndarray
    """Force on each node [N], shape (N, 3)."""
    torque: np.ndarray
    """Torque on each node [N m], shape (N, 3) (bending only)."""
    tension: np.ndarray
    """Thread tensions [N], shape (P,)."""
    shear: np.ndarray
    """Thread shear force magnitudes [N], shape (P,) (bending only)."""
    along: np.ndarray
    """Implicit block along each thread [kg], shape (P,)."""
    across: np.ndarray
    """Implicit block across each thread [kg], shape (P,)."""
    axis: np.ndarray
    """Thread unit directions [-], shape (P, 3)."""
    dv: np.ndarray
    """Velocity increment of the last step [m/s], shape (N, 3); warm start of CG."""
    cg: np.ndarray
    """CG vectors r, z, d, A d, shape (4, N, 3)."""
    block_inv: np.ndarray
    """Inverse block-Jacobi preconditioner [1/kg], shape (N, 3, 3)."""
    cg_iterations: np.ndarray
    """CG iterations summed over all implicit steps [-], shape (1,), int64."""
    bend: np.ndarray
    """Bending forces of the last evaluation [N], shape (N, 3); held until the next."""
    step_count: np.ndarray
    """Steps taken, for the bending schedule [-], shape (1,), int64."""
    gain: np.ndarray
    """Angular velocity change per step per unit held bending torque [rad/(N m s)],
    shape (N,) (:func:`angular_gains`)."""
    rotation: np.ndarray
    """The nodes' rotation vectors over the steps being taken [rad], shape (3, N)
    (:func:`~bulletnet.kernels.bending.advance_rotation`'s scratch)."""
    turned: np.ndarray
    """The nodes' turned orientations [-], shape (4, N) (its scratch)."""


def workspace(n: int, p: int) -> Workspace:
    """Zeroed scratch arrays for N nodes and P threads."""
    return Workspace(
        force=np.zeros((n, 3)), torque=np.zeros((n, 3)), tension=np.zeros(p),
        shear=np.zeros(p), along=np.zeros(p), across=np.zeros(p), axis=np.zeros((p, 3)),
        dv=np.zeros((n, 3)), cg=np.zeros((4, n, 3)), block_inv=np.zeros((n, 3, 3)),
        cg_iterations=np.zeros(1, dtype=np.int64), bend=np.zeros((n, 3)),
        step_count=np.zeros(1, dtype=np.int64), gain=np.zeros(n), rotation=np.zeros((3, n)),
        turned=np.zeros((4, n)))


class PairSystem(NamedTuple):
    """The implicit-Euler system on the pair list, as the operations of
    :func:`bulletnet.solver.pcg.solve` read it: only the arrays they use (each compiled call
    with reference counting increments and decrements every array it is passed)."""

    mass: np.ndarray
    """Node masses [kg], shape (N,)."""
    fixed: np.ndarray
    """Clamped nodes [-], shape (N,), bool."""
    pairs: np.ndarray
    """Thread end nodes (i, j) [-], shape (P, 2), int64."""
    along: np.ndarray
    """Implicit block along each thread [kg], shape (P,)."""
    across: np.ndarray
    """Implicit block across each thread [kg], shape (P,)."""
    axis: np.ndarray
    """Thread unit directions [-], shape (P, 3)."""
    block_inv: np.ndarray
    """Inverse block-Jacobi preconditioner [1/kg], shape (N, 3, 3) (with block D-ILU, the
    diagonal blocks it is factored from [kg])."""
    cables: CableArrays | None
    """The closing cables (their blocks and vertices' shares); None without."""
    dilu: dilu_kernels.DiluArrays | None
    """Block D-ILU's couplings and scratch; None: block Jacobi."""


@nb.njit(cache=True, error_model="numpy", inline="always")
def evaluate_bending(pos, vel, quat, omega, model, work):
    """The bending springs afresh: forces [N] into work's bend, torques [N m] into its
    torque, the threads' shear [N] into its shear. Without bending (``quat`` None) nothing,
    and nothing is compiled."""
    if quat is None:
        return
    work.torque[:] = 0.0
    work.bend[:] = 0.0
    bending_forces(pos, vel, quat, omega, model.pairs, model.rest_axis, model.k_t, model.c_t,
                   model.k_b, model.c_b, work.bend, work.torque, work.shear)


@nb.njit(cache=True, error_model="numpy", inline="always")
def external_forces(pos, vel, quat, omega, model, work, base, bending_weight, hold):
    """``base``, the forces that do not depend on the state (m g + load + external [N], (N, 3):
    :meth:`bulletnet.engines.base.Engine.base_forces`), and the bending forces into work's
    force (``quat``, ``omega``: the nodes' orientations (N, 4) and angular velocities [rad/s]
    (N, 3), or None without bending).
    With ``bending_weight`` w > 0 the bending springs are evaluated afresh first: their forces
    [N] into work's bend, their torques [N m] into work's torque, the threads' shear [N] into
    work's shear. The bending forces then enter as an impulse (w times, on this step only) or,
    with ``hold``, held (once on this and every step until the next evaluation)."""
    if bending_weight > 0.0:
        evaluate_bending(pos, vel, quat, omega, model, work)
    scale = 1.0 if hold else bending_weight  # (bend stays zero without bending)
    force, base_e, bend = work.force.reshape(-1), base.reshape(-1), work.bend.reshape(-1)
    for k in range(force.shape[0]):  # flat: vectorized
        force[k] = base_e[k] + scale * bend[k]


@nb.njit(cache=True, error_model="numpy")
def _apply_blocks(system, x, out):
    """out [kg m/s] = M x + sum_p B_p-Laplacian x + the cables' blocks x, the implicit-Euler
    system (:class:`PairSystem`) applied to x [m/s] (the product A x of
    :func:`bulletnet.solver.pcg.solve`; rows of clamped nodes are the identity); x and out
    (N, 3)."""
    mass, fixed = system.mass, system.fixed
    for i in range(x.shape[0]):
        for a in range(3):
            out[i, a] = mass[i] * x[i, a]
    add_thread_blocks(x, system.pairs, system.along, system.across, system.axis, out)
    add_cable_product(x, system.cables, out, 0.0, 1.0)
    for i in range(x.shape[0]):
        if fixed[i]:
            out[i, 0], out[i, 1], out[i, 2] = x[i, 0], x[i, 1], x[i, 2]


@nb.njit(cache=True, error_model="numpy")
def _block_jacobi(system):
    """Invert each node's 3x3 diagonal block of the implicit system (:class:`PairSystem`; the
    cables' vertices' shares included) into its block_inv (the preconditioner of
    :func:`bulletnet.solver.pcg.solve`)."""
    mass, pairs, along, across, axis = (system.mass, system.pairs, system.along, system.across,
                                        system.axis)
    n = mass.shape[0]
    flat = system.block_inv.reshape((n, 9))
    for i in range(n):
        for a in range(9):
            flat[i, a] = mass[i] if a % 4 == 0 else 0.0
    for p in range(pairs.shape[0]):
        if along[p] == 0.0 and across[p] == 0.0:
            continue
        for node in (pairs[p, 0], pairs[p, 1]):
            m = add_block((flat[node, 0], flat[node, 1], flat[node, 2], flat[node, 3],
                           flat[node, 4], flat[node, 5], flat[node, 6], flat[node, 7],
                           flat[node, 8]), along[p], across[p], axis[p, 0], axis[p, 1],
                          axis[p, 2])
            for a in range(9):
                flat[node, a] = m[a]
    add_cable_blocks(system.cables, flat, system.dilu is None)
    if _dilu_factor(system.dilu, system, flat):
        return
    for i in range(n):
        m = invert3((flat[i, 0], flat[i, 1], flat[i, 2], flat[i, 3], flat[i, 4], flat[i, 5],
                     flat[i, 6], flat[i, 7], flat[i, 8]))
        for a in range(9):
            flat[i, a] = m[a]


@nb.njit(cache=True, error_model="numpy")
def _dilu_factor(dilu, system, flat):
    """Block D-ILU's factor from the diagonal blocks ``flat`` (N, 9)
    (:func:`bulletnet.solver.dilu.factor`); False, and nothing compiled, without block D-ILU
    (``dilu`` None)."""
    if dilu is None:
        return False
    dilu_kernels.factor(dilu, flat.T, system.along, system.across, system.axis, system.cables,
                        None)
    return True


@nb.njit(cache=True, error_model="numpy")
def _precondition(system, r, z, ad, alpha):
    """:func:`_preconditioned` with the system's block D-ILU arrays (None: block Jacobi)."""
    return _preconditioned(system.dilu, system, r, z, ad, alpha)


@nb.njit(cache=True, error_model="numpy")
def _preconditioned(dilu, system, r, z, ad, alpha):
    """r [kg m/s] <- r - ``alpha`` [-] ad [kg m/s], then z [m/s] = the inverse diagonal blocks
    of :class:`PairSystem` times r, node by node, zero on clamped nodes; r, z and ad (N, 3).
    Returns r . z [kg m^2/s^2] and r . r [kg^2 m^2/s^2] summed in node order
    (:func:`bulletnet.solver.pcg.dot_terms`); with block D-ILU (system.dilu), z = its
    preconditioner times r (:func:`bulletnet.solver.dilu.precondition`)."""
    inv, fixed = system.block_inv, system.fixed
    if dilu is not None:
        return dilu_kernels.precondition(dilu, r.T, z.T, ad.T, alpha, r.shape[0],
                                         system.cables)
    rz = rr = 0.0
    for i in range(r.shape[0]):
        r0, r1, r2 = r[i, 0] - alpha * ad[i, 0], r[i, 1] - alpha * ad[i, 1], \
            r[i, 2] - alpha * ad[i, 2]
        r[i, 0], r[i, 1], r[i, 2] = r0, r1, r2
        z0 = z1 = z2 = 0.0
        if not fixed[i]:
            z0 = inv[i, 0, 0] * r0 + inv[i, 0, 1] * r1 + inv[i, 0, 2] * r2
            z1 = inv[i, 1, 0] * r0 + inv[i, 1, 1] * r1 + inv[i, 1, 2] * r2
            z2 = inv[i, 2, 0] * r0 + inv[i, 2, 1] * r1 + inv[i, 2, 2] * r2
        z[i, 0], z[i, 1], z[i, 2] = z0, z1, z2
        tz, tr = pcg.dot_terms(r0, r1, r2, z0, z1, z2)
        rz += tz
        rr += tr
    return rz, rr


@nb.njit(cache=True, error_model="numpy", inline="always")
def _components(x):
    """x (N, 3) as component rows (3, N) (its transpose)."""
    return x.T


@nb.njit(cache=True, error_model="numpy")
def implicit_increment(pos, vel, model, work, dt, tol):
    """Velocity increment dv [m/s] of one linearly implicit Euler step (see module doc), into
    work's dv (which holds the previous increment on entry: the CG warm start): the threads'
    linearization and the right-hand side on the pair list, then
    :func:`bulletnet.solver.pcg.solve` with the product :func:`_apply_blocks`, the
    preconditioner :func:`_block_jacobi`, :func:`_precondition`, to the relative residual
    ``tol`` [-] (``dt`` [s]; pos [m] and vel [m/s] (N, 3)). Work's force must hold the
    non-axial forces on entry (:func:`external_forces`)."""
    pairs, k_a, fixed = model.pairs, model.k_a, model.fixed
    force, along, across, axis = work.force, work.along, work.across, work.axis
    dv, cg = work.dv, work.cg
    n = pos.shape[0]
    cables = model.cables
    axial_linearization(pos, vel, pairs, model.rest, model.rest_rate, k_a, model.c_a,
                        model.bilateral, dt, force, work.tension, along, across, axis)
    cable_forces(pos, vel, cables, force, True, dt)
    orbit_forces(pos, vel, model.mass, model.orbit, force)  # explicit, Coriolis included
    r = cg[0]
    # right-hand side dt F - dt^2 K v, in r
    for i in range(n):
        for a in range(3):
            r[i, a] = dt * force[i, a]
    add_thread_rhs(vel, pairs, k_a, along, across, axis, dt, r)
    add_cable_product(vel, cables, r, dt * dt, -1.0)
    clamped = False
    for i in range(n):
        if fixed[i]:
            clamped = True
            r[i, 0], r[i, 1], r[i, 2] = 0.0, 0.0, 0.0
            dv[i, 0], dv[i, 1], dv[i, 2] = 0.0, 0.0, 0.0
    system = PairSystem(model.mass, fixed, pairs, along, across, axis, work.block_inv, cables,
                        model.dilu)
    pcg.solve(_apply_blocks, _block_jacobi, _precondition, _components, system, dv, r, cg[1],
              cg[2], cg[3], model.mass, n, tol, work.cg_iterations, not clamped)


@nb.njit(cache=True, error_model="numpy", inline="always")
def symplectic_increment(pos, vel, model, work, dt):
    """Velocity increment dv = dt F / m [m/s] of one symplectic Euler step, into work's dv.
    Work's force must hold the non-axial forces on entry (:func:`external_forces`)."""
    axial_forces(pos, vel, model.pairs, model.rest, model.rest_rate, model.k_a, model.c_a,
                 model.bilateral, work.force, work.tension)
    cable_forces(pos, vel, model.cables, work.force, False, dt)
    orbit_forces(pos, vel, model.mass, model.orbit, work.force)
    inv_mass, force, dv = model.inv_mass.reshape(-1), work.force.reshape(-1), work.dv.reshape(-1)
    for k in range(dv.shape[0]):  # flat: vectorized
        dv[k] = dt * inv_mass[k] * force[k]


@nb.njit(cache=True, error_model="numpy", inline="always")
def _move(pos, vel, dv, dt):
    """v <- v + dv [m/s], x <- x + dt v [m] over the flat (N, 3) arrays (vectorized)."""
    x, v, d = pos.reshape(-1), vel.reshape(-1), dv.reshape(-1)
    for k in range(x.shape[0]):
        v[k] += d[k]
        x[k] += dt * v[k]


@nb.njit(cache=True, error_model="numpy")
def angular_gains(method, weight, dt, model, gain):
    """Each node's angular velocity change per step of ``dt`` [s] per unit bending torque
    [rad/(N m s)] for springs evaluated every ``weight`` steps, into ``gain`` (N,): dt / J for
    symplectic Euler; for implicit Euler the rotations' own damping and stiffness are
    implicit on the diagonal, scaled by their Gershgorin bounds, dt / (J + h C_g + h^2 K_g)
    with h = weight dt (stable at any step). Zero for clamped nodes."""
    inertia, fixed, rot_c, rot_k = model.inertia, model.fixed, model.rot_c, model.rot_k
    h = dt * weight if method == IMPLICIT_EULER else 0.0
    for i in range(gain.shape[0]):
        gain[i] = 0.0 if fixed[i] else dt / (inertia[i] + h * rot_c[i] + h * h * rot_k[i])


@nb.njit(cache=True, error_model="numpy")
def bending_weight(bending, every, work):
    """Steps the bending springs evaluated this step stand for: ``every`` on every
    ``every``-th step, 0 otherwise (they are not evaluated) or without bending."""
    if not bending:
        return 0.0
    return float(every) if work.step_count[0] % every == 0 else 0.0


@nb.njit(cache=True, error_model="numpy", inline="always")
def symplectic_step(weight, pos, vel, quat, omega, model, work, base, dt, tol):
    """All forces at the state (bending with ``weight``), then symplectic Euler's velocity
    increment into work's dv; counts the step (``tol`` unused: the signature of
    :func:`implicit_step`)."""
    external_forces(pos, vel, quat, omega, model, work, base, weight, False)
    symplectic_increment(pos, vel, model, work, dt)
    work.step_count[0] += 1


@nb.njit(cache=True, error_model="numpy", inline="always")
def implicit_step(weight, pos, vel, quat, omega, model, work, base, dt, tol):
    """All forces at the state (bending with ``weight``), then implicit Euler's velocity
    increment (CG to the relative residual ``tol``) into work's dv; counts the step."""
    external_forces(pos, vel, quat, omega, model, work, base, weight, True)
    implicit_increment(pos, vel, model, work, dt, tol)
    work.step_count[0] += 1


def increment(implicit: bool):
    """The compiled kernel ``(weight, pos, vel, quat, omega, model, work, base, dt, tol)`` of
    one integrator: :func:`implicit_step` or :func:`symplectic_step` (each
    compiles only its own increment). Module-level functions, not closures: numba keys a
    closure's cache on its captured values, and a captured dispatcher pickles differently in
    every process, so a loop capturing one would compile anew in every run."""
    return implicit_step if implicit else symplectic_step


@functools.cache
def advance(on_grid: bool, implicit: bool):
    """The compiled loop ``(every, steps, pos, vel, quat, omega, model, work, base, dt, tol,
    contact, t0, grid, views, breakage, peaks)`` of the grid's stencils
    (``on_grid``) or the pair-list kernels, with implicit Euler (``implicit``: CG to the
    relative residual ``tol``) or symplectic Euler. It takes up to ``steps`` steps in place
    on (pos, vel[, quat, omega]) from time ``t0`` [s]: the bending forces every ``every``
    steps (``quat``, ``omega`` None: no bending); then contact
    (:func:`bulletnet.solver.contact_stage.contact_stage`; ``contact`` None: none); the
    winches reel the closing cables before each step (:func:`~bulletnet.kernels.cable.reel`;
    model's cables None: none); after each step the
    elements whose tension reached their breaking tension fail
    (:mod:`bulletnet.kernels.breakage`; ``breakage`` None: none, nothing compiled; the
    model's thread arrays k_a .. c_b must then be writable); after each step each element's
    running maximum of its tension is kept (:mod:`bulletnet.kernels.peaks`; ``peaks``
    None: none, nothing compiled); last, the reel at the chaser sets the tether's rest
    lengths for the next step from the state the step ended in
    (:func:`~bulletnet.kernels.reel.reel_tether`, into the pair list's arrays or the grid's
    other threads'; model's reel None: none). Returns the steps
    taken: fewer only if the self-contact list must grow first (the caller grows it and
    continues). The caller checks the result for non-finite values; a diverging chunk is at
    most one record interval. The bending springs, evaluated every ``every`` steps, act as
    one impulse standing for the interval (symplectic Euler: the multirate step stays
    symplectic) or are held over it (implicit Euler: a smooth right-hand side keeps the CG
    warm start); either way the orientations are advanced once per interval
    (:func:`~bulletnet.kernels.bending.advance_rotation`). On the grid
    (:mod:`bulletnet.solver.grid`)
    ``pos``, ``vel``, ``quat``, ``omega`` and work's dv are its ``views``, and base (m g + load +
    external [N], (N, 3)) has been loaded into its base (grid and views are None on the pair list).

    A scene compiles only the kernels it uses: ``on_grid`` and ``implicit`` are constants of
    the loop and a feature left out is None, and numba prunes those branches before typing
    (a net without bending compiles no bending kernel, a deployment no contact stage); a
    free net on the grid (no bending, contact or cables) takes
    :func:`bulletnet.solver.grid.free_steps` and compiles none of this loop.

    The loop is compiled without numba's reference counting (``_nrt=False``), as the grid
    kernels are, and so are the kernels it calls (they inherit the setting unless they set
    it): with it, every step counted references to the arrays each kernel takes, a call and
    an atomic increment or decrement each (over a hundred call sites in the pair list's step,
    read with ``inspect_asm``), and the pair list's deployment step took 1.24-1.70 plain loops
    (``benchmarks/yardstick.py``) against 1.05-1.10 without. Nothing in it allocates; a
    kernel that does says ``_nrt=True`` (the Verlet list's build, the contact stage), or
    compiling the loop fails: which kernels inherit the setting must not depend on which
    was compiled first."""
    hold = 1.0 if implicit else 0.0  # bending held over the interval, or an impulse
    method = IMPLICIT_EULER if implicit else SYMPLECTIC_EULER

    @nb.njit(cache=True, error_model="numpy", _nrt=False)
    def advance_loop(every, steps, pos, vel, quat, omega, model, work, base, dt,
                     tol, contact, t0, grid, views, breakage, peaks):
        n = pos.shape[0]
        mass, fixed, radius = model.mass, model.fixed, model.radius
        torque, dv, gain = work.torque, work.dv, work.gain
        pending = np.int64(0)  # steps of rotation not yet applied to (quat, omega) (typed
        # int64 from the start: a literal 0 would compile advance_rotation once more for it)
        if quat is not None:  # their component rows, advanced by advance_rotation: on the
            # grid its own rows, C-contiguous, so that the series' loop vectorizes (a view's
            # strides are not known when it is compiled and that loop then stays scalar: 8.7
            # against 3.6 us for 470 nodes); on the pair list the arrays' transposes
            q_rows, w_rows = (grid.q, grid.w) if on_grid else (quat.T, omega.T)
        taken = 0
        for k in range(steps):
            if contact is not None:
                if not ensure_pairs(pos, radius, contact):
                    break
            reel(pos, model.cables, t0 + k * dt, dt)
            weight = 0.0
            if quat is not None:
                weight = bending_weight(True, every, work)
                if weight > 0.0 and pending > 0:
                    advance_rotation(q_rows, w_rows, gain, torque, hold, pending, dt,
                                     work.rotation, work.turned)
                    pending = np.int64(0)
            if on_grid:  # the grid's stencils (bending as in external_forces)
                if quat is not None:
                    if weight > 0.0:
                        grid_kernels.bending(grid, views, work.torque)
                if implicit:
                    grid_kernels.implicit_step(grid, views, dt, tol, work.cg_iterations)
                else:
                    grid_kernels.symplectic_step(grid, views, dt, weight, contact is not None,
                                                 grid.base)
                work.step_count[0] += 1
            else:  # the increment's kernel named, not captured (see increment)
                if implicit:
                    implicit_step(weight, pos, vel, quat, omega, model, work, base, dt,
                                  tol)
                else:
                    symplectic_step(weight, pos, vel, quat, omega, model, work, base,
                                    dt, tol)
                _move(pos, vel, dv, dt)
            if contact is not None:
                contact_stage(pos, vel, dv, mass, radius, fixed, contact, dt, t0 + k * dt)
            if quat is not None:
                if weight > 0.0:
                    angular_gains(method, weight, dt, model, gain)
                    if not implicit:  # an impulse standing for the interval
                        for i in range(n):
                            for a in range(3):
                                omega[i, a] += weight * gain[i] * torque[i, a]
                pending += 1
            if peaks is not None:  # the step's own tensions, as breakage reads them
                if on_grid:
                    grid_kernels.track_peaks(grid, peaks)
                else:
                    track_threads(work.tension, peaks, 0)
                    track_cables(model.cables, peaks)
            if breakage is not None:  # at the step's end, from the step's own tensions
                if on_grid:
                    grid_kernels.break_threads(grid, views, model.pairs, model.rest,
                                               model.k_a, model.c_a, model.k_t, model.c_t,
                                               model.k_b, model.c_b, breakage, t0 + k * dt)
                else:
                    break_threads(pos, model.pairs, model.rest, work.tension, model.k_a,
                                  model.c_a, model.k_t, model.c_t, model.k_b, model.c_b,
                                  breakage, t0 + k * dt)
                break_cables(pos, model.cables, breakage, t0 + k * dt)
            if on_grid:  # the tether's rest lengths for the next step, where the step reads them
                reel_tether(pos, vel, model.reel, grid.o_rest, grid.o_rest_rate, grid.o_k,
                            grid.o_c, t0 + k * dt, dt)
            else:
                reel_tether(pos, vel, model.reel, model.rest, model.rest_rate, model.k_a,
                            model.c_a, t0 + k * dt, dt)
            taken += 1
        if quat is not None:
            if pending > 0:
                advance_rotation(q_rows, w_rows, gain, torque, hold, pending, dt,
                                 work.rotation, work.turned)
        return taken

    return advance_loop
