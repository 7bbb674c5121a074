"""Stability limits of the integrators, analytical, from the assembled threads (the measured
limits, by bisection over runs, are :func:`bulletnet.studies.bench.largest_stable_step`).

Linearised about a configuration with every thread taut, the net obeys
``M a = -K x - C v`` with ``K = sum_p k_p B_p``, ``C = sum_p c_p B_p`` and ``B_p`` thread p's
graph-Laplacian block ``e_p e_p^T`` (clamped nodes removed). Two eigenvalues bound what an
explicit step can take:

- ``omega_max^2 = lambda_max(M^-1 K)`` [rad^2/s^2], the fastest thread mode;
- ``gamma_max = lambda_max(M^-1 C)`` [1/s], the fastest damper relaxation rate.

Symplectic Euler on one damped mode ``x'' = -omega^2 x - gamma x'`` has the amplification
matrix ``[[1 - h gamma, -h omega^2], [h (1 - h gamma), 1 - h^2 omega^2]]`` (on (v, x)) with
determinant ``1 - h gamma`` and trace ``2 - h gamma - h^2 omega^2``; the Jury conditions reduce
to ``h gamma < 2`` and ``h^2 omega^2 + 2 h gamma < 4``, i.e.
``h < 4 / (gamma + sqrt(gamma^2 + 4 omega^2))``, which is ``2 / omega`` without damping (the
stiffness limit) and ``2 / gamma`` without stiffness (the damping limit). With both maxima in
it, it is a lower bound of the net's limit (exact when C is proportional to K, as for the
paper's axial dampers ``c_a = 2 xi_a k_a / omega_ref``). Linearly implicit Euler is A-stable on
the linearised threads: it has no step limit.

A closing cable adds rank-one blocks ``k g g^T`` and ``c g g^T``, whose one eigenvalue
depends on the configuration as the threads' do not: ``g^T M^-1 g`` grows as the cable folds
through its rings (:func:`cable_frequency`). Its damper relaxes over the step on the explicit
integrators (:mod:`bulletnet.solver.exponential_damping`): in a cinched bag its rate c g^T M^-1
g outruns every thread's (docs/tow.md, "The cinched cables' dampers"), and explicit it would
set the step. On its own mode the relaxed damper's factor is a = exp(-x) in [0, 1] (x = h c
g^T M^-1 g where no other damper meets its nodes, more where others share their masses) and
the step is stable while ``h^2 omega_c^2 < 2 (1 + a)``, at least ``sqrt(2) / omega_c``.
The limits add the fastest cable's ``omega_c^2`` to the threads' ``omega_max^2`` (the largest
eigenvalue of a sum is at most the sum of theirs). A run that diverges names the cables'
limit at its last finite frame.

Exponential Euler (:mod:`bulletnet.solver.exponential_damping`) is symplectic Euler with the
dampers' coefficients set for the step so that each relaxes its thread's rate without
overshoot: on one mode the damper's factor a = 1 - h gamma becomes a in [0, 1], and the
conditions ``|trace| < 1 + det`` give ``h^2 omega^2 < 2 (1 + a)``: at least
``h < sqrt(2) / omega_max`` (the relaxed limit), whatever the damping.

Bending springs are explicit in symplectic Euler (impulses every n steps, n >= 1 from
:func:`bulletnet.engines.base.bending_interval`), so with bending it has a second limit on
n dt, from the nodes' rotation on the bending and transverse springs: the same formula with
the Gershgorin bounds ``gamma_b <= 2 max_i sum(c_b + c_t l^2) / J_i`` and
``omega_b^2 <= 2 max_i sum(k_b + k_t l^2) / J_i`` (a graph Laplacian's eigenvalues are at most
twice its largest diagonal entry), so the bending limit is conservative. Implicit Euler
scales each node's angular update by those same bounds
(``dw = h tau / (J + h C_g + h^2 K_g)``, :mod:`bulletnet.solver.integrators`): every rotational mode
is then damped at any step, so it has no bending limit either.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..model.net import NetModel
from ..model.scenario import Scenario


@dataclass(frozen=True)
class Limits:
    """Analytical step limits of the net with every thread taut."""

    omega_max: float
    """Largest thread frequency sqrt(lambda_max(M^-1 K)) [rad/s]."""
    gamma_max: float
    """Largest damper relaxation rate lambda_max(M^-1 C) [1/s]."""
    bending_omega: float = 0.0
    """Bound on the fastest rotational frequency on the bending springs [rad/s] (0: none)."""
    bending_gamma: float = 0.0
    """Bound on the fastest rotational damping rate on the bending springs [1/s] (0: none)."""
    cable_omega: float = 0.0
    """Fastest closing cable's frequency sqrt(k g^T M^-1 g) [rad/s] (0: none)."""
    cable_time: float = 0.0
    """Time of the state the cables' frequency was taken at [s]."""

    @property
    def stiffness_limit(self) -> float:
        """2 / omega_max [s]: the explicit limit of the undamped threads."""
        return 2.0 / self.omega_max if self.omega_max > 0 else math.inf

    @property
    def damping_limit(self) -> float:
        """2 / gamma_max [s]: the explicit limit of the dampers alone."""
        return 2.0 / self.gamma_max if self.gamma_max > 0 else math.inf

    @property
    def cable_limit(self) -> float:
        """sqrt(2) / cable_omega [s]: the limit of the closing cables alone, their dampers
        relaxed over the step (module doc)."""
        return math.sqrt(2.0) / self.cable_omega if self.cable_omega > 0 else math.inf

    @property
    def explicit_limit(self) -> float:
        """4 / (gamma_max + sqrt(gamma_max^2 + 4 omega^2)) [s], omega^2 = omega_max^2 +
        cable_omega^2, and with closing cables at most the relaxed limit (their dampers relax):
        symplectic Euler's limit on the threads and the cables (the eigenvalues of a sum at
        most the sum of theirs: a lower bound)."""
        cables = self.relaxed_limit if self.cable_omega > 0 else math.inf
        return min(_explicit_step(self.gamma_max, math.hypot(self.omega_max, self.cable_omega)),
                   cables)

    @property
    def bending_limit(self) -> float:
        """The explicit limit of the bending impulses' interval n dt [s] (inf without bending)."""
        return _explicit_step(self.bending_gamma, self.bending_omega)

    @property
    def relaxed_limit(self) -> float:
        """sqrt(2) / omega [s], omega^2 = omega_max^2 + cable_omega^2: exponential Euler's limit
        on the threads and cables, whose dampers relax exactly
        (:mod:`bulletnet.solver.exponential_damping`): the springs' explicit limit with a
        damper that may take out a mode's whole rate in a step."""
        omega = math.hypot(self.omega_max, self.cable_omega)
        return math.sqrt(2.0) / omega if omega > 0 else math.inf

    def for_integrator(self, integrator: str) -> float:
        """The step limit [s] of ``integrator``: the explicit one (and the bending one, if any)
        for symplectic Euler, the relaxed one (and the bending one) for exponential Euler;
        none (inf) for implicit Euler."""
        if integrator == "symplectic_euler":
            return min(self.explicit_limit, self.bending_limit)
        if integrator == "exponential_euler":
            return min(self.relaxed_limit, self.bending_limit)
        return math.inf

    def describe(self, integrator: str) -> str:
        """One phrase naming ``integrator``'s analytical limit and where it comes from."""
        bending = (f", bending impulses {self.bending_limit:.3g} s"
                   if math.isfinite(self.bending_limit) else "")
        if integrator == "implicit_euler":
            return (f"{integrator} is A-stable on the threads (stiffness 2/omega_max = "
                    f"{self.stiffness_limit:.3g} s) and on the rotations")
        if integrator == "exponential_euler":
            return (f"the analytical limit of {integrator} on this net is "
                    f"{self.for_integrator(integrator):.3g} s (stiffness sqrt(2)/omega_max = "
                    f"{self.relaxed_limit:.3g} s, the dampers relaxed exactly{bending})")
        cables = (f", the closing cables at t = {self.cable_time:.6g} s sqrt(2)/omega_c = "
                  f"{self.cable_limit:.3g} s" if self.cable_omega > 0 else "")
        return (f"the analytical limit of {integrator} on this net is "
                f"{self.for_integrator(integrator):.3g} s (damping 2/gamma_max = "
                f"{self.damping_limit:.3g} s{cables}, stiffness 2/omega_max = "
                f"{self.stiffness_limit:.3g} s{bending})")


