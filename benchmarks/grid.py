"""The net's two kernel paths, grid stencils and pair list, against the yardsticks.

This machine's speed drifts by up to ~1.8x between days, so every case is timed interleaved
with the frozen yardstick (``yardstick.py``: a plain compiled loop of the same 3 s deployment,
symplectic Euler at 1e-6 s over a pair list) and reported as the median of its per-repeat
ratios to it, and, for the work of the plain deployment, to the machine's sqrt and division
bound (``common.Yardsticks``). Accuracy: Eq. 14 average position RMSE against converged
fine-step runs (symplectic Euler at 2.5e-7 s, with and without bending; cached in OUT).
Writes ``OUT/grid.json`` and ``OUT/grid.png``.

Usage: python benchmarks/grid.py [OUT] [--repeats N] [--capture-duration S]
       python benchmarks/grid.py --plot OUT/grid.json   (redraw the chart)
"""

from __future__ import annotations

import json
import statistics
import sys
from pathlib import Path

from common import DEPLOYMENT_THREADS, Yardsticks, errors, machine, output_dir, parser, timed

import bulletnet as bn

CASES = {
    "deployment": {"simulation.integrator": "symplectic_euler", "simulation.dt": 1e-6},
    "deployment_bending_ie_3e-5": {"bending.enabled": True, "simulation.dt": 3e-5,
                                   "simulation.integrator": "implicit_euler"},
    "deployment_bending_ie_4e-5": {"bending.enabled": True, "simulation.dt": 4e-5,
                                   "simulation.integrator": "implicit_euler"},
    "deployment_bending_ie_8e-5": {"bending.enabled": True, "simulation.dt": 8e-5,
                                   "simulation.integrator": "implicit_euler"},
}
"""The deployment cases: scene overrides of the 3 s deployment. With bending, implicit Euler's
error against the converged run grows slowly with its step (average RMSE 0.49, 0.67, 0.83,
1.03 mm at 4e-5, 6e-5, 8e-5, 1e-4 s on 2026-12-03): 8e-5 s is the largest of these within
1 mm."""

SCALING_SIDES = (11, 21, 41, 81)
"""Net sizes Ns of the scaling runs (symplectic Euler, 1e-6 s, SCALING_STEPS steps)."""

SCALING_STEPS = 20000


def fine(base, out, bending: bool):
    """The converged reference recording (symplectic Euler at 2.5e-7 s), cached."""
    path = out / ("fine_bending.h5" if bending else "fine.h5")
    if not path.exists():
        timed(base.with_overrides({"simulation.integrator": "symplectic_euler",
                                   "simulation.dt": 2.5e-7, "bending.enabled": bending}), path)
    return bn.open_recording(path)


def compile_first(scene, out, duration: float) -> None:
    """Run ``scene`` for ``duration`` [s] into OUT/warm.h5, so that its kernels are compiled
    before it is timed."""
    bn.run(scene.with_overrides({"scene.duration": duration}), out / "warm.h5", force=True)


def interleaved(scenes: dict, out, repeats: int, yard: Yardsticks) -> dict:
    """Wall times [s] of each named scene, run in turn REPEATS times after the plain loop:
    name -> list."""
    walls = {name: [] for name in scenes}
    for _ in range(repeats):
        yard.time()
        for name, scene in scenes.items():
            wall, _, _ = timed(scene, out / f"{name}.h5")
            walls[name].append(wall)
    return walls


