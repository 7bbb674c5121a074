"""Capture benchmark (Sec. 5, Figs. 10-11): the spinning Apollo CSM, 120 s, on ``fast``.

1. The paper's capture with and without bending, for each normal contact law (``exact``:
   Eq. 6 followed through every impact; ``implicit``: backward Euler, as constraint
   solvers do; the scene's default): wall time, first-contact time, wrap, leave time, the
   debris' spin change, and the largest rise of the mechanical energy above its start (a
   sound run has none). The figures of the implicit runs (``bulletnet plot``, Fig. 11
   snapshots) go to OUT/figures/.
2. Step convergence of the aggregate measures (the capture is chaotic: positions are not
   comparable over 120 s): the first 20 s at dt = 1e-3 ... 1.25e-4 s, each at the CG
   tolerance :data:`REFERENCE_TOLERANCE` (the step's error alone) and at the scene's,
   against the finest step at :data:`REFERENCE_TOLERANCE` (the reference).
   ``--tolerance`` (only this, into OUT/capture_tolerance.json): the same 20 s at the
   scene's 1e-3 s with the implicit solver's CG tolerance from 1e-6 to 3e-3, without and with
   bending, against the reference of each: what the tolerance adds to the step's error, and
   what it saves (CG iterations a step, loop time).
3. ``fast`` against ``bullet`` (PyBullet does the contact, per-body values fitted to the
   pairs) over the first second of contact, on a head-on variant (debris 5 m away, closing at
   2 m/s, contact at ~1.5 s): Eq. 14 RMSE, first-contact agreement, wrap; wall times.

Writes OUT/capture.json (OUT/capture_tolerance.json with ``--tolerance``).
Usage: python benchmarks/capture.py [OUT] [--skip-convergence | --tolerance]
"""

from __future__ import annotations

import json
import time

import numpy as np
from common import Yardsticks, output_dir, parser

import bulletnet as bn
from bulletnet.analysis.plots import plot_recordings

FIG11_TIMES = [9.0, 14.0, 27.0, 44.0, 82.0]
STEPS = [1e-3, 5e-4, 2.5e-4, 1.25e-4]
"""The convergence's steps [s], the last the reference's."""
REFERENCE_TOLERANCE = 1e-6
"""The CG tolerance [-] of the reference and of the convergence's own runs: the solver's error
two orders below the scene's, so that what is left is the step's."""
TOLERANCES = [1e-6, 1e-4, 3e-4, 1e-3, 3e-3]
"""The CG tolerances [-] compared at the scene's step."""
HEAD_ON = {"debris.position": [0.0, 0.0, 5.0], "debris.velocity": [0.0, 0.0, -2.0],
           "scene.duration": 2.5, "simulation.record_rate": 20.0}


def run(overrides: dict, path) -> tuple[float, bn.Recording, str]:
    """Run the capture scene with ``overrides``: (wall [s], recording, status)."""
    scene = bn.load_scenario("capture", overrides)
    start = time.perf_counter()
    status = "completed"
    try:
        bn.run(scene, path, force=True)
    except bn.DivergenceError as exc:
        status = f"diverged: {exc}"
    return time.perf_counter() - start, bn.open_recording(path), status


def measures(rec: bn.Recording) -> dict:
    s = bn.metrics.capture_summary(rec)
    return {k: s[k] for k in ("first_contact_s", "first_self_contact_s", "leave_s",
                              "max_nodes_in_contact", "max_wrap", "max_wrap_time_s", "spin",
                              "max_energy_gain_J")}


def against(rec: bn.Recording, ref: bn.Recording) -> dict:
    """The first 20 s's errors of ``rec`` against the reference ``ref``: first contact [s]
    (None if either run has none), the wrap's largest [-] and the mouth area's RMS [m^2] over
    their common frames."""
    n = min(rec.time.size, ref.time.size)
    first, first_ref = bn.metrics.first_contact_time(rec), bn.metrics.first_contact_time(ref)
    return {"first_contact_error_s": (None if first is None or first_ref is None
                                      else first - first_ref),
            "wrap_max_abs_error": float(np.abs(bn.metrics.wrap(rec)[:n]
                                               - bn.metrics.wrap(ref)[:n]).max()),
            "mouth_area_rms_error_m2": float(np.sqrt(np.mean(
                (bn.metrics.mouth_area(rec)[:n] - bn.metrics.mouth_area(ref)[:n]) ** 2)))}


def first_20s(out, dt: float, bending: bool, tolerance: float | None = None,
              reuse: bool = False) -> tuple[float | None, bn.Recording, str]:
    """The capture's first 20 s at step ``dt`` [s], without or with bending, at the CG
    ``tolerance`` [-] (None: the scene's), recorded in OUT (the step convergence's runs and
    the tolerance's references): (wall [s], recording, status); with ``reuse``, a completed
    recording already in OUT is taken (wall None)."""
    path = out / (f"converge_{dt:g}{'_bending' if bending else ''}"
                  f"{'' if tolerance is None else f'_tol{tolerance:g}'}.h5")
    if reuse and path.exists():
        rec = bn.open_recording(path)
        if rec.status == "completed":
            return None, rec, "completed"
    solver = {} if tolerance is None else {"simulation.cg_tolerance": tolerance}
    return run({"scene.duration": 20.0, "simulation.dt": dt, "bending.enabled": bending,
                **solver}, path)


