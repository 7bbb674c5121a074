"""Grid kernels against the pair-list path (issue: net kernels that use the grid).

This machine's speed drifts by up to ~1.8x between days, so every case is timed interleaved
with the baseline — the pair-list path on the plain 3 s deployment, symplectic Euler at
1e-6 s — and reported as a ratio to it (medians of REPEATS). Accuracy: Eq. 14 average
position RMSE against converged fine-step runs (symplectic Euler at 2.5e-7 s, with and
without bending; cached in OUT). Writes ``OUT/grid.json`` and ``OUT/grid.png``.

Usage: python benchmarks/grid.py [OUT] [--repeats N] [--capture-duration S]
       python benchmarks/grid.py --plot OUT/grid.json   (redraw the chart)
"""

from __future__ import annotations

import json
import platform
import statistics
import sys
import time
from pathlib import Path

from common import errors, output_dir, parser, timed

import bulletnet as bn

CASES = {
    "deployment": {"simulation.integrator": "symplectic_euler", "simulation.dt": 1e-6},
    "deployment_bending_ie_3e-5": {"bending.enabled": True, "simulation.dt": 3e-5,
                                   "simulation.integrator": "implicit_euler"},
    "deployment_bending_ie_4e-5": {"bending.enabled": True, "simulation.dt": 4e-5,
                                   "simulation.integrator": "implicit_euler"},
}
"""The deployment cases: scene overrides of the 3 s deployment."""

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


def sqrt_division_bound(threads: int, repeats: int = 200000) -> float:
    """The machine's throughput bound of a thread's unavoidable arithmetic: one square root
    and one reciprocal per thread, over ``threads`` contiguous values, vectorized as the
    stencils are [ns per thread] (best of 7)."""
    import numba as nb
    import numpy as np

    @nb.njit(error_model="numpy")
    def kernel(x, y, z, out, reps):
        for _ in range(reps):
            for i in range(x.shape[0]):
                length = np.sqrt(x[i] * x[i] + y[i] * y[i] + z[i] * z[i])
                out[i] = 1.0 / length + length

    rng = np.random.default_rng(0)
    x, y, z, out = (rng.random(threads) + 0.5 for _ in range(4))
    kernel(x, y, z, out, 10)
    best = float("inf")
    for _ in range(7):
        start = time.perf_counter()
        kernel(x, y, z, out, repeats)
        best = min(best, (time.perf_counter() - start) / repeats / threads)
    return 1e9 * best


