"""The grid kernels (stencils over the net's rows and columns) against the pair-list kernels.

Reference: the pair-list path, the general loop over the thread list that every other element
uses. The grid path sums every node's forces, right-hand side, matrix product and
preconditioner block in the pair-list order, so the two must agree bit for bit: positions,
velocities, orientations and angular velocities, on every integrator, with and without
bending, for odd, even and the smallest nets, and with contact; with closing cables and a
tether, to round-off (see there).
"""

from __future__ import annotations

import numpy as np
import pytest

import bulletnet as bn
from bulletnet.engines import make_engine
from bulletnet.solver import grid
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
                         [("symplectic_euler", 1e-6, 0.35), ("implicit_euler", 3e-5, 0.5),
                          ("exponential_euler", 5e-6, 0.35)])
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


@pytest.mark.parametrize("ns", [2, 8, 11, 21])
def test_thread_rows_start_cache_lines(ns):
    # not physics: the layout the stencils' speed rests on (docs/speed.md). Thread t's column
    # Ns + t begins a 64-byte line in every row of every thread quantity, so the stencils'
    # and the running maxima's vector stores never split a line; node rows begin lines too
    g = grid.build(bn.build_model(small_scene(**{"net.nodes_per_side": ns})))
    for rows in (g.th, g.tv, g.eh, g.ev, g.blocks, g.wh, g.wv, g.bh, g.bv, g.peak_rows):
        assert rows.shape[1] % 8 == 0
        assert all(rows[r, ns:].ctypes.data % grid.ALIGN == 0 for r in range(rows.shape[0]))
    for rows in (g.x, g.v, g.other, g.base, g.bend, g.dv):
        assert all(rows[r].ctypes.data % grid.ALIGN == 0 for r in range(3))


@pytest.mark.parametrize(("integrator", "dt"), [("symplectic_euler", 1e-6),
                                                ("implicit_euler", 3e-5),
                                                ("exponential_euler", 5e-6)])
@pytest.mark.parametrize("bending", [False, True])
@pytest.mark.parametrize("attach", ["center", "bridle"])
def test_grid_agrees_with_pairs_with_closing_and_tether(integrator, dt, bending, attach):
    # The closing cables and the tether run the same pair-list kernels on both paths, but a
    # node with both grid threads and other elements (a net corner in two cables and a corner
    # thread) sums them in another order: the paths agree to round-off, not bit for bit.
    # Cables short enough to be taut as the net opens, winches from 0.3 s, a tether taut from
    # the start; compared at 0.4 s, before the reeled net's chaotic motion amplifies the
    # round-off (measured <= 3e-9 m there; a term missing on one path moves the nodes by
    # dt^2 T / m per step, millimetres over the 0.1 s of reeling).
    states = []
    for kernels in ("pairs", "grid"):
        scene = small_scene(**{
            "net.nodes_per_side": 7, "scene.duration": 0.4, "bending.enabled": bending,
            "simulation.kernels": kernels, "simulation.integrator": integrator,
            "simulation.dt": dt, "closing.enabled": True, "closing.length_ratio": 0.5,
            "closing.reel_speed": 2.0, "closing.trigger": "time", "closing.trigger_time": 0.3,
            "tether.enabled": True, "tether.attach": attach, "tether.segments": 3,
            "tether.length": 1.0, "tether.chaser_distance": 1.0, "tether.chaser_mass": 1.0})
        model = bn.build_model(scene)
        engine = make_engine(scene, model)
        assert engine.kernels == kernels
        state = bn.initial_state(scene, model)
        engine.start_winches(0.3)  # what a run's WinchControl does for trigger "time"
        for t in np.linspace(0.0, 0.4, 9)[1:]:
            engine.advance(state, float(t))
        # both elements acted: the chaser, at rest at first, was pulled; the winches did work
        assert np.abs(state.velocity[-1]).max() > 0.0 and engine.cables.work.min() > 0.0
        states.append(state)
    np.testing.assert_allclose(states[0].position, states[1].position, rtol=0, atol=1e-6)
    np.testing.assert_allclose(states[0].velocity, states[1].velocity, rtol=0, atol=1e-4)
