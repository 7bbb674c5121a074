"""Speed against accuracy: a grid of (method, step) runs of one scene against a converged
reference run, its Pareto front, and the chart (matplotlib, imported lazily).

The grid runner is scene-agnostic: what a run is scored on is a list of *measures*, functions
``measure(run, reference) -> {name: value}`` of two recordings. The default,
:func:`rmse_measure`, is the paper's Eq. 14 RMSE (max and average over nodes); a chaotic scene
(capture) passes aggregate measures instead.

The reference is the scene run with symplectic Euler at :data:`REFERENCE_DT` (a quarter of the
default step; with bending, the bending springs evaluated every step): first order, so its own
error is about that of a run at twice its step against it (Richardson), which the grid shows
when it holds that step. A scene with contact (the capture) is chaotic once the net touches:
its reference is implicit Euler at :data:`REFERENCE_DT_CONTACT` (a quarter of the capture's
step; symplectic Euler would need 1e-6 s steps), and it is scored on aggregate measures
(``--measures first_contact wrap mouth_area``).
"""

from __future__ import annotations

import math
import statistics
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..common.errors import DivergenceError, ScenarioError
from ..model.scenario import ENGINES, INTEGRATORS, Scenario, to_toml
from ..recording.reader import Recording, open_recording

REFERENCE_DT = 2.5e-7
"""Step of the converged reference run [s] (symplectic Euler)."""

REFERENCE_DT_CONTACT = 1.25e-4
"""Step of the reference run of a scene with contact [s] (implicit Euler)."""


def reference_method(scene: Scenario) -> tuple[str, float]:
    """(integrator, step [s]) of ``scene``'s converged reference run."""
    if scene.contact.enabled:
        return "implicit_euler", REFERENCE_DT_CONTACT
    return "symplectic_euler", REFERENCE_DT

VORTEX_DEPLOYMENT = {
    "duration_s": 3.0,
    "runs": [
        {"bending": False, "dt": "5e-5", "wall_s": 2658.0, "rmse_pos_avg_m": 2.939e-3},
        {"bending": False, "dt": "1/60", "wall_s": 9.0, "rmse_pos_avg_m": None},
        {"bending": True, "dt": "5e-5", "wall_s": 5100.0, "rmse_pos_avg_m": None},
    ]}
"""The paper's Vortex runs of the 3 s deployment (Sec. 4: 44 min 18 s, 9 s, 1 h 25 min of
wall time, at the step ``dt`` [s]; Table 2's average position RMSE [m] against MATLAB where
the paper gives one)."""

VORTEX_CAPTURE = {
    "duration_s": 120.0,
    "runs": [
        {"bending": False, "dt": "1/60", "wall_s": 540.0, "rmse_pos_avg_m": None},
        {"bending": True, "dt": "1/60", "wall_s": 4800.0, "rmse_pos_avg_m": None},
    ]}
"""The paper's Vortex runs of the 120 s capture (Sec. 5: about 9 min, and 1 h 20 min with
bending, at dt = 1/60 s; accuracy not reported)."""

ERROR_KEYS = ("rmse_pos_max", "rmse_pos_avg", "rmse_vel_max", "rmse_vel_avg")

Measure = Callable[[Recording, Recording], dict]
"""A score of a run against the reference: ``measure(run, reference) -> {name: float}``."""


def rmse_measure(run: Recording, reference: Recording) -> dict:
    """Eq. 14 RMSE of ``run`` against ``reference``: position [m] and velocity [m/s], max and
    average over nodes (keys :data:`ERROR_KEYS`), and the common frame count ``samples``."""
    from ..analysis.metrics import rmse

    r = rmse(run, reference)
    return {k: r[k] for k in (*ERROR_KEYS, "samples")}


def mouth_area_measure(run: Recording, reference: Recording) -> dict:
    """Mouth-area curve of ``run`` against ``reference`` on their common frames: RMS and largest
    difference [m^2] (``mouth_area_rms``, ``mouth_area_max``); an aggregate measure that stays
    meaningful where node-by-node errors do not (chaotic contact)."""
    from ..analysis.metrics import common_times, mouth_area

    ia, ib = common_times(run, reference)
    diff = mouth_area(run)[ia] - mouth_area(reference)[ib]
    return {"mouth_area_rms": float(np.sqrt(np.mean(diff**2))),
            "mouth_area_max": float(np.abs(diff).max())}


