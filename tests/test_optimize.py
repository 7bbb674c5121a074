"""Robust design optimisation (``bulletnet optimize``): the optimum of an analytic noisy
objective, common random numbers, resuming after a killed driver, scoring, bad input, and a
tiny scene optimisation through the command line and its report."""

from __future__ import annotations

import json
import os
import tomllib
from pathlib import Path

import pytest
from test_recording_cli import cli

from bulletnet.common.errors import ScenarioError
from bulletnet.studies.optimize import (
    assess,
    design_quantities,
    load_optimisation,
    run_optimisation,
)
from bulletnet.studies.optimize_report import front, report_optimisation
from bulletnet.studies.report import wilson
from bulletnet.studies.study import draw, read_table
from tests import study_functions

ROOT = Path(__file__).resolve().parent.parent

BOWL = """
function = "tests.study_functions:bowl"
measures = ["f", "u_seen", "high"]
seed = 3
trials = {trials}
draws = 4
sampler = "{sampler}"
[design]
x = {{low = 0.0, high = 1.0}}
y = {{low = 0.0, high = 1.0}}
[vary]
u = {{dist = "normal", mean = 0.0, std = 1.0}}
[objective]
measure = "f"
"""

TINY_DEPLOYMENT = """
scene = "deployment"
seed = 5
trials = 2
draws = 2
[set]
"net.nodes_per_side" = 4
"scene.duration" = 0.2
[design]
"net.mesh_length" = {low = 0.4, high = 0.6}
"launch.corner_speed" = {low = 1.5, high = 3.0}
"net.thread_radius" = {low = 3e-4, high = 1e-3, log = true}
[vary]
"launch.elevation" = {dist = "uniform", low = 40, high = 60}
[objective]
measure = "overloaded"
equals = false
cost = "net_mass_kg"
cost_weight = 0.01
[constraints]
net_mass_kg = {max = 5.0}
min_safety_factor = {min = 1.0}
"""


@pytest.fixture(autouse=True)
def _subprocesses_import_the_test_functions(monkeypatch):
    """CLI subprocesses import ``tests.study_functions`` from the root."""
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join(
        [str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])]))


def bowl(tmp_path: Path, trials: int = 40, sampler: str = "tpe") -> Path:
    path = tmp_path / f"bowl_{trials}_{sampler}.toml"
    path.write_text(BOWL.format(trials=trials, sampler=sampler))
    return path


def without_wall(out: Path) -> list[dict]:
    """The table's rows without the wall time (the only column two runs may differ in)."""
    return [{k: v for k, v in row.items() if k != "wall_s"}
            for row in read_table(out / "runs.csv")[1]]


@pytest.mark.parametrize("sampler", ["tpe", "cmaes"])
def test_finds_the_maximum_of_a_noisy_bowl(tmp_path, sampler):
    # reference: f(x, y; u) = -(x - 0.3)^2 - (y - 0.7)^2 + 0.05 u has its maximum at
    # (0.3, 0.7) in closed form for every u; with the same draws for every design the mean
    # noise is one constant, so the optimiser sees the bowl itself. 40 designs of 4 runs,
    # serial: found within 0.05 of the maximum on each axis
    opt = load_optimisation(bowl(tmp_path, sampler=sampler))
    done = run_optimisation(opt, tmp_path / "out", serial=True)
    best = done["best"].params
    assert abs(best["x"] - 0.3) < 0.05 and abs(best["y"] - 0.7) < 0.05, best
    noise = 0.05 * sum(d["u"] for d in opt.draws) / len(opt.draws)
    assert done["best"].value == pytest.approx(
        -(best["x"] - 0.3) ** 2 - (best["y"] - 0.7) ** 2 + noise, abs=1e-12)


def test_every_design_runs_the_same_draws(tmp_path):
    # reference: common random numbers; the K draws are the seeded numpy draws of the file's
    # [vary] (study.draw, design "random"), the same for every design, as the run table and
    # what the function received (u_seen) both show
    opt = load_optimisation(bowl(tmp_path, trials=6))
    run_optimisation(opt, tmp_path / "out", serial=True)
    rows = read_table(tmp_path / "out" / "runs.csv")[1]
    expected = draw("random", 4, 3, opt.vary)
    assert [r["run"] for r in rows] == list(range(24))
    for r in rows:
        assert r["run"] == 4 * r["design"] + r["draw"]
        assert r["u"] == r["u_seen"] == expected[r["draw"]]["u"]
    designs = {(r["x"], r["y"]) for r in rows}
    assert len(designs) == 6  # six different designs, each on the same four draws


