"""Bending stiffness (Sec. 3.2): the kernel against its energy, balance laws and frame
invariance; the cantilever against beam theory (Fig. 2); the zero-bending check (Table 3);
bending on every engine."""

from __future__ import annotations

import math

import numpy as np
import pytest

import bulletnet as bn
from bulletnet.kernels.bending import bending_energy, bending_forces
from tests.conftest import small_scene


def random_unit_quaternions(rng, n):
    q = rng.normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1)[:, None]


def quat_multiply(a, b):
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return np.array([aw * bx + bw * ax + ay * bz - az * by,
                     aw * by + bw * ay + az * bx - ax * bz,
                     aw * bz + bw * az + ax * by - ay * bx,
                     aw * bw - ax * bx - ay * by - az * bz])


def small_rotation(axis, angle):
    axis = np.asarray(axis, dtype=float)
    return np.append(axis * math.sin(angle / 2), math.cos(angle / 2))


def evaluate(model, pos, vel, quat, omega):
    force, torque = np.zeros_like(pos), np.zeros_like(pos)
    shear = np.zeros(model.thread_count)
    bending_forces(pos, vel, quat, omega, model.pairs, model.rest_axis,
                   model.transverse_stiffness, model.transverse_damping,
                   model.bending_stiffness, model.bending_damping, force, torque, shear)
    return force, torque, shear


@pytest.fixture(scope="module")
def bent():
    """A 4 x 4 net, perturbed and with random node rotations of up to ~0.5 rad."""
    s = small_scene(**{"net.nodes_per_side": 4, "bending.enabled": True})
    model = bn.build_model(s)
    rng = np.random.default_rng(7)
    state = bn.initial_state(s, model)
    pos = state.position + rng.normal(0, 0.02, state.position.shape)
    quat = np.array([small_rotation(v / np.linalg.norm(v), a)
                     for v, a in zip(rng.normal(size=(model.node_count, 3)),
                                     rng.uniform(0, 0.5, model.node_count), strict=True)])
    vel = rng.normal(0, 0.3, pos.shape)
    omega = rng.normal(0, 2.0, pos.shape)
    return model, pos, vel, quat, omega


def test_straight_unrotated_net_feels_nothing():
    # Reference: Sec. 3.2 — at rest (threads along their joint axes, no relative rotation) the
    # relaxed prismatic joint exerts nothing; also after a common rigid rotation of everything.
    s = small_scene(**{"bending.enabled": True})
    model = bn.build_model(s)
    state = bn.initial_state(s, model)
    state.velocity[:] = 0.0  # at rest: the launch velocities would load the dampers
    force, torque, shear = evaluate(model, state.position, state.velocity,
                                    state.orientation, state.angular_velocity)
    scale = model.transverse_stiffness.max() * model.rest_length.max()
    # round-off only: the rest axes are normalized differences of the same coordinates
    assert np.abs(force).max() < 1e-12 * scale and np.abs(torque).max() < 1e-12 * scale
    assert shear.max() < 1e-12 * scale
    q = small_rotation([0.3, -0.5, 0.81], 1.1)
    q /= np.linalg.norm(q)
    rot = np.array([_rotate(q, e) for e in np.eye(3)]).T
    pos = state.position @ rot.T
    quat = np.array([quat_multiply(q, qi) for qi in state.orientation])
    force, torque, _ = evaluate(model, pos, state.velocity, quat, state.angular_velocity)
    assert np.abs(force).max() < 1e-12 * scale and np.abs(torque).max() < 1e-12 * scale


def _rotate(q, v):
    p = quat_multiply(quat_multiply(q, np.append(v, 0.0)), q * [-1, -1, -1, 1])
    return p[:3]


def test_force_and_moment_balance_per_thread(bent):
    # Reference: Newton's third law and the balance of moments, thread by thread: the forces
    # sum to zero and so do the moments about the origin (x_i x F_i + x_j x F_j + tau_i + tau_j).
    model, pos, vel, quat, omega = bent
    for p in range(model.thread_count):
        one = {f: getattr(model, f)[p:p + 1] for f in (
            "pairs", "rest_axis", "transverse_stiffness", "transverse_damping",
            "bending_stiffness", "bending_damping")}
        force, torque = np.zeros_like(pos), np.zeros_like(pos)
        bending_forces(pos, vel, quat, omega, one["pairs"], one["rest_axis"],
                       one["transverse_stiffness"], one["transverse_damping"],
                       one["bending_stiffness"], one["bending_damping"], force, torque,
                       np.zeros(1))
        scale = np.abs(force).max() + np.abs(torque).max()
        assert scale > 0
        np.testing.assert_allclose(force.sum(axis=0), 0, atol=1e-12 * scale)
        moment = np.cross(pos, force).sum(axis=0) + torque.sum(axis=0)
        np.testing.assert_allclose(moment, 0, atol=1e-11 * scale)


