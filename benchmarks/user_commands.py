"""The README's ``bulletnet run`` lines timed as a user runs them, against the frozen yardstick.

Each run line of the README's command list runs as written (``--force`` added, so repeats
overwrite) as a process, in a folder laid out as a clone's, with the kernels already
compiled (a short run of each line first: compiling is what ``first_run.py`` measures).
Before each command the frozen yardstick (``yardstick.py``: a plain compiled loop of the 3 s
deployment) is timed in this process, so every command's wall time is also given as a ratio
to the yardstick measured beside it. Writes ``OUT/user_commands.json``:

    python benchmarks/user_commands.py benchmarks/results
"""

from __future__ import annotations

import json
import shlex
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import h5py
import yardstick
from common import machine, output_dir, parser

ROOT = Path(__file__).resolve().parent.parent


def readme_run_lines() -> list[list[str]]:
    """The ``bulletnet run`` lines of the README's command list, as argument lists after
    ``bulletnet`` (continuation lines joined, comments dropped)."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    block = text.split("## What you can do", 1)[1].split("```bash\n", 1)[1].split("```", 1)[0]
    lines = [shlex.split(line, comments=True) for line in block.replace("\\\n", " ").splitlines()]
    return [args[1:] for args in lines if args[:2] == ["bulletnet", "run"]]


def run_command(args: list[str], folder: Path) -> float:
    """Wall time [s] of ``bulletnet ARGS --force`` as a process in ``folder``."""
    start = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "bulletnet.cli.main", *args, "--force"],
                          cwd=folder, capture_output=True, text=True, timeout=7200)
    wall = time.perf_counter() - start
    if proc.returncode != 0:
        raise SystemExit(f"user_commands: bulletnet {shlex.join(args)}: {proc.stderr.strip()}")
    return wall


def recording_of(args: list[str], folder: Path) -> Path:
    """The recording a run line (``run SCENE ...``) writes: its ``--out``, else SCENE.h5."""
    if "--out" in args:
        return folder / args[args.index("--out") + 1]
    import bulletnet as bn

    scene = args[1] if not args[1].endswith(".toml") else str(folder / args[1])
    return folder / f"{bn.load_scenario(scene).scene.name}.h5"


def main() -> int:
    args = parser(__doc__.split("\n\n")[0]).parse_args()
    out = output_dir(args)
    lines = readme_run_lines()
    rows = []
    yard = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        (folder / "assets").symlink_to(ROOT / "assets")
        shutil.copytree(ROOT / "scenarios", folder / "scenarios")
        subprocess.run([sys.executable, "-m", "bulletnet.cli.main", "scene", "capture"], check=True,
                       stdout=(folder / "mine.toml").open("w"))
        for line in lines:  # compile every line's kernels first
            run_command([*line, "--duration", "0.01", "--quiet"], folder)
        for line in lines:
            wall_yard, _ = yardstick.run()
            yard.append(wall_yard)
            wall = run_command(line, folder)
            with h5py.File(recording_of(line, folder)) as f:
                loop = float(f.attrs["wall_time_s"])
                simulated = float(f["time"][-1])
            rows.append({"command": "bulletnet " + shlex.join(line), "simulated_s": simulated,
                         "process_wall_s": wall, "loop_wall_s": loop, "yardstick_s": wall_yard,
                         "ratio_to_yardstick": wall / wall_yard})
            print(f"{wall:7.1f} s ({wall / wall_yard:5.2f} x the yardstick's {wall_yard:.2f} s)"
                  f"  loop {loop:7.1f} s  {rows[-1]['command']}", flush=True)
    result = {"what": "the README's run lines as processes, kernels compiled; each beside a "
                      "timing of the frozen yardstick (benchmarks/yardstick.py)",
              "date": time.strftime("%Y-%m-%d %H:%M"),
              "machine": machine(),
              "yardstick": {"sha256": yardstick.file_hash(), "walls_s": yard,
                            "median_s": statistics.median(yard)},
              "commands": rows}
    path = out / "user_commands.json"
    path.write_text(json.dumps(result, indent=1) + "\n")
    print(f"-> {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
