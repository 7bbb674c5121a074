"""Shared helpers: small scenes that run in a second or two."""

from __future__ import annotations

import pytest

import bulletnet as bn


def small_scene(**overrides):
    """The deployment scene shrunk to a 6 x 6 net (Fig. 1's), with dotted-key overrides."""
    base = {"net.nodes_per_side": 6, "scene.duration": 0.4}
    base.update(overrides)
    return bn.load_scenario("deployment", base)


@pytest.fixture
def scene():
    return small_scene()


def small_capture(**overrides):
    """The capture scene shrunk to a 6 x 6 net, 1 m mesh, with the debris 3 m above it coming
    down at 2 m/s: the net touches it between 0.4 and 0.6 s; 1 s at 20 Hz (0.2 s of wall
    time once the kernels are compiled); with dotted-key overrides."""
    return bn.load_scenario("capture", {
        "net.nodes_per_side": 6, "net.mesh_length": 1.0, "debris.position": [0.0, 0.0, 3.0],
        "debris.velocity": [0.0, 0.0, -2.0], "scene.duration": 1.0,
        "simulation.record_rate": 20.0, **overrides})


def uncached_loops(monkeypatch) -> dict:
    """Have the runs build each step loop (:func:`bulletnet.solver.integrators.advance`) anew,
    without numba's cache, so that a run compiles it in this process, typing the kernels it
    calls (a loop loaded from the cache types none); returns the loops as they are built,
    by (on_grid, implicit)."""
    from numba.core.caching import NullCache

    from bulletnet.solver import integrators

    loops, build = {}, integrators.advance.__wrapped__

    def anew(on_grid, implicit):
        if (on_grid, implicit) not in loops:
            loops[on_grid, implicit] = build(on_grid, implicit)
            loops[on_grid, implicit]._cache = NullCache()
        return loops[on_grid, implicit]

    monkeypatch.setattr(integrators, "advance", anew)
    return loops


def small_tow(**overrides):
    """:func:`small_capture` in orbit with a 3 m tether (3 threads) to a 10 kg chaser, which
    burns 5 N (ZV-shaped) from 0.2 s, before the net holds the debris (the tow, judged with
    a 1 m safe distance, slips at once); 0.5 s; with dotted-key overrides."""
    return small_capture(**{
        "scene.duration": 0.5, "tether.enabled": True, "tether.length": 3.0,
        "tether.segments": 3, "tether.chaser_distance": 3.0, "tether.chaser_mass": 10.0,
        "thrust.enabled": True, "thrust.trigger": "time", "thrust.trigger_time": 0.2,
        "thrust.profile": "zv", "thrust.force": 5.0, "tow.enabled": True,
        "tow.safe_distance": 1.0, "orbit.enabled": True, **overrides})


@pytest.fixture(scope="session")
def viewer_runs(tmp_path_factory):
    """Recordings for the replay tests: a plain deployment at 100 Hz, a bending deployment at
    50 Hz, and a real capture (:func:`small_capture`) whose net touches the debris."""
    d = tmp_path_factory.mktemp("viewer")
    plain, bending, capture = d / "plain.h5", d / "bending.h5", d / "capture.h5"
    bn.run(small_scene(**{"scene.duration": 0.3}), plain)
    bn.run(small_scene(**{"scene.duration": 0.3, "bending.enabled": True,
                          "simulation.record_rate": 50.0}), bending)
    bn.run(small_capture(), capture)
    assert bn.open_recording(capture).contacts["count"].max() > 0, "no contact in the capture"
    return {"plain": plain, "bending": bending, "capture": capture, "dir": d}


@pytest.fixture(scope="session")
def viewer_tow(tmp_path_factory):
    """A recording of :func:`small_tow`, for the replay's chaser, tether and tow panel."""
    path = tmp_path_factory.mktemp("viewer_tow") / "tow.h5"
    bn.run(small_tow(), path)
    return path


@pytest.fixture(scope="session")
def viewer_broken(tmp_path_factory):
    """A recording of the small deployment whose net threads break (1/85 of Technora's
    strength, breakage on; tests/test_breakage.py's nets), for the replay's failed threads."""
    path = tmp_path_factory.mktemp("viewer_broken") / "broken.h5"
    bn.run(small_scene(**{"strength.breakage": True, "strength.thread_breaking_stress": 4e7,
                          "scene.duration": 0.6}), path)
    return path
