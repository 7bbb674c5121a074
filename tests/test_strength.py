"""Strength and safety margins against closed forms: each element's breaking tension from its
kind's breaking stress, section and knots; the least safety factor, the first overload and
the snap loads of a thread pulled at constant speed; the element kinds with a tether, a
bridle and closing cables; a recording made before breaking tensions were recorded; and
strength that only measures (a large one changes no recorded number)."""

from __future__ import annotations

import json
import math
import subprocess
import sys

import h5py
import numpy as np
import pytest

import bulletnet as bn
from bulletnet.common.errors import ScenarioError
from bulletnet.engines.fast import FastEngine
from bulletnet.model import scenario
from bulletnet.model.builder import build_model
from bulletnet.model.net import ElementKind, NetModel, NodeKind, corner_threads, thread_kinds
from bulletnet.model.state import NetState
from bulletnet.recording.writer import Recorder
from tests.conftest import small_scene

K, C, L0, V = 1.0e4, 50.0, 0.5, 0.5
"""The pulled thread: stiffness [N/m], damping [N s/m], rest length [m], speed [m/s]."""


def pulled_thread(path, strength: float, duration: float = 1.0, rate: float = 20.0,
                  motion=lambda t: (V * t, V)):
    """A recording of one thread whose node 0 is clamped at the origin and whose node 1 moves
    along x by ``motion(t)``, its extension l - L0 [m] and speed [m/s] (prescribed, not
    integrated; default: away at constant speed V from l = L0): ``rate`` frames a second
    [Hz] for ``duration`` [s], tensions from the engine's own Eq. 3."""
    one = np.ones(1)
    model = NetModel(
        nodes_per_side=0, mass=np.ones(2), radius=np.full(2, 0.01),
        kind=np.zeros(2, dtype=np.int8), pairs=np.array([[0, 1]]), rest_length=L0 * one,
        thread_radius=1e-3 * one, axial_stiffness=K * one, axial_damping=C * one,
        transverse_stiffness=0 * one, transverse_damping=0 * one, bending_stiffness=0 * one,
        bending_damping=0 * one, inertia=np.full(2, 1e-7), rest_axis=np.array([[1.0, 0, 0]]),
        fixed=np.array([True, False]), load=np.zeros((2, 3)),
        breaking_tension=strength * one, bilateral=False)
    s = scenario.from_dict({"simulation": {"integrator": "symplectic_euler", "dt": 1e-5}})
    engine = FastEngine(s, model)
    with Recorder(path, model, {"scenario": scenario.to_toml(s)}) as recorder:
        for t in np.arange(round(duration * rate) + 1) / rate:
            extension, speed = motion(t)
            position = np.array([[0.0, 0, 0], [L0 + extension, 0, 0]])
            velocity = np.array([[0.0, 0, 0], [speed, 0, 0]])
            recorder.append(NetState(t, position, velocity), *engine.thread_loads(
                NetState(t, position, velocity)))
    return bn.open_recording(path)


def test_thread_pulled_at_constant_speed_least_safety_factor_in_closed_form(tmp_path):
    # Reference: Eq. 3. Pulled from l = l_0 at speed v, the thread is slack at t = 0 (l = l_0)
    # and taut after, with T(t) = k v t + c v: over a run of duration tau the least safety
    # factor is T_b / (k v tau + c v), at t = tau; one slack -> taut event, whose peak is
    # T(tau); and an element of strength T_b < T(tau) first reaches it at the first frame t_k
    # with k v t_k + c v >= T_b, i.e. t_k >= (T_b - c v) / (k v).
    strength = 1.0e4
    rec = pulled_thread(tmp_path / "strong.h5", strength)
    peak = K * V * 1.0 + C * V
    margin = bn.metrics.safety(rec)
    assert margin["least_safety_factor"] == pytest.approx(strength / peak, rel=1e-12)
    assert margin["time_s"] == 1.0 and margin["tension_N"] == pytest.approx(peak, rel=1e-12)
    assert margin["element"] == {"kind": "net thread", "index": 0, "nodes": [0, 1],
                                 "positions_m": [[0.0, 0.0, 0.0], [L0 + V, 0.0, 0.0]]}
    assert margin["overloaded_elements"] == 0 and margin["first_overload_s"] is None
    taut = rec.time > 0
    np.testing.assert_allclose(bn.metrics.utilisation(rec)[:, 0],
                               np.where(taut, (K * V * rec.time + C * V) / strength, 0.0),
                               rtol=1e-12)
    events, peaks, frames = bn.metrics.snap_loads(rec)
    assert events.tolist() == [1] and peaks[0] == pytest.approx(peak, rel=1e-12)
    assert rec.time[frames[0]] == 1.0

    weak = pulled_thread(tmp_path / "weak.h5", 3000.0)
    margin = bn.metrics.safety(weak)
    first = (3000.0 - C * V) / (K * V)  # 0.595 s: the next frame at 20 Hz is 0.6 s
    assert margin["first_overload_s"] == pytest.approx(math.ceil(first * 20) / 20, abs=1e-12)
    assert margin["overloaded_elements"] == 1
    assert margin["least_safety_factor"] == pytest.approx(3000.0 / peak, rel=1e-12)


