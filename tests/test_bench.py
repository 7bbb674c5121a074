"""The speed/accuracy grid, its Pareto front, and the run profile."""

from __future__ import annotations

import json

import pytest
from conftest import small_capture, small_scene, uncached_loops
from test_recording_cli import cli

import bulletnet as bn
from bulletnet.analysis.stability import scene_limits
from bulletnet.sim.profiling import ENGINE, Profile, report
from bulletnet.studies.bench import (
    REFERENCE_DT,
    Method,
    bench,
    mouth_area_measure,
    pareto_front,
    parse_method,
)


def test_pareto_front_is_the_set_of_non_dominated_runs():
    # Reference: the definition, checked by brute force over every pair of a fixed grid.
    rows = [{"stable": True, "wall_s": w, "rmse_pos_avg": e}
            for w, e in [(1, 5), (2, 3), (3, 4), (4, 1), (5, 1), (2, 6), (6, 0.5)]]
    rows.append({"stable": False, "wall_s": None, "rmse_pos_avg": None})
    front = pareto_front(rows)
    stable = [r for r in rows if r["stable"]]

    def dominated(r):
        return any(o["wall_s"] <= r["wall_s"] and o["rmse_pos_avg"] <= r["rmse_pos_avg"]
                   and o is not r and (o["wall_s"], o["rmse_pos_avg"])
                   != (r["wall_s"], r["rmse_pos_avg"]) for o in stable)

    assert [r for r in stable if not dominated(r)] == front


def test_bench_grid_converges_at_first_order_and_marks_divergence(tmp_path):
    # Reference: the fine-step reference run (symplectic Euler at 2.5e-7 s). Symplectic Euler
    # is first order, so its error against the reference grows as (h - h_ref) (to 10 %, both
    # steps below the explicit limit); a step 3x above the analytical limit diverges and is
    # recorded as such, not as a crash.
    scene = small_scene(**{"net.fold_ratio": 1.0, "scene.duration": 0.05})
    limit = scene_limits(scene).explicit_limit
    dts = [5e-7, 1e-6, 3 * limit]
    doc = bench(scene, [Method("fast", "symplectic_euler")], dts, tmp_path, log=lambda s: None)
    rows = {r["dt_s"]: r for r in doc["runs"]}
    ratio = rows[1e-6]["rmse_pos_avg"] / rows[5e-7]["rmse_pos_avg"]
    expected = (1e-6 - REFERENCE_DT) / (5e-7 - REFERENCE_DT)  # e(h) ~ C (h - h_ref)
    assert ratio == pytest.approx(expected, rel=0.1)
    assert not rows[3 * limit]["stable"] and "diverged" in rows[3 * limit]["message"]
    assert rows[1e-6]["steps"] == round(0.05 / 1e-6)
    assert rows[1e-6]["real_time_factor"] == pytest.approx(0.05 / rows[1e-6]["wall_s"])
    written = json.loads((tmp_path / "bench_deployment.json").read_text())
    assert written["pareto_front"] == pareto_front(written["runs"])
    assert (tmp_path / "bench_deployment.png").stat().st_size > 10_000
    # a second bench reuses the reference only if it is the same scene at the same step
    before = (tmp_path / "bench_deployment_runs" / "reference.h5").stat().st_mtime_ns
    bench(scene, [Method("fast", "symplectic_euler")], [1e-6], tmp_path, log=lambda s: None)
    assert (tmp_path / "bench_deployment_runs" / "reference.h5").stat().st_mtime_ns == before


def test_mouth_area_measure_is_the_curve_difference(tmp_path):
    # Reference: metrics.mouth_area of both recordings, differenced frame by frame; zero
    # against itself.
    a = bn.run(small_scene(), tmp_path / "a.h5").path
    b = bn.run(small_scene(**{"launch.elevation": 30.0}), tmp_path / "b.h5").path
    ra, rb = bn.open_recording(a), bn.open_recording(b)
    assert mouth_area_measure(ra, ra) == {"mouth_area_rms": 0.0, "mouth_area_max": 0.0}
    diff = bn.metrics.mouth_area(ra) - bn.metrics.mouth_area(rb)
    got = mouth_area_measure(ra, rb)
    assert got["mouth_area_max"] == pytest.approx(abs(diff).max(), rel=1e-12)
    assert got["mouth_area_rms"] == pytest.approx((diff**2).mean() ** 0.5, rel=1e-12)
    assert got["mouth_area_max"] > 0


