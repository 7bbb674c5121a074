"""Verification of the thread force and the integrators against analytical references.

Every test names its reference; tolerances follow from the method (round-off, or the
first-order truncation error whose size is measured, not assumed)."""

from __future__ import annotations

import math

import numpy as np
import pytest

import bulletnet as bn
from bulletnet.engines import make_engine
from bulletnet.kernels.axial import axial_energy, axial_forces, thread_tensions
from bulletnet.model.net import NetModel
from bulletnet.model.state import NetState
from bulletnet.solver import integrators
from tests.conftest import small_scene

K, M, L0 = 4.0e5, 4.0e-3, 0.5  # thread stiffness [N/m], node mass [kg], rest length [m]


def two_mass_model(c: float = 0.0) -> NetModel:
    """Two equal masses joined by one thread of stiffness K and damping c [N s/m]."""
    one = np.ones(1)
    return NetModel(
        nodes_per_side=2, mass=np.full(2, M), radius=np.full(2, 0.01),
        kind=np.zeros(2, dtype=np.int8), pairs=np.array([[0, 1]]), rest_length=L0 * one,
        thread_radius=1e-3 * one, axial_stiffness=K * one, axial_damping=c * one,
        transverse_stiffness=0 * one, transverse_damping=0 * one, bending_stiffness=0 * one,
        bending_damping=0 * one, inertia=np.full(2, 1e-7), rest_axis=np.array([[1.0, 0, 0]]),
        fixed=np.zeros(2, dtype=bool), load=np.zeros((2, 3)), breaking_tension=np.full(1, np.inf),
        bilateral=False)


def pull_apart(model: NetModel, method: str, dt: float, t_end: float, v0: float = 1.0):
    """Separate the two masses at relative speed v0 [m/s] from l = l_0; return the length
    history [m] sampled every step and the final relative velocity [m/s]."""
    pos = np.array([[0.0, 0, 0], [L0, 0, 0]])
    vel = np.array([[-v0 / 2, 0, 0], [v0 / 2, 0, 0]])
    w = integrators.workspace(2, 1)
    steps = round(t_end / dt)
    lengths = np.empty(steps)
    loop = integrators.advance(False, method == "implicit_euler")  # the pair-list kernels
    for s in range(steps):  # no bending, no contact
        loop(1, 1, pos, vel, None, None, integrators.model_arrays(model), w, np.zeros((2, 3)),
             dt, 1e-12, None, s * dt, None, None, None, None)
        lengths[s] = pos[1, 0] - pos[0, 0]
    return lengths, vel[1, 0] - vel[0, 0]


def test_slack_and_closing_thread_give_exactly_zero():
    # Reference: Eq. 3 — no force if l <= l_0, or if T = k (l - l_0) + c v_r <= 0.
    model = two_mass_model(c=1000.0)
    force, tension = np.zeros((2, 3)), np.zeros(1)
    args = (model.pairs, model.rest_length, None, model.axial_stiffness, model.axial_damping,
            model.bilateral)
    slack = np.array([[0.0, 0, 0], [0.4, 0.1, 0]])   # l < l_0, pulling apart fast
    axial_forces(slack, np.array([[0.0, 0, 0], [50, 0, 0]]), *args, force, tension)
    assert tension[0] == 0.0 and not force.any()
    taut = np.array([[0.0, 0, 0], [L0 + 1e-3, 0, 0]])  # 400 N of spring, closing at 1 m/s
    axial_forces(taut, np.array([[0.0, 0, 0], [-1.0, 0, 0]]), *args, force, tension)
    assert tension[0] == 0.0 and not force.any()
    axial_forces(taut, np.zeros((2, 3)), *args, force, tension)  # taut and still: k delta
    assert tension[0] == pytest.approx(K * 1e-3, rel=1e-9)
    assert force[0, 0] == pytest.approx(K * 1e-3, rel=1e-9) and force[1, 0] == -force[0, 0]


