"""exponential_euler: symplectic Euler with the threads' dampers relaxed exactly over each step
(bulletnet/solver/exponential_damping.py), against closed forms and converged runs."""

from __future__ import annotations

import math

import numpy as np
import pytest

import bulletnet as bn
from bulletnet.common.errors import BulletnetError
from bulletnet.engines import make_engine
from bulletnet.solver.exponential_damping import damping_ratio, node_shares
from tests.conftest import small_scene, small_tow
from tests.test_tow import point_masses, run_model, scene


def lone_damper(integrator: str, dt: float):
    """Two point masses (1 and 3 kg) on one thread of no stiffness and damping c = 750 N s/m
    (relaxation rate gamma = c (1/1 + 1/3) = 1000 1/s), taut (by 1 mm) and separating at
    1 m/s along x:
    the final state after 0.02 s (20 relaxation times) at steps of ``dt`` [s]."""
    s = scene(simulation__integrator=integrator, simulation__dt=dt, scene__duration=0.02,
              simulation__record_rate=50.0)
    model = point_masses([1.0, 3.0], [(0, 1)], [1.0], [0.0], [750.0])
    return run_model(s, model, [[0, 0, 0], [1.001, 0, 0]], [[-0.75, 0, 0], [0.25, 0, 0]], 0.02,
                     frames=1)


def test_a_lone_damper_relaxes_exactly_at_any_step():
    # Reference: the closed form of a damper alone on two masses: the rate of separation
    # u = u0 exp(-gamma t), the centre of mass at rest (the impulses are equal and opposite).
    # One thread: each end is its own (d = 1), so the step's relaxation is exact at any
    # step, here from 1/200 of symplectic Euler's limit 2 / gamma = 2e-3 s to 10 times it.
    for dt in (2e-2, 1e-3, 2e-4, 1e-5):
        state = lone_damper("exponential_euler", dt)
        u = state.velocity[1, 0] - state.velocity[0, 0]
        assert u == pytest.approx(math.exp(-1000.0 * 0.02), rel=1e-9), dt
        assert 1.0 * state.velocity[0, 0] + 3.0 * state.velocity[1, 0] == \
            pytest.approx(0.0, abs=1e-15)
    # symplectic Euler at 2e-2 s turns the rate to u0 (1 - gamma h) = -19 m/s in its one
    # step: a damper reversing the motion it resists
    state = lone_damper("symplectic_euler", 2e-2)
    assert state.velocity[1, 0] - state.velocity[0, 0] == pytest.approx(-19.0, rel=1e-12)


def test_damping_ratio_shares_each_node_among_its_dampers():
    # Reference: c_eff / c = (1 - exp(-x)) / x, x = c h (d_i / m_i + d_j / m_j), d counting
    # the dampers at a node (the undamped thread not), a clamped node taking no share.
    pairs = np.array([[0, 1], [1, 2], [2, 3]])
    c, mass, h = np.array([2.0, 3.0, 0.0]), np.array([1.0, 2.0, 4.0, 8.0]), 0.1
    fixed = np.array([True, False, False, False])
    x = np.array([2.0 * h * (0.0 + 2 / 2.0), 3.0 * h * (2 / 2.0 + 1 / 4.0)])
    share = node_shares(c, pairs, mass, fixed)
    np.testing.assert_allclose(damping_ratio(c, pairs, share, h),
                               [*(-np.expm1(-x) / x), 1.0], rtol=1e-15)
    assert damping_ratio(c, pairs, share, 1e-12)[:2] == pytest.approx(1.0, rel=1e-9)
    # a cable through node 2 (twice) takes two more shares there
    x[1] = 3.0 * h * (2 / 2.0 + 3 / 4.0)
    share = node_shares(c, pairs, mass, fixed, np.array([2, 2]))
    np.testing.assert_allclose(damping_ratio(c, pairs, share, h)[1], -np.expm1(-x[1]) / x[1],
                               rtol=1e-15)


