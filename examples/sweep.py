"""A small parameter sweep: launch elevation against bending, one run per combination,
summarised in a table (what `bulletnet sweep` does from a sweep file, here from Python).

    python examples/sweep.py            # 3 elevations x bending on/off, 1 s each, ~1 min wall
    python examples/sweep.py --quick    # 2 elevations x bending on/off, 0.6 s of a 6 x 6 net
"""

import sys
from pathlib import Path

from bulletnet.studies.sweep import Sweep, run_sweep, write_table

QUICK = "--quick" in sys.argv
elevations = [30.0, 60.0] if QUICK else [30.0, 45.0, 60.0]       # [deg]
fixed = ({"scene.duration": 0.6, "net.nodes_per_side": 6} if QUICK
         else {"scene.duration": 1.0})                          # [s], [-]

sweep = Sweep(scene="deployment", swept=("launch.elevation", "bending.enabled"),
              variants=tuple({**fixed, "launch.elevation": e, "bending.enabled": b}
                             for e in elevations for b in (False, True)))

# serial=True runs the variants one after another in this process; without it they go to a
# local Dask cluster (pip install -e '.[sweep]'), or to scheduler="tcp://HOST:8786".
rows = run_sweep(sweep, Path("sweep_out"), serial=True)

print(f"{'elevation [deg]':>15} {'bending':>8} {'mouth area [m^2]':>17} "
      f"{'max corner tension [N]':>23} {'wall [s]':>9}")
for row in rows:
    print(f"{row['launch.elevation']:15g} {str(row['bending.enabled']):>8} "
          f"{row['final_mouth_area_m2']:17.3f} {row['max_corner_tension_N']:23.1f} "
          f"{row['wall_s']:9.2f}")
print("table:", *write_table(rows, Path("sweep_out")))
