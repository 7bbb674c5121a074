"""The capture score and outcome (bulletnet.analysis.capture_score): the score against closed forms,
the outcome rules on synthetic time series, and real runs judged while they go, stopped once
decided, and judged again from their recordings alone."""

from __future__ import annotations

import math
from types import SimpleNamespace

import h5py
import numpy as np
import pytest

import bulletnet as bn
from bulletnet.analysis.capture_score import (
    SAMPLE_COUNT,
    OutcomeMonitor,
    Score,
    all_receding,
    enclosed_fraction,
    fibonacci_sphere,
    interior_samples,
    largest_distance,
    mouth_opening,
    receding,
)
from bulletnet.analysis.metrics import LEAVE_QUIET_S, leave_time
from bulletnet.model.debris import Part, make_debris, rotation_matrix, rotation_quaternion
from bulletnet.model.scenario import OutcomeRules
from bulletnet.model.topology import perimeter
from tests.conftest import small_capture


def three_sigma(p: float) -> float:
    """Three standard deviations of a share p estimated from SAMPLE_COUNT independent uniform
    points (binomial: sqrt(p (1 - p) / M))."""
    return 3.0 * math.sqrt(p * (1.0 - p) / SAMPLE_COUNT)


def flat_net(ns: int, mesh: float) -> np.ndarray:
    """A deployed flat square net in the plane z = 0, centred on the origin, and its four
    corner masses one mesh length out along the diagonals [m], shape (Ns^2 + 4, 3)."""
    r, c = np.divmod(np.arange(ns * ns), ns)
    half = 0.5 * (ns - 1) * mesh
    net = np.stack([c * mesh - half, r * mesh - half, np.zeros(ns * ns)], axis=1)
    corners = net[[0, ns - 1, ns * ns - ns, ns * ns - 1]] * (1.0 + mesh / half)
    return np.vstack([net, corners])


@pytest.fixture(scope="module")
def csm():
    debris = bn.load_debris("apollo_csm")
    return debris, interior_samples(debris)


def test_samples_are_seeded_and_inside_the_debris(csm):
    # reference: the debris' own signed distance (the contact query), negative inside
    from bulletnet.kernels.geometry import debris_distance
    from bulletnet.solver.contact_stage import debris_geometry

    debris, samples = csm
    assert samples.shape == (SAMPLE_COUNT, 3)
    np.testing.assert_array_equal(samples, interior_samples(debris))  # the same every time
    rows, mesh = debris_geometry(debris.parts)
    normal = np.empty(3)
    assert all(debris_distance(p, np.zeros(3), np.eye(3), rows, mesh, normal) < 0
               for p in samples)


def test_debris_inside_a_closed_spherical_net_is_wholly_enclosed(csm):
    # reference: the convex hull of points on a sphere of radius R, no two neighbours more
    # than an angle d apart, holds the concentric ball of radius R cos d. 445 Fibonacci
    # points on a 10 m sphere are ~0.17 rad apart: the ball of 9.8 m holds the CSM, whose
    # parts lie within its reach of the centre of mass
    debris, samples = csm
    reach = max(p.reach(debris.center_of_mass) for p in debris.parts)
    assert reach < 9.0
    q = rotation_quaternion(np.radians([20.0, -35.0, 50.0]))
    origin = np.array([3.0, -2.0, 7.0])
    centre = origin + rotation_matrix(q) @ debris.center_of_mass
    nodes = centre + 10.0 * fibonacci_sphere(21 * 21 + 4)
    assert enclosed_fraction(nodes, samples, origin, rotation_matrix(q)) == 1.0


def test_debris_far_from_a_net_or_across_a_flat_one_is_not_enclosed(csm):
    # reference: a flat net spans no volume (its hull is a polygon), and a cupped net 100 m
    # away holds no point of the debris
    debris, samples = csm
    net = flat_net(21, 1.0)
    assert enclosed_fraction(net, samples, np.zeros(3), np.eye(3)) == 0.0  # through the CSM
    cup = net + [0.0, 0.0, 100.0]
    cup[:, 2] -= 0.05 * (cup[:, 0] ** 2 + cup[:, 1] ** 2)
    assert enclosed_fraction(cup, samples, np.zeros(3), np.eye(3)) == 0.0