def first_contact_measure(run: Recording, reference: Recording) -> dict:
    """|first-contact time of ``run`` - the reference's| [s] (``first_contact_error``; inf if
    only one of them touches the debris)."""
    from ..analysis.metrics import first_contact_time

    a, b = first_contact_time(run), first_contact_time(reference)
    error = math.inf if (a is None) != (b is None) else abs(a - b) if a is not None else 0.0
    return {"first_contact_error": error}


def wrap_measure(run: Recording, reference: Recording) -> dict:
    """Largest and RMS difference of the wrap measure (fraction of directions from the
    debris covered by the net) on the common frames [-] (``wrap_max``, ``wrap_rms``)."""
    from ..analysis.metrics import common_times, wrap

    ia, ib = common_times(run, reference)
    diff = wrap(run)[ia] - wrap(reference)[ib]
    return {"wrap_max": float(np.abs(diff).max()), "wrap_rms": float(np.sqrt(np.mean(diff**2)))}


MEASURES: dict[str, tuple[Measure, dict[str, str]]] = {
    "rmse": (rmse_measure, {"rmse_pos_avg": "average position RMSE (Eq. 14) [m]",
                            "rmse_pos_max": "largest node position RMSE (Eq. 14) [m]",
                            "rmse_vel_avg": "average velocity RMSE (Eq. 14) [m/s]",
                            "rmse_vel_max": "largest node velocity RMSE (Eq. 14) [m/s]"}),
    "mouth_area": (mouth_area_measure, {"mouth_area_rms": "RMS mouth-area difference [m^2]",
                                        "mouth_area_max": "largest mouth-area difference [m^2]"}),
    "first_contact": (first_contact_measure,
                      {"first_contact_error": "first-contact time error [s]"}),
    "wrap": (wrap_measure, {"wrap_max": "largest wrap difference [-]",
                            "wrap_rms": "RMS wrap difference [-]"}),
}
"""Measures by name (``bulletnet bench --measures``): the function and the keys it writes,
each with its axis label and unit."""


@dataclass(frozen=True)
class Method:
    """An engine and its integrator, written ``engine:integrator`` (``reference`` alone)."""

    engine: str
    integrator: str

    @property
    def name(self) -> str:
        return "reference" if self.engine == "reference" else f"{self.engine}:{self.integrator}"

    @property
    def adaptive(self) -> bool:
        """Whether the method picks its own steps (the grid runs it once)."""
        return self.engine == "reference"


def parse_method(text: str) -> Method:
    """``fast:implicit_euler`` (or ``reference``) -> :class:`Method`; a clear error otherwise."""
    engine, _, integrator = text.partition(":")
    if engine == "reference" and not integrator:
        return Method("reference", "symplectic_euler")
    if engine not in ENGINES or integrator not in INTEGRATORS:
        raise ScenarioError(
            f"--methods {text!r}: expected ENGINE:INTEGRATOR with ENGINE one of "
            f"{', '.join(e for e in ENGINES if e != 'reference')} and INTEGRATOR one of "
            f"{', '.join(INTEGRATORS)}, or 'reference'")
    return Method(engine, integrator)


def method_scene(scene: Scenario, method: Method, dt: float | None) -> Scenario:
    """``scene`` run by ``method`` at step ``dt`` [s] (ignored by the adaptive reference)."""
    overrides = {"simulation.engine": method.engine, "simulation.integrator": method.integrator}
    if dt is not None and not method.adaptive:
        overrides["simulation.dt"] = dt
    return scene.with_overrides(overrides)


def timed(scene: Scenario, path, repeats: int = 1):
    """Run ``scene`` into ``path`` ``repeats`` times: (median wall [s], all walls [s], last
    result). A run that diverges raises :class:`DivergenceError` as usual."""
    from ..sim.loop import run

    walls = []
    for _ in range(repeats):
        start = time.perf_counter()
        result = run(scene, path, force=True)
        walls.append(time.perf_counter() - start)
    return statistics.median(walls), walls, result


def reference_run(scene: Scenario, path: Path) -> Recording:
    """The converged reference of ``scene`` (:func:`reference_method`) at ``path``: reused if
    the file there holds exactly this scene at that step, run otherwise."""
    integrator, dt = reference_method(scene)
    fine = scene.with_overrides({"simulation.engine": "fast",
                                 "simulation.integrator": integrator,
                                 "simulation.dt": dt,
                                 **({"bending.every": 1} if scene.bending.enabled else {})})
    if path.exists():
        rec = open_recording(path)
        if rec.status == "completed" and rec.attrs.get("scenario") == to_toml(fine):
            return rec
    timed(fine, path)
    return open_recording(path)


