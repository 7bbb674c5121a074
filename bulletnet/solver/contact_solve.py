"""The coupled contact solve (``contact.solver = "coupled"``): every contact of a step, node
with node and node with debris, solved together by projected Gauss-Seidel to a tolerance,
for nets whose contacts are stacked (layers of net pressed on the debris, ring nodes bunched
by the closing cables).

The sequential stage (:func:`bulletnet.solver.contact_stage.contact_stage`) solves each
contact once a step from its start gap and velocity, with the other contacts held: in a
stack the next contact's correction moves a node the last one has just placed, the step's
end gaps are not the ones the law predicted, and the next step removes the difference by
moving nodes (an overlap projection), which does work against the threads' and cables' pull
that no force does. Here the backward-Euler law of Eq. 6 (:func:`~bulletnet.kernels.contact.
implicit_normal_step`: the impulse ``dt F`` with F = -k_c s_1 - c_c u_1 at the step's end,
acting if F > 0 and s_1 < 0) and the regularized Coulomb friction of Eq. 12
(:func:`~bulletnet.kernels.contact.friction_impulse`, contact time the step) are imposed on
all contacts at once: each sweep updates every contact's accumulated impulses from the
velocities the others' current impulses leave (the single-contact law solved for its own
impulse), until no sweep changes any contact's end gap by more than ``contact.tolerance``
[m] (``contact.sweeps`` at most). The impulses start from the last step's (warm start), so
that a resting stack takes a few sweeps. A sweep passes over a contact whose nodes no
impulse has moved since it was last solved. A contact's friction is bounded in a step by
one coefficient, the regime it ended the last step in: mu_s if it stuck (or is new), mu_k if
it slid (:func:`_sweep`). A node-node
impulse acts equally and oppositely on its two nodes (clamped nodes do not move); debris
impulses are summed, force and moment, for its rigid body. Positions follow the velocities
(x_1 = x_0 + dt v_1), as in the free step.

Every pair the Verlet list holds within ``contact.skin`` and every node within reach of the
debris is a candidate; the sweeps run over the contacts that touch or close within the step
(or pushed last step), and once they converge a candidate whose end gap, at the solved
velocities, is negative joins them and the sweeps resume: no contact is missed.

An overlap at a step's start that the last step's solution did not predict (its end gap
taken at its fixed normal: a node sliding into a concave corner, a pair passing tangentially,
the debris turning) is not removed by moving the nodes: it is absorbed into the contact's
reference (an offset added to its gap, shrinking as the true overlap does and gone when the
contact opens), so the law acts on the overlap it predicted and nothing does work. Runs count
these absorptions as the sequential stage counts its projections.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numba as nb
import numpy as np

from ..kernels.contact import stick_fraction
from .debris_gap import debris_pose, start_gap, surface_speed

CONTACT_COLUMNS = 8
"""Columns of a contact's law row: reduced mass [kg], stiffness [N/m], damping [N s/m], the
step's friction coefficient [-] (mu_s, or mu_k if the contact's friction slid at the end of
the last step), the inverse masses of its two nodes [1/kg] (node i's 0 for the debris), gap
at the start of the step with its offset [m], the share of a slip's momentum the viscous
stick takes over the step [-] (:func:`~bulletnet.kernels.contact.stick_fraction`)."""


class SolveArrays(NamedTuple):
    """The coupled solve's arrays, for N nodes and a Verlet list of C pairs (K = N + C
    contact slots: :func:`solve_arrays`)."""

    settings: np.ndarray
    """Tolerance on the end gaps [m], most sweeps a step [-], shape (2,)."""
    node: np.ndarray
    """Each contact's nodes (i, j): i -1 for the debris [-], shape (K, 2), int64."""
    source: np.ndarray
    """Each contact's pair in the Verlet list (>= 0), or -1 - j for node j's debris contact
    [-], shape (K,), int64."""
    normal: np.ndarray
    """Unit normal from i (or the debris surface) to j [-], shape (K, 3)."""
    surface: np.ndarray
    """Velocity of the debris surface point at the step's end (0 for pairs) [m/s],
    shape (K, 3)."""
    lever: np.ndarray
    """Contact point from the debris' centre of mass [m], shape (K, 3)."""
    law: np.ndarray
    """Each contact's law (:data:`CONTACT_COLUMNS`), shape (K, 8)."""
    active: np.ndarray
    """Whether the sweeps update the contact [-], shape (K,), bool."""
    order: np.ndarray
    """The active contacts, in slot order [-], shape (K,), int64 (the first of them)."""
    sliding: np.ndarray
    """Whether the contact's friction slid (its bound below the viscous stick) when the
    sweeps last solved it in this step [-], shape (K,), bool."""
    solved_at: np.ndarray
    """The clock when the sweeps last solved the contact (-1: not yet in this step) [-],
    shape (K,), int64."""
    moved_at: np.ndarray
    """The clock when an impulse last changed the node's velocity [-], shape (N,), int64."""
    clock: np.ndarray
    """Contacts solved so far, the clock of ``solved_at`` and ``moved_at`` [-], shape (1,),
    int64."""
    impulse: np.ndarray
    """Accumulated normal impulse [N s], shape (K,)."""
    friction: np.ndarray
    """Accumulated friction impulse on j [N s], shape (K, 3)."""
    pair_warm: np.ndarray
    """Each pair's last normal impulse [N s] (4th column: none), friction impulse [N s] and
    whether that friction slid (1) or stuck (0) [-], shape (C, 5)."""
    debris_warm: np.ndarray
    """Each node's last debris normal and friction impulse [N s] and whether that friction
    slid [-], shape (N, 5)."""
    pair_offset: np.ndarray
    """Overlap absorbed into each pair's reference [m], shape (C,)."""
    debris_offset: np.ndarray
    """Overlap absorbed into each node's debris contact reference [m], shape (N,)."""
    old_pairs: np.ndarray
    """The Verlet list before a rebuild, with each pair's predicted gap, offset and warm
    start carried to the new list [-, m, m, N s, -], shape (C, 9)."""
    stats: np.ndarray
    """Sweeps so far, steps that reached the most sweeps, contacts solved (summed over
    steps) [-], shape (3,)."""


