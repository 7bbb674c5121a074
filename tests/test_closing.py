"""The closing cable, its winch and the main tether against closed forms: the forces of a cable
through a frictionless ring, Atwood's machine, a winch reeling to its stall tension, a tether
carrying the mass it accelerates, and the energy balance with the winches' work."""

from __future__ import annotations

import numpy as np
import pytest

from bulletnet.engines.fast import FastEngine
from bulletnet.kernels.cable import cable_arrays, cable_energy, cable_forces
from bulletnet.model import scenario
from bulletnet.model.builder import build_model, closing_routes, initial_state
from bulletnet.model.net import NetModel, NodeKind
from bulletnet.model.state import NetState
from bulletnet.model.topology import net_corners, perimeter


def _cable_model(position, mass, fixed, cable_nodes, rest, rigidity, damping_time):
    """A model of free or clamped point masses joined by one closing cable and no threads."""
    n = len(mass)
    none = np.zeros(0)
    return NetModel(
        nodes_per_side=0, mass=np.asarray(mass, float), radius=np.full(n, 0.01),
        kind=np.full(n, NodeKind.TETHER, dtype=np.int8), pairs=np.zeros((0, 2), np.int64),
        rest_length=none, thread_radius=none, axial_stiffness=none, axial_damping=none,
        transverse_stiffness=none, transverse_damping=none, bending_stiffness=none,
        bending_damping=none, inertia=np.full(n, 1e-6), rest_axis=np.zeros((0, 3)),
        fixed=np.asarray(fixed), load=np.zeros((n, 3)), breaking_tension=none, bilateral=False,
        cable_nodes=np.asarray(cable_nodes, np.int64),
        cable_start=np.array([0, len(cable_nodes)], np.int64),
        cable_rest_length=np.array([rest]), cable_rigidity=np.array([rigidity]),
        cable_damping_time=np.array([damping_time]))


def _scene(**keys):
    doc: dict = {}
    for key, value in keys.items():
        section, name = key.split("__")
        doc.setdefault(section, {})[name] = value
    return scenario.from_dict(doc, "<test>")


def test_cable_through_a_ring_pulls_both_sides_equally_and_the_ring_with_their_sum():
    # Reference: statics of a frictionless ring. A (0,0,-1) -> ring R (0,0,0) -> B (1,0,0):
    # L = 2, T = (E A / L_0) (L - L_0) on both sides; A and B are pulled towards R with T, R
    # with T (e_RA + e_RB).
    pos = np.array([[0.0, 0, -1], [0, 0, 0], [1, 0, 0]])
    ea, rest = 1000.0, 1.9
    cables = cable_arrays(np.array([0, 1, 2]), np.array([0, 3]), np.array([rest]),
                          np.array([ea]), np.zeros(1), np.zeros(1), np.full(1, np.inf),
                          np.zeros(1))
    force = np.zeros((3, 3))
    cable_forces(pos, np.zeros((3, 3)), cables, force, False, 0.0)
    t = ea / rest * (2.0 - rest)
    assert cables.tension[0] == pytest.approx(t, rel=1e-14)
    np.testing.assert_allclose(force[0], [0, 0, t], rtol=1e-14)
    np.testing.assert_allclose(force[2], [-t, 0, 0], rtol=1e-14)
    np.testing.assert_allclose(force[1], [t, 0, -t], rtol=1e-14)
    np.testing.assert_allclose(force.sum(axis=0), 0.0, atol=1e-12)  # internal: no net force
    # slack (L <= L_0): exactly nothing
    cables.rest[0] = 2.5
    force[:] = 0.0
    cable_forces(pos, np.zeros((3, 3)), cables, force, False, 0.0)
    assert cables.tension[0] == 0.0 and not force.any()


