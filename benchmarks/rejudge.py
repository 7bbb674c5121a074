"""Run the escaped runs of an optimisation's run tables again and rewrite their rows, after a
change to how a run's outcome or leave time is judged.

The judge's two changes of 2026-12-06 can move only an escaped run: an escape is no longer
decided while the debris floats inside a closed net (the hold goes on), and a leave time
ending exactly the quiet time before the run's end counts to the frame times' round-off. Each
escaped row of ``runs.csv`` and of every ``confirm_NNNN.csv`` in the folder is run again from
its own inputs (the table's columns, at full precision) with the optimisation's fixed
settings; every measure the changes do not touch must come out the same (first contact, wrap,
nodes in contact, energy gain, margins, overloads), or the script stops and says which. The
outcome and the leave time are rewritten, and the wall time where the outcome moved (a run
whose outcome stands took the same steps: its wall time is the table's own); the rest of the
table is left as it is. The optimisation's scores are not recomputed: the script prints the
runs whose outcome moved, and the designs they belong to.

    python benchmarks/rejudge.py scenarios/optimize_capture.toml \
        benchmarks/results/capture_optimisation [--workers 2]
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

from bulletnet.studies.optimize import load_optimisation
from bulletnet.studies.runner import fan_out
from bulletnet.studies.study import _cell, parse_cell, study_run

REWRITTEN = ("outcome", "leave_s", "message")
"""The cells a re-run rewrites (and ``wall_s`` where the outcome moved); every other measure
must come out as the table has it."""


def rejudge(opt, table: Path, workers: int) -> list[dict]:
    """Run the escaped rows of ``table`` again and rewrite it; return the rows whose
    outcome or leave time moved (run, design, old and new)."""
    with table.open(newline="", encoding="utf-8") as f:
        reader = csv.DictReader(f)
        header, rows = reader.fieldnames, list(reader)
    columns = opt.columns  # input key -> its column
    jobs = [(int(r["run"]), opt.scene, opt.function, opt.fixed,
             {key: parse_cell(r[col]) for key, col in columns.items()}, opt.measures, None)
            for r in rows if r["outcome"] == "escaped"]
    by_run = {int(r["run"]): r for r in rows}
    moved = []

    def lost(job, message):
        raise SystemExit(f"rejudge: run {job[0]} lost: {message}")

    for result in fan_out(study_run, jobs, lost, workers=workers, serial=workers == 0,
                          warm=(opt.scene, (opt.fixed,))):
        row = by_run[result["run"]]
        differs = [k for k in opt.measures if k not in REWRITTEN and row[k] != _cell(result[k])]
        if result["status"] != row["status"] or differs:
            raise SystemExit(f"rejudge: {table.name} run {row['run']}: {differs or 'status'} "
                             "came out otherwise: not a change of the judge alone")
        old = (row["outcome"], row["leave_s"])
        if result["outcome"] != old[0]:
            row["wall_s"] = _cell(result["wall_s"])
        for key in REWRITTEN:
            row[key] = _cell(result[key])
        if (row["outcome"], parse_cell(row["leave_s"])) != (old[0], parse_cell(old[1])):
            moved.append({"table": table.name, "run": row["run"], "design": row.get("design"),
                          "was": old, "now": (row["outcome"], row["leave_s"])})
    with table.open("w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, header)
        writer.writeheader()
        writer.writerows(rows)
    print(f"rejudge: {table.name}: {len(jobs)} escaped runs run again, {len(moved)} moved",
          file=sys.stderr)
    return moved


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("file", help="the optimisation's TOML")
    p.add_argument("folder", help="its results folder (runs.csv, confirm_NNNN.csv)")
    p.add_argument("--workers", type=int, default=2, help="Dask workers (0: in this process)")
    args = p.parse_args()
    opt = load_optimisation(args.file)
    folder = Path(args.folder)
    tables = [folder / "runs.csv", *sorted(folder.glob("confirm_*.csv"))]
    moved = [m for t in tables for m in rejudge(opt, t, args.workers)]
    for m in moved:
        print(f"{m['table']} run {m['run']} (design {m['design']}): outcome, leave_s "
              f"{m['was']} -> {m['now']}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
