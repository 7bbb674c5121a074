"""Each node's gap to the debris at the start of a step, as both contact stages (the
sequential :func:`~bulletnet.solver.contact_stage.debris_stage` and the coupled solve's
candidates) find it, with the least work that gives the same answer.

A node is a candidate for debris contact over a step if its start gap is within the step's
reach: what the node and the debris surface can close in one step, dt (|v| + |dv| + |v_d| +
|w| R) with R the debris' bounding radius. Three tests, cheapest first, each exact:

1. the debris' bounding sphere: a node farther from it than its reach cannot touch;
2. the distance cache: each node keeps a lower bound of its gap from its last query and the
   point it was queried at, in the debris' body frame. The debris moves rigidly, and a
   distance to a fixed set changes by at most the distance moved (it is 1-Lipschitz), so
   the gap is still at least the bound less how far the node has moved in the body frame
   since; while that exceeds the reach, the query is skipped;
3. the query (:func:`~bulletnet.kernels.geometry.debris_distance`), with its cutoff widened
   by ``contact.skin`` so that the bound it leaves lasts: a node that stays a skin's width
   clear is queried again only once it has moved most of the skin towards the debris.

Every test only skips a node the query would have found out of reach, so a run is the
same, bit for bit, with the cache as without it (tests/test_contact.py); a net wrapped on
its debris, most of its nodes within the bounding sphere but not on the surface, is queried
a fraction as often.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from ..kernels.geometry import debris_distance, quat_matrix

CLEAR_MARGIN = 1e-9
"""Kept between the cached bound and the reach [m], for the round-off of the body-frame
points (~1e-15 m at the debris' size)."""


@nb.njit(cache=True, error_model="numpy")
def debris_pose(com, quat, com_body):
    """The debris' rotation (3, 3) [-] and body-frame origin (3,) [m] from its centre of
    mass ``com`` [m], orientation ``quat`` (1, 4) and centre of mass in its body frame."""
    rot = np.empty((3, 3))
    quat_matrix(quat[0], rot)
    origin = np.empty(3)
    for a in range(3):
        origin[a] = com[a] - (rot[a, 0] * com_body[0] + rot[a, 1] * com_body[1]
                              + rot[a, 2] * com_body[2])
    return rot, origin


@nb.njit(cache=True, error_model="numpy")
def surface_speed(contact):
    """The largest speed of a point of the debris [m/s]: |v_d| + |w| R, R its bounding radius
    about its centre of mass."""
    vd, w = contact.velocity, contact.omega[0]
    return (math.sqrt(vd[0] * vd[0] + vd[1] * vd[1] + vd[2] * vd[2])
            + math.sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]) * contact.bound[0])


@nb.njit(cache=True, error_model="numpy")
def _row_norm(a, i):
    """Euclidean norm of row i of ``a`` (N, 3), without making the row a view."""
    return math.sqrt(a[i, 0] * a[i, 0] + a[i, 1] * a[i, 1] + a[i, 2] * a[i, 2])


@nb.njit(cache=True, error_model="numpy", _nrt=False)
def start_gap(i, pos, vel, dv, radius, contact, rot, origin, speed, dt, p0, normal):
    """Node i's start-of-step gap to the debris, for the step just taken ((pos, vel) its
    end, dv its velocity increment [m/s]) with the debris at its start pose (``rot``,
    ``origin``: :func:`debris_pose`) and largest surface speed ``speed`` [m/s]
    (:func:`surface_speed`). Returns (gap s0 [m], signed distance of the node's centre
    [m]); s0 is +inf if the node cannot touch the debris within the step. The node's start
    position goes into ``p0`` (3,), the outward normal at the nearest surface point into
    ``normal`` (3,) (valid when s0 is finite); the cache (``contact.clear``,
    ``contact.clear_at``) is read and renewed. Compiled without reference counting, as
    :func:`~bulletnet.kernels.geometry.debris_distance`: counting the references of the
    arrays of ``contact`` it reads would cost more, for each node, than the tests."""
    com, bound, clear, at = contact.com, contact.bound, contact.clear, contact.clear_at
    for a in range(3):
        p0[a] = pos[i, a] - dt * vel[i, a]
    reach = dt * (_row_norm(vel, i) + _row_norm(dv, i) + speed) + 1e-9
    rx, ry, rz = p0[0] - com[0], p0[1] - com[1], p0[2] - com[2]
    if math.sqrt(rx * rx + ry * ry + rz * rz) - bound[0] - radius[i] > reach:
        return np.inf, np.inf
    bx = by = bz = 0.0  # the body-frame point, as debris_distance computes it
    for a in range(3):
        d = p0[a] - origin[a]
        bx += rot[a, 0] * d
        by += rot[a, 1] * d
        bz += rot[a, 2] * d
    room = clear[i] - reach - CLEAR_MARGIN
    if room > 0.0:
        mx, my, mz = bx - at[i, 0], by - at[i, 1], bz - at[i, 2]
        if mx * mx + my * my + mz * mz < room * room:
            return np.inf, np.inf
    cutoff = reach + radius[i] + contact.params[1]
    d = debris_distance(p0, origin, rot, contact.parts, contact.mesh, normal, cutoff)
    clear[i] = min(d, cutoff) - radius[i]  # parts left out lie beyond the cutoff
    at[i, 0], at[i, 1], at[i, 2] = bx, by, bz
    s0 = d - radius[i]
    return (np.inf if s0 > reach else s0), d