def test_snap_loads_of_a_thread_stretched_and_released_twice_a_second(tmp_path):
    # Reference: Eq. 3 for l - l_0 = a sin(w t), w = 4 pi / s: T = k a sin(w t) + c a w
    # cos(w t) where l > l_0, so the thread is taut for w t in (0, pi - phi) of each period,
    # phi = atan(c w / k), and slack for the rest: two slack -> taut events in 1 s (at
    # t = 0 it is slack, l = l_0). Each spell's peak is the largest tension of its frames,
    # below a sqrt(k^2 + (c w)^2).
    a, w = 1e-3, 4 * math.pi
    rec = pulled_thread(tmp_path / "snaps.h5", 1e4, rate=200.0,
                        motion=lambda t: (a * math.sin(w * t), a * w * math.cos(w * t)))
    events, peaks, frames = bn.metrics.snap_loads(rec)
    assert events.tolist() == [2]
    assert peaks[0] == rec.tension[:, 0].max() <= a * math.hypot(K, C * w)
    assert peaks[0] > 0.99 * a * math.hypot(K, C * w)  # frames 5 ms apart
    assert bn.metrics.strength_summary(rec)["snap_events"] == 2


def test_breaking_tension_of_each_kind_from_stress_section_and_knots():
    # Reference: T_b = sigma_b pi d^2 / 4, times the knot efficiency on the net's threads and
    # the corner threads only, with every kind's own stress and diameter; the kinds found by
    # their ends: 2 Ns (Ns - 1) net threads, 4 corner threads, 4 bridle lines (which also end
    # on corner masses, so position or "touches a corner mass" would misfile them), the
    # tether's segments and 4 closing cables.
    s = small_scene(**{"net.nodes_per_side": 4, "tether.enabled": True,
                       "tether.attach": "bridle", "tether.segments": 5,
                       "closing.enabled": True, "closing.trigger": "time",
                       "strength.thread_breaking_stress": 1e9,
                       "strength.corner_thread_breaking_stress": 2e9,
                       "strength.tether_breaking_stress": 3e9,
                       "strength.closing_breaking_stress": 4e9,
                       "strength.knot_efficiency": 0.5})
    model = build_model(s)
    kinds = thread_kinds(model.pairs, model.kind)
    counts = {ElementKind(k).name: int(n) for k, n in zip(*np.unique(kinds, return_counts=True),
                                                          strict=True)}
    assert counts == {"NET": 24, "CORNER": 4, "BRIDLE": 4, "TETHER": 5}
    assert corner_threads(model.pairs, model.kind).tolist() == np.flatnonzero(
        kinds == ElementKind.CORNER).tolist()
    ends = model.kind[model.pairs[kinds == ElementKind.CORNER]]
    assert (np.sort(ends, axis=1) == [NodeKind.CORNER, NodeKind.CORNER_MASS]).all()

    def expected(stress, radius, knot=1.0):
        return stress * math.pi * radius**2 * knot

    t = s.tether.diameter / 2
    for kind, value in ((ElementKind.NET, expected(1e9, s.net.thread_radius, 0.5)),
                        (ElementKind.CORNER, expected(2e9, s.net.corner_thread_radius, 0.5)),
                        (ElementKind.BRIDLE, expected(3e9, t)),
                        (ElementKind.TETHER, expected(3e9, t))):
        np.testing.assert_allclose(model.breaking_tension[kinds == kind], value, rtol=1e-15)
    np.testing.assert_allclose(model.cable_breaking_tension,
                               expected(4e9, s.closing.diameter / 2), rtol=1e-15)


def test_a_run_with_tether_and_cables_records_every_kind(tmp_path):
    # Reference: the model the run was built from (its breaking tensions, recorded with their
    # unit) and the element kinds above; the margins name one least safety factor per kind.
    s = small_scene(**{"net.nodes_per_side": 4, "scene.duration": 0.05,
                       "tether.enabled": True, "tether.attach": "bridle",
                       "tether.segments": 3, "tether.chaser_distance": 3.0,
                       "closing.enabled": True, "closing.trigger": "time"})
    path = tmp_path / "tethered.h5"
    bn.run(s, path)
    model = build_model(s)
    with h5py.File(path) as f:
        for name, value in (("threads/breaking_tension", model.breaking_tension),
                            ("cables/breaking_tension", model.cable_breaking_tension)):
            np.testing.assert_array_equal(f[name][()], value)
            assert f[name].attrs["units"] == "N"
    rec = bn.open_recording(path)
    kinds = bn.metrics.element_kinds(rec)
    assert kinds.shape == (model.thread_count + 4,)
    assert (kinds[-4:] == ElementKind.CABLE).all()
    margin = bn.metrics.strength_summary(rec)
    assert set(margin["by_kind"]) == {"net thread", "corner thread", "bridle line",
                                      "tether thread", "closing cable"}
    assert margin["by_kind"]["closing cable"]["elements"] == 4
    cable = bn.metrics.element(rec, model.thread_count + 2, 0)
    start = rec.cables["start"]
    assert cable["kind"] == "closing cable" and cable["index"] == 2
    assert cable["nodes"] == rec.cables["nodes"][[start[2], start[3] - 1]].tolist()


