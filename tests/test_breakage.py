"""Breakage (``strength.breakage``): an element whose tension reaches its breaking tension
fails for good. Against closed forms: a thread pulled at constant speed fails when Eq. 3's
tension reaches T_b; a chain pulling a mass fails first where it is most loaded; a closing
cable's failure stops its force and its winch. And invariants: momentum with failed
threads, the two kernel paths alike, and breakage with a huge strength changing nothing."""

from __future__ import annotations

import h5py
import numpy as np
import pytest

import bulletnet as bn
from bulletnet.engines.bullet import BulletEngine
from bulletnet.engines.fast import FastEngine
from bulletnet.kernels.breakage import break_cables, breaking_arrays
from bulletnet.kernels.cable import cable_arrays, cable_forces
from bulletnet.model import scenario
from bulletnet.model.net import NetModel
from bulletnet.model.state import NetState
from tests.conftest import small_scene

K, C, L0, V, T_B, T_S = 1.0e4, 50.0, 0.5, 0.5, 1000.0, 0.01
"""The pulled thread: stiffness [N/m], damping [N s/m], rest length [m], speed [m/s],
breaking tension [N], and the time it is slack for at the start [s]."""


def chain_model(masses, k: float, c: float, strength: float, rest: float = L0,
                fixed=None) -> NetModel:
    """Nodes 0 .. n along x, ``rest`` [m] apart, of ``masses`` [kg] (n + 1,), joined by n
    threads i -> i + 1 of stiffness ``k`` [N/m], damping ``c`` [N s/m] and breaking tension
    ``strength`` [N]; no bending."""
    n = len(masses)
    p = n - 1
    ones = np.ones(p)
    return NetModel(
        nodes_per_side=0, mass=np.asarray(masses, dtype=float), radius=np.full(n, 0.01),
        kind=np.zeros(n, dtype=np.int8), pairs=np.array([[i, i + 1] for i in range(p)]),
        rest_length=rest * ones, thread_radius=1e-3 * ones, axial_stiffness=k * ones,
        axial_damping=c * ones, transverse_stiffness=0 * ones, transverse_damping=0 * ones,
        bending_stiffness=0 * ones, bending_damping=0 * ones, inertia=np.full(n, 1e-7),
        rest_axis=np.tile([1.0, 0, 0], (p, 1)),
        fixed=np.zeros(n, bool) if fixed is None else np.asarray(fixed),
        load=np.zeros((n, 3)), breaking_tension=strength * ones, bilateral=False)


def breakage_scene(integrator: str, dt: float):
    """A bare scene (no debris, no contact, 0 g) with breakage on."""
    return scenario.from_dict({"simulation": {"integrator": integrator, "dt": dt},
                               "strength": {"breakage": True}})


@pytest.mark.parametrize("engine_class, integrator", [
    (FastEngine, "symplectic_euler"), (FastEngine, "implicit_euler"),
    (BulletEngine, "symplectic_euler")])
def test_thread_pulled_at_constant_speed_fails_when_eq3_reaches_breaking_tension(
        engine_class, integrator):
    # Reference: Eq. 3. Node 0 clamped, node 1 (1e12 kg: its speed stays V) starts at
    # l = l_0 - V t_s moving away at V. The thread is slack until t_s, then
    # T(t) = k (l - l_0) + c v_r = k V (t - t_s) + c V, which reaches T_b at
    # t_b = t_s + (T_b - c V) / (k V) = 0.01 + 975 / 5000 = 0.205 s. The step from t_n
    # evaluates T(t_n), so the failure time recorded is the first t_n >= t_b: in
    # [t_b, t_b + dt). From then on the thread carries nothing (the step's own tension is 0)
    # and the energy lost is k (l - l_0)^2 / 2 at the end of the failing step, l - l_0 =
    # V (t_f + dt - t_s). The pair list only (two nodes are no grid; the grid is held to it
    # on a net below).
    dt = 1e-4
    model = chain_model([1.0, 1e12], K, C, T_B, fixed=[True, False])
    engine = engine_class(breakage_scene(integrator, dt), model)
    state = NetState(0.0, np.array([[0.0, 0, 0], [L0 - V * T_S, 0, 0]]),
                     np.array([[0.0, 0, 0], [V, 0, 0]]))
    try:
        engine.advance(state, 0.25)
        after = state.velocity.copy()
        engine.advance(state, 0.3)
        t_b = T_S + (T_B - C * V) / (K * V)
        t_f = engine.breakage.failure_time[0]
        assert t_b - 1e-9 <= t_f < t_b + dt + 1e-9
        assert engine.work.tension[0] == 0.0  # the last step's own tension
        assert engine.thread_loads(state)[0][0] == 0.0
        assert engine.breakage.energy[0] == pytest.approx(
            0.5 * K * (V * (t_f + dt - T_S)) ** 2, rel=1e-6)
        np.testing.assert_allclose(state.velocity, after, rtol=1e-12, atol=0)  # no force
    finally:
        engine.close()


