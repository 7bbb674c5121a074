"""Deployment benchmark (issue: engines against the reference, Table 2).

Runs the paper's 3 s deployment (Ns = 11) on every engine at its default settings and
compares each against the converged reference, then writes ``OUT/deployment.json``.

- The reference for the full 3 s is a converged fine-step run (symplectic Euler at
  2.5e-7 s, cached in OUT/fine.h5). scipy's DOP853 (the `reference` engine) is run over the
  first REF_HORIZON seconds and compared with it first, to show the stand-in is faithful.
- ``fast`` is timed REPEATS times (median reported); ``bullet`` (about 1 ms per step from
  Python) runs over BULLET_HORIZON seconds and its wall time is scaled to 3 s.

Usage: python benchmarks/deployment.py [OUT] [--repeats N] [--bullet-horizon S] [--ref-horizon S]
"""

from __future__ import annotations

import json
import statistics

from common import Yardsticks, errors, machine, output_dir, parser, timed

import bulletnet as bn


def main() -> None:
    p = parser(__doc__)
    p.add_argument("--bullet-horizon", type=float, default=0.5, help="[s]")
    p.add_argument("--ref-horizon", type=float, default=0.5, help="[s]")
    args = p.parse_args()
    out = output_dir(args)
    base = bn.load_scenario("deployment")
    duration = base.scene.duration
    doc = {"scene": "deployment", "duration_s": duration, "machine": machine(),
           "bulletnet_version": bn.__version__, "runs": {}}

    fine_path = out / "fine.h5"
    fine_scene = base.with_overrides({"simulation.integrator": "symplectic_euler",
                                      "simulation.dt": 2.5e-7})
    if not fine_path.exists():
        wall, _, _ = timed(fine_scene, fine_path)
        doc["fine_wall_s"] = wall
    fine = bn.open_recording(fine_path)

    # 1. the adaptive reference against the fine-step stand-in
    wall, _, _ = timed(base.with_overrides({"simulation.engine": "reference",
                                            "scene.duration": args.ref_horizon}),
                       out / "reference.h5")
    doc["reference_vs_fine"] = {"horizon_s": args.ref_horizon, "wall_s": wall,
                                **errors(out / "reference.h5", fine)}

    # 2. fast at its defaults, timed REPEATS times beside the yardsticks; and the
    # alternatives for scale
    yard = Yardsticks()
    walls = []
    for _ in range(args.repeats):
        yard.time()
        one, _, result = timed(base, out / "fast.h5")
        walls.append(one)
    wall = statistics.median(walls)
    doc["runs"]["fast"] = {"integrator": base.simulation.integrator, "dt_s": 1e-6,
                           "wall_s_median": wall, "wall_s_all": walls,
                           "steps": result.stats["steps"],
                           **yard.ratios(wall, result.stats["steps"]),
                           **errors(out / "fast.h5", fine)}
    for integrator, dt in (("symplectic_euler", 2e-6), ("implicit_euler", 1e-5)):
        name = f"fast_{integrator}_{dt:g}"
        wall, _, result = timed(base.with_overrides({"simulation.integrator": integrator,
                                                     "simulation.dt": dt}), out / f"{name}.h5")
        doc["runs"][name] = {"integrator": integrator, "dt_s": dt, "wall_s_median": wall,
                             "steps": result.stats["steps"], **yard.ratios(wall),
                             **errors(out / f"{name}.h5", fine)}

    # 3. bullet at its defaults over a shorter horizon
    wall, _, result = timed(base.with_overrides({"simulation.engine": "bullet",
                                                 "scene.duration": args.bullet_horizon}),
                            out / "bullet.h5")
    doc["runs"]["bullet"] = {"integrator": base.simulation.integrator, "dt_s": 1e-6,
                             "horizon_s": args.bullet_horizon, "wall_s": wall,
                             "wall_s_scaled_to_duration": wall * duration / args.bullet_horizon,
                             "x_yardstick_scaled": wall * duration / args.bullet_horizon
                             / yard.median,
                             "steps": result.stats["steps"], **errors(out / "bullet.h5", fine),
                             "vs_fast_same_horizon": errors(out / "bullet.h5",
                                                            bn.open_recording(out / "fast.h5"))}
    doc["vortex_paper"] = {"wall_s_dt_5e-5": 2658.0, "wall_s_dt_1_60": 9.0,
                           "table2_rmse_pos_max": 0.006835, "table2_rmse_pos_avg": 0.002939}
    doc["yardsticks"] = yard.doc()
    (out / "deployment.json").write_text(json.dumps(doc, indent=2))
    print(json.dumps(doc, indent=2))


if __name__ == "__main__":
    main()