def test_the_first_design_is_evaluated_first_on_the_same_draws(tmp_path):
    # reference: the bowl at a given design, f = -(x - 0.3)^2 - (y - 0.7)^2 + 0.05 u, on the
    # file's K draws: trial 0 is [first] and scored as the closed form says; the sampler's
    # designs follow (resumed, no second copy of it); a value outside its bound is refused
    path = bowl(tmp_path, trials=4)
    path.write_text(path.read_text() + "[first]\nx = 0.5\ny = 0.25\n")
    opt = load_optimisation(path)
    run_optimisation(opt, tmp_path / "out", serial=True)
    rows = read_table(tmp_path / "out" / "runs.csv")[1]
    first = [r for r in rows if r["design"] == 0]
    assert len(rows) == 16 and {(r["x"], r["y"]) for r in first} == {(0.5, 0.25)}
    assert [r["f"] for r in first] == pytest.approx(
        [-(0.5 - 0.3) ** 2 - (0.25 - 0.7) ** 2 + 0.05 * d["u"] for d in opt.draws], abs=1e-12)
    resumed = run_optimisation(load_optimisation(path), tmp_path / "out", serial=True)
    assert (resumed["skipped"], resumed["trials"]) == (4, 0)
    # the report confirms the best design and the first on the same fresh draws (paired)
    report_optimisation(tmp_path / "out", confirm_runs=3, serial=True, plots=False)
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    best = summary["best"]["design"]
    assert best != 0 and summary["confirmation_first"]["design"] == 0
    tables = [read_table(tmp_path / "out" / f"confirm_{n:04d}.csv")[1] for n in (best, 0)]
    assert [r["u"] for r in tables[0]] == [r["u"] for r in tables[1]]
    assert {(r["x"], r["y"]) for r in tables[1]} == {(0.5, 0.25)}
    path.write_text(path.read_text().replace("x = 0.5", "x = 1.5"))
    with pytest.raises(ScenarioError, match=r"first\.x: 1\.5 is outside"):
        load_optimisation(path)


@pytest.mark.parametrize("sampler", ["tpe", "cmaes"])
def test_resume_after_a_kill_gives_the_same_trials(tmp_path, sampler):
    # reference: the uninterrupted 40-design run; a driver stopped half-way through design
    # 17 (KeyboardInterrupt from the function, as Ctrl-C or a kill would stop it) and
    # resumed, and a run of 15 designs raised to 40, give the same table but wall times
    def plan(trials: int = 40):
        return load_optimisation(bowl(tmp_path, trials, sampler))

    straight = tmp_path / "straight"
    run_optimisation(plan(), straight, serial=True)

    killed = tmp_path / "killed"
    study_functions.BOWL_CALLS["left"] = 4 * 17 + 2
    try:
        with pytest.raises(KeyboardInterrupt):
            run_optimisation(plan(), killed, serial=True)
    finally:
        study_functions.BOWL_CALLS["left"] = None
    assert len(read_table(killed / "runs.csv")[1]) == 4 * 17 + 2  # finished runs kept
    resumed = run_optimisation(plan(), killed, serial=True)
    assert (resumed["skipped"], resumed["trials"]) == (17, 23)
    assert without_wall(killed) == without_wall(straight)

    extended = tmp_path / "extended"
    run_optimisation(plan(15), extended, serial=True)
    run_optimisation(plan(), extended, serial=True)
    assert without_wall(extended) == without_wall(straight)


def test_dask_and_serial_give_the_same_designs(tmp_path):
    # reference: the serial run; each design's runs on 2 Dask workers finish in any order,
    # but the table (in run order) and so the designs asked are the same
    opt = load_optimisation(bowl(tmp_path, trials=3))
    run_optimisation(opt, tmp_path / "serial", serial=True)
    run_optimisation(opt, tmp_path / "dask", workers=2)
    assert without_wall(tmp_path / "dask") == without_wall(tmp_path / "serial")


