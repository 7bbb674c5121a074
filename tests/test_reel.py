"""The reel at the chaser against closed forms: a slack tether reeled in at its speed, a
tethered pair pulled together with its momentum kept, the brake holding the tension at its
limit and capping a snap, the work-energy balance, and the reel on every path (grid and
pair list, fast and bullet) and in a recorded run."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

import bulletnet as bn
from bulletnet.engines import make_engine
from bulletnet.model.state import NetState
from bulletnet.sim.observers import Run
from bulletnet.sim.tow import ReelControl, Trigger
from tests.conftest import small_scene
from tests.test_grid import assert_identical
from tests.test_tow import point_masses, scene

EPS = np.finfo(float).eps


def tether(masses, rest, stiffness, damping, fixed_anchor=False):
    """A chain of point masses (the anchor first, the chaser last) joined by S = len(masses)
    - 1 threads of rest length ``rest`` [m], stiffness [N/m] and damping [N s/m]; the anchor
    clamped with ``fixed_anchor``."""
    count = len(masses) - 1
    model = point_masses(masses, [(i, i + 1) for i in range(count)], [rest] * count,
                         [stiffness] * count, [damping] * count)
    fixed = np.zeros(len(masses), bool)
    fixed[0] = fixed_anchor
    return dataclasses.replace(model, fixed=fixed)


def reel_run(model, distance, t_end, frames, integrator="symplectic_euler", dt=1e-4,
             pull=0.0, reel=True, **keys):
    """``model`` (:func:`tether`) laid straight along x, the chaser ``distance`` [m] from the
    anchor, at rest, with a reel (the ``reel.*`` ``keys``, trigger ``time``) started as a
    run starts it, and a constant ``pull`` [N] on the chaser along +x, to ``t_end`` [s];
    per frame (F + 1,): the times [s], the chaser thread's tension [N], its largest of every
    step since the frame before [N], the deployed length [m], the reel's work [J], the
    positions [m] (F + 1, N, 3) and velocities [m/s]."""
    segments = model.thread_count
    s = scene(tether__enabled=True, tether__segments=segments,
              tether__length=float(model.rest_length.sum()),
              tether__chaser_mass=float(model.mass[-1]), reel__enabled=reel,
              reel__trigger="time", simulation__integrator=integrator, simulation__dt=dt,
              simulation__cg_tolerance=1e-13,  # (implicit: solved to round-off)
              scene__duration=t_end, **{f"reel__{k}": v for k, v in keys.items()})
    position = np.zeros((model.node_count, 3))
    position[:, 0] = np.linspace(0.0, distance, model.node_count)
    state = NetState(0.0, position, np.zeros_like(position))
    engine = make_engine(s, model)
    engine.external[-1, 0] = pull
    if reel:
        ReelControl(s, None).frame(Run(s, model, engine, state))
    out = {k: [] for k in ("tension", "peak", "length", "work", "position", "velocity")}
    times = np.linspace(0.0, t_end, frames + 1)
    for t in times:
        if t > 0.0:
            engine.advance(state, float(t))
        tension = engine.thread_loads(state)[0]
        loads = engine.reel_loads() or {"length": float(model.rest_length.sum()), "work": 0.0}
        out["tension"].append(tension[-1])
        out["peak"].append(max(engine.peak_tensions()[0][-1], tension[-1]))
        out["length"].append(loads["length"])
        out["work"].append(loads["work"])
        out["position"].append(state.position.copy())
        out["velocity"].append(state.velocity.copy())
    engine.close()
    return {"time": times, **{k: np.array(v) for k, v in out.items()}}


@pytest.mark.parametrize("integrator", ["symplectic_euler", "implicit_euler"])
def test_slack_tether_reels_in_at_its_speed_to_the_least_length(integrator):
    # Reference: a reel at speed v from t_s shortens the deployed length as L0 - v (t - t_s)
    # until it is L_min, then holds it; a slack tether carries nothing, so nothing moves. Each
    # step subtracts v dt: the length is the closed form to round-off, at most half an ulp
    # of L0 a step (n steps since t_s), and the nodes stay exactly where they were.
    length, v, least, start, dt = 8.0, 1.0, 6.0, 0.25, 1e-3
    model = tether([3.0, 0.01, 0.01, 0.01, 1.0], length / 4, 1e4, 10.0)
    run = reel_run(model, 5.0, 3.0, 60, integrator, dt, speed=v, min_length=least,
                   trigger_time=start)
    t = run["time"]
    steps = np.maximum(np.round((t - start) / dt), 0.0)
    expected = np.maximum(length - v * dt * steps, least)
    assert run["length"][t <= start].tolist() == [length] * int((t <= start).sum())
    assert np.abs(run["length"] - expected).max() <= 0.5 * np.spacing(length) * steps.max()
    assert run["length"][-1] == least and (run["length"] > least).sum() == 45  # to 2.25 s
    assert not run["tension"].any()
    np.testing.assert_array_equal(run["position"], run["position"][:1].repeat(61, axis=0))


@pytest.mark.parametrize("integrator", ["symplectic_euler", "implicit_euler"])
def test_reel_in_pulls_a_tethered_pair_together_and_keeps_its_momentum(integrator):
    # Reference: Newton's third law. The reel is inside the system (the chaser's drum), so
    # with no external force the total momentum stays zero and the centre of mass where it
    # was, to round-off (a few ulps of a step's largest impulse: 1e-12 of m_c v here),
    # however hard the reel pulls, while the chaser (5 kg) and a heavy body (50 kg) at the
    # tether's far end close on each other. The tether (4 segments, light nodes) is reeled
    # in at v = 0.5 m/s for 2 s from taut at its rest length, 8 m: the deployed length falls
    # to 7 m (to round-off), and the pair closes at least as fast: a tension-only line that
    # snaps them together at v lets them coast on at up to 2 v once it slackens (an elastic
    # rebound), so the separation ends below the deployed length, the line slack.
    masses = np.array([50.0, 0.01, 0.01, 0.01, 5.0])
    model = tether(masses, 2.0, 1e4, 10.0)
    run = reel_run(model, 8.0, 2.0, 20, integrator, 1e-4, speed=0.5, min_length=1.0)
    momentum = np.einsum("n,tna->ta", masses, run["velocity"])
    center = np.einsum("n,tna->ta", masses, run["position"]) / masses.sum()
    assert np.abs(momentum).max() <= 1e-12 * masses[-1] * 0.5
    assert np.abs(center - center[0]).max() <= 1e-12 * 8.0
    assert run["length"][-1] == pytest.approx(7.0, abs=0.5 * np.spacing(8.0) * 2e4)
    gap = run["position"][:, -1, 0] - run["position"][:, 0, 0]
    assert (np.diff(gap) < 0).all() and gap[-1] < run["length"][-1]
    assert run["tension"][-1] == 0.0
    assert run["position"][-1, 0, 0] > 0.0 and run["position"][-1, -1, 0] < 8.0


F_PULL, T_LIMIT, K, M_C = 10.0, 6.0, 100.0, 1.0
"""The brake's rig: a pull [N] on a chaser [kg] tethered to a clamped anchor by a 2 m tether
of stiffness [N/m] (w = sqrt(k / m_c) = 10 rad/s), and the brake's tension limit [N]."""