def main() -> None:
    p = parser(__doc__)
    p.add_argument("--capture-duration", type=float, default=20.0,
                   help="simulated time of the capture comparison [s]")
    args = p.parse_args()
    out = output_dir(args)
    base = bn.load_scenario("deployment")
    yard = Yardsticks()
    doc = {"machine": machine(),
           "bulletnet_version": bn.__version__, "repeats": args.repeats, "cases": {}}
    references = {False: fine(base, out, False), True: fine(base, out, True)}

    scenes = {}
    for name, overrides in CASES.items():
        for kernels in ("pairs", "grid"):
            scenes[f"{name}_{kernels}"] = base.with_overrides(
                {**overrides, "simulation.kernels": kernels})
    for scene in scenes.values():  # compile every kernel before timing
        compile_first(scene, out, 0.001)
    walls = interleaved(scenes, out, args.repeats, yard)
    doc["yardsticks"] = yard.doc()
    steps = round(base.scene.duration / 1e-6)  # the plain deployment's steps: the bound's work
    for name, overrides in CASES.items():
        case = {"overrides": overrides}
        for kernels in ("pairs", "grid"):
            key = f"{name}_{kernels}"
            wall = statistics.median(walls[key])
            err = errors(out / f"{key}.h5", references[bool(overrides.get("bending.enabled"))])
            per_repeat = [w / y for w, y in zip(walls[key], yard.walls, strict=True)]
            case[kernels] = {"wall_s_median": wall, "wall_s_all": walls[key],
                             "x_yardstick": statistics.median(per_repeat),
                             "x_yardstick_all": per_repeat, **err}
            if name == "deployment":
                case[kernels]["x_bound"] = wall / yard.bound_s(steps)
        case["grid_speedup_over_pairs"] = (case["pairs"]["wall_s_median"]
                                           / case["grid"]["wall_s_median"])
        case["same_results"] = case["pairs"]["rmse_pos_avg"] == case["grid"]["rmse_pos_avg"]
        doc["cases"][name] = case
        print(f"{name}: pairs {case['pairs']['wall_s_median']:.2f} s "
              f"({case['pairs']['x_yardstick']:.2f}x yardstick), grid "
              f"{case['grid']['wall_s_median']:.2f} s ({case['grid']['x_yardstick']:.2f}x), "
              f"{1e3 * case['grid']['rmse_pos_avg']:.3f} mm; yardstick {yard.median:.2f} s")

    capture = bn.load_scenario("capture", {"bending.enabled": True,
                                           "scene.duration": args.capture_duration})
    cap = {}
    for kernels in ("pairs", "grid"):
        scene = capture.with_overrides({"simulation.kernels": kernels})
        compile_first(scene, out, 0.01)
        wall, _, result = timed(scene, out / f"capture_{kernels}.h5")  # compiled: timed alone
        cap[kernels] = {"wall_s": wall, "steps": result.stats["steps"], **yard.ratios(wall)}
    cap["grid_speedup_over_pairs"] = cap["pairs"]["wall_s"] / cap["grid"]["wall_s"]
    doc["capture_bending"] = {"duration_s": args.capture_duration, **cap}
    print(f"capture with bending, {args.capture_duration} s: pairs {cap['pairs']['wall_s']:.1f}"
          f" s, grid {cap['grid']['wall_s']:.1f} s")

    scaling = []
    for ns in SCALING_SIDES:
        scene = base.with_overrides({"net.nodes_per_side": ns,
                                     "scene.duration": SCALING_STEPS * 1e-6,
                                     "simulation.record_rate": 1.0 / (SCALING_STEPS * 1e-6)})
        compile_first(scene, out, 1e-5)
        wall, _, _ = timed(scene, out / "scaling.h5", args.repeats)
        nodes = ns * ns + 4
        scaling.append({"nodes_per_side": ns, "nodes": nodes,
                        "us_per_step": 1e6 * wall / SCALING_STEPS,
                        "ns_per_node_step": 1e9 * wall / SCALING_STEPS / nodes})
        print(f"Ns {ns}: {scaling[-1]['us_per_step']:.2f} us/step, "
              f"{scaling[-1]['ns_per_node_step']:.2f} ns per node-step")
    doc["scaling_symplectic_grid"] = scaling
    print(f"sqrt/division bound: {yard.bound_ns:.3f} ns per thread, "
          f"{1e-3 * yard.bound_ns * DEPLOYMENT_THREADS:.3f} us a step of the Ns = 11 net")
    (out / "grid.json").write_text(json.dumps(doc, indent=2))
    plot(doc, out / "grid.png")


def plot(doc: dict, path) -> None:
    """Wall time of each case on both paths, as a ratio to the frozen yardstick, and the cost
    per node-step against the node count."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4))
    names = list(doc["cases"])
    for k, kernels in enumerate(("pairs", "grid")):
        a.bar([i + 0.4 * k for i in range(len(names))],
              [doc["cases"][n][kernels]["x_yardstick"] for n in names], 0.4,
              label=kernels)
    a.set_xticks([i + 0.2 for i in range(len(names))],
                 [n.replace("deployment_", "").replace("_", " ") for n in names])
    a.axhline(1.0, color="k", lw=0.8)
    a.set_ylabel("wall time / frozen plain loop [-]")
    a.set_title(f"3 s deployment (plain loop "
                f"{doc['yardsticks']['plain_loop']['median_s']:.2f} s)")
    a.legend()
    rows = doc["scaling_symplectic_grid"]
    b.plot([r["nodes"] for r in rows], [r["ns_per_node_step"] for r in rows], "o-")
    b.set_xscale("log")
    b.minorticks_off()
    b.set_xticks([r["nodes"] for r in rows], [f"{r['nodes']}\n(Ns {r['nodes_per_side']})"
                                               for r in rows])
    b.set_xlabel("nodes N [-]")
    b.set_ylabel("wall per node and step [ns]")
    b.set_title("grid path, symplectic Euler")
    b.set_ylim(bottom=0)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "--plot":  # redraw from a JSON it wrote
        doc_path = Path(sys.argv[2])
        plot(json.loads(doc_path.read_text()), doc_path.with_suffix(".png"))
    else:
        main()