@pytest.mark.parametrize("integrator", ["symplectic_euler", "implicit_euler"])
def test_atwood_machine(integrator):
    # Reference: Atwood's machine. Masses m1, m2 hang under gravity g on a cable over two
    # clamped frictionless rings: a = g (m1 - m2) / (m1 + m2), T = 2 m1 m2 g / (m1 + m2).
    # The elastic cable's stretch oscillates about T's value and decays (damping ratio ~0.4 at
    # 850 rad/s), and its integral over the transient leaves no velocity offset (the stretch
    # rate starts and ends at 0), so at 0.2 s the velocities are the rigid machine's to the
    # integrators' error, which vanishes here: under constant forces symplectic Euler's
    # velocities are exact, and in the steady motion the implicit step's stiffness terms act
    # on zero (the cable's length rate and the strands' sideways velocities are 0).
    m1, m2, g = 2.0, 1.0, 9.81
    pos = np.array([[-0.05, 0, -1], [-0.05, 0, 0], [0.05, 0, 0], [0.05, 0, -1]])
    model = _cable_model(pos, [m1, 1.0, 1.0, m2], [False, True, True, False], [0, 1, 2, 3],
                         rest=2.1, rigidity=1e6, damping_time=1e-3)
    s = _scene(scene__gravity=[0.0, 0.0, -g], scene__duration=1.0,
               simulation__integrator=integrator, simulation__dt=1e-5,
               simulation__cg_tolerance=1e-13)  # (implicit: solved to round-off)
    engine = FastEngine(s, model)
    state = NetState(0.0, pos.copy(), np.zeros((4, 3)))
    engine.advance(state, 0.2)
    a = g * (m1 - m2) / (m1 + m2)
    tol = 1e-9 * a * 0.2  # round-off over 2e4 steps and the e^-70 of the transient
    np.testing.assert_allclose(state.velocity[0], [0, 0, -a * 0.2], rtol=0, atol=tol)
    np.testing.assert_allclose(state.velocity[3], [0, 0, a * 0.2], rtol=0, atol=tol)
    tension = engine.cable_loads()["tension"][0]
    assert tension == pytest.approx(2 * m1 * m2 * g / (m1 + m2), rel=1e-5)


def test_winch_reels_at_its_speed_until_stall_then_holds_stall_tension():
    # Reference: a cable between two clamped ends, its winch reeling at v from t = 0 with no
    # damper: L_0(t) = L_0 - v t while T = E A (L - L_0) / L_0 < stall; then the winch holds,
    # reeling one step whenever T drops below stall: T stays in [stall, stall + k v dt). Its
    # work is the elastic energy it stored (nothing moves, nothing dissipates).
    pos = np.array([[0.0, 0, 0], [0.5, 0, 0], [1.0, 0, 0]])
    model = _cable_model(pos, [1.0, 1.0, 1.0], [True, True, True], [0, 1, 2], rest=1.02,
                         rigidity=100.0, damping_time=0.0)
    v, stall, dt = 0.1, 2.0, 1e-4
    s = _scene(closing__reel_speed=v, closing__stall_tension=stall, closing__trigger="time",
               closing__trigger_time=0.0, scene__duration=1.0,
               simulation__integrator="symplectic_euler", simulation__dt=dt)
    engine = FastEngine(s, model)
    engine.start_winches(0.0)  # what a run's WinchControl does for trigger "time"
    state = NetState(0.0, pos.copy(), np.zeros((3, 3)))
    # T = stall at L_0 = E A L / (E A + stall) = 0.98039 m, reached at t_s = (1.02 - that) / v
    stall_rest = 100.0 / (100.0 + stall)
    t_stall = (1.02 - stall_rest) / v
    engine.advance(state, 0.1)
    assert engine.cables.rest[0] == pytest.approx(1.02 - v * 0.1, abs=1e-12)
    engine.advance(state, t_stall + 0.05)
    hold = []
    for k in range(1, 50):
        engine.advance(state, t_stall + 0.05 + k * dt)
        hold.append(engine.cables.tension[0])
    k_final = 100.0 / engine.cables.rest[0]
    assert min(hold) >= stall and max(hold) < stall + k_final * v * dt * (1 + 1e-9)
    assert engine.cables.rest[0] == pytest.approx(stall_rest, abs=v * dt)
    stored = cable_energy(1.0, engine.cables.rest[0], 100.0)
    assert engine.cables.work[0] == pytest.approx(stored, rel=1e-12)