def solve_arrays(tolerance: float, sweeps: int, nodes: int, pairs: int) -> SolveArrays:
    """Empty arrays of the coupled solve for ``nodes`` nodes and a list of ``pairs`` pairs,
    to the end-gap ``tolerance`` [m] in at most ``sweeps`` sweeps a step."""
    slots = nodes + pairs
    return SolveArrays(
        settings=np.array([tolerance, float(sweeps)]),
        node=np.zeros((slots, 2), dtype=np.int64), source=np.zeros(slots, dtype=np.int64),
        normal=np.zeros((slots, 3)), surface=np.zeros((slots, 3)), lever=np.zeros((slots, 3)),
        law=np.zeros((slots, CONTACT_COLUMNS)), active=np.zeros(slots, dtype=np.bool_),
        order=np.zeros(slots, dtype=np.int64), sliding=np.zeros(slots, dtype=np.bool_),
        solved_at=np.zeros(slots, dtype=np.int64), moved_at=np.zeros(nodes, dtype=np.int64),
        clock=np.zeros(1, dtype=np.int64),
        impulse=np.zeros(slots), friction=np.zeros((slots, 3)),
        pair_warm=np.zeros((pairs, 5)), debris_warm=np.zeros((nodes, 5)),
        pair_offset=np.zeros(pairs), debris_offset=np.zeros(nodes),
        old_pairs=np.zeros((pairs, 9)), stats=np.zeros(3))


def grown(solve: SolveArrays, nodes: int, pairs: int) -> SolveArrays:
    """Arrays for a list of ``pairs`` pairs (after an overflow: the list is rebuilt, the
    pairs' warm starts and offsets start anew)."""
    fresh = solve_arrays(solve.settings[0], int(solve.settings[1]), nodes, pairs)
    fresh.debris_warm[:] = solve.debris_warm
    fresh.debris_offset[:] = solve.debris_offset
    fresh.stats[:] = solve.stats
    return fresh


@nb.njit(cache=True, error_model="numpy")
def keep_pairs(solve, pairs, count, pair_gap):
    """Before the Verlet list is rebuilt: its ``count`` pairs with their predicted gaps,
    offsets and warm starts, for :func:`carry_pairs`."""
    if solve is None:
        return
    old = solve.old_pairs
    for q in range(count):
        old[q, 0], old[q, 1] = min(pairs[q, 0], pairs[q, 1]), max(pairs[q, 0], pairs[q, 1])
        old[q, 2] = pair_gap[q]
        old[q, 3] = solve.pair_offset[q]
        for a in range(5):
            old[q, 4 + a] = solve.pair_warm[q, a]


