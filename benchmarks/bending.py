"""Bending benchmark (Sec. 4.2, Table 4, Figs. 6-9): the deployment with and without bending.

On the fast engine at its defaults (3 s, Ns = 11), reports the paper's measures side by side:
90 % deployment time (first time the mouth area reaches 90 % of the fully open L^2), the
mouth-area ratio at 1.5 s, Table 4's RMSE between the two runs, the centre-of-mass agreement,
and the cost of bending on each engine (wall-time ratios of interleaved runs, median). The
bending run's own accuracy is measured against a converged fine-step bending run
(dt = 2.5e-7 s, bending evaluated every step; cached in OUT/fine_bending.h5). Writes
OUT/bending.json and the figures (``bulletnet plot``) into OUT/figures/.

Usage: python benchmarks/bending.py [OUT] [--repeats N] [--bullet-horizon S]
"""

from __future__ import annotations

import json
import statistics

import numpy as np
from common import ERROR_KEYS, Yardsticks, errors, output_dir, parser, timed

import bulletnet as bn
from bulletnet.analysis.plots import plot_recordings


def main() -> None:
    p = parser(__doc__)
    p.add_argument("--bullet-horizon", type=float, default=0.05, help="[s]")
    args = p.parse_args()
    out = output_dir(args)
    base = bn.load_scenario("deployment")
    doc = {"scene": "deployment", "duration_s": base.scene.duration}

    # plain and bending runs interleaved, so that the machine's drift hits both alike; the
    # cost of bending is the median of the per-pair ratios
    runs, walls = {}, {"plain": [], "bending": []}
    yard = Yardsticks()
    for _ in range(args.repeats):
        yard.time()
        for name, bending in (("plain", False), ("bending", True)):
            scene = base.with_overrides({"bending.enabled": bending})
            wall, _, result = timed(scene, out / f"fast_{name}.h5")
            walls[name].append(wall)
            runs[name] = result
    for name in walls:
        doc[f"fast_{name}"] = {"wall_s_median": statistics.median(walls[name]),
                               "wall_s_all": walls[name], "steps": runs[name].stats["steps"],
                               **yard.ratios(statistics.median(walls[name]))}
        runs[name] = bn.open_recording(runs[name].path)
    doc["yardsticks"] = yard.doc()
    doc["fast_bending_cost_ratio"] = statistics.median(
        b / p for p, b in zip(walls["plain"], walls["bending"], strict=True))

    fine_path = out / "fine_bending.h5"
    if not fine_path.exists():
        bn.run(base.with_overrides({"bending.enabled": True, "bending.every": 1,
                                    "simulation.dt": 2.5e-7}), fine_path)
    doc["fast_bending_vs_fine"] = errors(out / "fast_bending.h5", bn.open_recording(fine_path))

    r = bn.metrics.rmse(runs["plain"], runs["bending"])
    doc["table4_with_vs_without"] = {
        "ours": {k: r[k] for k in ERROR_KEYS},
        "paper": {"rmse_pos_max": 0.759863, "rmse_pos_avg": 0.515628,
                  "rmse_vel_max": 1.474281, "rmse_vel_avg": 1.022107}}
    measures = {}
    for name, rec in runs.items():
        area = bn.metrics.mouth_area(rec)
        k15 = int(np.argmin(np.abs(rec.time - 1.5)))
        measures[name] = {"deployed_90pct_s": bn.metrics.deployed_time(rec, 0.9),
                          "mouth_area_1_5s_m2": float(area[k15]),
                          "max_mouth_area_m2": float(area.max())}
    doc["measures"] = measures
    doc["mouth_area_ratio_1_5s"] = (measures["bending"]["mouth_area_1_5s_m2"]
                                    / measures["plain"]["mouth_area_1_5s_m2"])
    doc["paper"] = {"deployed_90pct_s": {"bending": "just after 2", "plain": "3"},
                    "mouth_area_ratio_1_5s": 2.5, "vortex_bending_cost_ratio": 1.92}
    mass = runs["plain"].mass
    com = [(rec.position * mass[None, :, None]).sum(axis=1) / mass.sum()
           for rec in runs.values()]
    doc["centre_of_mass_max_difference_m"] = float(np.abs(com[0] - com[1]).max())

    bullet = {}
    for name, bending in (("plain", False), ("bending", True)):
        scene = base.with_overrides({"bending.enabled": bending, "simulation.engine": "bullet",
                                     "scene.duration": args.bullet_horizon})
        bullet[name] = timed(scene, out / f"bullet_{name}.h5")[0]
    doc["bullet_bending_cost_ratio"] = bullet["bending"] / bullet["plain"]
    doc["bullet_horizon_s"] = args.bullet_horizon

    figures = plot_recordings(runs["plain"], runs["bending"], out / "figures",
                              [0.5, 1.0, 1.5, 2.0, 2.5, 3.0])
    doc["figures"] = [str(p) for p in figures]
    (out / "bending.json").write_text(json.dumps(doc, indent=2))
    print(json.dumps(doc, indent=2))


if __name__ == "__main__":
    main()