def spring_tension(t, zeta):
    """Tension [N] of the brake's rig without a brake: the chaser pulled by F from rest at
    the tether's rest length, mu x'' + c x' + k x = F, x(0) = x'(0) = 0, so T = k x + c x'
    with x = F / k (1 - e^(-s t) (cos w_d t + s / w_d sin w_d t)), s = zeta w,
    w_d = w sqrt(1 - zeta^2)."""
    w = math.sqrt(K / M_C)
    s, w_d = zeta * w, w * math.sqrt(1 - zeta**2)
    decay = math.exp(-s * t)
    x = F_PULL / K * (1 - decay * (math.cos(w_d * t) + s / w_d * math.sin(w_d * t)))
    rate = F_PULL / K * decay * (s * s / w_d + w_d) * math.sin(w_d * t)
    return K * x + 2 * zeta * math.sqrt(K * M_C) * rate


@pytest.mark.parametrize("zeta", [0.0, 0.2])
@pytest.mark.parametrize("integrator", ["symplectic_euler", "implicit_euler"])
def test_brake_holds_the_tension_at_its_limit_while_it_pays_out(integrator, zeta):
    # Reference: a chaser (m_c) pulled by F from a clamped anchor through an elastic tether:
    # the tension rises as :func:`spring_tension` (F (1 - cos w t) undamped) and reaches the
    # brake's limit T_lim < F at t* (0.116 s undamped; found by brentq). From then on the
    # brake pays out just enough to hold it: the deployed length stays L0 exactly before
    # t* and grows after, the tension at every frame is T_lim (to round-off), and the chaser
    # accelerates at (F - T_lim) / m_c. Symplectic Euler applies the tension of the step's
    # start, which the brake has set: that acceleration to round-off. Implicit Euler applies
    # the end of the step's tension, T_lim + k_n (x_(n+1) - x_n) + c_n (u_(n+1) - u_n) (the
    # rest length held over the step; c_n = tau k_n), so between two frames the chaser's
    # momentum falls short of (F - T_lim) dt_frame by dt times the sum of those terms:
    # between dt k_min and dt k_max times (dx + tau du), its displacement and speed change
    # (k falls as the line pays out; the CG solve to round-off). Undamped, the spring alone
    # holds T_lim, so the deployed length is the chaser's distance over 1 + T_lim / (E A)
    # at every frame.
    from scipy.optimize import brentq

    dt, dt_frame = 1e-4, 0.01
    c = 2 * zeta * math.sqrt(K * M_C)
    model = tether([1.0, M_C], 2.0, K, c, fixed_anchor=True)
    run = reel_run(model, 2.0, 1.0, 100, integrator, dt, pull=F_PULL, tension_limit=T_LIMIT)
    t_star = brentq(lambda t: spring_tension(t, zeta) - T_LIMIT, 0.0, math.pi / 10.0)
    before, braking = run["time"] < t_star - dt, run["time"] > t_star + dt_frame
    assert (run["length"][before] == 2.0).all() and (np.diff(run["length"][braking]) > 0).all()
    # (the brake's root cancels terms of E A (1 + tau / dt) l_0 to T_lim l_0: a few ulps of
    # their ratio)
    ea, tau = K * 2.0, c / K
    np.testing.assert_allclose(run["tension"][braking], T_LIMIT,
                               rtol=8 * EPS * (1 + tau / dt) * ea / T_LIMIT)
    speed, where = run["velocity"][:, -1, 0], run["position"][:, -1, 0]
    du, dx = np.diff(speed[braking]), np.diff(where[braking])
    expected = (F_PULL - T_LIMIT) * dt_frame / M_C
    if integrator == "symplectic_euler":
        np.testing.assert_allclose(du, expected, rtol=1e-9)
    else:
        k_min = ea / run["length"][braking][1:]  # the line pays out: k (and c) fall
        k_max = ea / run["length"][braking][:-1]
        short = (expected - du) * M_C / dt
        assert (short >= k_min * (dx + tau * du) * (1 - 1e-9)).all()
        assert (short <= k_max * (dx + tau * du) * (1 + 1e-9)).all()
    if zeta == 0.0:
        distance = where - run["position"][:, 0, 0]
        np.testing.assert_allclose(run["length"][braking],
                                   distance[braking] / (1 + T_LIMIT / (K * 2.0)), rtol=1e-12)


