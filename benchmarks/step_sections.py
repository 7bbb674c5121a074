"""Where an implicit scene's step spends its time, timed inside the compiled loop.

Timing a kernel alone, from a fixed state, misses what a run pays for it among the others
(its data out of the caches, a Verlet list rebuilt every few steps, the warm start's
iterations), and an external split (``bulletnet run --profile``) sees only forces, contact
and the rest. Here a copy of the package, in a temporary folder, reads the processor's
cycle counter (LLVM's ``readcyclecounter``) at the boundaries of the loop's sections
(:data:`ANCHORS`: the contact list's upkeep, the reel and bending's rotations, the step,
the contact stage, the rest; inside the grid's implicit step the threads' linearization,
the other threads and cables, the right-hand side, the solve and in it the
preconditioner's factor, the update), summed over the steps into the loop's CG counter,
widened for them. The copy runs the scene to ``--at`` in a process of its own, with a numba
cache of its own (it compiles once, 1-2 min), then ``--span`` seconds more, timed; each
section's counts over those steps become µs a step at the counter's rate, measured against
``time.perf_counter``. Each round (``--repeats``, medians reported) times the frozen plain
loop (``yardstick.py``; once more at the end), the instrumented copy, then the same span on
the package as it is, in a process of its own, so that the counters' own cost shows as the
difference of the two walls a step; every figure is also given as the scene's whole run at
that cost a step, in plain loops. An anchor the code no longer has stops the benchmark with
its name. Writes ``OUT/step_sections_SCENE.json``:

    python benchmarks/step_sections.py benchmarks/results [--scene capture_closing]
        [--at 30] [--span 2] [--repeats 3] [--set KEY=VALUE ...]
"""

from __future__ import annotations

import json
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from common import At, Yardsticks, machine, output_dir, parser, user_env

import bulletnet

RDTSC = '''"""The processor's cycle counter, for timing sections of compiled loops."""
from llvmlite import ir
from numba.core import cgutils, types
from numba.extending import intrinsic


@intrinsic
def rdtsc(typingctx):
    def codegen(context, builder, signature, args):
        fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(ir.IntType(64), []),
                                            "llvm.readcyclecounter")
        return builder.call(fn, [])
    return types.int64(), codegen
'''

SECTIONS = {
    10: "contact list upkeep (ensure_pairs)",
    11: "reel, bending's rotations",
    12: "step (bending forces, threads, solve)",
    1: "  threads' linearization (grid stencils)",
    2: "  other threads, cables, orbit",
    3: "  right-hand side",
    4: "  solve (PCG)",
    6: "    preconditioner's factor",
    5: "  update",
    13: "contact stage",
    14: "rest (rotations' gains, peaks, breakage, tether reel)",
}
"""Counter slot -> section (slots 1-6 inside the grid's implicit step; 15 counts the steps)."""