def test_a_failed_run_is_a_row_not_a_crash(tmp_path):
    # reference: the draws themselves; runs whose u > 0.5 raise, each is a row with status
    # error and the exception's message, and every design is scored from the others
    path = bowl(tmp_path, trials=3)
    path.write_text(path.read_text().replace("[vary]", "[set]\nfail_above = 0.5\n[vary]"))
    opt = load_optimisation(path)
    done = run_optimisation(opt, tmp_path / "out", serial=True)
    failing = sum(d["u"] > 0.5 for d in opt.draws)
    assert 0 < failing < len(opt.draws)
    rows = read_table(tmp_path / "out" / "runs.csv")[1]
    errors = [r for r in rows if r["status"] == "error"]
    assert len(errors) == 3 * failing and all("ValueError" in r["message"] for r in errors)
    assert done["trials"] == 3 and done["best"].user_attrs["completed"] == 4 - failing


def test_cli_set_is_the_files_set_extended(tmp_path):
    # Reference: the same optimisation with the input written in its file's [set]: --set
    # adds it to every run of every design, so the two tables agree to the last bit (but for
    # wall time), and the optimisation's record keeps it with its [set].
    path = bowl(tmp_path, trials=3)
    proc = cli("optimize", str(path), "--out", str(tmp_path / "cli"), "--serial", "--set",
               "fail_above=0.5")
    assert proc.returncode == 0, proc.stderr
    written = tmp_path / "written.toml"
    written.write_text(path.read_text().replace("[vary]", "[set]\nfail_above = 0.5\n[vary]"))
    run_optimisation(load_optimisation(written), tmp_path / "file", serial=True)
    assert without_wall(tmp_path / "cli") == without_wall(tmp_path / "file")
    assert any(r["status"] == "error" for r in without_wall(tmp_path / "cli"))
    record = json.loads((tmp_path / "cli" / "optimize.json").read_text())
    assert record["file"]["set"] == {"fail_above": 0.5}
    for args, needle in ((("--out", str(tmp_path / "o"), "--set", "x=0.5"), "varies it"),
                         (("--report", str(tmp_path / "cli"), "--set", "u=1"), "not to --report")):
        proc = cli("optimize", *([] if args[0] == "--report" else [str(path)]), *args)
        assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
        assert needle in proc.stderr


def test_a_probability_objective_is_its_wilson_bound_less_the_cost(tmp_path):
    # reference: Wilson 1927 (report.wilson): 3 captures of 4 runs, one of them an error
    # (which counts as not captured); score = lower bound - cost_weight * net mass; the
    # constraint's violation is the worst draw's
    path = tmp_path / "p.toml"
    path.write_text(BOWL.format(trials=1, sampler="tpe").replace(
        'measure = "f"', 'measure = "high"\nequals = true\ncost = "f"\ncost_weight = 2.0\n'
        '[constraints]\nf = {min = -0.5}'))
    opt = load_optimisation(path)
    rows = [{"status": "completed", "high": True, "f": -0.2},
            {"status": "completed", "high": True, "f": -0.4},
            {"status": "completed", "high": True, "f": -0.9},
            {"status": "error", "high": None, "f": None}]
    scores = assess(opt, rows, {})
    p, low, high = wilson(3, 4, 0.95)
    assert (scores["p"], scores["low"], scores["high"]) == (p, low, high)
    assert scores["score"] == pytest.approx(low - 2.0 * (-0.5))
    assert scores["constraints"] == {"f": pytest.approx(0.4)} and not scores["feasible"]