def run_grid(scene: Scenario, methods: Sequence[Method], dts: Sequence[float],
             reference: Recording, workdir: Path, measures: Sequence[Measure] = (rmse_measure,),
             repeats: int = 1, log=None) -> list[dict]:
    """Every method at every step [s] of ``dts`` (an adaptive method once), each scored by
    ``measures`` against ``reference``. One dict a run: method, engine, integrator, dt_s [s]
    (None if adaptive), stable, status, steps, wall_s [s] (median of ``repeats``),
    wall_s_all [s], real_time_factor [-] (simulated over wall time) and the measures (None for
    a diverged run; its ``message`` says why). Recordings go to ``workdir``."""
    from ..sim.loop import warm_up

    workdir.mkdir(parents=True, exist_ok=True)
    rows = []
    for method in methods:
        warm_up(method_scene(scene, method, dts[0]))  # loading kernels is not timed
        for dt in ([None] if method.adaptive else dts):
            rows.append(_grid_point(scene, method, dt, reference, workdir, measures, repeats))
            if log is not None:
                log(_row_text(rows[-1]))
    return rows


def _grid_point(scene, method, dt, reference, workdir, measures, repeats) -> dict:
    """One (method, step) point of the grid: the run ``repeats`` times
    (:func:`~bulletnet.studies.runner.run_scene`), its median wall time, and each of
    ``measures`` of its recording against the reference."""
    from .runner import run_scene

    point = method_scene(scene, method, dt)
    label = "reference" if dt is None else f"{dt:.3g}"
    path = workdir / f"{method.name.replace(':', '_')}_{label}.h5"
    row = {"method": method.name, "engine": method.engine,
           "integrator": None if method.adaptive else method.integrator,
           "dt_s": dt, "simulated_s": point.scene.duration}
    walls = []
    for _ in range(repeats):
        run = run_scene(point, out=path, measures={})
        if run["status"] == "diverged":
            return row | {"stable": False, "status": "diverged", "message": run["message"],
                          "steps": None, "wall_s": None, "wall_s_all": [],
                          "real_time_factor": None}
        if run["status"] != "completed":
            raise ScenarioError(f"{method.name} at {label}: {run['message']}")
        walls.append(run["wall_s"])
    wall = statistics.median(walls)
    row |= {"stable": True, "status": run["status"], "steps": run["steps"],
            "wall_s": wall, "wall_s_all": walls,
            "real_time_factor": point.scene.duration / wall}
    run_rec = open_recording(path)
    for measure in measures:
        row |= measure(run_rec, reference)
    return row


def _row_text(row: dict) -> str:
    dt = "adaptive" if row["dt_s"] is None else f"dt {row['dt_s']:.3g} s"
    if not row["stable"]:
        return f"{row['method']:<24} {dt:<16} diverged"
    err = row.get("rmse_pos_avg")
    err_text = "" if err is None else f"  avg position RMSE {err * 1e3:.4g} mm"
    return f"{row['method']:<24} {dt:<16} {row['wall_s']:8.2f} s wall{err_text}"


def pareto_front(rows: Sequence[dict], error_key: str = "rmse_pos_avg") -> list[dict]:
    """The stable runs no other stable run beats on both wall time and ``error_key``, sorted
    by wall time."""
    points = sorted((r for r in rows if r["stable"] and r.get(error_key) is not None),
                    key=lambda r: (r["wall_s"], r[error_key]))
    front, best = [], math.inf
    for r in points:
        if r[error_key] < best:
            front.append(r)
            best = r[error_key]
    return front


