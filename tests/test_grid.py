"""The grid kernels (stencils over the net's rows and columns) against the pair-list kernels.

Reference: the pair-list path, the general loop over the thread list that every other element
uses. The grid path sums every node's forces, right-hand side, matrix product and
preconditioner block in the pair-list order, so the two must agree bit for bit: positions,
velocities, orientations and angular velocities, on every integrator, with and without
bending, for odd, even and the smallest nets, and with contact.
"""

from __future__ import annotations

import numpy as np
import pytest

import bulletnet as bn
from bulletnet import grid
from bulletnet.engines import make_engine
from tests.conftest import small_capture, small_scene


def final_states(scene_for) -> list[bn.NetState]:
    """The final state of one run per kernel choice (pairs, grid) of ``scene_for(kernels)``."""
    out = []
    for kernels in ("pairs", "grid"):
        scene = scene_for(kernels)
        model = bn.build_model(scene)
        engine = make_engine(scene, model)
        assert engine.kernels == kernels
        state = bn.initial_state(scene, model)
        for t in np.linspace(0.0, scene.scene.duration, 4)[1:]:  # a few chunks, as a run
            engine.advance(state, float(t))
        engine.close()
        out.append(state)
    return out


def assert_identical(a: bn.NetState, b: bn.NetState) -> None:
    assert np.isfinite(a.position).all()
    np.testing.assert_array_equal(a.position, b.position)
    np.testing.assert_array_equal(a.velocity, b.velocity)
    if a.oriented:
        np.testing.assert_array_equal(a.orientation, b.orientation)
        np.testing.assert_array_equal(a.angular_velocity, b.angular_velocity)
    if a.debris is not None:
        np.testing.assert_array_equal(a.debris, b.debris)


@pytest.mark.parametrize("ns", [2, 7, 10])
@pytest.mark.parametrize("bending", [False, True])
@pytest.mark.parametrize(("integrator", "dt", "duration"),
                         [("symplectic_euler", 1e-6, 0.35), ("implicit_euler", 3e-5, 0.5)])
def test_grid_equals_pairs(ns, bending, integrator, dt, duration):
    states = final_states(lambda kernels: small_scene(**{
        "net.nodes_per_side": ns, "bending.enabled": bending, "simulation.kernels": kernels,
        "simulation.integrator": integrator, "simulation.dt": dt, "scene.duration": duration}))
    # the net has moved (its corner threads tighten at ~0.25 s): not two initial states
    assert np.abs(states[0].velocity[: ns * ns]).max() > 0.01
    assert_identical(*states)


@pytest.mark.parametrize("bending", [False, True])
def test_grid_equals_pairs_through_contact(bending):
    # the 6 x 6 capture touches the debris between 0.4 and 0.6 s; 0.8 s covers the impact
    pairs, on_grid = final_states(lambda kernels: small_capture(**{
        "scene.duration": 0.8, "bending.enabled": bending, "simulation.kernels": kernels}))
    assert pairs.debris[9] != 0.0 or pairs.debris[7] != 0.0  # the net has pushed the debris
    assert_identical(pairs, on_grid)


def test_grid_applies_to_nets_only():
    # the cantilever (a clamped, bilateral beam) keeps the pair-list path
    beam = bn.load_scenario("cantilever")
    assert not grid.applies(bn.build_model(beam))
    assert make_engine(beam, bn.build_model(beam)).kernels == "pairs"
    assert grid.applies(bn.build_model(small_scene()))