@nb.njit(cache=True, error_model="numpy")
def carry_pairs(solve, pairs, count, old_count, pair_gap, nodes):
    """After the Verlet list is rebuilt: each pair that was in the old list takes its
    predicted gap, offset and warm start (:func:`keep_pairs`); a new pair has none (gap
    +inf). Pairs are found by their lower node (counting sort), in time linear in the list."""
    if solve is None:
        return
    old = solve.old_pairs
    start = np.zeros(nodes + 1, dtype=np.int64)
    for q in range(old_count):
        start[int(old[q, 0]) + 1] += 1
    for i in range(nodes):
        start[i + 1] += start[i]
    fill = start[:-1].copy()
    order = np.empty(old_count, dtype=np.int64)
    for q in range(old_count):
        i = int(old[q, 0])
        order[fill[i]] = q
        fill[i] += 1
    for q in range(count):
        lo, hi = min(pairs[q, 0], pairs[q, 1]), max(pairs[q, 0], pairs[q, 1])
        pair_gap[q] = np.inf
        solve.pair_offset[q] = 0.0
        solve.pair_warm[q, :] = 0.0
        for b in range(start[lo], start[lo + 1]):
            p = order[b]
            if int(old[p, 1]) == hi:
                pair_gap[q] = old[p, 2]
                solve.pair_offset[q] = old[p, 3]
                for a in range(5):
                    solve.pair_warm[q, a] = old[p, 4 + a]
                break


@nb.njit(cache=True, error_model="numpy")
def add_debris_impulse(imp, r, d):
    """Add the impulse ``d`` (3,) [N s] at ``r`` (3,) [m] from the debris' centre of mass to
    its force and moment impulse ``imp`` (6,)."""
    imp[0] += d[0]
    imp[1] += d[1]
    imp[2] += d[2]
    imp[3] += r[1] * d[2] - r[2] * d[1]
    imp[4] += r[2] * d[0] - r[0] * d[2]
    imp[5] += r[0] * d[1] - r[1] * d[0]


@nb.njit(cache=True, error_model="numpy")
def _forget(predicted, offset, warm, k):
    """Contact ``k`` out of reach: no predicted gap, offset or warm start."""
    predicted[k] = np.inf
    offset[k] = 0.0
    warm[k, :] = 0.0


@nb.njit(cache=True, error_model="numpy")
def _absorb(s0, offset, predicted, stats):
    """The offset [m] of a contact at measured start gap ``s0`` [m]: its last ``offset``,
    no larger than the true overlap (-s0, or 0), plus the part of the gap below the one the
    last step predicted (``predicted``, +inf: none) or below touching, whichever is deeper;
    that part counted in ``stats`` (number, total distance [m])."""
    offset = min(offset, max(-s0, 0.0))
    target = min(predicted, 0.0)
    gap = s0 + offset
    if gap < target:
        stats[0] += 1.0
        stats[1] += target - gap
        offset += target - gap
    return offset


@nb.njit(cache=True, error_model="numpy", inline="always")
def _add(solve, c, k, kc, cc, mu_s, mu_k, wi, wj, gap, warm, dt, slip):
    """Fill contact slot ``c`` (nodes, normal, surface and lever set by the caller) with its
    law over the step ``dt`` [s] (friction's ``slip`` coefficient [s/kg]; mu_k if ``warm``
    says the friction slid, else mu_s), and start its impulses from ``warm`` (normal, then
    friction in the tangent plane), not yet solved."""
    law = solve.law
    law[c, 0] = m = 1.0 / (wi + wj)
    law[c, 1], law[c, 2], law[c, 3] = kc, cc, mu_k if warm[4] > 0.0 else mu_s
    law[c, 4], law[c, 5], law[c, 6] = wi, wj, gap
    law[c, 7] = stick_fraction(dt, m, slip)
    solve.sliding[c] = False
    solve.solved_at[c] = -1
    n = solve.normal
    along = warm[1] * n[c, 0] + warm[2] * n[c, 1] + warm[3] * n[c, 2]
    solve.impulse[c] = warm[0]
    for a in range(3):
        solve.friction[c, a] = warm[1 + a] - along * n[c, a]
    solve.source[c] = k


