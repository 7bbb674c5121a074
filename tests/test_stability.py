"""Stability limits: the analytical bounds of bulletnet.analysis.stability against runs that blow
up."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
from conftest import small_scene
from test_recording_cli import cli

import bulletnet as bn
from bulletnet.analysis.stability import Limits, analytical_limits, scene_limits
from bulletnet.engines import make_engine
from bulletnet.studies.bench import is_stable


def test_two_mass_thread_limits_match_closed_form():
    # Reference: one taut thread between masses m1, m2 is one mode with
    # omega^2 = k (1/m1 + 1/m2) and gamma = c (1/m1 + 1/m2) (reduced mass); the eigen-solver
    # must find exactly that on a 2-node model.
    scene = bn.load_scenario("cantilever")
    model = bn.build_model(scene)
    model = dataclasses.replace(model, fixed=np.zeros_like(model.fixed))
    position = bn.initial_state(scene, model).position
    limits = analytical_limits(model, position)
    inv = 1.0 / model.mass[0] + 1.0 / model.mass[1]
    assert limits.omega_max == pytest.approx(math.sqrt(model.axial_stiffness[0] * inv), rel=1e-12)
    assert limits.gamma_max == pytest.approx(model.axial_damping[0] * inv, rel=1e-12)


def test_explicit_limit_reduces_to_the_textbook_bounds():
    # Reference: h < 4 / (gamma + sqrt(gamma^2 + 4 omega^2)) is 2/omega without damping and
    # 2/gamma without stiffness, and never exceeds either.
    assert Limits(omega_max=1e4, gamma_max=0.0).explicit_limit == pytest.approx(2e-4)
    assert Limits(omega_max=0.0, gamma_max=1e6).explicit_limit == pytest.approx(2e-6)
    both = Limits(omega_max=1e4, gamma_max=1e6)
    assert both.explicit_limit < min(both.stiffness_limit, both.damping_limit)


def _bilateral_flat_net():
    """A 6 x 6 net laid flat at rest length with bilateral threads: linear in its stretch,
    every thread active from the first step, so the linear analysis applies exactly."""
    scene = small_scene(**{"net.fold_ratio": 1.0, "scene.duration": 0.05})
    model = dataclasses.replace(bn.build_model(scene), bilateral=True)
    return scene, model, bn.initial_state(scene, model)


@pytest.mark.parametrize(("factor", "stable"), [(0.95, True), (1.05, False)])
def test_symplectic_euler_fails_where_theory_says(factor, stable):
    # Reference: the Jury conditions of symplectic Euler on the damped modes (stability.py's
    # doc); with C proportional to K the bound is exact: 5 % below it the run stays bounded,
    # 5 % above it the fastest mode grows without bound within 0.05 s.
    scene, model, state = _bilateral_flat_net()
    limit = analytical_limits(model, state.position).explicit_limit
    engine = make_engine(scene.with_overrides({"simulation.dt": factor * limit}), model)
    engine.advance(state, scene.scene.duration)
    speed = np.linalg.norm(state.velocity, axis=1).max()
    assert bool(np.isfinite(speed) and speed < 2 * scene.launch.corner_speed) == stable


def test_tension_only_deployment_diverges_a_modest_factor_above_the_limit(tmp_path):
    # Reference: the analytical all-taut limit. Tension-only threads cut the pushing half of a
    # damper's overshoot, so the real net survives somewhat above the linear bound, but not 3x:
    # the run stops with the typed error naming the step and the limit, recording 'diverged'.
    scene = small_scene(**{"net.fold_ratio": 1.0, "scene.duration": 0.1})
    limit = scene_limits(scene).explicit_limit
    assert bn.run(scene.with_overrides({"simulation.dt": 0.9 * limit})).status == "completed"
    with pytest.raises(bn.DivergenceError) as info:
        bn.run(scene.with_overrides({"simulation.dt": 3 * limit}), tmp_path / "d.h5")
    assert info.value.step == pytest.approx(3 * limit)
    assert info.value.limit == pytest.approx(limit)
    assert f"{limit:.3g} s" in str(info.value) and f"{3 * limit:.3g} s" in str(info.value)
    assert bn.open_recording(tmp_path / "d.h5").status == "diverged"


def test_bisection_brackets_the_stable_step_and_implicit_euler_has_no_limit():
    # Reference: the measured largest stable step lies at or above the conservative linear
    # bound; implicit Euler (A-stable) runs 100x above the explicit bound and beyond the
    # undamped stiffness limit 2/omega_max without diverging.
    proc = cli("stability", "deployment", "--set", "net.nodes_per_side=6", "--set",
               "net.fold_ratio=1.0", "--horizon", "0.05", "--json")
    assert proc.returncode == 0, proc.stderr
    explicit, implicit = json.loads(proc.stdout)
    limits = scene_limits(small_scene(**{"net.fold_ratio": 1.0}))
    assert explicit["analytical_limit_s"] == pytest.approx(limits.explicit_limit)
    assert limits.explicit_limit <= explicit["dt_stable_s"] < explicit["dt_unstable_s"]
    assert explicit["dt_unstable_s"] <= 1.03 * explicit["dt_stable_s"]
    assert implicit["analytical_limit_s"] is None and implicit["dt_unstable_s"] is None
    scene = small_scene(**{"net.fold_ratio": 1.0, "simulation.integrator": "implicit_euler"})
    dt = 100 * limits.explicit_limit
    assert dt > limits.stiffness_limit
    assert is_stable(scene, dt, 0.05)


def test_bending_rotations_limit_only_the_explicit_method():
    # Reference: the Gershgorin bound on the nodes' rotational modes (stability.py's doc):
    # symplectic Euler's bending impulses run below the (conservative) bound and diverge 3x
    # above it; implicit Euler, whose angular update is scaled by the same bounds, runs at
    # 3x and at 100x it.
    scene = small_scene(**{"net.fold_ratio": 1.0, "scene.duration": 0.1,
                           "bending.enabled": True, "simulation.integrator": "implicit_euler"})
    limits = scene_limits(scene)
    assert math.isinf(limits.for_integrator("implicit_euler")) and limits.bending_limit < 1
    assert is_stable(scene, 3 * limits.bending_limit, 0.1)
    assert is_stable(scene, 100 * limits.bending_limit, 0.1)
    dt = 0.9 * limits.explicit_limit  # the threads stable; the impulse interval n dt varies

    def explicit(every):
        return scene.with_overrides({"simulation.integrator": "symplectic_euler",
                                     "bending.every": every})
    assert is_stable(explicit(math.floor(0.9 * limits.bending_limit / dt)), dt, 0.1)
    assert not is_stable(explicit(math.ceil(3 * limits.bending_limit / dt)), dt, 0.1)


def test_divergence_advice_names_what_can_diverge():
    # An implicit-Euler run's threads cannot diverge (A-stable): its error must not advise
    # the integrator it already uses; with the exact contact law (not passive beside them,
    # docs/capture.md) it names the implicit law.
    from bulletnet.sim.loop import _divergence

    scene = small_scene()
    limits = scene_limits(scene)
    state = bn.initial_state(scene, bn.build_model(scene))
    for integrator, exact, wanted, unwanted in (
            ("symplectic_euler", False, "the implicit_euler integrator", "contact.model"),
            ("implicit_euler", False, "use a smaller --dt", "implicit_euler integrator"),
            ("implicit_euler", True, "use contact.model=implicit", "implicit_euler integrator")):
        text = str(_divergence("non-finite state", state, 1e-3, integrator, limits, exact))
        assert wanted in text and unwanted not in text
    # with closing cables, symplectic Euler's names their limit where it was taken
    cables = dataclasses.replace(limits, cable_omega=1e5, cable_time=51.5)
    text = str(_divergence("non-finite state", state, 8e-6, "symplectic_euler", cables, False))
    assert "closing cables at t = 51.5 s sqrt(2)/omega_c = 1.41e-05 s" in text


@pytest.mark.parametrize(("factor", "relaxed", "stable"),
                         [(0.9, True, True), (0.9, False, False), (1.5, True, False)])
def test_a_folded_cable_limits_symplectic_euler_where_theory_says(factor, relaxed, stable):
    # Reference: a cable's blocks are rank one along g (stability.cable_frequency), so its
    # one mode has omega_c^2 = k g^T M^-1 g, and its damper, relaxed over the step from the
    # vertices' shares (1 / m here: no other damper meets them), the factor a = exp(-h tau
    # omega_c^2): the step is stable while h^2 omega_c^2 < 2 (1 + a) (module doc), solved
    # here. A heavily damped cable folded back through three free rings (|g| = 2 at each),
    # 1 % stretched: 10 % under that step its speeds stay within what its elastic energy can
    # give a node; with its damper explicit (shares 0) the same step is over seven times the
    # explicit limit 4 / (gamma + sqrt(gamma^2 + 4 omega^2)), gamma = tau omega^2, and blows
    # up. Over the limit the taut mode's first overshoot slackens the tension-only cable,
    # which can then stay slack (so at 1.1 times); at 1.5 times it blows up within 2000
    # steps.
    from scipy.optimize import brentq
    from test_closing import _cable_model, _scene

    from bulletnet.engines.fast import FastEngine
    from bulletnet.model.state import NetState

    pos = np.array([[0.0, 0, 0], [1, 0, 0], [0, 0.05, 0], [1, 0.1, 0], [0, 0.15, 0]])
    length = np.linalg.norm(np.diff(pos, axis=0), axis=1).sum()
    ea, mass, tau = 100.0, 1e-3, 2e-2
    model = _cable_model(pos, [mass] * 5, [False] * 5, range(5), rest=0.99 * length,
                         rigidity=ea, damping_time=tau)
    limits = analytical_limits(model, pos)
    assert limits.gamma_max == limits.omega_max == 0.0
    omega, gamma = limits.cable_omega, tau * limits.cable_omega**2
    limit = brentq(lambda h: (h * omega) ** 2 - 2 * (1 + math.exp(-h * gamma)), 0.0, 2 / omega)
    assert limits.explicit_limit == pytest.approx(math.sqrt(2) / omega)
    assert limits.explicit_limit <= limit
    assert 0.9 * limit > 7 * 4 / (gamma + math.sqrt(gamma**2 + 4 * omega**2))
    dt = factor * limit
    scene = _scene(scene__duration=1.0, simulation__integrator="symplectic_euler",
                   simulation__dt=dt)
    state = NetState(0.0, pos.copy(), np.zeros((5, 3)))
    engine = FastEngine(scene, model)
    if not relaxed:
        engine.arrays.cables.share[:] = 0.0
    engine.advance(state, 2000 * dt)
    energy = 0.5 * ea / (0.99 * length) * (0.01 * length) ** 2  # [J] the stretch's
    bound = math.sqrt(2 * energy / mass)  # [m/s] all of it in one node
    speed = np.linalg.norm(state.velocity, axis=1).max()
    assert bool(np.isfinite(speed) and speed < bound) == stable