def test_large_strength_changes_no_recorded_number(tmp_path):
    # Reference: today's recording. Strength is measured against, never acting: a strength
    # 1e12 times the default gives the same datasets bit for bit, all but the breaking
    # tensions themselves (the golden check holds this for every path of the solver).
    paths = []
    for factor in (1.0, 1e12):
        stress = factor * scenario.TECHNORA_BREAKING_STRESS
        s = small_scene(**{"scene.duration": 0.3, **{
            f"strength.{key}_breaking_stress": stress
            for key in ("thread", "corner_thread", "tether", "closing")}})
        paths.append(bn.run(s, tmp_path / f"x{factor:g}.h5").path)
    with h5py.File(paths[0]) as a, h5py.File(paths[1]) as b:
        names = []
        a.visititems(lambda name, obj: names.append(name) if isinstance(obj, h5py.Dataset)
                     else None)
        for name in names:
            same = np.array_equal(a[name][()], b[name][()])
            assert same == (name != "threads/breaking_tension"), name
    margins = [bn.metrics.safety(bn.open_recording(p))["least_safety_factor"] for p in paths]
    assert margins[1] == pytest.approx(1e12 * margins[0], rel=1e-12)


def test_recording_without_breaking_tensions_is_judged_from_its_scene(tmp_path):
    # Reference: the same recording with its breaking tensions. One made before they were
    # recorded gets them from its scene (the `scenario` attribute) built again, the same
    # numbers; `bulletnet metrics` prints the margins for it.
    path = bn.run(small_scene(**{"scene.duration": 0.4}), tmp_path / "new.h5").path
    expected = bn.metrics.strength_summary(bn.open_recording(path))
    with h5py.File(path, "r+") as f:
        del f["threads/breaking_tension"]
    old = bn.open_recording(path)
    assert old.breaking_tension is None
    assert bn.metrics.strength_summary(old) == expected
    proc = subprocess.run([sys.executable, "-m", "bulletnet.cli.main", "metrics", str(path)],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert f"least safety factor (breaking tension / largest tension): " \
           f"{expected['least_safety_factor']:.4g}, corner thread" in proc.stdout
    assert "largest snap load:" in proc.stdout and "corner threads" in proc.stdout
    doc = json.loads(subprocess.run(
        [sys.executable, "-m", "bulletnet.cli.main", "metrics", str(path), "--json"],
        capture_output=True, text=True, timeout=300).stdout)
    assert doc["strength"]["least_safety_factor"] == expected["least_safety_factor"]


@pytest.mark.parametrize("key, value, needle", [
    ("strength.knot_efficiency", 1.5, "expected a number in (0, 1]"),
    ("strength.thread_breaking_stress", -1.0, "expected a positive number [Pa]"),
    ("strength.tether_breaking_stress", "strong", "expected a number [Pa]"),
])
def test_bad_strength_is_one_clear_error(key, value, needle):
    with pytest.raises(ScenarioError) as err:
        small_scene(**{key: value})
    assert needle in str(err.value) and key in str(err.value)
    assert "\n" not in str(err.value)


def test_study_report_gives_the_probability_of_an_overload():
    # Reference: the Wilson interval of the share of runs in which an element reached its
    # breaking tension (a true/false measure), overall and by input bin.
    from bulletnet.studies.report import probabilities, wilson

    doc = {"design": "random",
           "measures": ["min_safety_factor", "overloaded_elements", "overloaded"],
           "columns": {"net.thread_radius": "net.thread_radius_m"},
           "vary": {"net.thread_radius": {"dist": "uniform"}}}
    over = [True, True, False, False, False]
    rows = [{"status": "completed", "net.thread_radius_m": 1e-4 * (k + 1),
             "min_safety_factor": 0.5 if o else 2.0, "overloaded_elements": 3 * o,
             "overloaded": o} for k, o in enumerate(over)]
    probs = probabilities(doc, rows, bins=1)
    assert set(probs) == {"overloaded"}
    p, low, high = wilson(2, 5)
    assert probs["overloaded"]["overall"]["True"] == {"count": 2, "n": 5, "p": p, "low": low,
                                                      "high": high}
