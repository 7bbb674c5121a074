"""The README's ``bulletnet run`` lines timed as a user runs them, against the frozen yardstick.

Each run line of the README's command list runs as written (``--force`` added, so repeats
overwrite) as a process, in a folder laid out as a clone's, with the kernels already
compiled and the package's bytecode cached (a short run of each line first: compiling is what
``first_run.py`` measures; :func:`common.user_env`).
Before each command the frozen yardstick (``yardstick.py``: a plain compiled loop of the 3 s
deployment) is timed in this process, so every command's wall time is also given as a ratio
to the yardstick measured beside it. With ``--repeats N`` the list runs N times over,
interleaved, and each command reports the medians of its N walls, loops and ratios (each
ratio to the yardstick timed just before that run) beside all N. ``--only TEXT`` keeps the
lines that contain TEXT (repeatable); ``--variant KEY=VALUE`` also runs each line with
``--set KEY=VALUE``, right after it in every repeat (repeatable; several settings of one
variant separated by spaces, each quoted as on a shell line). Writes
``OUT/user_commands.json``, or with ``--only`` and ``--variant``
``OUT/user_commands_TEXT_KEY_VALUE.json``:

    python benchmarks/user_commands.py benchmarks/results --repeats 1
    python benchmarks/user_commands.py benchmarks/results --only "capture --bending" --repeats 5
    python benchmarks/user_commands.py benchmarks/results --only capture --repeats 3 \
        --variant 'simulation.preconditioner="block_dilu"'
"""

from __future__ import annotations

import json
import re
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
from common import machine, output_dir, parser, user_env

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
                          cwd=folder, env=user_env(), capture_output=True, text=True,
                          timeout=7200)
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


def with_settings(variant: str) -> list[str]:
    """``--set`` arguments of a variant, "KEY=VALUE [KEY=VALUE ...]" (shell-quoted)."""
    return [arg for kv in shlex.split(variant) for arg in ("--set", kv)]


def main() -> int:
    p = parser(__doc__.split("\n\n")[0])
    p.add_argument("--only", action="append", default=[], metavar="TEXT",
                   help="time only the run lines that contain TEXT (repeatable)")
    p.add_argument("--variant", action="append", default=[], metavar="KEY=VALUE",
                   help="also time each line with --set KEY=VALUE (several: space-separated), "
                   "interleaved (repeatable)")
    args = p.parse_args()
    out = output_dir(args)
    lines = [variant for line in readme_run_lines()
             if not args.only or any(t in shlex.join(line) for t in args.only)
             for variant in [line] + [[*line, *with_settings(kv)] for kv in args.variant]]
    if not lines:
        raise SystemExit(f"user_commands: no run line of the README contains {args.only}")
    runs: list[list[dict]] = [[] for _ in lines]
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        (folder / "assets").symlink_to(ROOT / "assets")
        shutil.copytree(ROOT / "scenarios", folder / "scenarios")
        subprocess.run([sys.executable, "-m", "bulletnet.cli.main", "scene", "capture"], check=True,
                       stdout=(folder / "mine.toml").open("w"))
        for line in lines:  # compile every line's kernels first
            run_command([*line, "--duration", "0.01", "--quiet"], folder)
        for _ in range(args.repeats):  # interleaved: each command beside its own yardstick
            for line, done in zip(lines, runs, strict=True):
                wall_yard, _ = yardstick.run()
                wall = run_command(line, folder)
                with h5py.File(recording_of(line, folder)) as f:
                    loop = float(f.attrs["wall_time_s"])
                    simulated = float(f["time"][-1])
                done.append({"wall": wall, "loop": loop, "yard": wall_yard,
                             "simulated": simulated})
                print(f"{wall:7.1f} s ({wall / wall_yard:5.2f} x the yardstick's "
                      f"{wall_yard:.2f} s)  loop {loop:7.1f} s  bulletnet {shlex.join(line)}",
                      flush=True)
    median = statistics.median
    rows = [{"command": "bulletnet " + shlex.join(line), "simulated_s": done[0]["simulated"],
             "process_wall_s": median(r["wall"] for r in done),
             "loop_wall_s": median(r["loop"] for r in done),
             "yardstick_s": median(r["yard"] for r in done),
             "ratio_to_yardstick": median(r["wall"] / r["yard"] for r in done),
             "process_walls_s": [r["wall"] for r in done],
             "loop_walls_s": [r["loop"] for r in done],
             "yardsticks_s": [r["yard"] for r in done],
             "ratios_to_yardstick": [r["wall"] / r["yard"] for r in done]}
            for line, done in zip(lines, runs, strict=True)]
    yard = [r["yard"] for done in runs for r in done]
    result = {"what": "the README's run lines as processes, kernels compiled; each beside a "
                      "timing of the frozen yardstick (benchmarks/yardstick.py); medians of "
                      "interleaved repeats",
              "date": time.strftime("%Y-%m-%d %H:%M"),
              "machine": machine(),
              "repeats": args.repeats,
              "yardstick": {"sha256": yardstick.file_hash(), "walls_s": yard,
                            "median_s": statistics.median(yard)},
              "commands": rows}
    slug = "_".join(re.sub(r"[^a-z0-9]+", "_", t.lower()).strip("_")
                    for t in args.only + args.variant)
    path = out / (f"user_commands_{slug}.json" if slug else "user_commands.json")
    path.write_text(json.dumps(result, indent=1) + "\n")
    print(f"-> {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