@pytest.mark.parametrize(("args", "needle"), [
    (["--measures", "area"], "--measures area"),
    # a --front-by of a measure not chosen (the default is the chosen measures' first)
    (["--measures", "mouth_area", "--front-by", "rmse_pos_avg"], "--front-by rmse_pos_avg"),
])
def test_bad_bench_measures_are_one_line_errors(args, needle, tmp_path):
    proc = cli("bench", "deployment", *args, "--out", str(tmp_path))
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1 and needle in proc.stderr


@pytest.mark.parametrize("text", ["fast", "fast:rk4", "vortex:symplectic_euler", "reference:x"])
def test_bad_methods_are_one_line_errors(text, tmp_path):
    with pytest.raises(bn.ScenarioError, match="ENGINE:INTEGRATOR"):
        parse_method(text)
    proc = cli("bench", "deployment", "--methods", text, "--out", str(tmp_path))
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1


def test_profile_accounts_for_the_run_loop(tmp_path):
    # Reference: the run's own wall time, without racing the clock. The timed sections are
    # disjoint parts of the loop, each timed inside it, so they add up to no more than it;
    # the report shares the whole loop out (the engine step between forces and integration
    # by the calibrated split, the rest as "other"), so its rows add up to the loop's time
    # and no row is negative. How large each share is depends on the machine's load at the
    # moment: that is a benchmark's question (`bulletnet run --profile`), not a test's.
    profile = Profile()
    result = bn.run(small_scene(**{"scene.duration": 0.1}), tmp_path / "p.h5", profile=profile)
    measured = sum(profile.seconds.values())
    assert 0 < measured <= result.wall_time_s
    assert profile.seconds[ENGINE] > 0
    split = profile.split
    assert split["force_s_per_step"] > 0 and split["step_s_per_step"] > 0
    rows = [float(line.split()[-4]) for line in report(profile, result.wall_time_s, False)
            if line.endswith("%")]
    assert min(rows) >= 0
    assert sum(rows) == pytest.approx(result.wall_time_s, abs=5e-3)  # printed to 1 ms a row
    # the split is calibrated at the run's last state, and the report says at which
    assert split["time_s"] == result.state.time
    assert any(f"last state, t = {result.state.time:.4g} s" in line
               for line in report(profile, result.wall_time_s, False))


def test_compiling_in_the_loop_is_counted_apart(tmp_path, monkeypatch):
    # Reference: numba's own timers of the step loop's compilation. A first run compiles its
    # step loop at the first step, inside the run loop: the run records that time as
    # compile_time_s (at least the loop's own compile, at most the loop's wall time) and the
    # profile books it as compiling, not as the engine's step; a second run of the same
    # loop, compiled by then, compiles nothing.
    from bulletnet.sim.profiling import COMPILING

    scene = small_capture(**{"scene.duration": 0.05})
    loops = uncached_loops(monkeypatch)
    profile = Profile()
    first = bn.run(scene, tmp_path / "first.h5", profile=profile)
    [compiled] = loops[True, True].overloads.values()  # (the grid's implicit step)
    # numba's passes over the loop, timed inside its compilation (the compiler lock's timer
    # is not: it can exceed the compilation's own span)
    passes = compiled.metadata["pipeline_times"]["nopython"].values()
    assert (sum(p.init + p.run + p.finalize for p in passes) <= first.compile_time_s
            < first.wall_time_s)
    assert profile.seconds[COMPILING] == first.compile_time_s
    assert profile.seconds[ENGINE] <= first.wall_time_s - first.compile_time_s
    assert bn.open_recording(tmp_path / "first.h5").attrs["compile_time_s"] == \
        first.compile_time_s
    assert bn.run(scene, tmp_path / "second.h5").compile_time_s == 0.0


def test_profile_leaves_the_run_as_it_was(tmp_path):
    # Reference: the same run without the profile, bit for bit. The profile's calibration
    # steps the engine on past the run's end (here across the net's first touch of the
    # debris, 0.05 s after it), so it must come after everything the run records; its
    # contact share is the contact stage's own time, a part of the step.
    import h5py
    import numpy as np

    touch = bn.run(small_capture(**{"scene.duration": 0.8}), tmp_path / "touch.h5").path
    with h5py.File(touch) as f:
        first = float(f.attrs["first_contact_s"])
    assert 0.1 < first < 0.8
    profile = Profile()
    ended = small_capture(**{"scene.duration": round(first - 0.05, 2)})
    paths = [bn.run(ended, tmp_path / f"{name}.h5", profile=p).path
             for name, p in (("plain", None), ("profiled", profile))]
    with h5py.File(paths[0]) as plain, h5py.File(paths[1]) as profiled:
        assert plain.attrs["first_contact_s"] == profiled.attrs["first_contact_s"] == -1.0
        names = []
        plain.visit(lambda n: names.append(n) if isinstance(plain[n], h5py.Dataset) else None)
        for name in names:
            np.testing.assert_array_equal(plain[name][()], profiled[name][()], err_msg=name)
        for key, value in plain.attrs.items():
            if "wall" not in key:
                np.testing.assert_array_equal(value, profiled.attrs[key], err_msg=key)
    split = profile.split
    assert 0 <= split["contact_s_per_step"] < split["step_s_per_step"]