LOOP = "bulletnet/solver/integrators.py"
ANCHORS = [
    (LOOP, "cg_iterations=np.zeros(1, dtype=np.int64)",
     "cg_iterations=np.zeros(32, dtype=np.int64)"),
    (LOOP, "from . import dilu as dilu_kernels\n",
     "from . import dilu as dilu_kernels\nfrom ..kernels.cycles import rdtsc\n"),
    (LOOP, "        for k in range(steps):\n            if contact is not None:\n",
     "        P = work.cg_iterations\n        for k in range(steps):\n            c0 = rdtsc()\n"
     "            if contact is not None:\n"),
    (LOOP, "            reel(pos, model.cables, t0 + k * dt, dt)\n",
     "            c1 = rdtsc()\n            P[10] += c1 - c0\n"
     "            reel(pos, model.cables, t0 + k * dt, dt)\n"),
    (LOOP, "            if on_grid:  # the grid's stencils (bending as in external_forces)\n",
     "            c2 = rdtsc()\n            P[11] += c2 - c1\n"
     "            if on_grid:  # the grid's stencils (bending as in external_forces)\n"),
    (LOOP, "            if contact is not None:\n                contact_stage(",
     "            c3 = rdtsc()\n            P[12] += c3 - c2\n"
     "            if contact is not None:\n                contact_stage("),
    (LOOP, "            if quat is not None:\n                if weight > 0.0:\n"
           "                    angular_gains(",
     "            c4 = rdtsc()\n            P[13] += c4 - c3\n"
     "            if quat is not None:\n                if weight > 0.0:\n"
     "                    angular_gains("),
    (LOOP, "            taken += 1\n",
     "            P[14] += rdtsc() - c4\n            P[15] += 1\n            taken += 1\n"),
    ("bulletnet/solver/grid.py", "from . import pcg\n",
     "from . import pcg\nfrom ..kernels.cycles import rdtsc\n"),
    ("bulletnet/solver/grid.py", "    _linearize_stencil(x, v, ONE, grid.h_rest,",
     "    c0 = rdtsc()\n    _linearize_stencil(x, v, ONE, grid.h_rest,"),
    ("bulletnet/solver/grid.py", "    _other_threads(grid, views, dt, True)\n",
     "    c1 = rdtsc()\n    iterations[1] += c1 - c0\n    _other_threads(grid, views, dt, True)\n"
     "    c2 = rdtsc()\n    iterations[2] += c2 - c1\n"),
    ("bulletnet/solver/grid.py", "    pcg.solve(_apply, _block_jacobi,",
     "    c3 = rdtsc()\n    iterations[3] += c3 - c2\n    pcg.solve(_apply, _block_jacobi,"),
    ("bulletnet/solver/grid.py", "    _move(x, v, dv, dt, count)\n\n",
     "    c4 = rdtsc()\n    iterations[4] += c4 - c3\n    _move(x, v, dv, dt, count)\n"
     "    iterations[5] += rdtsc() - c4\n\n"),
    ("bulletnet/solver/pcg.py", "import numba as nb\n",
     "import numba as nb\n\nfrom ..kernels.cycles import rdtsc\n"),
    ("bulletnet/solver/pcg.py", "    factor(system)\n",
     "    c0 = rdtsc()\n    factor(system)\n    iterations[6] += rdtsc() - c0\n"),
]
"""(file, text, its instrumented replacement): each text must occur in its file once."""


def instrumented_copy(folder: Path) -> Path:
    """The package copied into ``folder`` with the counters read at :data:`ANCHORS` (its
    data folders, the scenes among them, linked beside it)."""
    from bulletnet.common.resources import FOLDERS, data_dir

    source = Path(bulletnet.__file__).parent
    target = folder / "bulletnet"
    shutil.copytree(source, target, ignore=shutil.ignore_patterns("__pycache__", *FOLDERS))
    for name in FOLDERS:
        (folder / name).symlink_to(data_dir(name).resolve(), target_is_directory=True)
    (target / "kernels" / "cycles.py").write_text(RDTSC, encoding="utf-8")
    for name, old, new in ANCHORS:
        path = folder / name
        text = path.read_text(encoding="utf-8")
        if text.count(old) != 1:
            raise SystemExit(f"step_sections: {name} no longer has (once): {old.strip()!r}")
        path.write_text(text.replace(old, new), encoding="utf-8")
    return folder


def child(scene: str, at: float, span: float, sets: list[str], instrumented: bool) -> dict:
    """In the child process: the scene run to ``at``, then ``span`` seconds timed; with the
    counters (``instrumented``) each section's µs a step."""
    import numba as nb

    import bulletnet as bn

    overrides = {"scene.duration": at + span + 1.0}
    for item in sets:
        key, value = item.split("=", 1)
        overrides[key] = json.loads(value)

    class Snapshot(At):
        def act(self, engine, state):
            return engine, state

    snapshot = Snapshot(at)
    scenario = bn.load_scenario(scene, overrides)
    bn.run(scenario, None, observers=[snapshot])
    engine, state = snapshot.taken
    engine.advance(state, state.time + 0.05)  # the loop's compiled version resolved
    counters = engine.work.cg_iterations
    counters[:] = 0
    contact = engine.contact_arrays
    builds = contact.pair_meta[2] if contact is not None else 0
    steps = engine.steps
    start = time.perf_counter()
    engine.advance(state, state.time + span)
    wall = time.perf_counter() - start
    steps = engine.steps - steps
    whole = bn.load_scenario(scene, {k: v for k, v in overrides.items()
                                     if k != "scene.duration"}).scene.duration
    doc = {"steps": steps, "wall_us_per_step": 1e6 * wall / steps,
           "scene_steps": round(whole / scenario.simulation.dt),
           "cg_iterations_per_step": float(counters[0]) / steps,
           "verlet_builds": (int(contact.pair_meta[2] - builds)
                             if contact is not None else 0)}
    if instrumented:
        from bulletnet.kernels.cycles import rdtsc

        @nb.njit
        def cycles():
            return rdtsc()

        cycles()
        c0, t0 = cycles(), time.perf_counter()
        time.sleep(0.5)
        rate = (cycles() - c0) / (time.perf_counter() - t0)
        us = {label: 1e6 * float(counters[slot]) / rate / steps
              for slot, label in SECTIONS.items()}
        loop = sum(us[SECTIONS[s]] for s in (10, 11, 12, 13, 14))
        doc.update(counter_GHz=rate * 1e-9, sections_us=us, loop_sections_us=loop,
                   outside_loop_us=doc["wall_us_per_step"] - loop)
    return doc