def test_box_partly_inside_a_hull_matches_the_volume_share():
    # reference: the volume of a box below a plane across it, over the box's volume. A
    # 2 x 4 x 1 m box, turned so that its 4 m edge lies along z, centred at z = 3, spans
    # z = 1 .. 5; a hull reaching up to z = 3.5 holds (3.5 - 1) / 4 = 0.625 of it, within
    # the sample's binomial error
    box = make_debris("box", (Part(name="box", shape="box", size=(2.0, 4.0, 1.0),
                                   mass=1.0),))
    samples = interior_samples(box)
    q = rotation_quaternion([math.pi / 2, 0.0, 0.0])  # body y -> world z
    origin = np.array([1.0, 2.0, 3.0])
    hull = np.array([[x, y, z] for x in (-10.0, 10.0) for y in (-10.0, 10.0)
                     for z in (-10.0, 3.5)])
    share = enclosed_fraction(hull, samples, origin, rotation_matrix(q))
    assert share == pytest.approx(0.625, abs=three_sigma(0.625))
    # half inside: the plane through the box's centre
    hull[:, 2] = np.where(hull[:, 2] > 0, 3.0, -10.0)
    share = enclosed_fraction(hull, samples, origin, rotation_matrix(q))
    assert share == pytest.approx(0.5, abs=three_sigma(0.5))


def test_mouth_opening_of_a_flat_net_is_one_and_of_a_cinched_one_zero():
    # reference: the largest chord of a square is its diagonal, sqrt(2) L; a perimeter
    # gathered to one point has none; the folded start (fold ratio 1/4) is a square of L / 4
    ns, mesh = 21, 1.0
    net = flat_net(ns, mesh)
    assert mouth_opening(net, ns, (ns - 1) * mesh) == pytest.approx(1.0, rel=1e-12)
    assert mouth_opening(0.25 * net, ns, (ns - 1) * mesh) == pytest.approx(0.25, rel=1e-12)
    cinched = net.copy()
    cinched[perimeter(ns)] = [0.5, -2.0, 3.0]
    assert mouth_opening(cinched, ns, (ns - 1) * mesh) == 0.0


def test_largest_distance_is_scipys_pdist_bit_for_bit():
    # reference: scipy's pdist, which the mouth opening used before its own loop; the same
    # distances' bits (the recorded outcomes stay the same), and a non-finite node is NaN
    from scipy.spatial.distance import pdist

    rng = np.random.default_rng(7)
    for _ in range(300):
        m = int(rng.integers(2, 90))
        scale = 10.0 ** rng.uniform(-3, 3)
        positions = rng.normal(size=(m + 5, 3)) * scale + rng.normal(size=3) * 100 * scale
        nodes = rng.permutation(m + 5)[:m]
        assert largest_distance(positions, nodes) == pdist(positions[nodes]).max()
    positions[nodes[1], 2] = np.nan
    assert math.isnan(largest_distance(positions, nodes))


def judge(frames, **rules) -> OutcomeMonitor:
    """An outcome monitor fed synthetic frames (t [s], enclosed, mouth, contacts, moving
    away: the net's centre of mass and every node alike); the run completed."""
    monitor = OutcomeMonitor(OutcomeRules(enabled=True, **rules), geometry=None)
    for t, enclosed, mouth, contacts, away in frames:
        monitor.update(t, Score(enclosed, mouth, enclosed * (1 - mouth)), contacts, away, away)
    monitor.finish(completed=True)
    return monitor


TIMES = np.round(np.arange(0.0, 40.01, 0.1), 10)
"""Synthetic frames every 0.1 s over 40 s [s]."""


def test_captured_once_enclosed_and_closed_for_the_hold_time():
    # the hold restarts when the mouth opens (at 8 s) and completes 10 s after it closes
    # again (9 s); the decision is final though the net later leaves
    frames = [(t, 0.95 if t >= 2 else 0.0, 0.2 if (2 <= t < 8 or t >= 9) and t < 25 else 0.6,
               5 if 1 <= t < 25 else 0, True) for t in TIMES]
    monitor = judge(frames)
    assert (monitor.outcome, monitor.time, monitor.since) == ("captured", 19.0, 9.0)
    # the same frames less the last one of the hold: undecided (touched, never held 10 s)
    assert judge([f for f in frames if f[0] < 19.0]).outcome == "undecided"


def test_escaped_after_the_quiet_time_once_the_net_moves_away():
    # last contact at 5 s; quiet from 10 s, but the net only moves away from 12 s on
    frames = [(t, 0.5, 0.8, 3 if 1 <= t <= 5 else 0, t >= 12) for t in TIMES]
    monitor = judge(frames)
    assert (monitor.outcome, monitor.time, monitor.since) == ("escaped", 12.0, 5.0)
    moving_away = [(t, e, m, c, True) for t, e, m, c, _ in frames]
    assert judge(moving_away).time == 10.0