def plot_bench(doc: dict, path: Path) -> Path:
    """Wall time [s] against the document's ``error_key``, log-log: a line per method labelled
    with its steps, the Pareto front, and the paper's Vortex runs (scaled to the benchmark's
    duration) for scale, at their error where it is known and on that key. Returns ``path``."""
    from ..analysis.plots import _pyplot

    error_key = doc["error_key"]
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7.5, 5.2))
    rows = doc["runs"]
    for name in dict.fromkeys(r["method"] for r in rows):
        mine = [r for r in rows if r["method"] == name]
        ok = sorted((r for r in mine if r["stable"]), key=lambda r: r["dt_s"] or 0)
        bad = [r["dt_s"] for r in mine if not r["stable"]]
        label = name + (f" (diverged at dt >= {min(bad):.2g} s)" if bad else "")
        line, = ax.plot([r[error_key] for r in ok], [r["wall_s"] for r in ok], "o-",
                        label=label)
        for r in ok:
            if r["dt_s"] is not None:
                ax.annotate(f"{r['dt_s']:.2g}", (r[error_key], r["wall_s"]), fontsize=7,
                            xytext=(4, 3), textcoords="offset points", color=line.get_color())
    front = doc["pareto_front"]
    ax.plot([r[error_key] for r in front], [r["wall_s"] for r in front], "s", ms=11,
            mfc="none", mec="black", label="Pareto front")
    vortex = doc["vortex_paper"]
    scale = doc["simulated_s"] / vortex["duration_s"]
    for run in vortex["runs"]:
        if run["bending"] != doc["bending"]:
            continue
        label = f"Vortex (paper), dt {run['dt']} s"
        if run["rmse_pos_avg_m"] is None or error_key != "rmse_pos_avg":
            ax.axhline(run["wall_s"] * scale, color="gray", ls="--", lw=1,
                       label=label + ": error not reported")
        else:
            ax.plot([run["rmse_pos_avg_m"]], [run["wall_s"] * scale], "*", ms=14, color="k",
                    label=label + " (error against MATLAB)")
    ax.set_xscale("log")
    ax.set_yscale("log")
    labels = {k: v for _, keys in MEASURES.values() for k, v in keys.items()}
    ax.set_xlabel(labels.get(error_key, error_key) + " against the reference")
    ax.set_ylabel("wall time [s]")
    bending = "with" if doc["bending"] else "without"
    ax.set_title(f"{doc['scene']}, {doc['simulated_s']:g} s simulated, {bending} bending"
                 + (f" (Vortex times x {scale:.2g})" if scale != 1 else ""), fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, loc="best")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def is_stable(scenario: Scenario, dt: float, horizon: float) -> bool:
    """Whether ``scenario`` runs ``horizon`` seconds at step ``dt`` [s] without the run's own
    :class:`DivergenceError` (non-finite state or runaway node speed)."""
    from ..sim.loop import run

    scene = scenario.with_overrides({"simulation.dt": dt, "scene.duration": horizon,
                                     "simulation.record_rate": min(
                                         scenario.simulation.record_rate, 1.0 / dt)})
    try:
        run(scene)
    except DivergenceError:
        return False
    return True


def largest_stable_step(scenario: Scenario, horizon: float, low: float, high: float,
                        rel_tol: float = 0.02) -> dict:
    """Bisect (geometrically) for the largest stable step [s] between ``low`` and ``high``.

    Returns ``{"dt_stable_s", "dt_unstable_s", "runs"}``: the largest step found stable and the
    smallest found unstable (``None`` if ``high`` itself is stable, or ``low`` is not), to
    ``rel_tol`` of each other."""
    runs = 0
    if is_stable(scenario, high, horizon):
        return {"dt_stable_s": high, "dt_unstable_s": None, "runs": 1}
    runs += 1
    if not is_stable(scenario, low, horizon):
        return {"dt_stable_s": None, "dt_unstable_s": low, "runs": runs + 1}
    runs += 1
    while high / low > 1.0 + rel_tol:
        mid = math.sqrt(low * high)
        runs += 1
        if is_stable(scenario, mid, horizon):
            low = mid
        else:
            high = mid
    return {"dt_stable_s": low, "dt_unstable_s": high, "runs": runs}


def stability_table(scene: Scenario, methods: Sequence[Method], horizon: float,
                    rel_tol: float = 0.03, log=None) -> list[dict]:
    """Per fixed-step method: the analytical limits of the scene's net and the largest stable
    step found by bisection over ``horizon`` [s] (from half to 8 times the method's limit; a
    method without one from the explicit limit up to 100 times the stiffness limit), at most
    a tenth of the horizon. Steps in [s], rates in [1/s], frequencies in [rad/s]."""
    from ..analysis.stability import scene_limits

    limits = scene_limits(scene)
    rows = []
    for method in methods:
        if method.adaptive:
            continue
        analytical = limits.for_integrator(method.integrator)
        if math.isfinite(analytical):
            low, high = 0.5 * analytical, 8.0 * analytical
        else:
            low, high = limits.explicit_limit, 100.0 * limits.stiffness_limit
        high = min(high, horizon / 10)
        found = largest_stable_step(method_scene(scene, method, None), horizon, low, high,
                                    rel_tol)
        row = {"method": method.name, "horizon_s": horizon,
               "analytical_limit_s": analytical if math.isfinite(analytical) else None,
               "stiffness_limit_s": limits.stiffness_limit,
               "damping_limit_s": limits.damping_limit,
               "bending_limit_s": (limits.bending_limit if math.isfinite(limits.bending_limit)
                                   else None),
               "omega_max_rad_per_s": limits.omega_max, "gamma_max_per_s": limits.gamma_max,
               "searched_s": [low, high], **found}
        row["measured_over_analytical"] = (
            found["dt_stable_s"] / analytical
            if found["dt_stable_s"] is not None and math.isfinite(analytical) else None)
        rows.append(row)
        if log is not None:
            log(stability_text(row))
    return rows