def test_forces_and_torques_are_minus_energy_gradient(bent):
    # Reference: F = -dE/dx and tau = -dE/dtheta for E = sum k_t |d|^2/2 + k_b |phi|^2/2 (no
    # damping: zero velocities), by central differences (O(h^2) truncation at h = 1e-6).
    model, pos, _, quat, _ = bent
    zero = np.zeros_like(pos)
    force, torque, _ = evaluate(model, pos, zero, quat, zero)
    args = (model.pairs, model.rest_axis, model.transverse_stiffness, model.bending_stiffness)
    h = 1e-6
    for i in (0, 5, model.node_count - 1):
        for a in range(3):
            plus, minus = pos.copy(), pos.copy()
            plus[i, a] += h
            minus[i, a] -= h
            grad = (bending_energy(plus, quat, *args)
                    - bending_energy(minus, quat, *args)) / (2 * h)
            assert -grad == pytest.approx(force[i, a], rel=1e-5, abs=1e-7 * np.abs(force).max())
            axis = np.eye(3)[a]
            qp, qm = quat.copy(), quat.copy()
            qp[i] = quat_multiply(small_rotation(axis, h), quat[i])
            qm[i] = quat_multiply(small_rotation(axis, -h), quat[i])
            grad = (bending_energy(pos, qp, *args) - bending_energy(pos, qm, *args)) / (2 * h)
            assert -grad == pytest.approx(torque[i, a], rel=1e-5,
                                          abs=1e-7 * np.abs(torque).max())


def test_dampers_dissipate(bent):
    # Reference: the dampers derive from a Rayleigh function D >= 0, so their power
    # sum F.v + tau.w is never positive (zero stiffness isolates them).
    model, pos, vel, quat, omega = bent
    force, torque = np.zeros_like(pos), np.zeros_like(pos)
    zeros = np.zeros(model.thread_count)
    bending_forces(pos, vel, quat, omega, model.pairs, model.rest_axis, zeros,
                   model.transverse_damping, zeros, model.bending_damping, force, torque,
                   np.zeros(model.thread_count))
    power = (force * vel).sum() + (torque * omega).sum()
    assert power < 0


def run_cantilever(**overrides):
    s = bn.load_scenario("cantilever", overrides)
    result = bn.run(s)
    return s, result.state


def test_cantilever_tip_deflection_fig2():
    # Reference: Euler-Bernoulli beam, tip deflection P L^3 / (3 E I) + w L^4 / (8 E I). The
    # two-node model lumps half the beam's weight at the tip, which over-counts the own-weight
    # term by 4/3: +0.19 % of the total here, inside the 1 % the issue asks for.
    s, state = run_cantilever()
    e, length, r = 69e9, 0.5, 0.01
    inertia = math.pi * r**4 / 4
    w = 2700 * math.pi * r**2 * 9.81
    exact = 262 * length**3 / (3 * e * inertia) + w * length**4 / (8 * e * inertia)
    assert -state.position[1, 2] == pytest.approx(exact, rel=0.01)
    # and the lumped model's own prediction, to the residual oscillation (xi_b = 0.014 after 3 s)
    lumped = (262 + w * length / 2) * length**3 / (3 * e * inertia)
    assert -state.position[1, 2] == pytest.approx(lumped, rel=1e-4)


def test_cantilever_end_load_is_exact_without_gravity():
    # Reference: k_t = 3 E I / L^3 is the cantilever's end-load stiffness, so with no own
    # weight the tip settles at P L^3 / (3 E I) up to the decaying oscillation.
    s, state = run_cantilever(**{"scene.gravity": [0.0, 0.0, 0.0]})
    exact = 262 * 0.5**3 / (3 * 69e9 * math.pi * 0.01**4 / 4)
    assert -state.position[1, 2] == pytest.approx(exact, rel=1e-4)