def test_no_escape_while_the_debris_floats_inside_a_closed_net():
    # one contact at 30 s, enclosed (E = 1) in a closed net (M = 0.1) from then on, the debris
    # floating free inside the bag and the net's centre of mass moving away from its: the
    # quiet time (5 s) passes inside the hold (10 s), which decides it: captured at 40 s
    def frames(mouth):
        return [(t, 1.0 if t >= 30.0 else 0.0, mouth(t), 5 if abs(t - 30.0) < 1e-9 else 0,
                 True) for t in TIMES]
    held = judge(frames(lambda t: 0.1))
    assert (held.outcome, held.time, held.since) == ("captured", 40.0, 30.0)
    # the mouth open again from 33 s: no hold, and the quiet time decides an escape
    opened = judge(frames(lambda t: 0.1 if t < 33.0 else 0.6))
    assert (opened.outcome, opened.time, opened.since) == ("escaped", 35.0, 30.0)


def test_missed_without_contact_by_the_miss_time_or_the_end():
    frames = [(t, 0.0, 0.9, 0, True) for t in TIMES]
    monitor = judge(frames, miss_time=3.0)
    assert (monitor.outcome, monitor.time) == ("missed", 3.0)
    assert monitor.reason == "no contact by outcome.miss_time, 3 s"
    assert (judge(frames).outcome, judge(frames).time) == ("missed", 40.0)
    assert judge(frames).reason == ("no contact by the end, every net node moving away from "
                                    "the debris")
    interrupted = OutcomeMonitor(OutcomeRules(), geometry=None)
    interrupted.update(1.0, Score(0.0, 0.9, 0.0), 0, True, True)
    interrupted.finish(completed=False)  # cut short: not a miss
    assert (interrupted.outcome, interrupted.time) == ("undecided", -1.0)
    assert interrupted.reason == "the run stopped at 1.00 s, before its end"


def test_a_run_over_before_contact_was_possible_is_undecided_not_missed():
    # the rules: a miss needs the net past the debris (moving away) or miss_time reached;
    # a run shortened to 2 s ends with the net still on its way, or before miss_time
    approaching = [(t, 0.0, 0.9, 0, False) for t in TIMES if t <= 2.0]
    monitor = judge(approaching)
    assert (monitor.outcome, monitor.time, monitor.reason) == (
        "undecided", -1.0, "no contact yet: the run ended at 2.00 s with net nodes still "
        "approaching the debris")
    early = judge([(t, 0.0, 0.9, 0, True) for t in TIMES if t <= 2.0], miss_time=30.0)
    assert (early.outcome, early.reason) == (
        "undecided", "no contact yet: the run ended at 2.00 s, before outcome.miss_time, 30 s")


def test_a_net_whose_centre_of_mass_has_passed_the_debris_can_still_reach_it():
    # The paper's capture at 8 s, in miniature: the corner masses (0.5 kg each, 2.0 kg of the
    # net's 2.9) fly ahead, past the debris' centre at z = 10 m, and carry the centre of mass
    # with them, while the lighter bag behind them (0.9 kg) still approaches (it touches the
    # CSM at 10.1 s). By the centre of mass the net recedes; by its nodes it does not, and a run
    # stopped here is undecided, not missed. Once every node has passed, it is a miss.
    position = np.array([[2.0, 2.0, 11.0], [-2.0, 2.0, 11.0], [2.0, -2.0, 11.0],
                         [-2.0, -2.0, 11.0], [0.0, 0.0, 8.0]])  # corners, then the bag [m]
    velocity = np.array([[0.0, 0.0, 1.4]] * 4 + [[0.0, 0.0, 1.8]])  # [m/s]
    mass = np.array([0.5, 0.5, 0.5, 0.5, 0.3])  # [kg]
    centre, still = np.array([0.0, 0.0, 10.0]), np.zeros(3)
    assert receding(position, velocity, mass, centre, still)  # the centre of mass: past
    assert not all_receding(position, velocity, centre, still)  # the bag: approaching
    position[4, 2] = 10.5  # the bag past the debris' centre too
    assert all_receding(position, velocity, centre, still)