def tolerance(out) -> list[dict]:
    """The first 20 s at the scene's step by CG tolerance, without and with bending (module
    doc, 2.): errors against the reference (:func:`first_20s`), CG iterations a step,
    loop and run wall [s]."""
    rows = []
    for bending in (False, True):
        ref = first_20s(out, STEPS[-1], bending, REFERENCE_TOLERANCE, reuse=True)[1]
        for tol in TOLERANCES:
            wall, rec, status = run({"scene.duration": 20.0, "simulation.cg_tolerance": tol,
                                     "bending.enabled": bending},
                                    out / f"tolerance_{tol:g}_{bending}.h5")
            stats = rec.attrs
            rows.append({"bending": bending, "cg_tolerance": tol, "status": status,
                         "wall_s": wall, "loop_s": float(stats["wall_time_s"]),
                         "cg_iterations_per_step": (float(stats["stats_cg_iterations"])
                                                    / float(stats["stats_steps"])),
                         "first_contact_s": bn.metrics.first_contact_time(rec),
                         **against(rec, ref)})
            print(json.dumps(rows[-1]), flush=True)
    return rows


def main() -> None:
    p = parser(__doc__)
    only = p.add_mutually_exclusive_group()
    only.add_argument("--skip-convergence", action="store_true")
    only.add_argument("--tolerance", action="store_true", help="run only the CG tolerance's "
                      "comparison, into capture_tolerance.json")
    args = p.parse_args()
    out = output_dir(args)
    if args.tolerance:
        table = out / "capture_tolerance.json"
        table.write_text(json.dumps({"bulletnet_version": bn.__version__,
                                     "cg_tolerance_20s": tolerance(out)}, indent=1))
        print(f"wrote {table}")
        return
    doc = {"paper": {"first_contact_s": {"bending": 9.0, "no_bending": 13.0},
                     "gone_by_s": 82.0, "vortex_wall_s": {"bending": 4800.0,
                                                          "no_bending": 540.0}}}

    yard = Yardsticks()  # timed before each capture run and at the end
    runs = {}
    for law in ("exact", "implicit"):
        for bending in (False, True):
            key = f"{law}_{'bending' if bending else 'no_bending'}"
            yard.time()
            wall, rec, status = run({"contact.model": law, "bending.enabled": bending},
                                    out / f"capture_{key}.h5")
            runs[key] = {"wall_s": wall, "status": status,
                         "real_time_factor": rec.time[-1] / wall, **measures(rec)}
            print(key, json.dumps(runs[key]), flush=True)
    for row in runs.values():
        row.update(yard.ratios(row["wall_s"]))
    doc["capture_120s"] = runs
    plot_recordings(bn.open_recording(out / "capture_implicit_no_bending.h5"),
                    bn.open_recording(out / "capture_implicit_bending.h5"), out / "figures",
                    FIG11_TIMES)

    if not args.skip_convergence:
        scene_tolerance = bn.load_scenario("capture").simulation.cg_tolerance
        ref = first_20s(out, STEPS[-1], False, REFERENCE_TOLERANCE)
        conv = []
        for tol in (REFERENCE_TOLERANCE, scene_tolerance):
            for dt in STEPS:
                wall, rec, status = (ref if (dt, tol) == (STEPS[-1], REFERENCE_TOLERANCE)
                                     else first_20s(out, dt, False, tol))
                conv.append({"dt_s": dt, "cg_tolerance": tol, "wall_s": wall,
                             "status": status,
                             "first_contact_s": bn.metrics.first_contact_time(rec),
                             **against(rec, ref[1])})
                print(json.dumps(conv[-1]), flush=True)
        doc["convergence_20s"] = conv

    head_on = {}
    for engine, law in (("fast", "exact"), ("fast", "implicit"), ("bullet", "implicit")):
        wall, rec, status = run({**HEAD_ON, "simulation.engine": engine,
                                 "contact.model": law}, out / f"head_on_{engine}_{law}.h5")
        head_on[f"{engine}_{law}"] = {"wall_s": wall, "status": status,
                                      "first_contact_s": bn.metrics.first_contact_time(rec),
                                      "final_wrap": float(bn.metrics.wrap(rec)[-1])}
    bullet = bn.open_recording(out / "head_on_bullet_implicit.h5")
    for key in ("fast_exact", "fast_implicit"):
        r = bn.metrics.rmse(bn.open_recording(out / f"head_on_{key}.h5"), bullet)
        head_on[key]["against_bullet"] = {k: r[k] for k in (
            "rmse_pos_max", "rmse_pos_avg", "rmse_vel_max", "rmse_vel_avg")}
    doc["head_on_fast_vs_bullet"] = head_on
    print(json.dumps(head_on, indent=1))
    yard.time()
    doc["yardsticks"] = yard.doc()
    (out / "capture.json").write_text(json.dumps(doc, indent=1))


if __name__ == "__main__":
    main()