def test_a_cable_damper_relaxes_exactly_over_the_step():
    # Reference: the lone damper's closed form (above) on a straight cable of two vertices
    # (its length rate u = e . (v_1 - v_0), g = -e, +e), next to no stiffness: with
    # the vertices' shares d / m the kernel's damper takes the impulse that turns u into
    # u exp(-x) in one step, x = c h (1 / m_0 + 1 / m_1) = 10 (symplectic Euler's: 1 - x).
    from bulletnet.kernels.cable import cable_arrays, cable_forces

    mass, h = np.array([1.0, 3.0]), 1e-2  # c = 750 N s/m: k = 1e-9 N/m, c / k = 7.5e11 s
    cables = cable_arrays(np.array([0, 1]), np.array([0, 2]), np.array([1.0]),
                          np.array([1e-9]), np.array([7.5e11]), np.zeros(1),
                          np.full(1, np.inf), np.zeros(1))
    pos = np.array([[0.0, 0, 0], [1.001, 0, 0]])
    vel = np.array([[-0.75, 0, 0], [0.25, 0, 0]])
    for share, expected in ((1.0 / mass, math.exp(-10.0)), (np.zeros(2), 1.0 - 10.0)):
        cables.share[:] = share
        force = np.zeros((2, 3))
        cable_forces(pos, vel, cables, force, False, h)
        after = vel + h * force / mass[:, None]
        assert after[1, 0] - after[0, 0] == pytest.approx(expected, rel=1e-9)


def test_exponential_euler_converges_to_the_symplectic_euler_reference():
    # Reference: a converged run (symplectic Euler at 2.5e-7 s) of the 6 x 6 deployment to
    # 0.5 s (its corner threads taut from about 0.25 s). exponential_euler is first order:
    # c_eff -> c as the step shrinks, so its error shrinks with the step, about halving
    # with it. At 4 times symplectic Euler's analytical limit (7.7e-6 s), where symplectic
    # Euler diverges, it stays within 1 cm of the reference (2.4 mm measured; symplectic
    # Euler at twice its limit, still finite at 0.5 s, is off by 114 mm).
    from bulletnet.analysis.stability import scene_limits

    def final(integrator, dt):
        return bn.run(small_scene(**{"scene.duration": 0.5, "simulation.integrator": integrator,
                                     "simulation.dt": dt})).state.position

    reference = final("symplectic_euler", 2.5e-7)
    errors = [np.abs(final("exponential_euler", dt) - reference).max()
              for dt in (4e-6, 2e-6, 1e-6)]
    assert errors[0] > errors[1] > errors[2] and errors[0] / errors[2] > 2.5, errors
    step = 4 * scene_limits(small_scene()).explicit_limit
    assert np.abs(final("exponential_euler", step) - reference).max() < 0.01
    with pytest.raises(BulletnetError, match="diverged"):
        final("symplectic_euler", step)


def test_the_tow_switches_to_exponential_euler_and_back():
    # The engine sets the threads' damping for exponential Euler's step at the switch, and
    # the model's again when it leaves it (the coefficients the kernels read on both paths).
    s = small_tow()
    model = bn.build_model(s)
    engine = make_engine(s, model)
    c = engine.arrays.c_a.copy()
    engine.switch_integrator("exponential_euler", 1e-4)
    expected = c * damping_ratio(c, model.pairs,
                                 node_shares(c, model.pairs, model.mass, model.fixed), 1e-4)
    np.testing.assert_allclose(engine.arrays.c_a, expected, rtol=1e-15)
    assert (engine.arrays.c_a < c).any() and model.axial_damping is not engine.arrays.c_a
    engine.switch_integrator("implicit_euler", 1e-4)
    np.testing.assert_allclose(engine.arrays.c_a, c, rtol=1e-14)


def test_the_closing_cables_dampers_relax_on_both_explicit_integrators():
    # Reference: the shares' definition (node_shares, above). On implicit Euler the cables'
    # dampers are in the solve (shares 0); on symplectic Euler they relax over the step from
    # the nodes' shares d / m (the threads' own dampers unchanged, explicit); on exponential
    # Euler from the same shares, beside the threads' c_eff.
    s = small_tow(**{"closing.enabled": True})
    model = bn.build_model(s)
    engine = make_engine(s, model)
    cables, c = engine.arrays.cables, engine.arrays.c_a.copy()
    shares = node_shares(c, model.pairs, model.mass, model.fixed, cables.nodes)[cables.nodes]
    assert shares.all() and engine.implicit and not cables.share.any()
    engine.switch_integrator("symplectic_euler", 1e-5)
    np.testing.assert_array_equal(cables.share, shares)
    np.testing.assert_array_equal(engine.arrays.c_a, c)
    engine.switch_integrator("exponential_euler", 1e-4)
    np.testing.assert_array_equal(cables.share, shares)
    assert (engine.arrays.c_a < c).any()
    engine.switch_integrator("implicit_euler", 1e-4)
    assert not cables.share.any()
    np.testing.assert_allclose(engine.arrays.c_a, c, rtol=1e-14)


def test_a_reel_refuses_exponential_euler():
    with pytest.raises(bn.ScenarioError, match="reel"):
        small_tow(**{"reel.enabled": True, "reel.speed": 0.1,
                     "thrust.integrator": "exponential_euler"})