def test_an_escape_stopped_when_decided_has_left_the_debris():
    # The escape's quiet time and the leave time are the same 5 s (metrics.LEAVE_QUIET_S):
    # a run stopped at the frame that decides the escape ends 5 s after its last contact, and
    # frame times of 0.2 s (k / 5 Hz) put 8.2 - 3.2 at 4.999999999999999 s, not 5: to the
    # frame times' round-off, as the outcome judges it, the net has left at 3.2 s.
    times = np.arange(42) / 5.0  # to 8.2 s
    count = np.where(times <= 3.2 + 1e-12, 4, 0)
    frames = [(t, 0.1, 0.9, c, True) for t, c in zip(times, count, strict=True)]
    assert times[-1] - 3.2 < LEAVE_QUIET_S and judge(frames).outcome == "escaped"
    rec = SimpleNamespace(path="run.h5", time=times, contacts={"count": count})
    assert leave_time(rec) == 3.2
    assert leave_time(SimpleNamespace(path="run.h5", time=times[:-1],
                                      contacts={"count": count[:-1]})) is None  # 4.8 s


def test_undecided_while_touching_an_open_net():
    frames = [(t, 0.98, 0.4, 10 if t >= 9 else 0, True) for t in TIMES]
    monitor = judge(frames)
    assert (monitor.outcome, monitor.time, monitor.since) == ("undecided", -1.0, -1.0)
    assert monitor.reason == "touched, but neither captured nor escaped by the end, 40.00 s"


RELAXED = {"outcome.enclosed_fraction": 0.01, "outcome.mouth_opening": 0.3,
           "outcome.hold_time": 0.1}
"""Rules the small capture (tests/conftest.py) meets at 0.5 s: 1 % of the debris in the
net's hull, the mouth within 0.3 of its diagonal, for 0.1 s."""


@pytest.mark.parametrize(("overrides", "outcome", "stop_s"), [
    (RELAXED, "captured", 0.5),
    # the debris crossing at 4 m/s grazes the net (last touched at 0.30 s with the 56.5 deg
    # launch and the capture's 1e-3 s step) and is gone
    ({"debris.velocity": [4.0, 0.0, -2.0], "outcome.quiet_time": 0.5}, "escaped", 0.8),
    ({"debris.position": [40.0, 0.0, 3.0], "debris.velocity": [0.0, 0.0, 0.0],
      "outcome.miss_time": 0.3}, "missed", 0.3),
])
def test_a_run_stops_once_decided_and_its_recording_judges_the_same(tmp_path, capsys,
                                                                    overrides, outcome, stop_s):
    # reference: the recording alone (bulletnet.analysis.metrics.capture_outcome, the same monitor
    # on the recorded frames), and the same run carried to its end
    from bulletnet.cli.main import main

    scene = small_capture(**{"outcome.stop_when_decided": True, **overrides})
    result = bn.run(scene, tmp_path / "stop.h5")
    assert (result.status, result.outcome) == ("completed", outcome)
    assert result.outcome_time_s == pytest.approx(stop_s, abs=1e-9)
    rec = bn.open_recording(tmp_path / "stop.h5")
    assert rec.time[-1] == result.outcome_time_s and rec.time.size < 21
    assert (rec.attrs["outcome"], rec.attrs["outcome_time_s"]) == (outcome, rec.time[-1])
    assert rec.attrs["outcome_reason"] == result.outcome_reason != ""
    with h5py.File(tmp_path / "stop.h5") as f:
        assert f["debris/interior_samples"].shape == (SAMPLE_COUNT, 3)
        assert f["debris/interior_samples"].attrs["units"] == "m"
    _, judged = bn.metrics.capture_outcome(rec)
    assert (judged.outcome, judged.time, judged.reason) == (outcome, result.outcome_time_s,
                                                            result.outcome_reason)
    full = bn.run(small_capture(**overrides), tmp_path / "full.h5")
    assert (full.status, full.frames, full.outcome) == ("completed", 21, outcome)
    assert full.outcome_time_s == result.outcome_time_s
    assert main(["metrics", str(tmp_path / "stop.h5")]) == 0
    assert (f"outcome: {outcome}, decided at {stop_s:.2f} s ({result.outcome_reason})"
            in capsys.readouterr().out)


def test_a_recording_without_its_sample_is_scored_from_its_scene(tmp_path):
    # reference: the same recording with the sample the run stored
    bn.run(small_capture(**{"scene.duration": 0.6}), tmp_path / "a.h5")
    with h5py.File(tmp_path / "a.h5", "a") as f:
        f.copy("debris/interior_samples", "kept")
        del f["debris/interior_samples"]
    rec = bn.open_recording(tmp_path / "a.h5")
    assert "interior_samples" not in rec.debris
    with h5py.File(tmp_path / "a.h5") as f:
        kept = f["kept"][()]
    np.testing.assert_array_equal(bn.metrics.score_geometry(rec).samples, kept)
