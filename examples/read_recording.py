"""Read a recording with plain h5py, no bulletnet needed: the layout, the units, and a few
quantities computed from the arrays (docs/recordings.md describes every dataset).

    python examples/read_recording.py RUN.h5     # any recording
    python examples/read_recording.py --quick    # records a 1 s deployment first
"""

import sys

import h5py
import numpy as np

if "--quick" in sys.argv:
    import bulletnet as bn

    path = "read_me.h5"
    bn.run(bn.load_scenario("deployment", {"scene.duration": 1.0}), path, force=True)
else:
    path = sys.argv[1]

with h5py.File(path, "r") as f:
    # Root attributes: how the run was made and how it ended.
    print(f"{path}: status {f.attrs['status']}, engine {f.attrs['engine']}, "
          f"integrator {f.attrs['integrator']}, dt {f.attrs['dt']} s, "
          f"{f.attrs['nodes_per_side']} nodes per side")

    # Every dataset carries its unit.
    f.visititems(lambda name, item: print(f"  {name:<28} {str(item.shape):<16} "
                                          f"[{item.attrs.get('units', '')}]")
                 if isinstance(item, h5py.Dataset) else None)

    time = f["time"][:]                       # (T,) [s]
    position = f["nodes/position"][:]         # (T, N, 3) [m]
    velocity = f["nodes/velocity"][:]         # (T, N, 3) [m/s]
    mass = f["nodes/mass"][:]                 # (N,) [kg]
    kind = f["nodes/kind"][:]                 # (N,) 0 inner, 1 edge, 2 corner, 3 corner mass
    tension = f["threads/tension"][:]         # (T, P) [N], 0 when slack

# Centre of mass and linear momentum of the net (conserved in zero gravity).
com = np.einsum("n,tna->ta", mass, position) / mass.sum()
momentum = np.einsum("n,tna->ta", mass, velocity)
print(f"centre of mass moved {np.linalg.norm(com[-1] - com[0]):.4f} m in {time[-1]:g} s; "
      f"momentum {np.linalg.norm(momentum[0]):.4g} -> {np.linalg.norm(momentum[-1]):.4g} kg m/s")

# The corner masses' spread and the largest thread tension.
corners = position[-1, kind == 3]
print(f"corner masses at {time[-1]:g} s: {np.linalg.norm(corners[:, :2], axis=1).round(3)} m "
      f"from the axis; largest tension {tension.max():.1f} N")
