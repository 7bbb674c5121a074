"""First run after an install: what a new user waits for, from an empty kernel cache.

Each repeat empties a numba cache folder and runs, as separate processes, in order:

1. ``bulletnet run deployment`` -- the README's first command (compiles the free net's
   kernels, then the 3 s deployment);
2. ``bulletnet run capture --duration 1`` -- adds contact and implicit Euler;
3. ``bulletnet run capture_closing --bending --duration 1`` -- adds bending and the cables;
4. ``bulletnet run deployment`` again -- the warm start.

It reports each command's whole wall time (imports, model, compilation, run, recording) and
the compile time the command itself prints (the package's bytecode cached as a user's
interpreter caches it: :func:`common.user_env`), medians over the repeats, to
``OUT/first_run.json``, with the frozen yardstick (``yardstick.py``) timed at the start of
each repeat, so that the warm run can be read as a ratio to it. Run it on an otherwise
idle machine:

    python benchmarks/first_run.py benchmarks/results --repeats 3
"""

from __future__ import annotations

import json
import platform
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yardstick
from common import machine, output_dir, parser, user_env

STEPS = {
    "deployment (first)": ["run", "deployment"],
    "capture --duration 1": ["run", "capture", "--duration", "1"],
    "capture_closing --bending --duration 1": ["run", "capture_closing", "--bending",
                                               "--duration", "1"],
    "deployment (warm)": ["run", "deployment"],
}
"""Label -> the command's arguments after ``bulletnet``, in the order they run."""
COMPILED = re.compile(r"first run: ([0-9.]+) s compiling kernels")


def timed_command(args: list[str], cwd: Path, cache: Path) -> tuple[float, float]:
    """(wall time [s], compile time the command printed [s], 0 if none) of ``bulletnet
    ARGS`` run as a process with the numba cache in ``cache``."""
    env = user_env(NUMBA_CACHE_DIR=str(cache))
    start = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "bulletnet.cli.main", *args, "--force",
                           "--out", "run.h5"], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=3600)
    wall = time.perf_counter() - start
    if proc.returncode != 0:
        raise SystemExit(f"first_run: bulletnet {' '.join(args)} failed: {proc.stderr.strip()}")
    found = COMPILED.search(proc.stdout)
    return wall, float(found.group(1)) if found else 0.0


def main() -> int:
    args = parser(__doc__.split("\n\n")[0]).parse_args()
    out = output_dir(args)
    runs: dict[str, list[dict]] = {label: [] for label in STEPS}
    yard = []
    for repeat in range(args.repeats):
        yard.append(yardstick.run()[0])
        print(f"repeat {repeat + 1}: yardstick {yard[-1]:.2f} s", flush=True)
        with tempfile.TemporaryDirectory() as tmp:
            cache = Path(tmp) / "numba"
            for label, command in STEPS.items():
                wall, compiled = timed_command(command, Path(tmp), cache)
                runs[label].append({"wall_s": wall, "compile_s": compiled})
                print(f"repeat {repeat + 1}: {label}: {wall:.1f} s wall, "
                      f"{compiled:.1f} s compiling", flush=True)
    summary = {label: {"wall_s_median": statistics.median(r["wall_s"] for r in rows),
                       "compile_s_median": statistics.median(r["compile_s"] for r in rows),
                       "repeats": rows} for label, rows in runs.items()}
    result = {"what": "bulletnet commands as processes from an empty numba cache, in order",
              "date": time.strftime("%Y-%m-%d"), "machine": {
                  **machine(), "python": platform.python_version()},
              "yardstick": {"sha256": yardstick.file_hash(), "walls_s": yard,
                            "median_s": statistics.median(yard)},
              "steps": summary}
    path = out / "first_run.json"
    path.write_text(json.dumps(result, indent=1) + "\n")
    for label, row in summary.items():
        print(f"{label:<40} {row['wall_s_median']:6.1f} s wall, "
              f"{row['compile_s_median']:5.1f} s compiling (median of {args.repeats})")
    print(f"-> {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
