"""The threads' dampers of ``exponential_euler``: symplectic Euler whose dampers relax
exponentially over each step, so that they no longer limit the step.

Symplectic Euler takes a damper's force c u (u the thread's rate of extension [m/s]) as
explicit: on the paper's threads, damped in proportion to their stiffness (Eq. 3: c = 2 xi k
/ omega_ref), the fastest damper relaxes at gamma_max = lambda_max(M^-1 C) and the step must
stay below 2 / gamma_max, about 20 times below the springs' own limit 2 / omega_max
(:mod:`bulletnet.analysis.stability`; on ``scenarios/removal.toml``'s net 9.5e-6 against
2.0e-4 s).

``exponential_euler`` gives each thread's damper, over a step h, the impulse that relaxes its
rate exactly, as if it acted alone on its two ends, each end's mass shared among the d damped
threads that meet there (mass splitting: the thread sees m_i / d_i):

    J = mu u (1 - exp(-c h / mu)),   1 / mu = d_i / m_i + d_j / m_j,

that is, the damper with the coefficient ``c_eff = c (1 - exp(-x)) / x``, x = c h / mu
(:func:`damping_ratio` gives c_eff / c), in the unchanged symplectic step (the same kernels,
on the pair list and the grid). Properties:

- consistent: c_eff -> c as h -> 0 (c_eff = c (1 - x / 2 + ...)); a slow mode's damper
  (x << 1) is symplectic Euler's;
- a damper never overshoots: each thread's share of its ends' velocities keeps the sign of
  its rate (u e^-x), and a node's new velocity is the mass-weighted mean of its threads'
  shares, whose kinetic energy is at most theirs (Jensen): the dampers alone only
  dissipate, at any step; with the springs, on one mode with a = e^-x in [0, 1], the step
  is stable up to h = sqrt(2 (1 + a)) / omega, at least sqrt(2) / omega_max;
- a fast, overdamped mode (x >> 1) is damped less than the model says (c_eff ~ mu / h):
  what it costs is measured in docs/tow.md ("The tow at a large step").

The coefficients are set for a step; the engine sets them when it starts on the integrator
(:meth:`bulletnet.engines.base.Engine.switch_integrator`). A closing cable's damper, on the
rate of its length L' = sum_v g_v . v_v (g_v = dL/dx_v), relaxes the same way, with
1 / mu = sum_v |g_v|^2 d_v / m_v from the step's own g
(:func:`bulletnet.kernels.cable.cable_forces`, from the vertices' shares
``CableArrays.share``; a node that a cable passes twice counted per pass). The bending
springs' dampers stay explicit (their own limit, :mod:`bulletnet.analysis.stability`).

Symplectic Euler relaxes the closing cables' dampers the same way, from the same shares,
and keeps the threads' explicit: a cable folded through its rings (|g_v| = 2 at each) damps
at a rate c sum_v |g_v|^2 / m_v that in a cinched bag outruns every thread's (docs/tow.md,
"The cinched cables' dampers"). With the shares, each of a node's dampers acts on its own
d-th of the node's mass: a relaxed one never overshoots, an explicit thread damper does not
while c h (d_i / m_i + d_j / m_j) <= 2, about symplectic Euler's own damping limit on the
threads, so the dampers together still only dissipate there.
"""

from __future__ import annotations

import numpy as np


def node_shares(c: np.ndarray, pairs: np.ndarray, mass: np.ndarray, fixed: np.ndarray,
                others: np.ndarray | None = None) -> np.ndarray:
    """Each node's d / m [1/kg], shape (N,): d the dampers meeting there (the damped threads
    of damping ``c`` [N s/m] (P,) and end nodes ``pairs`` (P, 2), and ``others``: one entry a
    damper at a node, the closing cables' vertices), ``mass`` [kg] (N,); 0 at a clamped node
    (``fixed``, (N,): it takes no share)."""
    ends = pairs[c > 0.0].ravel()
    if others is not None:
        ends = np.concatenate([ends, others])
    degree = np.bincount(ends, minlength=mass.size)
    return np.where(fixed, 0.0, degree / mass)


def damping_ratio(c: np.ndarray, pairs: np.ndarray, share: np.ndarray,
                  dt: float) -> np.ndarray:
    """c_eff / c of each thread at steps of ``dt`` [s] (module doc), shape (P,): damping ``c``
    [N s/m] (P,), end nodes ``pairs`` (P, 2), the nodes' shares d / m [1/kg] (N,)
    (:func:`node_shares`). 1 where a thread has no damper or moves nothing."""
    x = c * dt * (share[pairs[:, 0]] + share[pairs[:, 1]])
    safe = np.where(x > 0.0, x, 1.0)
    return np.where(x > 0.0, -np.expm1(-x) / safe, 1.0)