def test_tether_carries_the_mass_it_accelerates():
    # Reference: Newton's second law on a chain. A force F on the chaser (the chain's last
    # node) accelerates the payload, tether nodes and chaser together at a = F / M once the
    # chain's axial oscillations have decayed (the slowest, payload against chaser through the
    # four threads in series: damping ratio 0.55 at 55 rad/s, e^-90 after 3 s); each thread
    # then carries a times the mass beyond it, to round-off (symplectic Euler's velocities
    # are exact under constant forces).
    mass = np.array([1.0, 0.01, 0.01, 0.01, 5.0])
    n = mass.size
    pairs = np.array([[k, k + 1] for k in range(n - 1)], np.int64)
    p = n - 1
    pos = np.zeros((n, 3))
    pos[:, 2] = -np.arange(n)
    model = NetModel(
        nodes_per_side=0, mass=mass, radius=np.full(n, 0.01),
        kind=np.full(n, NodeKind.TETHER, dtype=np.int8), pairs=pairs, rest_length=np.ones(p),
        thread_radius=np.full(p, 1e-3), axial_stiffness=np.full(p, 1e4),
        axial_damping=np.full(p, 200.0), transverse_stiffness=np.zeros(p),
        transverse_damping=np.zeros(p), bending_stiffness=np.zeros(p),
        bending_damping=np.zeros(p), inertia=np.full(n, 1e-6), rest_axis=np.zeros((p, 3)),
        fixed=np.zeros(n, bool), load=np.zeros((n, 3)), breaking_tension=np.full(p, np.inf),
        bilateral=False)
    s = _scene(scene__duration=4.0, simulation__integrator="symplectic_euler",
               simulation__dt=1e-5)
    engine = FastEngine(s, model)
    force = 2.0
    engine.external[-1] = [0.0, 0.0, -force]
    state = NetState(0.0, pos, np.zeros((n, 3)))
    engine.advance(state, 3.0)
    tension = engine.thread_loads(state)[0]
    np.testing.assert_allclose(tension, force / mass.sum() * np.cumsum(mass)[:-1], rtol=1e-9)


def test_builder_tether_has_its_material_and_masses():
    # Reference: Eq. 2 and Eq. 3 with the tether's material: each tether thread of rest length
    # l = length / segments has k = E_t A_t / l and c = 2 xi_t k / omega_ref, no bending
    # springs; each tether node carries half of each of its threads; the chaser its mass too.
    s = scenario.load("deployment", {
        "net.nodes_per_side": 3, "tether.enabled": True, "tether.segments": 4,
        "tether.length": 8.0, "tether.chaser_mass": 7.0})
    model = build_model(s)
    t = s.tether
    area = np.pi * t.diameter**2 / 4
    k = t.young_modulus * area / 2.0
    tail = slice(-4, None)
    np.testing.assert_allclose(model.axial_stiffness[tail], k, rtol=1e-14)
    np.testing.assert_allclose(model.axial_damping[tail],
                               2 * t.damping_ratio * k / s.damping.axial_reference_frequency,
                               rtol=1e-14)
    assert not model.bending_stiffness[tail].any() and not model.transverse_stiffness[tail].any()
    thread_mass = t.density * area * 2.0
    np.testing.assert_allclose(model.mass[-4:-1], thread_mass, rtol=1e-14)
    assert model.mass[-1] == pytest.approx(7.0 + thread_mass / 2, rel=1e-14)
    assert list(model.kind[-4:]) == [NodeKind.TETHER] * 3 + [NodeKind.CHASER]
    assert model.pairs[-4, 0] == 4  # the centre node of the 3 x 3 net
    state = initial_state(s, model)
    assert state.position[-1] == pytest.approx([0.0, 0.0, -t.chaser_distance])


def test_closing_routes_follow_the_perimeter():
    # Reference: the mouth's order (topology.perimeter). Each side's cable starts and ends at
    # the corner masses of its two net corners and passes every node of that side once.
    ns = 5
    corners = net_corners(ns)
    sides = closing_routes("sides", ns)
    assert len(sides) == 4
    ring = list(perimeter(ns))
    covered = []
    for nodes in sides:
        assert nodes.size == ns + 2
        assert nodes[0] == ns * ns + list(corners).index(nodes[1])
        assert nodes[-1] == ns * ns + list(corners).index(nodes[-2])
        covered.extend(nodes[1:-1])
    assert sorted(set(covered)) == sorted(ring)
    (loop,) = closing_routes("perimeter", ns)
    assert loop[0] == loop[-1] == ns * ns and list(loop[1:-2]) == ring