@pytest.mark.parametrize("integrator", ["symplectic_euler", "implicit_euler"])
def test_chain_pulling_a_mass_fails_first_nearest_the_pull(integrator):
    # Reference: Newton's second law on a chain. A force F(t) = F' t pulls node 5 of a chain
    # whose node 0 is a 5 kg mass and nodes 1-5 are 1 kg each (10 kg in all); slowly
    # ramped, the chain accelerates as one body at a = F / 10 kg and thread i (nodes i to
    # i + 1) drags the nodes behind it, T_i = a (5 + i) kg = F (5 + i) / 10: the thread
    # nearest the pull (i = 4, 0.9 F) is the most loaded and the only one to fail (the
    # others at 0.8 F and less, and unloaded once it has failed).
    masses = [5.0, 1.0, 1.0, 1.0, 1.0, 1.0]
    model = chain_model(masses, 1e4, 50.0, 100.0)
    engine = FastEngine(breakage_scene(integrator, 1e-4), model)
    x = np.arange(6) * L0
    state = NetState(0.0, np.column_stack([x, np.zeros(6), np.zeros(6)]), np.zeros((6, 3)))
    rate = 500.0  # F' [N/s]
    for t in np.arange(1, 401) * 1e-3:
        engine.external[5, 0] = rate * (t - 0.5e-3)  # the ramp's mean over the chunk
        engine.advance(state, t)
    failed = engine.breakage.failure_time
    assert failed[4] >= 0 and (failed[:4] < 0).all()
    # it failed when its quasi-static tension 0.9 F' t reached 100 N, to the ramp's lag
    assert failed[4] == pytest.approx(100.0 / (0.9 * rate), rel=0.05)


def momentum(rec) -> np.ndarray:
    """Total momentum sum m v of each frame [kg m/s], shape (T, 3)."""
    return np.einsum("n,tna->ta", rec.mass, rec.velocity)


@pytest.fixture(scope="module")
def broken_nets(tmp_path_factory):
    """The small deployment (0 g) with net threads of 1/85 of Technora's strength, breakage
    on, on both kernel paths with both integrators: {(kernels, integrator): recording}."""
    d = tmp_path_factory.mktemp("breakage")
    out = {}
    for kernels in ("grid", "pairs"):
        for integrator in ("symplectic_euler", "implicit_euler"):
            path = d / f"{kernels}_{integrator}.h5"
            bn.run(small_scene(**{"strength.breakage": True,
                                  "strength.thread_breaking_stress": 4e7,
                                  "simulation.kernels": kernels,
                                  "simulation.integrator": integrator,
                                  "scene.duration": 0.6}), path)
            out[kernels, integrator] = bn.open_recording(path)
    return out