def _explicit_step(gamma: float, omega: float) -> float:
    """4 / (gamma + sqrt(gamma^2 + 4 omega^2)) [s], inf when both are 0."""
    if gamma == 0 and omega == 0:
        return math.inf
    return 4.0 / (gamma + math.sqrt(gamma * gamma + 4.0 * omega * omega))


def _taut_laplacian(model: NetModel, position: np.ndarray, weight: np.ndarray):
    """sum_p weight_p B_p as a sparse (3F, 3F) matrix over the F free nodes, B_p the Laplacian
    block e_p e_p^T of thread p along its direction at ``position`` [m] (N, 3)."""
    from scipy import sparse

    free = np.flatnonzero(~model.fixed)
    index = np.full(model.node_count, -1)
    index[free] = np.arange(free.size)
    i, j = model.pairs[:, 0], model.pairs[:, 1]
    d = position[j] - position[i]
    e = d / np.linalg.norm(d, axis=1, keepdims=True)
    block = weight[:, None, None] * e[:, :, None] * e[:, None, :]  # (P, 3, 3)
    rows, cols, vals = [], [], []
    a, b = np.meshgrid(np.arange(3), np.arange(3), indexing="ij")
    for u, v, sign in ((i, i, 1.0), (j, j, 1.0), (i, j, -1.0), (j, i, -1.0)):
        ok = (index[u] >= 0) & (index[v] >= 0)
        rows.append((3 * index[u][ok, None, None] + a).ravel())
        cols.append((3 * index[v][ok, None, None] + b).ravel())
        vals.append((sign * block[ok]).ravel())
    size = 3 * free.size
    matrix = sparse.coo_matrix((np.concatenate(vals), (np.concatenate(rows),
                                np.concatenate(cols))), shape=(size, size)).tocsr()
    return matrix, free