def run_child(args, folder: Path, instrumented: bool) -> dict:
    """:func:`child` in a process of its own: the package in ``folder`` (``instrumented``), or
    as installed (run in ``folder``)."""
    env = user_env()
    if instrumented:  # (its kernels in a cache of their own)
        env.update(PYTHONPATH=str(folder), NUMBA_CACHE_DIR=str(folder / "numba_cache"))
    command = [sys.executable, __file__, "--child", args.scene, str(args.at), str(args.span),
               "1" if instrumented else "0", *args.set]
    proc = subprocess.run(command, env=env, capture_output=True, text=True, timeout=7200,
                          cwd=folder)
    if proc.returncode != 0:
        raise SystemExit(f"step_sections: the run failed: {proc.stderr.strip()[-2000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def main() -> int:
    if len(sys.argv) > 1 and sys.argv[1] == "--child":
        scene, at, span, instrumented, *sets = sys.argv[2:]
        print(json.dumps(child(scene, float(at), float(span), sets, instrumented == "1")))
        return 0
    p = parser(__doc__.split("\n\n")[0])
    p.add_argument("--scene", default="capture_closing", help="a scene with implicit Euler")
    p.add_argument("--at", type=float, default=30.0, help="when the timed span starts [s]")
    p.add_argument("--span", type=float, default=2.0, help="the timed span [s] (simulated)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="a scene override, the value as JSON (e.g. bending.enabled=true)")
    args = p.parse_args()
    out = output_dir(args)
    yard = Yardsticks()
    rounds = []  # (instrumented, as it is), alternating, each a process of its own
    with tempfile.TemporaryDirectory() as tmp:
        folder = instrumented_copy(Path(tmp))
        for _ in range(args.repeats):
            yard.time()
            rounds.append((run_child(args, folder, True), run_child(args, Path(tmp), False)))
    yard.time()
    median = statistics.median
    sections = {label: median(r[0]["sections_us"][label] for r in rounds)
                for label in SECTIONS.values()}
    walls = [median(r[k]["wall_us_per_step"] for r in rounds) for k in (0, 1)]
    loop = median(r[0]["loop_sections_us"] for r in rounds)
    plain = rounds[0][1]
    doc = {"machine": machine(), "scene": Path(args.scene).stem, "at_s": args.at,
           "span_s": args.span, "overrides": args.set, "repeats": args.repeats,
           "sections_us": sections, "loop_sections_us": loop,
           "wall_us_per_step": {"instrumented": walls[0], "as_it_is": walls[1]},
           "outside_loop_us": walls[0] - loop,
           "cg_iterations_per_step": plain["cg_iterations_per_step"],
           "verlet_builds": plain["verlet_builds"], "steps": plain["steps"],
           "scene_steps": plain["scene_steps"],
           "rounds": [{"instrumented": a, "as_it_is": b} for a, b in rounds],
           "yardsticks": yard.doc()}
    steps = plain["scene_steps"]  # the scene's whole run at these costs, in plain loops
    doc["x_yardstick"] = {label: value * 1e-6 * steps / yard.median
                          for label, value in sections.items()}
    doc["x_yardstick"]["a step as it is"] = walls[1] * 1e-6 * steps / yard.median
    name = f"step_sections_{Path(args.scene).stem}.json"
    (out / name).write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
    for label, value in sections.items():
        print(f"{label:56s} {value:7.2f} us {doc['x_yardstick'][label]:6.2f} x yardstick")
    print(f"{'in the loop':56s} {loop:7.2f} us; outside it (Python, between chunks) "
          f"{doc['outside_loop_us']:.2f} us")
    print(f"a step: {walls[0]:.1f} us with the counters, {walls[1]:.1f} us as it is (medians "
          f"of {args.repeats}); CG {plain['cg_iterations_per_step']:.2f} iterations a step; "
          f"{plain['verlet_builds']} Verlet builds in {plain['steps']} steps; the scene's "
          f"{steps} steps at it {doc['x_yardstick']['a step as it is']:.2f} plain loops "
          f"({yard.median:.2f} s) -> {out / name}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