@nb.njit(cache=True, error_model="numpy", inline="always")
def _apply(pos, vel, i, j, wi, wj, d, dt, moved_at, now):
    """Impulse ``d`` (3,) [N s] on node j and -d on node i (i < 0: the debris), with the
    positions following the velocities over the step; both nodes' ``moved_at`` set to
    ``now``."""
    moved_at[j] = now
    if i >= 0:
        moved_at[i] = now
    for a in range(3):
        vel[j, a] += wj * d[a]
        pos[j, a] += dt * wj * d[a]
        if i >= 0:
            vel[i, a] -= wi * d[a]
            pos[i, a] -= dt * wi * d[a]


@nb.njit(cache=True, error_model="numpy", inline="always")
def _relative(vel, solve, c, rel):
    """Velocity of node j relative to node i (or to the debris surface) into ``rel`` (3,);
    returns its normal component [m/s]."""
    i, j = solve.node[c, 0], solve.node[c, 1]
    un = 0.0
    for a in range(3):
        rel[a] = vel[j, a] - (vel[i, a] if i >= 0 else solve.surface[c, a])
        un += rel[a] * solve.normal[c, a]
    return un


@nb.njit(cache=True, error_model="numpy")
def _sweep(pos, vel, solve, active, dt, d, rel):
    """One Gauss-Seidel sweep over the ``active`` contacts (solve.order's first): each one's
    normal impulse from the backward-Euler law, then its friction impulse, at the velocities
    the others leave. A contact neither of whose nodes has moved since it was last solved
    is left as it is (solving it again would give its impulses again, to round-off).
    The friction impulse is the viscous stick of Eq. 12 limited to the step's coefficient
    times the normal impulse, a bound that stays fixed through the step's sweeps (the
    regime the contact ended the last step in: a stick past mu_s N slides at mu_s N for
    this step and at mu_k N from the next). Eq. 12's jump from mu_s to mu_k within the
    sweeps made contacts sharing a node flip between sticking and sliding from one sweep to
    the next, and the sweeps not converge. Returns the largest change of an end gap the
    sweep made [m]."""
    law, n, lam, fr = solve.law, solve.normal, solve.impulse, solve.friction
    moved_at, solved_at, clock = solve.moved_at, solve.solved_at, solve.clock
    change = 0.0
    for b in range(active):
        c = solve.order[b]
        i, j = solve.node[c, 0], solve.node[c, 1]
        if solved_at[c] >= moved_at[j] and (i < 0 or solved_at[c] >= moved_at[i]):
            continue
        clock[0] += 1
        now = clock[0]
        solved_at[c] = now
        m, k, cc, mu = law[c, 0], law[c, 1], law[c, 2], law[c, 3]
        wi, wj, gap = law[c, 4], law[c, 5], law[c, 6]
        u_free = _relative(vel, solve, c, rel) - lam[c] / m  # without its own impulse
        new = m * (-dt * k * gap - (dt * dt * k + dt * cc) * u_free) / (m + dt * cc
                                                                          + dt * dt * k)
        if new <= 0.0 or gap + dt * (u_free + new / m) >= 0.0:
            new = 0.0  # the law's force acts if positive with the end gap negative
        step = new - lam[c]
        if step != 0.0:
            for a in range(3):
                d[a] = step * n[c, a]
            _apply(pos, vel, i, j, wi, wj, d, dt, moved_at, now)
            lam[c] = new
            change = max(change, dt * abs(step) / m)
        un = _relative(vel, solve, c, rel)
        speed = 0.0
        for a in range(3):  # tangential slip without its own friction
            rel[a] -= fr[c, a] / m + un * n[c, a]
            speed += rel[a] * rel[a]
        speed = math.sqrt(speed)
        jt = stick = 0.0
        if speed > 0.0 and new > 0.0:
            stick = m * speed * law[c, 7]
            jt = min(stick, mu * new)
        solve.sliding[c] = jt < stick
        moved = 0.0
        for a in range(3):
            target = -jt * rel[a] / speed if jt > 0.0 else 0.0
            d[a] = target - fr[c, a]
            fr[c, a] = target
            moved += d[a] * d[a]
        if moved > 0.0:
            _apply(pos, vel, i, j, wi, wj, d, dt, moved_at, now)
            change = max(change, dt * math.sqrt(moved) / m)
    return change