def test_profile_sections_are_exclusive(monkeypatch):
    # Reference: a clock that moves only when the work says (no racing the real clock). A
    # section that calls another is charged only its own time; the two add up to the call;
    # a stopped profile charges nothing more.
    import types

    import bulletnet.sim.profiling

    clock = [0.0]
    monkeypatch.setattr(bulletnet.sim.profiling, "time",
                        types.SimpleNamespace(perf_counter=lambda: clock[0]))

    class Work:
        def outer(self):
            clock[0] += 0.02
            self.inner()

        def inner(self):
            clock[0] += 0.03

    work, profile = Work(), Profile()
    profile.wrap(work, "outer", "outer")
    profile.wrap(work, "inner", "inner")
    work.outer()
    assert profile.seconds == pytest.approx({"outer": 0.02, "inner": 0.03}, abs=1e-12)
    profile.stop()
    work.outer()
    assert profile.seconds == pytest.approx({"outer": 0.02, "inner": 0.03}, abs=1e-12)


def test_cli_profile_names_every_section(tmp_path):
    proc = cli("run", "deployment", "--set", "net.nodes_per_side=6", "--duration", "0.05",
               "--out", str(tmp_path / "p.h5"), "--quiet", "--profile")
    assert proc.returncode == 0, proc.stderr
    for name in ("forces", "integration", "contact", "recording", "I/O"):
        assert name in proc.stdout


def test_capture_bench_scores_aggregates_against_a_fine_implicit_reference(tmp_path):
    # Reference: the contact scene's own converged run (implicit Euler at 1.25e-4 s). The
    # first-contact error of a step h is at most about h (contact is found to the step) plus
    # the deployment's first-order drift; a run scored against itself scores exactly zero.
    from bulletnet.studies.bench import REFERENCE_DT_CONTACT, first_contact_measure, wrap_measure

    scene = small_capture(**{"scene.duration": 0.8})
    doc = bench(scene, [Method("fast", "implicit_euler")], [1e-3, 5e-4], tmp_path,
                measures=[first_contact_measure, wrap_measure], error_key="wrap_rms",
                log=lambda s: None)
    assert doc["reference"]["integrator"] == "implicit_euler"
    assert doc["reference"]["dt_s"] == REFERENCE_DT_CONTACT
    assert doc["vortex_paper"]["duration_s"] == 120.0
    rows = {r["dt_s"]: r for r in doc["runs"]}
    for dt, row in rows.items():
        assert row["stable"] and row["first_contact_error"] <= 2 * dt
        assert 0.0 <= row["wrap_rms"] <= row["wrap_max"] <= 1.0
    ref = bn.open_recording(tmp_path / "bench_capture_runs" / "reference.h5")
    assert bn.metrics.first_contact_time(ref) is not None
    assert first_contact_measure(ref, ref) == {"first_contact_error": 0.0}
    assert wrap_measure(ref, ref) == {"wrap_max": 0.0, "wrap_rms": 0.0}


def test_cli_profile_times_contact_apart(tmp_path):
    # Reference: the sections are exclusive and add up to the run loop (percentages sum to
    # 100 to rounding), the contact's share measured against steps with contact switched off.
    proc = cli("run", "capture", "--set", "net.nodes_per_side=6", "--set",
               "debris.position=[0, 0, 3]", "--set", "debris.velocity=[0, 0, -2]",
               "--duration", "1", "--out", str(tmp_path / "p.h5"), "--quiet", "--profile")
    assert proc.returncode == 0, proc.stderr
    rows = [line for line in proc.stdout.splitlines() if line.rstrip().endswith("%")]
    assert any(line.strip().startswith("contact (") for line in rows)
    assert sum(float(line.split()[-2]) for line in rows) == pytest.approx(100.0, abs=0.5)