def interleaved(scenes: dict, out, repeats: int) -> dict:
    """Wall times [s] of each named scene, run in turn REPEATS times: name -> list."""
    walls = {name: [] for name in scenes}
    for _ in range(repeats):
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
    doc = {"machine": platform.processor() or platform.machine(),
           "bulletnet_version": bn.__version__, "repeats": args.repeats,
           "baseline": "pair-list path, plain 3 s deployment, symplectic Euler at 1e-6 s",
           "cases": {}}
    references = {False: fine(base, out, False), True: fine(base, out, True)}

    scenes = {"baseline": base.with_overrides({"simulation.kernels": "pairs"})}
    for name, overrides in CASES.items():
        for kernels in ("pairs", "grid"):
            scenes[f"{name}_{kernels}"] = base.with_overrides(
                {**overrides, "simulation.kernels": kernels})
    for scene in scenes.values():  # compile every kernel before timing
        bn.run(scene.with_overrides({"scene.duration": 0.001}), out / "warm.h5", force=True)
    walls = interleaved(scenes, out, args.repeats)
    baseline = statistics.median(walls["baseline"])
    doc["baseline_wall_s"] = baseline
    doc["baseline_wall_s_all"] = walls["baseline"]
    for name, overrides in CASES.items():
        case = {"overrides": overrides}
        for kernels in ("pairs", "grid"):
            key = f"{name}_{kernels}"
            wall = statistics.median(walls[key])
            err = errors(out / f"{key}.h5", references[bool(overrides.get("bending.enabled"))])
            case[kernels] = {"wall_s_median": wall, "wall_s_all": walls[key],
                             "ratio_to_baseline": wall / baseline,
                             "speedup_over_baseline": baseline / wall, **err}
        case["grid_speedup_over_pairs"] = (case["pairs"]["wall_s_median"]
                                           / case["grid"]["wall_s_median"])
        case["same_results"] = case["pairs"]["rmse_pos_avg"] == case["grid"]["rmse_pos_avg"]
        doc["cases"][name] = case
        print(f"{name}: pairs {case['pairs']['wall_s_median']:.2f} s, grid "
              f"{case['grid']['wall_s_median']:.2f} s ({case['grid_speedup_over_pairs']:.2f}x), "
              f"{1e3 * case['grid']['rmse_pos_avg']:.3f} mm; baseline {baseline:.2f} s")

    capture = bn.load_scenario("capture", {"bending.enabled": True,
                                           "scene.duration": args.capture_duration})
    cap = {}
    for kernels in ("pairs", "grid"):
        wall, _, result = timed(capture.with_overrides({"simulation.kernels": kernels}),
                                out / f"capture_{kernels}.h5")
        cap[kernels] = {"wall_s": wall, "steps": result.stats["steps"]}
    cap["grid_speedup_over_pairs"] = cap["pairs"]["wall_s"] / cap["grid"]["wall_s"]
    doc["capture_bending"] = {"duration_s": args.capture_duration, **cap}
    print(f"capture with bending, {args.capture_duration} s: pairs {cap['pairs']['wall_s']:.1f}"
          f" s, grid {cap['grid']['wall_s']:.1f} s")

    scaling = []
    for ns in SCALING_SIDES:
        scene = base.with_overrides({"net.nodes_per_side": ns,
                                     "scene.duration": SCALING_STEPS * 1e-6,
                                     "simulation.record_rate": 1.0 / (SCALING_STEPS * 1e-6)})
        bn.run(scene.with_overrides({"scene.duration": 1e-5}), out / "warm.h5", force=True)
        wall, _, _ = timed(scene, out / "scaling.h5", args.repeats)
        nodes = ns * ns + 4
        scaling.append({"nodes_per_side": ns, "nodes": nodes,
                        "us_per_step": 1e6 * wall / SCALING_STEPS,
                        "ns_per_node_step": 1e9 * wall / SCALING_STEPS / nodes})
        print(f"Ns {ns}: {scaling[-1]['us_per_step']:.2f} us/step, "
              f"{scaling[-1]['ns_per_node_step']:.2f} ns per node-step")
    doc["scaling_symplectic_grid"] = scaling
    threads = 2 * 11 * 10 + 4  # the Ns = 11 net
    bound = sqrt_division_bound(threads)
    doc["sqrt_division_bound"] = {
        "threads": threads, "ns_per_thread": bound,
        "us_per_step": 1e-3 * bound * threads,
        "note": "sqrt + reciprocal per thread, vectorized: the floor of the thread stencils"}
    print(f"sqrt/division bound: {bound:.3f} ns per thread, "
          f"{1e-3 * bound * threads:.3f} us a step of the Ns = 11 net")
    (out / "grid.json").write_text(json.dumps(doc, indent=2))
    plot(doc, out / "grid.png")


def plot(doc: dict, path) -> None:
    """Wall time of each case on both paths, as a ratio to the baseline, and the cost per
    node-step against the node count."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4))
    names = list(doc["cases"])
    for k, kernels in enumerate(("pairs", "grid")):
        a.bar([i + 0.4 * k for i in range(len(names))],
              [doc["cases"][n][kernels]["ratio_to_baseline"] for n in names], 0.4,
              label=kernels)
    a.set_xticks([i + 0.2 for i in range(len(names))],
                 [n.replace("deployment_", "").replace("_", " ") for n in names])
    a.set_ylabel("wall time / baseline [-]")
    a.set_title(f"3 s deployment (baseline {doc['baseline_wall_s']:.2f} s)")
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