def stability_text(row: dict) -> str:
    """One line of the stability table."""
    def s(v):
        return "none" if v is None else f"{v:.3g} s"

    stable = s(row["dt_stable_s"]) + (" (top of the search)" if row["dt_unstable_s"] is None
                                      else f" (diverges at {row['dt_unstable_s']:.3g} s)")
    bending = (f", bending {s(row['bending_limit_s'])}" if row["bending_limit_s"] is not None
               else "")
    return (f"{row['method']:<24} analytical {s(row['analytical_limit_s']):<10} "
            f"(2/omega_max {s(row['stiffness_limit_s'])}, 2/gamma_max "
            f"{s(row['damping_limit_s'])}{bending})  largest stable over {row['horizon_s']:g} s: "
            f"{stable}")


def bench(scene: Scenario, methods: Sequence[Method], dts: Sequence[float], out: Path,
          measures: Sequence[Measure] = (rmse_measure,), repeats: int = 1,
          stability_horizon: float | None = None, error_key: str = "rmse_pos_avg",
          log=None) -> dict:
    """The whole benchmark of ``scene``: reference, grid, Pareto front on wall time and
    ``error_key`` (a key the measures write), stability table (if ``stability_horizon`` [s]
    is given); writes ``OUT/bench_NAME.json`` and
    ``OUT/bench_NAME.png`` (NAME the scene's name, ``_bending`` appended with bending) and
    returns the document."""
    import json
    import platform

    from .. import __version__

    log = log or (lambda text: print(text, file=sys.stderr))
    stem = f"bench_{scene.scene.name}" + ("_bending" if scene.bending.enabled else "")
    runs_dir = out / f"{stem}_runs"
    runs_dir.mkdir(parents=True, exist_ok=True)
    integrator, reference_dt = reference_method(scene)
    log(f"reference: {integrator} at {reference_dt:g} s ...")
    start = time.perf_counter()
    reference = reference_run(scene, runs_dir / "reference.h5")
    log(f"reference ready ({time.perf_counter() - start:.1f} s)")
    rows = run_grid(scene, methods, dts, reference, runs_dir, measures, repeats, log)
    doc = {"scene": scene.scene.name, "bending": scene.bending.enabled,
           "simulated_s": scene.scene.duration, "nodes_per_side": scene.net.nodes_per_side,
           "reference": {"engine": "fast", "integrator": integrator,
                         "dt_s": reference_dt, "bending_every": 1 if scene.bending.enabled
                         else None},
           "repeats": repeats, "machine": platform.machine(), "cpus": _cpus(),
           "bulletnet_version": __version__, "runs": rows,
           "units": {"dt_s": "s", "wall_s": "s", "rmse_pos_max": "m", "rmse_pos_avg": "m",
                     "rmse_vel_max": "m/s", "rmse_vel_avg": "m/s", "mouth_area_rms": "m^2",
                     "mouth_area_max": "m^2", "real_time_factor": "-",
                     "first_contact_error": "s", "wrap_max": "-", "wrap_rms": "-"},
           "vortex_paper": VORTEX_CAPTURE if scene.contact.enabled else VORTEX_DEPLOYMENT}
    doc["error_key"] = error_key
    doc["pareto_front"] = pareto_front(rows, error_key)
    if stability_horizon is not None:
        doc["stability"] = stability_table(scene, methods, stability_horizon, log=log)
    (out / f"{stem}.json").write_text(json.dumps(doc, indent=2))
    plot_bench(doc, out / f"{stem}.png")
    return doc


def _cpus() -> int:
    import os

    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
