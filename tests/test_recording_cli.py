"""Recordings, the CLI and the API: layout, statuses, errors, metrics."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

import bulletnet as bn
from bulletnet.model.scenario import loads, to_toml
from tests.conftest import small_scene

ROOT = Path(__file__).resolve().parent.parent
TINY = ["--set", "net.nodes_per_side=4", "--set", "net.fold_ratio=0.99",
        "--duration", "0.02", "--record-rate", "500"]


def cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "bulletnet.cli.main", *args], capture_output=True,
                          text=True, cwd=cwd, timeout=300)


def test_cli_run_writes_documented_layout(tmp_path):
    out = tmp_path / "run.h5"
    proc = cli("run", "deployment", *TINY, "--out", str(out), "--quiet")
    assert proc.returncode == 0, proc.stderr
    with h5py.File(out) as f:
        t = f["time"].shape[0]
        assert t == 11  # 0.02 s at 500 Hz, both ends
        n, p = 20, 28
        shapes = {"nodes/position": (t, n, 3), "nodes/velocity": (t, n, 3), "nodes/mass": (n,),
                  "nodes/radius": (n,), "nodes/kind": (n,), "threads/pairs": (p, 2),
                  "threads/rest_length": (p,), "threads/stiffness": (p,),
                  "threads/damping": (p,), "threads/breaking_tension": (p,),
                  "threads/tension": (t, p), "time": (t,)}
        for name, shape in shapes.items():
            assert f[name].shape == shape, name
            assert "units" in f[name].attrs, name
        assert f["nodes/position"].attrs["units"] == "m"
        for key in ("scenario", "engine", "integrator", "dt", "bending", "status",
                    "wall_time_s", "compile_time_s", "bulletnet_version", "format_version"):
            assert key in f.attrs, key
        assert f.attrs["status"] == "completed"
        assert f.attrs["units"] == "dt: s, record_rate: Hz"  # the root's unsuffixed ones
        scene = loads(f.attrs["scenario"])
    assert scene.net.nodes_per_side == 4 and scene.scene.duration == 0.02
    assert not (tmp_path / "run.h5.part").exists()


def test_scenario_toml_round_trip():
    s = small_scene(**{"launch.elevation": 30.0})
    assert loads(to_toml(s)) == s


def test_scene_from_a_base_scene(tmp_path):
    # a scene that starts from another equals that scene with its own keys set over it
    child = tmp_path / "child.toml"
    child.write_text('base = "capture"\n[net]\nnodes_per_side = 7\n[scene]\nname = "c"\n')
    assert bn.load_scenario(str(child)) == bn.load_scenario(
        "capture", {"net.nodes_per_side": 7, "scene.name": "c"})
    assert bn.load_scenario("capture_closing").debris == bn.load_scenario("capture").debris
    loop = tmp_path / "loop.toml"
    loop.write_text('base = "loop.toml"\n')
    proc = cli("params", str(loop))
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1
    assert "includes itself" in proc.stderr


def test_interrupted_run_keeps_frames(tmp_path):
    calls = []

    def stop_after_three(t, duration, wall):
        calls.append(t)
        if len(calls) == 3:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        bn.run(small_scene(), tmp_path / "r.h5", progress=stop_after_three)
    rec = bn.open_recording(tmp_path / "r.h5")
    assert rec.status == "interrupted"
    assert rec.time.size == 4  # the initial frame and three more
    np.testing.assert_allclose(rec.time, [0, 0.01, 0.02, 0.03])


def test_divergence_is_typed_and_kept(tmp_path):
    # Reference: explicit Euler on a damper c is unstable for dt > 2 m / c (~1e-5 s here with
    # several threads per node); at 5e-5 s it must blow up and say so.
    s = small_scene(**{"simulation.integrator": "symplectic_euler", "simulation.dt": 5e-5,
                       "net.fold_ratio": 0.9})
    with pytest.raises(bn.DivergenceError, match="step"):
        bn.run(s, tmp_path / "d.h5")
    rec = bn.open_recording(tmp_path / "d.h5")
    assert rec.status == "diverged" and "diverged at t" in rec.attrs["message"]
    assert np.isfinite(rec.position).all() and rec.time.size >= 2
    proc = cli("run", "deployment", "--set", "net.nodes_per_side=6", "--set",
               "net.fold_ratio=0.9", "--integrator", "symplectic_euler", "--dt", "5e-5",
               "--out", str(tmp_path / "d2.h5"), "--quiet")
    assert proc.returncode == 3
    assert proc.stderr.strip().count("\n") == 1 and "diverged at t" in proc.stderr


def test_an_overflowing_speed_is_a_divergence_not_a_warning(scene):
    # reference: float64's largest value, 1.8e308, below the square of a 1e200 m/s speed: the
    # check finds the divergence without numpy's overflow warning (made an error here)
    import warnings

    from bulletnet.model.builder import build_model, initial_state
    from bulletnet.sim.loop import _check

    state = initial_state(scene, build_model(scene))
    state.velocity[3] = [1e200, 0.0, 0.0]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert _check(state, 350.0) == "a node moves at inf m/s (limit 350 m/s)"


def test_run_creates_the_folders_of_its_recording(tmp_path):
    # reference: plot --out and view --html, which create their folders; a folder that
    # cannot be created (a file in its way) is one line naming the recording, exit code 2
    proc = cli("run", "deployment", *TINY, "--out", "no/such/folder/x.h5", "--quiet",
               cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert bn.open_recording(tmp_path / "no/such/folder/x.h5").status == "completed"
    (tmp_path / "afile").write_text("")
    proc = cli("run", "deployment", *TINY, "--out", "afile/x.h5", "--quiet", cwd=tmp_path)
    assert proc.returncode == 2 and proc.stderr.count("\n") == 2  # the run's header, the error
    assert proc.stderr.splitlines()[-1] == ("bulletnet: error: afile/x.h5: cannot create its "
                                            "folder afile: File exists")


def test_a_misspelt_key_in_a_scene_file_gets_the_closest_key(tmp_path):
    # reference: difflib's closest match among the scene's keys, as for --set
    (tmp_path / "s.toml").write_text('base = "capture"\n[net]\nnodes_per_sid = 5\n')
    proc = cli("params", "s.toml", cwd=tmp_path)
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1
    assert "unknown key 'net.nodes_per_sid' (did you mean 'net.nodes_per_side'?)" in proc.stderr


@pytest.mark.parametrize(("args", "needle"), [
    (["run", "nosuchscene"],
     "named scenes: cantilever, capture, capture_closing, capture_envisat, deployment, "
     "deployment_breaking, removal)"),
    (["run", "sweep_example"], "a sweep file, not a scene; run it with `bulletnet sweep"),
    (["run", "deployment", "--set", "net.colour=3"], "unknown key"),
    (["run", "deployment", "--set", "net.nodes_per_sid=5"],
     "unknown key (did you mean 'net.nodes_per_side'?)"),
    (["run", "deployment", "--set", "nte.nodes_per_side=5"],
     "no table 'nte' (did you mean 'net.nodes_per_side'?)"),
    (["run", "deployment", "--set", "net.nodes_per_side=1"], "nodes_per_side"),
    (["run", "deployment", "--set", "net.mesh_length=-0.5"], "positive"),
    (["run", "deployment", "--set", "net.mesh_length=nan"], "finite"),
    (["run", "deployment", "--set", "net.nodes_per_side=2.5"], "integer"),
    (["run", "deployment", "--dt", "0"], "positive"),
    (["run", "deployment", "--dt", "0.01", "--record-rate", "1000"], "record_rate"),
    (["run", "deployment", "--record-rate", "2e6"], "record_rate"),
    (["run", "deployment", "--set", "outcome.enabled=true"], "outcome.enabled"),
    (["run", "capture", "--set", "outcome.enclosed_fraction=1.5"], "in (0, 1]"),
    (["compare", "missing_a.h5", "missing_b.h5"], "no such recording"),
    (["metrics", str(ROOT / "pyproject.toml")], "not a readable HDF5"),
    (["params", "capture", "--set", f"debris.asset='{ROOT / 'pyproject.toml'}'"], "[[parts]]"),
    (["params", "capture", "--set", f"debris.asset='{ROOT / 'assets/meshes/apollo_csm.obj'}'"],
     "needs debris.mass"),
    (["run", "deployment", "--out", "tests", "--force"], "tests: is a folder"),
    (["metrics", "tests"], "tests: a folder, not a recording"),
    (["bench", "deployment", "--measures", "wrap"], "--measures wrap: needs debris"),
    (["run", "deployment", "--engine", "reference", "--integrator", "implicit_euler"],
     "DOP853"),
    (["run", "deployment", "--set", "net.nodes_per_side=5000", "--out", "big.h5"],
     "GB; lower --record-rate"),  # refused before a model of 25 million nodes is built
    (["study"], "give a STUDY.toml to run, or --report DIR\n"),
])
def test_bad_input_one_line_exit_2(args, needle, tmp_path):
    # run in tmp_path, where a command that wrongly went ahead would write its default output
    # (SCENE.h5, bench/, --out big.h5); "tests" is a folder there, as in the repository
    (tmp_path / "tests").mkdir()
    proc = cli(*args, cwd=tmp_path)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr
    assert needle in proc.stderr


def test_params_prints_the_debris_mass_properties():
    # Reference: the asset's computed mass properties (bulletnet.model.debris, checked in
    # test_debris), as the CLI reports them.
    proc = cli("params", "capture_envisat", "--json")
    assert proc.returncode == 0, proc.stderr
    debris = json.loads(proc.stdout)["debris"]
    envisat = bn.load_debris("envisat")
    assert debris["mass_kg"] == envisat.mass
    np.testing.assert_array_equal(debris["inertia_kg_m2"], envisat.inertia)
    np.testing.assert_array_equal(debris["principal_axes"], envisat.principal_axes.T)


def test_params_describes_the_beam_as_a_beam():
    # Reference: scenarios/cantilever.toml, a two-node beam 0.5 m long (Fig. 2): no net side,
    # no corner threads, no contact pairs.
    doc = json.loads(cli("params", "cantilever", "--json").stdout)
    assert doc["beam_length_m"] == 0.5 and "nodes_per_side" not in doc
    assert list(doc["threads"]) == ["inner"] and doc["contact"] == {}
    text = cli("params", "cantilever").stdout
    assert text.startswith("scene cantilever: a beam 0.5 m long, 2 masses, 1 threads")
    assert "threads (Table 7)        inner\n" in text and "contact pair" not in text


def test_existing_output_needs_force(tmp_path):
    out = tmp_path / "x.h5"
    out.write_bytes(b"keep me")
    proc = cli("run", "deployment", *TINY, "--out", str(out), "--quiet")
    assert proc.returncode == 2 and "--force" in proc.stderr
    assert out.read_bytes() == b"keep me"


def test_compare_and_metrics_json(tmp_path):
    a, b = tmp_path / "a.h5", tmp_path / "b.h5"
    for path, integrator in ((a, "implicit_euler"), (b, "symplectic_euler")):
        assert cli("run", "deployment", *TINY, "--integrator", integrator, "--dt", "2e-6",
                   "--out", str(path), "--quiet").returncode == 0
    doc = json.loads(cli("compare", str(a), str(b), "--json").stdout)
    assert set(doc) >= {"rmse_pos_max", "rmse_pos_avg", "rmse_vel_max", "rmse_vel_avg"}
    assert 0 < doc["rmse_pos_avg"] <= doc["rmse_pos_max"]
    m = json.loads(cli("metrics", str(a), "--json").stdout)
    assert len(m["time_s"]) == len(m["mouth_area_m2"]) == 11


def test_metrics_on_the_folded_start(tmp_path):
    # Reference: geometry of the initial state. The folded net is a flat square of side
    # (Ns - 1) * fold * l_mesh: mouth area its square, diagonal sqrt(2) times it, height 0.
    s = small_scene(**{"scene.duration": 0.01})
    rec = bn.open_recording(bn.run(s, tmp_path / "m.h5").path)
    side = 5 * 0.25 * 0.5
    assert bn.metrics.mouth_area(rec)[0] == pytest.approx(side**2, rel=1e-12)
    assert bn.metrics.mouth_diagonal(rec)[0] == pytest.approx(math.sqrt(2) * side, rel=1e-12)
    assert bn.metrics.net_height(rec)[0] == 0.0


def test_rmse_of_a_rigid_shift(tmp_path):
    # Reference: Eq. 14 of a copy shifted by d everywhere is exactly |d| for every node.
    rec = bn.open_recording(bn.run(small_scene(**{"scene.duration": 0.02}),
                                   tmp_path / "s.h5").path)
    shifted = bn.Recording(**{**rec.__dict__, "position": rec.position + [0.003, 0.004, 0.0]})
    r = bn.metrics.rmse(rec, shifted)
    assert r["rmse_pos_max"] == pytest.approx(0.005, rel=1e-9)
    assert r["rmse_pos_avg"] == pytest.approx(0.005, rel=1e-9)
    assert r["rmse_vel_max"] == 0.0


def test_rmse_needs_more_than_the_start_in_common(tmp_path):
    # two recordings that share only t = 0 (their identical initial state) compare nothing
    rec = bn.open_recording(bn.run(small_scene(**{"scene.duration": 0.02}),
                                   tmp_path / "s.h5").path)
    later = bn.Recording(**{**rec.__dict__, "time": np.where(rec.time > 0, rec.time + 1e-3, 0)})
    with pytest.raises(bn.RecordingError, match="share only the sample at 0 s"):
        bn.metrics.rmse(rec, later)


def test_a_beam_gets_its_tip_not_the_net_measures(tmp_path):
    # Reference: Euler-Bernoulli, tip deflection P L^3 / (3 E I) + w L^4 / (8 E I) (within
    # the 1 % of tests/test_bending.py; the two-node model lumps half the weight at the tip)
    # and the lumped model's own, (P + w L / 2) L^3 / (3 E I), to the residual oscillation.
    path = tmp_path / "beam.h5"
    bn.run(bn.load_scenario("cantilever"), path)
    beam = bn.metrics.summary(bn.open_recording(path))["beam"]
    tip = beam["tip_displacement_m"][-1][2]
    e, length, r = 69e9, 0.5, 0.01
    inertia, w = math.pi * r**4 / 4, 2700 * math.pi * r**2 * 9.81
    theory = 262 * length**3 / (3 * e * inertia) + w * length**4 / (8 * e * inertia)
    assert beam["euler_bernoulli_m"][2] == pytest.approx(-theory, rel=1e-12)
    assert tip == pytest.approx(-theory, rel=0.01)
    assert tip == pytest.approx(beam["two_node_model_m"][2], rel=1e-4)
    proc = cli("metrics", str(path))
    assert proc.returncode == 0 and "Euler-Bernoulli" in proc.stdout, proc.stderr
    for args in (["plot", str(path), "--out", str(tmp_path / "fig")],
                 ["view", str(path), "--html", str(tmp_path / "r.html")]):
        proc = cli(*args)
        assert proc.returncode == 2 and "a beam (the cantilever), not a net" in proc.stderr
        assert proc.stderr.count("\n") == 1


def test_plot_writes_the_figures(tmp_path):
    a, b = tmp_path / "a.h5", tmp_path / "b.h5"
    for path, flag in ((a, "--no-bending"), (b, "--bending")):
        assert cli("run", "deployment", *TINY, flag, "--out", str(path),
                   "--quiet").returncode == 0
    proc = cli("plot", str(a), str(b), "--out", str(tmp_path / "fig"))
    assert proc.returncode == 0, proc.stderr
    names = {"mouth.png", "height.png", "diagonal.png", "area.png", "rmse.png",
             "corner_thread.png", "strength.png"}
    assert {p.name for p in (tmp_path / "fig").iterdir()} == names
    for name in names:
        assert (tmp_path / "fig" / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # a time outside the recording (0 to 0.02 s) is an error, not a snapshot clamped to it
    for args in (["plot", str(a), "--times", "99", "--out", str(tmp_path / "late")],
                 ["view", str(a), "--snapshots", "-3", "--html", str(tmp_path / "r.html")]):
        proc = cli(*args)
        assert proc.returncode == 2 and "outside the recording, 0 to 0.02 s" in proc.stderr