def test_force_is_minus_energy_gradient():
    # Reference: F = -dE/dx with E = sum k (l - l_0)^2 / 2 (c = 0), by central differences;
    # their truncation error is O(h^2 E''') ~ 1e-8 relative at h = 1e-7 m.
    s = small_scene(**{"damping.axial_ratio": 0.0})
    model = bn.build_model(s)
    rng = np.random.default_rng(1)
    pos = bn.initial_state(s, model).position * 4.4 + rng.normal(0, 0.05, (model.node_count, 3))
    force, tension = np.zeros_like(pos), np.zeros(model.thread_count)
    axial_forces(pos, np.zeros_like(pos), model.pairs, model.rest_length, None,
                 model.axial_stiffness, model.axial_damping, model.bilateral, force, tension)
    assert np.count_nonzero(tension) > model.thread_count // 2  # most threads taut
    h = 1e-7
    grad = np.zeros_like(pos)
    for i in range(model.node_count):
        for a in range(3):
            plus, minus = pos.copy(), pos.copy()
            plus[i, a] += h
            minus[i, a] -= h
            grad[i, a] = (axial_energy(plus, model.pairs, model.rest_length,
                                       model.axial_stiffness)
                          - axial_energy(minus, model.pairs, model.rest_length,
                                         model.axial_stiffness)) / (2 * h)
    scale = np.abs(force).max()
    np.testing.assert_allclose(force, -grad, atol=1e-6 * scale)


@pytest.mark.parametrize("rates", [False, True])
def test_recorded_tensions_are_the_steps(rates):
    # Reference: the step's own force kernel. A frame records each thread's tension from the
    # tension law alone (thread_tensions); it must be the tension axial_forces computes and
    # applies at the same state, bit for bit, taut, slack and closing threads alike (a
    # jittered net with random velocities: about half its threads slack), with and without
    # rest-length rates.
    s = small_scene()
    model = bn.build_model(s)
    rng = np.random.default_rng(3)
    pos = bn.initial_state(s, model).position * 4.4 + rng.normal(0, 0.05, (model.node_count, 3))
    vel = rng.normal(0, 2.0, pos.shape)
    rate = rng.normal(0, 0.5, model.thread_count) if rates else None
    args = (model.pairs, model.rest_length, rate, model.axial_stiffness, model.axial_damping,
            model.bilateral)
    force, applied, recorded = np.zeros_like(pos), np.zeros(model.thread_count), \
        np.full(model.thread_count, np.nan)
    axial_forces(pos, vel, *args, force, applied)
    thread_tensions(pos, vel, *args, recorded)
    assert 0 < np.count_nonzero(applied) < model.thread_count
    np.testing.assert_array_equal(recorded, applied)


@pytest.mark.parametrize("method", ["symplectic_euler", "implicit_euler"])
def test_two_mass_thread_half_period(method):
    # Reference: while taut the relative motion is harmonic, l = l_0 + (v0/w) sin(w t) with
    # w = sqrt(k / mu), mu = M/2; the thread goes slack after half a period pi/w, at the
    # peak stretch v0/w, and (undamped) the masses then close at exactly v0.
    model = two_mass_model()
    omega = math.sqrt(K / (M / 2))
    dt = 1e-3 / omega
    lengths, v_rel = pull_apart(model, method, dt, 1.5 * math.pi / omega)
    t = dt * np.arange(1, lengths.size + 1)
    taut_time = dt * np.count_nonzero(lengths > L0)
    # first-order methods at w dt = 1e-3: errors of a few w dt relative
    assert taut_time == pytest.approx(math.pi / omega, rel=5e-3)
    assert lengths.max() - L0 == pytest.approx(1.0 / omega, rel=5e-3)
    taut = t < math.pi / omega
    np.testing.assert_allclose(lengths[taut] - L0, np.sin(omega * t[taut]) / omega,
                               atol=5e-3 / omega)
    if method == "symplectic_euler":
        assert v_rel == pytest.approx(-1.0, rel=5e-3)   # no numerical dissipation beyond O(w dt)
    else:
        assert -1.0 < v_rel < -1.0 + 0.01  # implicit Euler loses O(w dt) of the energy


