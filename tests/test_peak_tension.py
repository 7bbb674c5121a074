"""Each element's largest tension between frames (``/threads/peak_tension``): against a run
recording at every step, on both kernel paths, both integrators and the bullet engine; the
least safety factor no longer depends on the record rate; a recording without peaks falls
back to its frames."""

from __future__ import annotations

import shutil

import h5py
import numpy as np
import pytest

import bulletnet as bn
from tests.conftest import small_scene

DURATION = 2.0**-5
"""[s]: a 4 x 4 net nearly unfolded (fold ratio 0.97) snaps taut at 14.9 ms."""
COARSE = 2.0**10
"""Frames of the coarse run [Hz]. Every time is a dyadic fraction, so both runs take the same
steps bit for bit (the engine's step is the record interval over its steps)."""


def snapping(**overrides):
    return small_scene(**{"net.nodes_per_side": 4, "net.fold_ratio": 0.97,
                          "scene.duration": DURATION, **overrides})


CASES = {  # (engine, kernels, integrator, step [s], duration [s])
    "grid-symplectic": ("fast", "grid", "symplectic_euler", 2.0**-20, DURATION),
    "pairs-symplectic": ("fast", "pairs", "symplectic_euler", 2.0**-20, DURATION),
    "grid-implicit": ("fast", "grid", "implicit_euler", 2.0**-16, DURATION),
    "pairs-implicit": ("fast", "pairs", "implicit_euler", 2.0**-16, DURATION),
    "bullet-symplectic": ("bullet", "pairs", "symplectic_euler", 2.0**-20, 2.0**-6),
}


@pytest.fixture(scope="module", params=list(CASES))
def runs(request, tmp_path_factory):
    """A coarse recording (frames at 1024 Hz) and one at every step of the same run."""
    engine, kernels, integrator, dt, duration = CASES[request.param]
    d = tmp_path_factory.mktemp(request.param)
    out = {}
    for name, rate in (("coarse", COARSE), ("fine", 1.0 / dt)):
        s = snapping(**{"simulation.engine": engine, "simulation.kernels": kernels,
                        "simulation.integrator": integrator, "simulation.dt": dt,
                        "simulation.record_rate": rate, "scene.duration": duration})
        bn.run(s, d / f"{name}.h5")
        out[name] = bn.open_recording(d / f"{name}.h5")
    return request.param, out["coarse"], out["fine"]


def test_peak_is_the_largest_step_tension_between_frames(runs):
    # Reference: a run recording at every step (record rate 1 / dt), whose frames' tensions
    # are every step's own (the tension each step computes its forces from, at its start):
    # the coarse run's peak at frame k is the largest of them over [t_(k-1), t_k] (the steps
    # of its interval and the frame's own tension), at frame 0 the frame's tension. The two
    # runs take the same steps, so bit for bit on the pair list; on the grid a step's tension
    # is the length of its stored T e, equal to Eq. 3's to round-off.
    case, coarse, fine = runs
    assert coarse.peak_tension is not None
    assert np.array_equal(fine.time[::round(fine.time.size / (coarse.time.size - 1))],
                          coarse.time)
    assert (coarse.peak_tension >= coarse.tension).all()
    assert coarse.peak_tension.max() > 100.0 * coarse.tension.max()  # a snap between frames
    per = (fine.time.size - 1) // (coarse.time.size - 1)
    expected = np.vstack([fine.tension[:1]] + [fine.tension[(k - 1) * per:k * per + 1].max(axis=0)
                                               for k in range(1, coarse.time.size)])
    np.testing.assert_array_equal(coarse.tension, fine.tension[::per])
    if case.startswith("grid"):
        np.testing.assert_allclose(coarse.peak_tension, expected, rtol=1e-13, atol=0.0)
    else:
        np.testing.assert_array_equal(coarse.peak_tension, expected)
    # the every-step recording's own peaks: its frame's and the step before's tension
    np.testing.assert_allclose(fine.peak_tension[1:],
                               np.maximum(fine.tension[1:], fine.tension[:-1]), rtol=1e-13)


def test_least_safety_factor_does_not_depend_on_the_record_rate(runs):
    # Reference: the least safety factor of the every-step recording (every step's tension
    # seen); the coarse recording's, from its peaks, is the same (bit for bit on the pair
    # list, to round-off on the grid), at the frame that ends the interval of the peak.
    case, coarse, fine = runs
    a, b = bn.metrics.safety(coarse), bn.metrics.safety(fine)
    assert a["between_frames"] and b["between_frames"]
    assert a["least_safety_factor"] == pytest.approx(b["least_safety_factor"], rel=1e-13)
    assert a["element"]["index"] == b["element"]["index"]
    assert b["time_s"] <= a["time_s"] < b["time_s"] + 1.0 / COARSE
    # the frames alone miss the snap
    frames_only = (bn.metrics.breaking_tension(coarse)
                   / np.maximum(bn.metrics.element_tension(coarse).max(axis=0), 1e-300)).min()
    assert frames_only > 100.0 * a["least_safety_factor"]
    # the largest snap load is the largest tension of any step (the corner threads')
    assert bn.metrics.strength_summary(coarse)["largest_snap"]["tension_N"] == pytest.approx(
        fine.tension.max(), rel=1e-13)


def test_recording_without_peaks_reads_its_frames(runs, tmp_path):
    # Reference: the frames' own tensions (recordings made before peaks were recorded).
    case, coarse, _ = runs
    old = tmp_path / "old.h5"
    shutil.copy(coarse.path, old)
    with h5py.File(old, "r+") as f:
        del f["threads/peak_tension"]
    rec = bn.open_recording(old)
    assert rec.peak_tension is None
    np.testing.assert_array_equal(bn.metrics.utilisation(rec),
                                  coarse.tension / bn.metrics.breaking_tension(coarse))
    assert not bn.metrics.safety(rec)["between_frames"]
