"""The paper's sensitivity study (issue 16): scenarios/study_bending_sensitivity.toml, how much
bending changes the 3 s deployment as Ns, l_mesh, r_net and E vary (Sobol' design, 192
design points of two deployments each), and the study's throughput.

Throughput, in the same run: the first SUBSET design points one after another in this
process, then the same points on a fresh local Dask cluster of WORKERS processes (both warm
their kernels first; runs per hour with and without the cluster's start). Then the whole
study on that cluster into WORK/study, which is resumed if an earlier run of this script
stopped half-way (its runs per hour then count this session's runs only). Writes
OUT/study_bending.json (the report's summary.json, the throughput
and the load average) and OUT/study_bending_runs.csv (the table); the figures are in
WORK/study/figures/.

Usage: python benchmarks/study_bending.py [OUT] [--work DIR] [--workers N] [--subset K]
"""

from __future__ import annotations

import dataclasses
import json
import os
import shutil
import time
from pathlib import Path

from common import Yardsticks, output_dir, parser

from bulletnet.model.scenario import SCENARIO_DIR
from bulletnet.studies.report import report
from bulletnet.studies.runner import dask_client, warm_up
from bulletnet.studies.study import load_study, read_table, run_study


def timed_study(study, out: Path, **kwargs) -> dict:
    """Run ``study`` into a fresh ``out``; wall time [s], runs per hour, and the workers'
    busy time (sum of the runs' wall times [s])."""
    shutil.rmtree(out, ignore_errors=True)
    start = time.perf_counter()
    run_study(study, out, **kwargs)
    wall = time.perf_counter() - start
    rows = read_table(out / "runs.csv")[1]
    busy = sum(r["wall_s"] or 0.0 for r in rows)
    return {"runs": len(rows), "wall_s": wall, "runs_per_hour": 3600 * len(rows) / wall,
            "sum_of_run_walls_s": busy}


def main() -> None:
    p = parser(__doc__)
    p.add_argument("--work", default="benchmarks/out/study_bending", help="study folders")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--subset", type=int, default=16, help="design points of the throughput "
                   "comparison")
    args = p.parse_args()
    out, work = output_dir(args), Path(args.work)
    study = load_study(SCENARIO_DIR / "study_bending_sensitivity.toml")
    subset = dataclasses.replace(study, values=study.values[:args.subset])
    # the run function deploys each net without and with bending: warm both kernels
    first = study.fixed | study.values[0]
    warm = (study.scene, (first, first | {"bending.enabled": True}))
    load = {"before": os.getloadavg()}

    yard = Yardsticks()
    yard.time()
    warm_up(*warm)
    serial = timed_study(subset, work / "serial", serial=True)
    load["after_serial"] = os.getloadavg()
    start = time.perf_counter()
    with dask_client(None, args.workers) as client:
        client.run(warm_up, *warm)
        ready = time.perf_counter() - start
        dask = timed_study(subset, work / "dask", scheduler=client.scheduler.address)
        dask["wall_with_cluster_start_s"] = dask["wall_s"] + ready
        load["after_dask_subset"] = os.getloadavg()
        begin = time.perf_counter()
        done = run_study(study, work / "study", scheduler=client.scheduler.address,
                         log=lambda text: print(text, flush=True))
        whole = {"ran": done["ran"], "skipped": done["skipped"],
                 "wall_s": time.perf_counter() - begin}
        whole["runs_per_hour"] = 3600 * done["ran"] / whole["wall_s"] if done["ran"] else None
    # the table's own record, whatever session ran each row: busy time per design point
    walls = [r["wall_s"] for r in read_table(work / "study" / "runs.csv")[1]]
    whole |= {"rows": len(walls), "sum_of_run_walls_s": sum(walls),
              "mean_run_wall_s": sum(walls) / len(walls)}
    load["after_study"] = os.getloadavg()
    yard.time()
    whole["mean_run_wall_x_yardstick"] = whole["mean_run_wall_s"] / yard.median
    report(work / "study")
    summary = json.loads((work / "study" / "summary.json").read_text())
    doc = {
        "study": "scenarios/study_bending_sensitivity.toml", "cpus": os.cpu_count(),
        "workers": args.workers,
        "throughput": {"design_points": args.subset, "serial": serial, "dask": dask,
                       "speedup": serial["wall_s"] / dask["wall_s"],
                       "speedup_with_cluster_start": serial["wall_s"]
                       / dask["wall_with_cluster_start_s"],
                       "same_measures": _measures(work / "serial")
                       == _measures(work / "dask")},
        "whole_study": whole, "load_average": load, "summary": summary,
        "yardsticks": yard.doc(),
    }
    (out / "study_bending.json").write_text(json.dumps(doc, indent=2) + "\n")
    shutil.copy(work / "study" / "runs.csv", out / "study_bending_runs.csv")
    print(json.dumps({k: v for k, v in doc.items() if k != "summary"}, indent=2))


def _measures(folder: Path) -> list[dict]:
    """The table's rows without the wall time, in run order."""
    rows = sorted(read_table(folder / "runs.csv")[1], key=lambda r: r["run"])
    return [{k: v for k, v in r.items() if k != "wall_s"} for r in rows]


if __name__ == "__main__":
    main()