@pytest.mark.parametrize("method", ["symplectic_euler", "implicit_euler"])
def test_convergence_order(method):
    # Reference: the damped two-mass thread while taut, l - l_0 = (v0/wd) e^(-z w t) sin(wd t);
    # both integrators are first order, so halving dt must halve the error (order 1).
    c = 0.2 * 2 * math.sqrt(K * M / 2)  # damping ratio 0.2
    model = two_mass_model(c)
    omega = math.sqrt(K / (M / 2))
    zeta = c / (2 * math.sqrt(K * M / 2))
    wd = omega * math.sqrt(1 - zeta**2)
    t_end = 1.0 / omega  # well inside the taut phase
    errors = []
    for dt in (t_end / 400, t_end / 800, t_end / 1600):
        lengths, _ = pull_apart(model, method, dt, t_end)
        exact = math.exp(-zeta * omega * t_end) * math.sin(wd * t_end) / wd
        errors.append(abs(lengths[-1] - L0 - exact))
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    np.testing.assert_allclose(orders, 1.0, atol=0.1)


@pytest.mark.parametrize("method", ["symplectic_euler", "implicit_euler"])
def test_momentum_conserved_in_zero_g(method):
    # Reference: conservation of linear momentum (internal pairwise forces, no gravity): the
    # centre of mass moves at the initial momentum / total mass, to round-off.
    s = small_scene(**{"simulation.integrator": method, "simulation.dt": 2e-6,
                       "net.fold_ratio": 0.9, "scene.duration": 0.05})
    model = bn.build_model(s)
    state = bn.initial_state(s, model)
    p0 = (model.mass[:, None] * state.velocity).sum(axis=0)
    com0 = (model.mass[:, None] * state.position).sum(axis=0) / model.mass.sum()
    engine = make_engine(s, model)
    engine.advance(state, 0.05)
    assert engine.thread_loads(state)[0].any()  # threads did snap taut
    p1 = (model.mass[:, None] * state.velocity).sum(axis=0)
    com1 = (model.mass[:, None] * state.position).sum(axis=0) / model.mass.sum()
    scale = (model.mass * np.linalg.norm(state.velocity, axis=1)).sum()
    np.testing.assert_allclose(p1, p0, atol=1e-12 * scale)
    np.testing.assert_allclose(com1, com0 + 0.05 * p0 / model.mass.sum(), atol=1e-12)


@pytest.mark.parametrize("method", ["symplectic_euler", "implicit_euler"])
def test_energy_error_first_order_without_damping(method):
    # Reference: conservation of energy (c = 0). Symplectic Euler keeps the energy error
    # bounded and O(dt); implicit Euler dissipates O(dt). Either way the error halves with dt.
    s = small_scene(**{"damping.axial_ratio": 0.0, "simulation.integrator": method,
                       "net.fold_ratio": 0.99, "scene.duration": 0.02})
    model = bn.build_model(s)
    errors = []
    for dt in (2e-7, 1e-7):
        state = bn.initial_state(s, model)
        e0 = 0.5 * (model.mass * (state.velocity**2).sum(axis=1)).sum()
        engine = make_engine(s.with_overrides({"simulation.dt": dt}), model)
        worst, most_elastic = 0.0, 0.0
        for t in np.linspace(0.001, 0.02, 20):
            engine.advance(state, t)
            kinetic = 0.5 * (model.mass * (state.velocity**2).sum(axis=1)).sum()
            elastic = axial_energy(state.position, model.pairs, model.rest_length,
                                   model.axial_stiffness)
            most_elastic = max(most_elastic, elastic)
            worst = max(worst, abs(kinetic + elastic - e0) / e0)
        assert most_elastic > 0.01 * e0  # the threads did store energy
        errors.append(worst)
    if method == "symplectic_euler":
        assert errors[0] < 0.01  # a symplectic method: bounded error, no drift
    assert math.log2(errors[0] / errors[1]) == pytest.approx(1.0, abs=0.15)


def test_state_untouched_by_zero_interval():
    s = small_scene()
    model = bn.build_model(s)
    state = bn.initial_state(s, model)
    before = state.copy()
    make_engine(s, model).advance(state, 0.0)
    assert isinstance(state, NetState) and np.array_equal(state.position, before.position)