def test_net_with_failed_threads_conserves_momentum_and_both_paths_agree(broken_nets):
    # Reference: Newton's third law. A failed thread carries nothing on either end, every
    # other force is internal and the scene is in 0 g: the total momentum stays what it was
    # (zero, the launch is symmetric) to round-off, failures or not. The grid's stencils
    # give the pair list's arithmetic bit for bit (solver/grid.py), so the two paths fail
    # the same threads at the same steps; a failed thread's recorded tension is 0 after.
    for (kernels, integrator), rec in broken_nets.items():
        failed = rec.failure_time >= 0
        assert failed.sum() >= 4, (kernels, integrator)
        scale = np.einsum("n,tna->t", rec.mass, np.abs(rec.velocity)).max()
        drift = np.abs(momentum(rec) - momentum(rec)[0]).max()
        assert drift <= 1e-12 * scale, (kernels, integrator, drift / scale)
        after = (rec.time[:, None] > rec.failure_time) & failed
        assert (rec.tension[after] == 0.0).all()
        doc = bn.metrics.breakage(rec)
        assert doc["broken_threads"] == failed.sum() and doc["first_break_kind"] == "net thread"
        assert doc["first_break_s"] == rec.failure_time[failed].min()
        assert rec.attrs["broken_threads"] == failed.sum() and rec.attrs["broken_energy_J"] > 0
        with h5py.File(rec.path) as f:
            assert f["threads/failure_time"].attrs["units"] == "s"
    for integrator in ("symplectic_euler", "implicit_euler"):
        np.testing.assert_array_equal(broken_nets["grid", integrator].failure_time,
                                      broken_nets["pairs", integrator].failure_time)


@pytest.mark.parametrize("overrides", [
    {},                                                        # grid, symplectic Euler
    {"simulation.kernels": "pairs", "simulation.integrator": "implicit_euler",
     "bending.enabled": True}])
def test_breakage_with_huge_strength_records_the_same_numbers(tmp_path, overrides):
    # Reference: the breakage step only ever zeroes a failed element's parameters. With a
    # strength 1e12 times Technora's nothing fails, and every recorded dataset is the one of
    # breakage off bit for bit (on the grid the free net then runs the general loop, not
    # grid.free_steps: the same step kernels); the run with breakage adds only its failure
    # times (all -1) and attributes.
    paths = []
    for on in (False, True):
        keys = {"strength.breakage": True, **{f"strength.{k}_breaking_stress": 3.4e21 for k in (
            "thread", "corner_thread", "tether", "closing")}} if on else {}
        paths.append(tmp_path / f"{on}.h5")
        bn.run(small_scene(**{"scene.duration": 0.3, **overrides, **keys}), paths[-1])
    with h5py.File(paths[0]) as off, h5py.File(paths[1]) as on:
        names = []
        off.visit(lambda name: names.append(name) if isinstance(off[name], h5py.Dataset)
                  else None)
        for name in names:
            if name != "threads/breaking_tension":
                np.testing.assert_array_equal(off[name][()], on[name][()], err_msg=name)
        assert (on["threads/failure_time"][()] == -1.0).all()
        assert "threads/failure_time" not in off and on.attrs["broken_threads"] == 0


def test_failed_cable_carries_nothing_and_its_winch_stops():
    # Reference: the cable law (kernels/cable.py), T = k (L - L_0) + c (L' - L_0'),
    # k = E A / L_0. A straight two-span cable over nodes 0-1-2, L = 2 m, L_0 = 1.9 m,
    # E A = 1.9e4 N: k = 1e4 N/m, T = 1000 N at rest. At T_b = 800 N it fails: the elastic
    # energy lost is k (L - L_0)^2 / 2 = 50 J, its rigidity and reel speed go to zero, and
    # the next evaluation gives it no tension and no force.
    pos = np.array([[0.0, 0, 0], [1.0, 0, 0], [2.0, 0, 0]])
    vel = np.zeros((3, 3))
    cables = cable_arrays(np.array([0, 1, 2]), np.array([0, 3]), np.array([1.9]),
                          np.array([1.9e4]), np.array([0.01]), np.array([0.1]),
                          np.array([5000.0]), np.array([1.0]))
    force = np.zeros((3, 3))
    cable_forces(pos, vel, cables, force, False, 0.0)
    assert cables.tension[0] == pytest.approx(1000.0)
    breakage = breaking_arrays(np.zeros(0), np.array([800.0]))
    break_cables(pos, cables, breakage, 0.25)
    assert breakage.cable_failure_time[0] == 0.25
    assert breakage.energy[0] == pytest.approx(50.0)
    assert cables.rigidity[0] == 0.0 and cables.reel_speed[0] == 0.0
    force[:] = 0.0
    cable_forces(pos, vel, cables, force, True, 1e-4)
    assert cables.tension[0] == 0.0 and (force == 0.0).all() and cables.along[0] == 0.0
