"""Sweep benchmark (issue 5): the 16 variants of scenarios/sweep_example.toml on a local Dask
cluster of WORKERS processes against the same variants one after another in one process,
REPEATS interleaved pairs in the same run (median speed-up reported). Both warm their
compiled kernels first (not in any variant's wall time); the Dask time is reported with and
without starting the cluster. Writes OUT/sweep_speedup.json.

Usage: python benchmarks/sweep_speedup.py [OUT] [--workers N] [--repeats N]
"""

from __future__ import annotations

import json
import os
import statistics
import time

from common import Yardsticks, output_dir, parser

from bulletnet.model.scenario import SCENARIO_DIR
from bulletnet.studies.runner import dask_client
from bulletnet.studies.sweep import load_sweep, run_sweep


def one_pair(spec, out, workers: int) -> dict:
    """One run one after another, then one on a fresh local cluster: timings and diagnostics."""
    load_before = os.getloadavg()
    start = time.perf_counter()
    serial = run_sweep(spec, out / "serial", serial=True)
    serial_s = time.perf_counter() - start
    start = time.perf_counter()
    with dask_client(None, workers) as client:
        ready = time.perf_counter()
        parallel = run_sweep(spec, out / "dask", scheduler=client.scheduler.address)
    done = time.perf_counter()
    return {
        "serial_s": serial_s, "dask_s": done - ready, "dask_with_cluster_start_s": done - start,
        "speedup": serial_s / (done - ready),
        "speedup_with_cluster_start": serial_s / (done - start),
        # how busy the workers were (sum of variant walls over the sweep's wall), and how much
        # slower each variant ran beside the others than alone
        "worker_parallelism": sum(r["wall_s"] for r in parallel) / (done - ready),
        "variant_slowdown_under_dask": (sum(r["wall_s"] for r in parallel)
                                        / sum(r["wall_s"] for r in serial)),
        "load_average_before_after": [load_before, os.getloadavg()],
        "statuses": sorted({r["status"] for r in serial + parallel}),
        "same_measures": all(a["final_mouth_area_m2"] == b["final_mouth_area_m2"]
                             for a, b in zip(serial, parallel, strict=True)),
    }


def main() -> None:
    p = parser(__doc__)
    p.add_argument("--workers", type=int, default=2)
    args = p.parse_args()
    out = output_dir(args)
    spec = load_sweep(SCENARIO_DIR / "sweep_example.toml")
    pairs = []
    yard = Yardsticks()
    for _ in range(args.repeats):
        yard.time()
        pairs.append(one_pair(spec, out, args.workers))
        print(json.dumps(pairs[-1]), flush=True)
    doc = {"variants": len(spec.variants), "workers": args.workers, "cpus": os.cpu_count(),
           "repeats": args.repeats,
           **{f"{k}_median": statistics.median(pair[k] for pair in pairs)
              for k in ("serial_s", "dask_s", "speedup", "speedup_with_cluster_start",
                        "worker_parallelism", "variant_slowdown_under_dask")},
           "pairs": pairs, "yardsticks": yard.doc()}
    doc["serial_s_x_yardstick"] = doc["serial_s_median"] / yard.median
    (out / "sweep_speedup.json").write_text(json.dumps(doc, indent=2))
    print(json.dumps({k: v for k, v in doc.items() if k != "pairs"}, indent=2))


if __name__ == "__main__":
    main()