@pytest.mark.parametrize("integrator", ["symplectic_euler", "implicit_euler"])
def test_below_its_limit_the_brake_pays_nothing_out(integrator):
    # Reference: the same rig pulled by F = 5 N < T_lim / 2: the undamped tension
    # F (1 - cos w t) peaks at 2 F = 10 N < T_lim = 12 N, so the brake never slips: the
    # deployed length stays exactly L0, and the run is the run without a reel (to round-off:
    # the reel writes the tether's k = E A / l_0 back, E A read as k l_0).
    model = tether([1.0, M_C], 2.0, K, 0.0, fixed_anchor=True)
    runs = [reel_run(model, 2.0, 1.0, 100, integrator, pull=5.0, reel=reel, tension_limit=12.0)
            for reel in (True, False)]
    assert (runs[0]["length"] == 2.0).all()
    assert runs[0]["tension"].max() == pytest.approx(10.0, rel=2e-2)  # 2 F, first order
    np.testing.assert_allclose(runs[0]["tension"], runs[1]["tension"], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(runs[0]["position"], runs[1]["position"], rtol=1e-13)


@pytest.mark.parametrize("integrator", ["symplectic_euler", "implicit_euler"])
def test_brake_caps_the_snap_of_a_slack_tether(integrator):
    # Reference: tests/test_tow.py's snap: a step F = 10 N on a chaser (m_c = 1 kg) whose
    # tether to m_d = 3 kg is slack by d = 5 cm meets it at v = sqrt(2 F d / m_c) and snaps
    # to P + sqrt(P^2 + (v mu w)^2) = 19.0 N (P = F m_d / M = 7.5 N, mu the reduced mass,
    # w = sqrt(k / mu)): the stretch x = P / k + A sin(w t - phi), A = sqrt((P / k)^2 +
    # (v / w)^2). With the brake's limit at 12 N no step's tension exceeds it (to round-off:
    # the brake sets each step's tension from the state it starts in). The stretch reaches
    # T_lim / k at the rate x' = w sqrt(A^2 - (T_lim / k - P / k)^2); from there the
    # tension is T_lim, the separation grows at x' decelerating at T_lim / mu - F / m_c, and
    # its growth x'^2 / (2 (T_lim / mu - F / m_c)) is paid out but for the stretch's own
    # growth at the falling k = E A / L: L gains that over 1 + T_lim / (E A), 0.1164 m.
    # Then the pair oscillates about P up to T_lim again, and the line pays out no more.
    # First order: within 1 % (implicit Euler's numerical damping takes 0.4 % of x'^2).
    masses, gap, limit = [3.0, 1.0], 0.05, 12.0
    model = tether(masses, 2.0, K, 0.0)
    free = reel_run(model, 2.0 - gap, 1.5, 1500, integrator, pull=F_PULL, reel=False)
    capped = reel_run(model, 2.0 - gap, 1.5, 1500, integrator, pull=F_PULL,
                      tension_limit=limit)
    mu, p = 0.75, F_PULL * 3.0 / 4.0
    w, v = math.sqrt(K / mu), math.sqrt(2 * F_PULL * gap / 1.0)
    assert free["peak"].max() == pytest.approx(p + math.hypot(p, v * mu * w), rel=1e-2)
    assert capped["peak"].max() == pytest.approx(limit, rel=1e-12)
    rate = w * math.sqrt((p / K) ** 2 + (v / w) ** 2 - ((limit - p) / K) ** 2)
    paid = rate**2 / (2 * (limit / mu - F_PULL / 1.0)) / (1 + limit / (K * 2.0))
    after = capped["length"][capped["time"] >= 0.5]
    assert after[0] - 2.0 == pytest.approx(paid, rel=1e-2)
    assert after[-1] - after[0] <= 1e-3 * paid


def mechanical_energy(run, masses, rigidity, segments):
    """Kinetic energy and the tether's elastic energy E A (l - l_0)^2 / (2 l_0) at l_0 =
    L / S [J] of a :func:`reel_run` on a chain, per frame (F + 1,)."""
    kinetic = 0.5 * np.einsum("n,tna,tna->t", np.asarray(masses), run["velocity"],
                              run["velocity"])
    spans = np.linalg.norm(np.diff(run["position"], axis=1), axis=2)
    rest = run["length"][:, None] / segments
    return kinetic + (0.5 * rigidity * np.maximum(spans - rest, 0.0) ** 2 / rest).sum(axis=1)


@pytest.mark.parametrize("integrator", ["symplectic_euler", "implicit_euler"])
def test_energy_changes_by_the_reels_work(integrator):
    # Reference: the work-energy theorem. A pair (3 kg, 1 kg) on an undamped tether, the
    # chaser pulled by F = 10 N; the reel reels in at 0.3 m/s while the tension is below
    # its 12 N limit and its brake pays out above it (the pull's step overshoots to 15 N):
    # the mechanical energy (kinetic and elastic) changes by the pull's work, F times the
    # chaser's displacement, plus the reel's (both signs here). Symplectic Euler keeps a
    # modified energy within O(w dt) of the oscillation's ~3 J (w dt = 1.2e-3): within 1e-4
    # of the ~30 J of work; implicit Euler's numerical damping (~w dt / 2) takes at most
    # ~w^2 dt T E_osc = 0.1 J over 2 s and never gives: within 1e-2 of it, from below.
    masses = [3.0, 1.0]
    model = tether(masses, 2.0, K, 0.0)
    run = reel_run(model, 2.0, 2.0, 200, integrator, pull=F_PULL, speed=0.3,
                   tension_limit=12.0)
    energy = mechanical_energy(run, masses, K * 2.0, 1)
    pull = F_PULL * (run["position"][:, -1, 0] - 2.0)
    work = pull + run["work"]
    assert np.diff(run["work"]).min() < -0.01 and np.diff(run["work"]).max() > 0.01
    gained = energy - energy[0]
    if integrator == "symplectic_euler":
        assert np.abs(gained - work).max() <= 1e-4 * work.max()
    else:
        assert (gained <= work + 1e-12 * work.max()).all()
        assert (gained >= work - 1e-2 * work.max()).all()


@pytest.mark.parametrize(("integrator", "dt"), [("symplectic_euler", 1e-6),
                                                ("implicit_euler", 3e-5)])
def test_grid_equals_pairs_with_a_reel(integrator, dt):
    # Reference: the pair-list path (tests/test_grid.py). The reel writes the tether's rest
    # lengths, stiffness and damping where each path's steps read them (the pair list's
    # arrays, the grid's other threads' rows) with the same arithmetic: bit for bit. A
    # stretched tether (2.9 m laid over 3 m) on a 5 x 5 net: the brake pays out to its 50 N,
    # then the motor reels in at 1 m/s.
    states, lengths = [], []
    for kernels in ("pairs", "grid"):
        s = small_scene(**{
            "net.nodes_per_side": 5, "simulation.kernels": kernels, "scene.duration": 0.1,
            "simulation.integrator": integrator, "simulation.dt": dt, "tether.enabled": True,
            "tether.length": 2.9, "tether.segments": 3, "tether.chaser_distance": 3.0,
            "reel.enabled": True, "reel.speed": 1.0, "reel.tension_limit": 50.0,
            "reel.trigger": "time"})
        model = bn.build_model(s)
        engine = make_engine(s, model)
        assert engine.kernels == kernels
        state = bn.initial_state(s, model)
        engine.start_reel(0.0)
        for t in (0.03, 0.07, 0.1):
            engine.advance(state, t)
        states.append(state)
        lengths.append(engine.reel_loads()["length"])
        engine.close()
    assert lengths[0] == lengths[1] and lengths[0] != 2.9
    assert_identical(*states)


def test_trigger_starts_at_the_time_or_after_the_capture():
    # The shared start rule of [thrust] and [reel]: trigger "time" at trigger_time; trigger
    # "captured" at trigger_delay after the frame that decided the capture, unknown before.
    class Capture:
        outcome, time = "undecided", -1.0

    rules = scene(tether__enabled=True, reel__enabled=True, reel__speed=1.0,
                  reel__trigger="time", reel__trigger_time=4.0).reel
    assert Trigger(rules, None).start_time() == 4.0
    capture = Capture()
    after = Trigger(dataclasses.replace(rules, trigger="captured", trigger_delay=1.5), capture)
    assert after.start_time() is None
    capture.outcome, capture.time = "captured", 38.4
    assert after.start_time() == 38.4 + 1.5


@pytest.mark.parametrize(("keys", "message"), [
    ({"tether.enabled": False}, "reel.enabled: a reel needs a chaser (tether.enabled with "
                                "tether.chaser_mass > 0)"),
    ({"tether.chaser_mass": 0.0}, "reel.enabled: a reel needs a chaser"),
    ({"simulation.engine": "reference"}, "reel.enabled: the reference engine has no reel; "
                                         "use --engine fast or bullet"),
    ({"reel.trigger": "captured"}, "reel.trigger: 'captured' needs outcome.enabled"),
    ({"reel.speed": 0.0}, "reel.speed: a reel without a speed [m/s] or a reel.tension_limit "
                          "[N] does nothing"),
    ({"reel.min_length": 60.0}, "reel.min_length: expected at most tether.length (50 m), got "
                                "60 m"),
    ({"reel.max_length": 40.0}, "reel.max_length: expected at least tether.length (50 m)"),
    ({"reel.tension_limit": -1.0}, "reel.tension_limit: expected a number >= 0 [N]"),
])
def test_bad_reels_are_refused_in_one_line(keys, message):
    with pytest.raises(bn.ScenarioError, match=None) as error:
        small_scene(**{"tether.enabled": True, "reel.enabled": True, "reel.speed": 1.0,
                       "reel.trigger": "time", **keys})
    assert message in str(error.value) and "\n" not in str(error.value)


def test_a_run_records_the_reel_and_metrics_report_it(tmp_path):
    # A recorded run on a 4 x 4 net with a tether stretched by 3 % (7.6 kN, 380 J): the
    # brake pays out against the motor in the first frame, taking energy out, then the motor
    # reels in at 2 m/s (doing work against the tension) to the least length. The recording
    # holds the deployed length [m] and the reel's work [J] per frame, with their units, and
    # `bulletnet metrics` prints them. Reference: the energy balance (as
    # tests/test_closing.py's for the winches): every force but the reel is passive, so the
    # mechanical energy, with the reeled tether's elastic energy at its recorded length
    # (bulletnet.analysis.metrics.energy), never rises above its start plus the reel's work.
    import subprocess
    import sys

    import h5py

    from bulletnet.analysis.metrics import energy, reel_work, summary

    s = small_scene(**{
        "net.nodes_per_side": 4, "scene.duration": 0.3, "simulation.integrator": "implicit_euler",
        "simulation.dt": 1e-4, "tether.enabled": True, "tether.length": 2.9,
        "tether.segments": 3, "tether.chaser_distance": 3.0, "reel.enabled": True,
        "reel.speed": 2.0, "reel.tension_limit": 50.0, "reel.trigger": "time",
        "reel.min_length": 2.5})
    result = bn.run(s, tmp_path / "reel.h5")
    rec = bn.open_recording(result.path)
    with h5py.File(result.path) as f:
        units = {name: f[f"tether/{name}"].attrs["units"]
                 for name in ("threads", "length", "reel_work")}
    assert units == {"threads": "1", "length": "m", "reel_work": "J"}
    assert rec.attrs["reel_start_s"] == 0.0
    assert rec.tether["threads"].tolist() == [rec.pairs.shape[0] - k for k in (3, 2, 1)]
    length, work = rec.tether["length"], reel_work(rec)
    assert length[0] == 2.9 and length[1] > length[0] and length[-1] == 2.5
    assert work[1] < -50.0 and (np.diff(work[2:22]) > 0.0).all()  # the brake, then the motor
    doc = summary(rec)["reel"]
    assert doc["largest_length_m"] == length.max() and doc["work_J"] == work[-1]
    gain = energy(rec) - energy(rec)[0]
    assert (gain <= work + 1e-12 * abs(energy(rec)).max()).all()
    out = subprocess.run([sys.executable, "-m", "bulletnet.cli.main", "metrics",
                          str(result.path)], capture_output=True, text=True, check=True).stdout
    assert "reel at the chaser: from 0.00 s; tether deployed 2.900 m -> 2.500 m" in out
