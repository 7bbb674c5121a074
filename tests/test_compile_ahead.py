"""Compiling a first run's kernel groups apart (bulletnet.sim.compile_ahead): the groups name
exactly the specializations the compiled loop uses, so what a second process compiles into
numba's cache is what the run loads."""

from __future__ import annotations

import pytest
from conftest import small_capture

import bulletnet as bn
from bulletnet.engines import make_engine
from bulletnet.sim.compile_ahead import is_cached, signature


@pytest.mark.parametrize("overrides", [
    {},                                                          # grid, implicit Euler
    {"bending.enabled": True},                                   # with bending
    {"simulation.kernels": "pairs"},                             # the pair list
    {"simulation.integrator": "symplectic_euler", "simulation.dt": 2e-6},
])
def test_kernel_groups_are_the_loops_own_specializations(tmp_path, monkeypatch, overrides):
    # Reference: numba's record of the signatures each dispatcher compiled (or loaded) for the
    # run's loop: every (kernel, arguments) of the groups is one of them, for the arguments'
    # types as the loop passes them. The loop is a new dispatcher compiled here, not loaded
    # from numba's cache (a loaded loop types none of the kernels it calls, so their records
    # would be empty).
    from numba.core.caching import NullCache

    from bulletnet.solver import integrators

    scene = small_capture(**{"scene.duration": 0.1, **overrides})
    model = bn.build_model(scene)
    engine = make_engine(scene, model)
    loop = integrators.advance.__wrapped__(engine.grid is not None, engine.implicit)  # anew
    loop._cache = NullCache()
    monkeypatch.setattr(integrators, "advance", lambda on_grid, implicit: loop)
    bn.run(scene, tmp_path / "run.h5")
    groups = engine.kernel_groups(bn.initial_state(scene, model))
    bending = overrides.get("bending.enabled", False) and "simulation.kernels" not in overrides
    assert set(groups) == {"step", "contact"} | ({"bending"} if bending else set())
    for calls in groups.values():
        for dispatcher, args in calls:
            assert signature(args) in dispatcher.overloads, dispatcher.py_func.__name__
            assert is_cached(dispatcher, args)


def test_a_free_net_has_no_groups():
    # Reference: the definition: a free net's first run compiles only grid.free_steps.
    scene = bn.load_scenario("deployment")
    model = bn.build_model(scene)
    assert make_engine(scene, model).kernel_groups(bn.initial_state(scene, model)) == {}