@nb.njit(cache=True, error_model="numpy")
def _gather_pairs(pos, vel, mass, radius, fixed, contact, solve, dt, count):
    """Candidates among the Verlet list's pairs (start gap within the skin) into slots
    from ``count``; returns the new count."""
    cls, kc, cc, mu_s, mu_k = (contact.node_class, contact.stiffness, contact.damping,
                               contact.mu_static, contact.mu_kinetic)
    pairs, meta, predicted, stats = (contact.pairs, contact.pair_meta, contact.pair_gap,
                                     contact.projections)
    skin = contact.params[1]
    n = solve.normal
    for q in range(meta[0]):
        i, j = pairs[q, 0], pairs[q, 1]
        dist = 0.0
        for a in range(3):
            n[count, a] = (pos[j, a] - dt * vel[j, a]) - (pos[i, a] - dt * vel[i, a])
            dist += n[count, a] * n[count, a]
        dist = math.sqrt(dist)
        s0 = dist - radius[i] - radius[j]
        wi = 0.0 if fixed[i] else 1.0 / mass[i]
        wj = 0.0 if fixed[j] else 1.0 / mass[j]
        if s0 > skin or wi + wj == 0.0:
            _forget(predicted, solve.pair_offset, solve.pair_warm, q)
            continue
        for a in range(3):
            n[count, a] /= dist
            solve.surface[count, a] = 0.0
        offset = _absorb(s0, solve.pair_offset[q], predicted[q], stats)
        solve.pair_offset[q] = offset
        solve.node[count, 0], solve.node[count, 1] = i, j
        ci, cj = cls[i], cls[j]
        _add(solve, count, q, kc[ci, cj], cc[ci, cj], mu_s[ci, cj], mu_k[ci, cj], wi, wj,
             s0 + offset, solve.pair_warm[q], dt, contact.params[0])
        count += 1
    return count


@nb.njit(cache=True, error_model="numpy")
def _gather_debris(pos, vel, dv, mass, radius, fixed, contact, solve, dt, count):
    """Candidates among the nodes within reach of the debris over the step (as
    :func:`~bulletnet.solver.contact_stage.debris_stage` finds them) into slots from
    ``count``; returns the new count."""
    cls, kc, cc, mu_s, mu_k = (contact.node_class, contact.stiffness, contact.damping,
                               contact.mu_static, contact.mu_kinetic)
    com, vd, wd = contact.com, contact.velocity, contact.omega
    predicted, stats = contact.debris_gap, contact.projections
    rot, origin = debris_pose(com, contact.quat, contact.com_body)
    w = wd[0]
    speed = surface_speed(contact)
    p0, r, nrm = np.empty(3), np.empty(3), np.empty(3)
    for i in range(pos.shape[0]):
        if fixed[i] or cls[i] < 0:
            continue
        s0, d = start_gap(i, pos, vel, dv, radius, contact, rot, origin, speed, dt, p0, nrm)
        if s0 == np.inf:
            _forget(predicted, solve.debris_offset, solve.debris_warm, i)
            continue
        lever, vs = solve.lever[count], solve.surface[count]
        for a in range(3):
            solve.normal[count, a] = nrm[a]
            lever[a] = p0[a] - d * nrm[a] - com[a]  # contact point on the surface
        # the surface point's velocity at the step's end: w x r, plus dt w x (w x r)
        vs[0] = w[1] * lever[2] - w[2] * lever[1]
        vs[1] = w[2] * lever[0] - w[0] * lever[2]
        vs[2] = w[0] * lever[1] - w[1] * lever[0]
        r[0] = w[1] * vs[2] - w[2] * vs[1]
        r[1] = w[2] * vs[0] - w[0] * vs[2]
        r[2] = w[0] * vs[1] - w[1] * vs[0]
        for a in range(3):
            vs[a] += vd[a] + dt * r[a]
        offset = _absorb(s0, solve.debris_offset[i], predicted[i], stats)
        solve.debris_offset[i] = offset
        solve.node[count, 0], solve.node[count, 1] = -1, i
        c = cls[i]
        _add(solve, count, -1 - i, kc[0, c], cc[0, c], mu_s[0, c], mu_k[0, c], 0.0,
             1.0 / mass[i], s0 + offset, solve.debris_warm[i], dt, contact.params[0])
        count += 1
    return count