def test_closing_energy_rises_by_the_winch_work_and_no_more():
    # Reference: the energy balance. Every force is passive except the winches, so the
    # mechanical energy (kinetic + thread and cable elastic) may rise above its start by the
    # winches' work and no more; a model error that creates energy fails this.
    from bulletnet import run
    from bulletnet.analysis.metrics import energy, winch_work
    from bulletnet.recording.reader import open_recording

    s = scenario.load("deployment", {
        "net.nodes_per_side": 7, "scene.duration": 2.0, "closing.enabled": True,
        "closing.trigger": "time", "closing.trigger_time": 0.5, "closing.reel_speed": 2.0,
        "closing.stall_tension": 50.0, "simulation.integrator": "implicit_euler",
        "simulation.dt": 1e-4})
    import tempfile
    from pathlib import Path

    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "closing.h5"
        run(s, out)
        rec = open_recording(out)
    work = winch_work(rec)
    gain = energy(rec) - energy(rec)[0]
    assert work[-1] > 1e-3  # the winches did work
    assert np.all(gain <= work + 1e-12 * abs(energy(rec)[0]))
    assert rec.cables["rest_length"][-1].max() < rec.cables["rest_length"][0].min()


def test_a_recorded_run_takes_the_course_of_an_unrecorded_one(tmp_path):
    # Reference: determinism. Recording reads the run (each frame's thread loads, cable
    # loads, peaks), so a run with closing cables must end in the same state, bit for bit,
    # recorded at 100 Hz or not at all.
    from bulletnet import run

    s = scenario.load("deployment", {
        "net.nodes_per_side": 7, "scene.duration": 1.5, "closing.enabled": True,
        "closing.trigger": "time", "closing.trigger_time": 0.3, "closing.reel_speed": 2.0,
        "closing.stall_tension": 5.0, "simulation.integrator": "implicit_euler",
        "simulation.dt": 1e-4, "simulation.record_rate": 100.0})
    recorded = run(s, tmp_path / "recorded.h5").state
    alone = run(s).state
    np.testing.assert_array_equal(recorded.position, alone.position)
    np.testing.assert_array_equal(recorded.velocity, alone.velocity)


@pytest.mark.parametrize("trigger", ["contact", "wrap"])
def test_winches_start_at_their_trigger(tmp_path, trigger):
    # Reference: the trigger rules. The winches reel (the rest length falls) from
    # first contact + delay (to the step) or from the first recorded frame whose wrap
    # (metrics.wrap, recomputed from the recording) reaches the threshold, and not before.
    from bulletnet import run
    from bulletnet.analysis.metrics import first_contact_time, wrap
    from bulletnet.recording.reader import open_recording
    from tests.conftest import small_capture

    scene = small_capture(**{"closing.enabled": True, "closing.trigger": trigger,
                             "closing.trigger_delay": 0.12, "closing.trigger_wrap": 0.02,
                             "closing.reel_speed": 1.0})
    rec = open_recording(run(scene, tmp_path / "trigger.h5").path)
    rest = rec.cables["rest_length"][:, 0]
    reeling = np.nonzero(rest < rest[0])[0]
    assert reeling.size, "the winches never started"
    if trigger == "contact":
        start = first_contact_time(rec) + 0.12
    else:
        start = rec.time[np.nonzero(wrap(rec) >= 0.02)[0][0]]
    # the first frame showing a shorter cable is the first frame after the start
    assert rec.time[reeling[0] - 1] <= start < rec.time[reeling[0]]
    assert rest[-1] == pytest.approx(rest[0] - 1.0 * (rec.time[-1] - start), abs=2e-3)


@pytest.mark.slow
def test_paper_capture_with_closing_is_captured(tmp_path):
    # Reference: the capture score's outcome rules (docs/capture.md) on the paper's capture
    # with the closing mechanism (scenarios/capture_closing.toml, no bending). Without it the
    # same net escapes (docs/capture.md); with the winches started at first contact the
    # perimeter gathers round the CSM and holds it: captured (at 38.9 s at the 56.5° launch,
    # held to 120 s: benchmarks/closing.py). The run stops once decided.
    from bulletnet import run

    scene = scenario.load("capture_closing", {"outcome.stop_when_decided": True})
    result = run(scene)
    assert result.status == "completed"
    assert result.outcome == "captured"
    assert result.state.time < 60.0  # stopped when decided, not at 120 s