def test_a_run_that_did_not_complete_counts_against_a_probability(tmp_path):
    # reference: Wilson 1927 (report.wilson). Minimising P(high) over 4 runs, one an error:
    # the error counts as the event (2 of 4), so a design whose runs fail cannot beat one
    # whose runs complete; a mean objective is the completed runs' mean
    path = tmp_path / "p.toml"
    path.write_text(BOWL.format(trials=1, sampler="tpe").replace(
        'measure = "f"', 'measure = "high"\nequals = true\ndirection = "minimize"'))
    rows = [{"status": "completed", "high": True, "f": -0.2},
            {"status": "completed", "high": False, "f": -0.4},
            {"status": "completed", "high": False, "f": -0.9},
            {"status": "error", "high": None, "f": None}]
    scores = assess(load_optimisation(path), rows, {})
    assert scores["successes"] == 1 and scores["high"] == wilson(2, 4, 0.95)[2]
    failed = [{"status": "diverged", "high": None, "f": None}] * 4
    assert assess(load_optimisation(path), failed, {})["score"] > scores["score"]
    mean = tmp_path / "m.toml"
    mean.write_text(BOWL.format(trials=1, sampler="tpe"))
    assert assess(load_optimisation(mean), rows, {})["score"] == pytest.approx(
        (-0.2 - 0.4 - 0.9) / 3)


def test_the_front_keeps_the_designs_nothing_beats():
    # reference: by hand; (objective, cost, design), higher objective and lower cost better
    points = [(0.5, 1.0, 0), (0.4, 2.0, 1), (0.7, 2.0, 2), (0.6, 3.0, 3), (0.9, 4.0, 4)]
    assert front(points, maximize=True) == [0, 2, 4]


@pytest.mark.parametrize(("change", "needle"), [
    (("seed = 3", "seed = 3\ncolour = 1"), "unknown key 'colour'"),
    (("x = {low = 0.0, high = 1.0}", "x = {low = 1.0, high = 0.0}"), "expected low < high"),
    (("x = {low = 0.0, high = 1.0}", "x = {low = 0.0, high = 1.0, log = true}"), "low > 0"),
    (("x = {low = 0.0, high = 1.0}", "x = {low = 0.5, high = 3, int = true}"), "whole bounds"),
    (("x = {low = 0.0, high = 1.0}", "x = {lo = 0.0, high = 1.0}"), "unknown key 'lo'"),
    (('[objective]\nmeasure = "f"', ""), "needs an [objective]"),
    (('measure = "f"', 'measure = "g"'), "measure: expected one of f, high, u_seen"),
    (('measure = "f"', 'measure = "f"\ndirection = "up"'), "direction"),
    (("trials = 40", "trials = 0"), "trials: expected an integer >= 1"),
    (('sampler = "tpe"', 'sampler = "grid"'), "sampler"),
    (('measure = "f"', 'measure = "f"\n[constraints]\nf = {least = 1}'), "constraints.f"),
    (("[vary]", "[vary]\nx = {dist = \"uniform\", low = 0, high = 1}"), "more than one of"),
])
def test_bad_files_are_refused_before_running(tmp_path, change, needle):
    path = bowl(tmp_path)
    text = path.read_text()
    assert change[0] in text
    path.write_text(text.replace(*change))
    with pytest.raises(ScenarioError, match=needle.replace("[", r"\[")):
        load_optimisation(path)


def test_cli_bad_input_is_one_line(tmp_path):
    path = bowl(tmp_path)
    path.write_text(path.read_text().replace('[objective]\nmeasure = "f"', ""))
    proc = cli("optimize", str(path), "--out", str(tmp_path / "out"), "--serial")
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
    assert "needs an [objective]" in proc.stderr
    proc = cli("optimize", "--report", str(tmp_path))
    assert proc.returncode == 2 and "not an optimisation folder" in proc.stderr
    proc = cli("optimize", str(bowl(tmp_path)), "--out", str(tmp_path / "x"), "--confirm", "3")
    assert proc.returncode == 2 and "--confirm" in proc.stderr