@nb.njit(cache=True, error_model="numpy")
def _start(pos, vel, solve, count, dt):
    """Apply the warm-started impulses and mark active the contacts that touch, close
    within the step at the free velocities, or start with an impulse; returns how many
    are active (:func:`_listed`)."""
    d, rel = np.empty(3), np.empty(3)
    for c in range(count):
        un = _relative(vel, solve, c, rel)
        gap = solve.law[c, 6]
        solve.active[c] = gap <= 0.0 or gap + dt * un < 0.0 or solve.impulse[c] > 0.0
        if not solve.active[c]:
            solve.impulse[c] = 0.0
            solve.friction[c, :] = 0.0
            continue
        for a in range(3):
            d[a] = solve.impulse[c] * solve.normal[c, a] + solve.friction[c, a]
        _apply(pos, vel, solve.node[c, 0], solve.node[c, 1], solve.law[c, 4],
               solve.law[c, 5], d, dt, solve.moved_at, solve.clock[0])
    return _listed(solve, count)


@nb.njit(cache=True, error_model="numpy")
def _listed(solve, count):
    """The active contacts among the first ``count`` slots into solve.order, in slot order;
    returns how many."""
    active = 0
    for c in range(count):
        if solve.active[c]:
            solve.order[active] = c
            active += 1
    return active


@nb.njit(cache=True, error_model="numpy")
def _join(vel, solve, count, dt):
    """Activate the inactive candidates whose end gap at the current velocities is
    negative; returns how many joined."""
    rel = np.empty(3)
    joined = 0
    for c in range(count):
        if not solve.active[c] and solve.law[c, 6] + dt * _relative(vel, solve, c, rel) < 0.0:
            solve.active[c] = True
            joined += 1
    return joined


@nb.njit(cache=True, error_model="numpy")
def coupled_stage(pos, vel, dv, mass, radius, fixed, contact, solve, dt, t):
    """The step's contacts solved together (see the module doc): (pos, vel) hold the free
    step's end, dv its velocity increment [m/s]; the debris moves rigidly at its velocity
    over the step. Impulses on the debris are added to contact.impulse, and each contact's
    end gap is kept as the next step's prediction."""
    flags = contact.flags
    count = 0
    if flags[1]:
        count = _gather_pairs(pos, vel, mass, radius, fixed, contact, solve, dt, count)
    if flags[0]:
        count = _gather_debris(pos, vel, dv, mass, radius, fixed, contact, solve, dt, count)
    active = _start(pos, vel, solve, count, dt)
    tol, most = solve.settings[0], int(solve.settings[1])
    d, rel = np.empty(3), np.empty(3)
    sweeps = 0
    while sweeps < most:
        change = _sweep(pos, vel, solve, active, dt, d, rel)
        sweeps += 1
        if change <= tol:
            if _join(vel, solve, count, dt) == 0:
                break
            active = _listed(solve, count)
    stats = solve.stats
    stats[0] += sweeps
    stats[2] += count
    if sweeps == most:
        stats[1] += 1
    imp, first = contact.impulse, contact.first_contact
    for c in range(count):
        i, j, k = solve.node[c, 0], solve.node[c, 1], solve.source[c]
        lam = solve.impulse[c]
        end = solve.law[c, 6] + dt * _relative(vel, solve, c, rel)
        warm = solve.pair_warm[k] if k >= 0 else solve.debris_warm[-1 - k]
        warm[0] = lam
        for a in range(3):
            warm[1 + a] = solve.friction[c, a]
        warm[4] = 1.0 if solve.sliding[c] else 0.0
        if k >= 0:
            contact.pair_gap[k] = end
        else:
            contact.debris_gap[j] = end
        if lam <= 0.0:
            continue
        if i >= 0:
            contact.self_impulse[i] += lam
            contact.self_impulse[j] += lam
            if first[1] < 0.0:
                first[1] = t + dt
            continue
        contact.node_impulse[j] += lam
        lever = solve.lever[c]
        for a in range(3):
            d[a] = -(lam * solve.normal[c, a] + solve.friction[c, a])  # on the debris
        add_debris_impulse(imp, lever, d)
        if first[0] < 0.0:
            first[0] = t + dt
