"""Strength benchmark: the least safety factor, where and when, of the paper's deployment and
capture and of the closing capture, without and with bending.

The least safety factor (breaking tension over the largest tension of any thread or cable)
and the largest snap load of each run, at the scene's own record rate: every frame carries
each element's largest tension of every step since the frame before
(``/threads/peak_tension``), so the margins see every step whatever the rate (this model's
snap loads last microseconds: docs/strength.md).

Each run is recorded to OUT, measured (:func:`bulletnet.analysis.metrics.strength_summary`)
and deleted. Writes OUT/strength.json (copy it to benchmarks/results/) and
docs/figures/strength.png (``bulletnet plot``'s figure of the deployment without and with
bending).
Then the capture's first 9 s at steps from 1e-3 to 6.25e-5 s (``--convergence``: only these),
at the CG tolerance :data:`CONVERGENCE_TOLERANCE`: how its least safety factor, set by snaps
shorter than its step, depends on the step.
Usage: python benchmarks/strength.py [OUT] [--only NAME ...] [--convergence]
"""

from __future__ import annotations

import json
import shutil
import tempfile
import time
from pathlib import Path

from common import output_dir, parser

import bulletnet as bn
from bulletnet.analysis.plots import plot_recordings

FIGURE = Path(__file__).resolve().parent.parent / "docs" / "figures" / "strength.png"
CASES = [("deployment", 100.0, None), ("capture", 10.0, None), ("capture_closing", 10.0, None)]
"""(scene, record rate [Hz], duration [s] or None: the scene's own), each run without and
with bending, at the scene's own record rate."""
FIGURE_RATE = 100.0
"""Record rate of the deployments drawn in the figure [Hz]."""
CONVERGENCE_STEPS = [1e-3, 5e-4, 2.5e-4, 1.25e-4, 6.25e-5]
"""Steps [s] of the capture's first 9 s (its least safety factor comes before contact, in
the unfolding's snaps), without and with bending: how the snaps' peaks depend on the step."""
CONVERGENCE_DURATION = 9.0
"""[s]: past the capture's least factors (4-8 s), before its first contact (9.1-10.1 s)."""
CONVERGENCE_TOLERANCE = 1e-6
"""The CG tolerance [-] of the step convergence's runs: two orders below the scene's, so that
the step's error is what changes (a tolerance relative to each step's right-hand side adds
its error once a step: at finer steps the scene's would add more)."""


def measure(path: Path, wall: float) -> dict:
    """The run's margins (JSON-ready, without the per-frame series) and its wall time [s]."""
    rec = bn.open_recording(path)
    doc = bn.metrics.strength_summary(rec)
    doc.pop("max_utilisation")
    return {"frames": int(rec.time.size), "wall_s": wall, **doc}


def step_convergence(out: Path) -> list[dict]:
    """The capture's least safety factor over its first :data:`CONVERGENCE_DURATION` at each
    of :data:`CONVERGENCE_STEPS`, without and with bending, at :data:`CONVERGENCE_TOLERANCE`:
    step [s], factor, where, when [s], the tension [N], wall [s]."""
    rows = []
    for bending in (False, True):
        for dt in CONVERGENCE_STEPS:
            path = out / "convergence.h5"
            start = time.perf_counter()
            bn.run(bn.load_scenario("capture", {"bending.enabled": bending,
                                                "scene.duration": CONVERGENCE_DURATION,
                                                "simulation.dt": dt,
                                                "simulation.cg_tolerance":
                                                    CONVERGENCE_TOLERANCE}), path, force=True)
            least = measure(path, time.perf_counter() - start)
            path.unlink()
            rows.append({"bending": bending, "dt_s": dt, "cg_tolerance": CONVERGENCE_TOLERANCE,
                         "least_safety_factor": least["least_safety_factor"],
                         "element": least["element"], "time_s": least["time_s"],
                         "tension_N": least["tension_N"], "wall_s": least["wall_s"]})
            print(f"bending {bending}, dt {dt:g} s: least safety factor "
                  f"{least['least_safety_factor']:.4g} ({least['element']['kind']} "
                  f"{least['element']['index']} at {least['time_s']:.4f} s)", flush=True)
    return rows


def main() -> None:
    p = parser(__doc__)
    p.add_argument("--only", nargs="+", metavar="NAME", help="run these cases only (e.g. "
                   "capture_plain_2000Hz_15s) and update them in an existing strength.json")
    p.add_argument("--convergence", action="store_true", help="run only the capture's step "
                   "convergence and update it in an existing strength.json")
    args = p.parse_args()
    out = output_dir(args)
    table = out / "strength.json"
    doc = (json.loads(table.read_text()) if (args.only or args.convergence) and table.exists()
           else {"bulletnet_version": bn.__version__, "runs": {}})
    if args.convergence:
        doc["capture_step_convergence"] = step_convergence(out)
        table.write_text(json.dumps(doc, indent=1))
        print(f"wrote {table}")
        return
    figure = {}
    for scene, rate, duration in CASES:
        for bending in (False, True):
            name = (f"{scene}_{'bending' if bending else 'plain'}_{rate:g}Hz"
                    + (f"_{duration:g}s" if duration else ""))
            if args.only and name not in args.only:
                continue
            path = out / f"{name}.h5"
            start = time.perf_counter()
            overrides = {"bending.enabled": bending, "simulation.record_rate": rate}
            if duration:
                overrides["scene.duration"] = duration
            bn.run(bn.load_scenario(scene, overrides), path, force=True)
            doc["runs"][name] = {"scene": scene, "bending": bending, "record_rate_Hz": rate,
                                 "duration_s": duration,
                                 **measure(path, time.perf_counter() - start)}
            run = doc["runs"][name]
            print(f"{name}: least safety factor {run['least_safety_factor']:.4g} "
                  f"({run['element']['kind']} {run['element']['index']} at "
                  f"{run['time_s']:.4f} s), {run['wall_s']:.0f} s wall", flush=True)
            if scene == "deployment" and rate == FIGURE_RATE:
                figure[bending] = path
            else:
                path.unlink()
            table.write_text(json.dumps(doc, indent=1))
    if len(figure) == 2:
        with tempfile.TemporaryDirectory() as tmp:
            plot_recordings(bn.open_recording(figure[False]), bn.open_recording(figure[True]),
                            tmp)
            shutil.copy(Path(tmp) / "strength.png", FIGURE)
        print(f"wrote {FIGURE}")
    if not args.only:
        doc["capture_step_convergence"] = step_convergence(out)
        table.write_text(json.dumps(doc, indent=1))
    print(f"wrote {table}")


if __name__ == "__main__":
    main()