def _largest_eigenvalue(model: NetModel, position: np.ndarray, weight: np.ndarray) -> float:
    """lambda_max(M^-1 A) for A = sum_p weight_p B_p, via the symmetric M^-1/2 A M^-1/2."""
    from scipy import sparse
    from scipy.sparse.linalg import eigsh

    matrix, free = _taut_laplacian(model, position, weight)
    if matrix.shape[0] == 0 or not np.any(weight):
        return 0.0
    scale = sparse.diags(np.repeat(1.0 / np.sqrt(model.mass[free]), 3))
    sym = scale @ matrix @ scale
    if sym.shape[0] <= 60:  # small: dense is exact and cheaper than Lanczos
        return float(np.linalg.eigvalsh(sym.toarray())[-1])
    return float(eigsh(sym, k=1, which="LA", return_eigenvectors=False, tol=1e-6)[0])


def cable_frequency(model: NetModel, position: np.ndarray,
                    rest: np.ndarray | None = None) -> float:
    """The fastest closing cable's frequency sqrt(k g^T M^-1 g) [rad/s] at ``position`` [m]
    (N, 3) with rest lengths ``rest`` [m] (C,) (the model's if None): a cable's tension acts
    along g, g_v = dL/dx_v (:mod:`bulletnet.kernels.cable`), so its stiffness block k g g^T is
    rank one, with the one eigenvalue k g^T M^-1 g (the geometric stiffness across its spans
    left out); its damper's rate is c g^T M^-1 g = tau omega_c^2 (c = tau k).
    g^T M^-1 g = sum_v |g_v|^2 / m_v grows as the cable folds through its rings (|g_v| = 2 at
    a hairpin): a cinched bag's cables can be far faster than the straight ones at launch.
    0 without cables."""
    if model.cable_count == 0:
        return 0.0
    rest = model.cable_rest_length if rest is None else rest
    weight = np.where(model.fixed, 0.0, 1.0 / model.mass)
    omega2 = 0.0
    for c in range(model.cable_count):
        nodes = model.cable_nodes[model.cable_start[c]:model.cable_start[c + 1]]
        span = np.diff(position[nodes], axis=0)
        axis = span / np.linalg.norm(span, axis=1, keepdims=True)
        g = np.zeros((model.node_count, 3))  # by node: a node passed twice sums its passes
        np.add.at(g, nodes[1:], axis)
        np.add.at(g, nodes[:-1], -axis)
        share = float(np.sum(weight * np.einsum("ij,ij->i", g, g)))
        k = model.cable_rigidity[c] / rest[c]
        omega2 = max(omega2, k * share)
    return math.sqrt(omega2)


def analytical_limits(model: NetModel, position: np.ndarray, bending: bool = False) -> Limits:
    """Step limits of the net with every thread taut along its direction at ``position`` [m],
    shape (N, 3) (the initial state's directions are the deployed net's), the closing cables
    at their rest lengths there (:func:`cable_frequency`); with ``bending``, the bending
    impulses' limit too."""
    omega2 = _largest_eigenvalue(model, position, model.axial_stiffness)
    gamma = _largest_eigenvalue(model, position, model.axial_damping)
    bending_gamma = bending_omega = 0.0
    if bending:
        from ..engines.base import rotational_rates

        damping, frequency2 = rotational_rates(model)
        bending_gamma = 2.0 * float(damping.max())
        bending_omega = math.sqrt(2.0 * float(frequency2.max()))
    return Limits(omega_max=math.sqrt(max(omega2, 0.0)), gamma_max=max(gamma, 0.0),
                  bending_omega=bending_omega, bending_gamma=bending_gamma,
                  cable_omega=cable_frequency(model, position))


def scene_limits(scenario: Scenario) -> Limits:
    """:func:`analytical_limits` of the scene's model at its initial state."""
    from ..model.builder import build_model, initial_state

    model = build_model(scenario)
    return analytical_limits(model, initial_state(scenario, model).position,
                             scenario.bending.enabled)
