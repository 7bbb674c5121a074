"""Compiling a first run's kernel groups apart (bulletnet.sim.compile_ahead): the groups name
exactly the specializations the compiled loop uses, so what a second process compiles into
numba's cache is what the run loads."""

from __future__ import annotations

from pathlib import Path

import pytest
from conftest import small_capture, small_tow, uncached_loops

import bulletnet as bn
from bulletnet.common.direct_call import signature
from bulletnet.engines import make_engine
from bulletnet.sim.compile_ahead import is_cached


@pytest.mark.parametrize("overrides", [
    {},                                                          # grid, implicit Euler
    {"bending.enabled": True},                                   # with bending
    {"simulation.kernels": "pairs"},                             # the pair list
    {"simulation.integrator": "symplectic_euler", "simulation.dt": 2e-6},
])
def test_kernel_groups_are_the_loops_own_specializations(tmp_path, monkeypatch, overrides):
    # Reference: numba's record of the signatures each dispatcher compiled (or loaded) for the
    # run's loop and its frames' thread loads: every (kernel, arguments) of the groups is one
    # of them, for the arguments' types as the loop (or the frame) passes them. The loop is a
    # new dispatcher compiled here, not loaded from numba's cache (a loaded loop types none of
    # the kernels it calls, so their records would be empty).
    scene = small_capture(**{"scene.duration": 0.1, **overrides})
    model = bn.build_model(scene)
    engine = make_engine(scene, model)
    uncached_loops(monkeypatch)
    bn.run(scene, tmp_path / "run.h5")
    groups = engine.kernel_groups(bn.initial_state(scene, model))
    on_grid = "simulation.kernels" not in overrides
    bending = overrides.get("bending.enabled", False) and on_grid
    # (the grid's symplectic step is inlined into the loop whole: no group of its own)
    inlined = on_grid and overrides.get("simulation.integrator") == "symplectic_euler"
    assert set(groups) == ({"contact", "frame"} | ({"bending"} if bending else set())
                           | (set() if inlined else {"step"}))
    for calls in groups.values():
        for dispatcher, args in calls:
            assert signature(args) in dispatcher.overloads, dispatcher.py_func.__name__
            assert is_cached(dispatcher, args)


def test_a_free_net_has_no_groups():
    # Reference: the definition: a free net's first run compiles only grid.free_steps.
    scene = bn.load_scenario("deployment")
    model = bn.build_model(scene)
    assert make_engine(scene, model).kernel_groups(bn.initial_state(scene, model)) == {}


def test_the_tow_group_is_the_loop_the_burn_switches_to(tmp_path, monkeypatch):
    # Reference: numba's record of the signatures each loop compiled for (as above): the
    # run switches to symplectic Euler at the burn (thrust.integrator), and the group `tow`
    # names that loop for the arguments' types it is called with; a scene without the switch
    # has no such group.
    from bulletnet.sim import loop as run_loop

    loops = uncached_loops(monkeypatch)
    monkeypatch.setattr(run_loop, "compile_ahead", lambda *args: None)  # no second process
    scene = small_tow(**{"thrust.integrator": "symplectic_euler", "thrust.dt": 8e-6})
    model = bn.build_model(scene)
    state = bn.initial_state(scene, model)
    assert "tow" not in make_engine(small_tow(), model).kernel_groups(state)
    groups = make_engine(scene, model).kernel_groups(state)
    assert bn.run(scene, tmp_path / "run.h5").status == "completed"
    [(dispatcher, args)] = groups["tow"]
    assert dispatcher is loops[True, False] and signature(args) in dispatcher.overloads


def test_the_tow_loop_compiles_in_a_process_that_ends_with_the_run(monkeypatch):
    # Reference: the definition (sim/compile_ahead.py): with the tow's loop not cached,
    # compile_ahead returns the running second process instead of waiting for it, and
    # stop_helper ends it; with everything cached there is none.
    from bulletnet.sim import compile_ahead as ahead

    scene = small_tow(**{"thrust.integrator": "symplectic_euler", "thrust.dt": 8e-6})
    model = bn.build_model(scene)
    state = bn.initial_state(scene, model)
    engine = make_engine(scene, model)
    [(tow_loop, _)] = engine.kernel_groups(state)["tow"]
    monkeypatch.setattr(ahead, "is_cached", lambda dispatcher, args: True)
    assert ahead.compile_ahead(scene, engine, state) is None
    monkeypatch.setattr(ahead, "is_cached", lambda dispatcher, args: dispatcher is not tow_loop)
    helper = ahead.compile_ahead(scene, engine, state)
    assert helper is not None and helper.poll() is None  # still compiling: not waited for
    ahead.stop_helper(helper)
    assert helper.poll() is not None and not Path(helper.args[3]).exists()  # its scene file