def test_zero_bending_reproduces_plain_model_table3(tmp_path):
    # Reference: the paper's Table 3 — bending model with k_b = k_t = 0 against the model
    # without bending; the paper got 3e-14 m average, our bar is 1e-9 m.
    scene = small_scene(**{"net.fold_ratio": 0.9, "scene.duration": 0.1})
    plain = bn.run(scene, tmp_path / "plain.h5")
    zero = bn.run(scene.with_overrides({"bending.enabled": True,
                                        "bending.stiffness_scale": 0.0}), tmp_path / "zero.h5")
    a, b = bn.open_recording(plain.path), bn.open_recording(zero.path)
    assert a.tension.any()
    r = bn.metrics.rmse(a, b)
    assert r["rmse_pos_max"] < 1e-9


def test_bending_changes_shape_not_centre_of_mass(tmp_path):
    # Reference: momentum conservation (Sec. 4.2: the centre of mass moves identically with
    # and without bending), while the shape differs.
    scene = small_scene(**{"net.fold_ratio": 0.9, "scene.duration": 0.2})
    runs = [bn.open_recording(bn.run(scene.with_overrides({"bending.enabled": on}),
                                     tmp_path / f"{on}.h5").path) for on in (False, True)]
    mass = runs[0].mass
    com = [(r.position * mass[None, :, None]).sum(axis=1) / mass.sum() for r in runs]
    np.testing.assert_allclose(com[0], com[1], atol=1e-12)
    assert bn.metrics.rmse(*runs)["rmse_pos_max"] > 1e-4
    assert runs[1].shear.any() and not runs[0].shear.any()
    assert runs[1].orientation is not None and runs[0].orientation is None


@pytest.mark.parametrize("integrator", ["symplectic_euler", "implicit_euler"])
def test_bullet_matches_fast_with_bending(tmp_path, integrator):
    # Reference: the fast engine. PyBullet integrates the same forces and torques with the same
    # semi-implicit update (exponential-map rotation), so the two differ by rounding only.
    scene = small_scene(**{"net.nodes_per_side": 4, "net.fold_ratio": 0.99,
                           "scene.duration": 0.01, "simulation.dt": 2e-6,
                           "simulation.integrator": integrator, "bending.enabled": True,
                           "simulation.record_rate": 1000.0})
    recs = [bn.open_recording(bn.run(scene.with_overrides({"simulation.engine": e}),
                                     tmp_path / f"{e}.h5").path) for e in ("fast", "bullet")]
    assert np.abs(recs[0].orientation[-1, :, :3]).max() > 1e-6  # nodes did turn
    assert bn.metrics.rmse(*recs)["rmse_pos_max"] < 1e-9
    np.testing.assert_allclose(recs[0].orientation, recs[1].orientation, atol=1e-9)


def test_fast_matches_reference_with_bending(tmp_path):
    # Reference: scipy DOP853 on the same right-hand side (quaternion kinematics included);
    # fast at its default step is first order, well under our 1 mm bar here.
    scene = small_scene(**{"net.fold_ratio": 0.9, "scene.duration": 0.06,
                           "bending.enabled": True, "simulation.record_rate": 1000.0})
    ref = bn.run(scene.with_overrides({"simulation.engine": "reference"}), tmp_path / "r.h5")
    fast = bn.run(scene, tmp_path / "f.h5")
    r = bn.metrics.rmse(bn.open_recording(fast.path), bn.open_recording(ref.path))
    assert r["rmse_pos_avg"] < 1e-4


def test_bending_impulse_interval_costs_less_than_the_step(tmp_path):
    # Reference: the converged bending run. Evaluating the soft bending springs every n steps
    # (as impulses, the automatic n) must add less error than halving the step removes, i.e.
    # stay below the base integrator's own truncation error.
    scene = small_scene(**{"net.fold_ratio": 0.9, "scene.duration": 0.2,
                           "bending.enabled": True})
    runs = {}
    for name, over in (("auto", {}), ("every1", {"bending.every": 1}),
                       ("half", {"bending.every": 1, "simulation.dt": 5e-7})):
        runs[name] = bn.open_recording(bn.run(scene.with_overrides(over),
                                              tmp_path / f"{name}.h5").path)
    truncation = bn.metrics.rmse(runs["every1"], runs["half"])["rmse_pos_avg"]
    multirate = bn.metrics.rmse(runs["auto"], runs["every1"])["rmse_pos_avg"]
    assert 0 < multirate < truncation
