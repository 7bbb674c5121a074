"""Deploy the paper's net with and without bending stiffness and compare the two runs
(Botta et al. 2016, Sec. 4.2, Table 4).

    python examples/bending_vs_plain.py            # the paper's 3 s deployment, ~35 s wall
    python examples/bending_vs_plain.py --quick    # 1.4 s of a 6 x 6 net, a few seconds
"""

import sys

import bulletnet as bn

QUICK = "--quick" in sys.argv
# Scene keys as in scenarios/deployment.toml, values in SI units.
overrides = {"net.nodes_per_side": 6, "scene.duration": 1.4} if QUICK else {}

recordings = {}
for bending in (False, True):
    scene = bn.load_scenario("deployment", {**overrides, "bending.enabled": bending})
    path = f"deployment_{'bending' if bending else 'plain'}.h5"
    result = bn.run(scene, path, force=True)  # force: overwrite an earlier run's file
    print(f"bending {'on ' if bending else 'off'}: {result.status}, "
          f"{result.wall_time_s:.1f} s wall -> {path}")
    recordings[bending] = bn.open_recording(path)

plain, bent = recordings[False], recordings[True]

# Table 4: Eq. 14 RMSE between the two runs, max and average over the nodes.
errors = bn.metrics.rmse(plain, bent)
print(f"position RMSE max / avg: {errors['rmse_pos_max']:.3g} / {errors['rmse_pos_avg']:.3g} m")
print(f"velocity RMSE max / avg: {errors['rmse_vel_max']:.3g} / {errors['rmse_vel_avg']:.3g} m/s")

# Bending opens the mouth sooner: time to 90 % of the fully open area L^2, and the area now.
for name, rec in (("plain", plain), ("bending", bent)):
    deployed = bn.metrics.deployed_time(rec, 0.9)
    print(f"{name:>7}: 90 % deployed: "
          f"{'not within the run' if deployed is None else f'{deployed:.2f} s'}, "
          f"mouth area at {rec.time[-1]:g} s: {bn.metrics.mouth_area(rec)[-1]:.3g} m^2, "
          f"net height (Eq. 13): {bn.metrics.net_height(rec)[-1]:.3g} m")