def test_scene_optimisation_end_to_end(tmp_path):
    # reference: the deployment scene, 2 designs of 2 runs of 0.2 s (4 x 4 nodes), serial,
    # through the command line; then its report with a 2-draw confirmation of the best design
    # (fresh draws: none of the optimisation's)
    path = tmp_path / "dep.toml"
    path.write_text(TINY_DEPLOYMENT)
    out = tmp_path / "out"
    proc = cli("optimize", str(path), "--out", str(out), "--serial")
    assert proc.returncode == 0, proc.stderr
    assert "optimize: design 2/2" in proc.stderr and "best:" in proc.stdout
    rows = read_table(out / "runs.csv")[1]
    assert len(rows) == 4 and {r["status"] for r in rows} == {"completed"}
    proc = cli("optimize", "--report", str(out), "--confirm", "2", "--serial")
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((out / "summary.json").read_text())
    best, confirmation = summary["best"], summary["confirmation"]
    assert best["design"] in (0, 1) and 0 < best["net_mass_kg"] < 5.0
    assert confirmation["design"] == best["design"] and confirmation["runs"] == 2
    fresh = {r["launch.elevation_deg"] for r in read_table(
        out / f"confirm_{best['design']:04d}.csv")[1]}
    assert fresh.isdisjoint({r["launch.elevation_deg"] for r in rows})
    assert "confirmation on 2 fresh draws" in proc.stdout
    for name in ("front", "history", "importance"):
        assert (out / "figures" / f"{name}.png").stat().st_size > 0


def test_the_capture_optimisation_file_loads(tmp_path):
    # reference: scenarios/optimize_capture.toml and docs/studies.md's example variables
    # (integer, log-scale and choice); the K draws are the envelope study's [vary] keys, the
    # nominal net (1 m mesh, 0.5 kg corner masses: 3.03 kg) is within the 4 kg budget
    path = ROOT / "scenarios" / "optimize_capture.toml"
    opt = load_optimisation(path)
    assert (opt.trials, len(opt.draws), opt.objective.equals) == (24, 12, "captured")
    envelope = tomllib.loads((ROOT / "scenarios" / "study_capture_envelope.toml").read_text())
    assert set(opt.vary) == set(envelope["vary"]) - set(opt.design)
    nominal = design_quantities(opt, {"net.mesh_length": 1.0, "net.corner_mass": 0.5})
    assert nominal["net_mass_kg"] == pytest.approx(3.03, abs=0.01) and \
        nominal["net_mass_kg"] < opt.constraints["net_mass_kg"]["max"]
    mine = tmp_path / "mine.toml"
    mine.write_text(path.read_text().replace("[design]", '[design]\n"net.nodes_per_side" = '
                                             '{low = 15, high = 21, int = true}\n'
                                             '"closing.trigger" = {values = ["contact", "wrap"]}')
                    .replace("[first]", '[first]\n"net.nodes_per_side" = 21\n'
                                        '"closing.trigger" = "contact"'))
    columns = load_optimisation(mine).columns
    assert columns["net.nodes_per_side"] == "net.nodes_per_side"
    assert columns["closing.trigger"] == "closing.trigger"


def test_of_equal_scores_the_best_design_is_the_cheapest():
    # reference: the definition (a Wilson bound over K runs takes few values, so designs tie):
    # of the feasible designs of the best score, the least cost; without a cost, the first
    import optuna

    from bulletnet.studies.optimize import best_trial

    def study(with_cost: bool):
        s = optuna.create_study(direction="maximize")
        x = optuna.distributions.FloatDistribution(0.0, 1.0)
        for value, cost, feasible in ((0.7, 3.0, True), (0.7, 2.5, True), (0.7, 2.0, False),
                                      (0.6, 1.0, True)):
            s.add_trial(optuna.trial.create_trial(
                value=value, params={"x": cost / 10}, distributions={"x": x},
                user_attrs={"feasible": feasible} | ({"cost": cost} if with_cost else {})))
        return s

    assert best_trial(study(True)).number == 1
    assert best_trial(study(False)).number == 0


def test_a_changed_file_does_not_resume_into_the_folder(tmp_path):
    # reference: the folder's optimize.json; more trials go on, any other change is refused
    run_optimisation(load_optimisation(bowl(tmp_path, trials=2)), tmp_path / "out", serial=True)
    path = bowl(tmp_path, trials=3)
    path.write_text(path.read_text().replace("seed = 3", "seed = 4"))
    with pytest.raises(ScenarioError, match="holds another optimisation"):
        run_optimisation(load_optimisation(path), tmp_path / "out", serial=True)
    done = run_optimisation(load_optimisation(bowl(tmp_path, trials=3)), tmp_path / "out",
                            serial=True)
    assert (done["skipped"], done["trials"]) == (2, 1)
