"""Sweeps: variants of a scene over Dask, gathered into one table."""

from __future__ import annotations

import csv

import numpy as np
import pytest
from test_recording_cli import cli

import bulletnet as bn
import bulletnet.model.scenario
from bulletnet.studies.sweep import load_sweep, run_sweep, write_table

SWEEP = """
scene = "deployment"
mode = "list"
[set]
"net.nodes_per_side" = 4
"scene.duration" = 0.05
[[variant]]
"launch.elevation" = 30.0
[[variant]]
"launch.elevation" = 60.0
"bending.enabled" = true
[[variant]]
"simulation.dt" = 5e-5
"net.fold_ratio" = 0.9
"""


@pytest.fixture
def sweep_file(tmp_path):
    path = tmp_path / "sweep.toml"
    path.write_text(SWEEP)
    return path


def test_dask_sweep_matches_the_runs_one_by_one(sweep_file, tmp_path):
    # Reference: each variant run on its own with bulletnet.run (runs are deterministic, so
    # the Dask workers must give bit-identical measures); the third variant steps 25x above
    # the explicit limit and must come back as a 'diverged' row, not stop the sweep.
    spec = load_sweep(sweep_file)
    assert spec.swept == ("launch.elevation", "bending.enabled", "simulation.dt",
                          "net.fold_ratio")
    rows = run_sweep(spec, tmp_path / "dask", workers=2)
    assert [r["status"] for r in rows] == ["completed", "completed", "diverged"]
    assert "diverged at t" in rows[2]["message"]
    for row, overrides in zip(rows[:2], spec.variants[:2], strict=True):
        alone = bn.run(bn.load_scenario("deployment", overrides), tmp_path / "alone.h5",
                       force=True)
        rec = bn.open_recording(alone.path)
        assert row["final_mouth_area_m2"] == bn.metrics.mouth_area(rec)[-1]
        assert row["max_corner_tension_N"] == rec.tension[:, -4:].max()  # no tether: the last 4
        assert row["steps"] == alone.stats["steps"]
    table = write_table(rows, tmp_path / "dask")[0]
    with table.open() as f:
        read = list(csv.DictReader(f))
    assert [r["status"] for r in read] == ["completed", "completed", "diverged"]
    assert float(read[1]["launch.elevation"]) == 60.0


def test_cli_sweep_serial_writes_table_and_plots(sweep_file, tmp_path):
    proc = cli("sweep", str(sweep_file), "--serial", "--out", str(tmp_path / "o"))
    assert proc.returncode == 0, proc.stderr
    assert "2 completed, 1 diverged" in proc.stdout
    assert (tmp_path / "o" / "sweep.csv").exists()
    assert (tmp_path / "o" / "figures" / "launch.elevation.png").exists()


def test_cli_sweep_set_is_the_files_set_extended(sweep_file, tmp_path):
    # Reference: the same sweep with the key written in its file's [set]: --set adds it to
    # every variant, so the two tables agree to the last bit (but for wall time and paths).
    proc = cli("sweep", str(sweep_file), "--serial", "--out", str(tmp_path / "cli"),
               "--set", "scene.duration=0.06")
    assert proc.returncode == 0, proc.stderr
    written = tmp_path / "written.toml"
    written.write_text(SWEEP.replace('"scene.duration" = 0.05', '"scene.duration" = 0.06'))
    proc = cli("sweep", str(written), "--serial", "--out", str(tmp_path / "file"))
    assert proc.returncode == 0, proc.stderr

    def rows(folder):
        with (folder / "sweep.csv").open() as f:
            return [{k: v for k, v in r.items() if k not in ("wall_s", "recording")}
                    for r in csv.DictReader(f)]

    assert rows(tmp_path / "cli") == rows(tmp_path / "file")
    assert all(r["scene.duration"] == "0.06" for r in rows(tmp_path / "cli"))
    proc = cli("sweep", str(sweep_file), "--out", str(tmp_path / "o"), "--set",
               "launch.elevation=40")
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
    assert "varies it" in proc.stderr


@pytest.mark.parametrize(("text", "needle"), [
    ('scene = "deployment"\n[vary]\n"net.colour" = [1]\n', "unknown key"),
    ('scene = "deployment"\n[vary]\n"net.nodes_per_side" = 11\n', "non-empty list"),
    ('scene = "deployment"\nmode = "grid"\n', "mode"),
    ('scene = "deployment"\n[vary]\n"net.mesh_length" = [0.5, -1.0]\n', "variant 1"),
    ('scene = "nosuchscene"\n', "no such scene"),
    ("scene = [\n", "malformed TOML"),
])
def test_bad_sweep_files_are_refused_before_running(tmp_path, text, needle):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(bn.ScenarioError, match=needle):
        load_sweep(path)


def test_cli_bad_sweep_is_one_line(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text('scene = "deployment"\nmode = "grid"\n')
    proc = cli("sweep", str(path), "--out", str(tmp_path / "o"))
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1 and "mode" in proc.stderr


def test_example_sweep_is_sixteen_valid_variants():
    spec = load_sweep(bn.model.scenario.SCENARIO_DIR / "sweep_example.toml")
    assert len(spec.variants) == 16 and len(set(map(str, spec.variants))) == 16


def test_corner_tension_is_the_corner_threads_with_a_tether_on():
    # Reference: Fig. 1's topology: the four corner threads join a net corner to its corner
    # mass; the tether's threads, appended after them, join the net's centre, tether nodes
    # and the chaser. The measure takes the corner threads by their ends' kinds, not the
    # last four threads (which, with a tether, are the tether's).
    from types import SimpleNamespace

    from bulletnet.model.net import NodeKind, corner_threads
    from bulletnet.studies.measures import max_corner_tension

    model = bn.build_model(bn.load_scenario("capture_closing"))
    corner = corner_threads(model.pairs, model.kind)
    ends = np.sort(model.kind[model.pairs[corner]], axis=1)
    assert corner.size == 4 and (ends == [NodeKind.CORNER, NodeKind.CORNER_MASS]).all()
    tether = np.flatnonzero((model.kind[model.pairs] == NodeKind.TETHER).any(axis=1))
    assert tether.size and tether.min() > corner.max()
    tension = np.zeros((2, model.thread_count))
    tension[1, corner[2]], tension[0, tether[-1]] = 3.0, 50.0  # the tether pulls harder
    rec = SimpleNamespace(tension=tension, pairs=model.pairs, kind=model.kind)
    assert max_corner_tension(rec) == 3.0
