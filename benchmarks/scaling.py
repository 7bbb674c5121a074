"""Scaling benchmark (issue 5): wall time per simulated second against the net size.

The deployment (fast engine, symplectic Euler at its default step, no recording) for
Ns = 11, 21, 41, 81 (N = Ns^2 + 4 nodes), every size over the same first HORIZON seconds (the
same phase of the deployment: the net unfolding, its threads mostly slack); the wall time is
the run's integration loop (``RunResult.wall_time_s``), median of REPEATS runs, with and
without bending. Fits the slope of log(wall per simulated second) against log(N): 1 is linear
growth. Writes OUT/scaling.json and OUT/scaling.png.

Usage: python benchmarks/scaling.py [OUT] [--repeats N] [--horizon S]
"""

from __future__ import annotations

import json
import statistics

import numpy as np
from common import Yardsticks, machine, output_dir, parser

import bulletnet as bn
from bulletnet.analysis.plots import _pyplot

SIZES = (11, 21, 41, 81)


def main() -> None:
    p = parser(__doc__)
    p.add_argument("--horizon", type=float, default=0.05, help="simulated time [s]")
    args = p.parse_args()
    out = output_dir(args)
    doc = {"scene": "deployment", "machine": machine(), "repeats": args.repeats,
           "units": {"duration_s": "s", "wall_s": "s", "wall_per_simulated_s": "s/s"},
           "series": {}}
    yard = Yardsticks()
    for bending in (False, True):
        yard.time()
        rows = []
        for ns in SIZES:
            duration = args.horizon
            scene = bn.load_scenario("deployment", {"net.nodes_per_side": ns,
                                                    "scene.duration": duration,
                                                    "bending.enabled": bending})
            bn.run(scene.with_overrides({"scene.duration": 0.01 * duration}))  # warm
            results = [bn.run(scene) for _ in range(args.repeats)]
            walls = [r.wall_time_s for r in results]
            wall, result = statistics.median(walls), results[-1]
            rows.append({"nodes_per_side": ns, "nodes": ns * ns + 4, "duration_s": duration,
                         "steps": result.stats["steps"], "wall_s": wall, "wall_s_all": walls,
                         "wall_per_simulated_s": wall / duration,
                         "x_bound": wall / yard.bound_s(result.stats["steps"],
                                                        2 * ns * (ns - 1) + 4)})
            print(rows[-1], flush=True)
        n = np.array([r["nodes"] for r in rows], float)
        cost = np.array([r["wall_per_simulated_s"] for r in rows])
        slope, _ = np.polyfit(np.log(n), np.log(cost), 1)
        doc["series"]["bending" if bending else "plain"] = {"runs": rows,
                                                            "log_log_slope": float(slope)}
    yard.time()
    doc["yardsticks"] = yard.doc()
    (out / "scaling.json").write_text(json.dumps(doc, indent=2))
    plot(doc, out / "scaling.png")
    print(json.dumps({k: v["log_log_slope"] for k, v in doc["series"].items()}))


def plot(doc: dict, path) -> None:
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6, 4.5))
    for name, series in doc["series"].items():
        n = np.array([r["nodes"] for r in series["runs"]], float)
        cost = np.array([r["wall_per_simulated_s"] for r in series["runs"]])
        line, = ax.loglog(n, cost, "o", label=f"{name} (slope {series['log_log_slope']:.2f})")
        fit = np.polyfit(np.log(n), np.log(cost), 1)
        ax.loglog(n, np.exp(np.polyval(fit, np.log(n))), "-", color=line.get_color())
    n0 = doc["series"]["plain"]["runs"][0]
    ref = np.array([n0["nodes"], doc["series"]["plain"]["runs"][-1]["nodes"]], float)
    ax.loglog(ref, n0["wall_per_simulated_s"] * ref / ref[0], "k:", label="linear in N")
    ax.xaxis.set_minor_formatter(plt.NullFormatter())
    ax.set_xlabel("nodes N = Ns^2 + 4 [-]")
    ax.set_ylabel("wall time per simulated second [s/s]")
    ax.set_title("deployment, fast engine, symplectic Euler 1e-6 s", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


if __name__ == "__main__":
    main()
