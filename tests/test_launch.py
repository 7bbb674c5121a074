"""The default launch against the paper's deployment results (Sec. 4.2, Table 4), from which
it was identified (``benchmarks/launch_identification.py``, docs/launch.md)."""

from __future__ import annotations

import numpy as np
import pytest

import bulletnet as bn

TABLE4 = {"rmse_pos_max": 0.759863, "rmse_pos_avg": 0.515628,  # [m]
          "rmse_vel_max": 1.474281, "rmse_vel_avg": 1.022107}  # [m/s]
"""Table 4: RMSE between the deployments with and without bending, max and average over
the nodes."""


def deployment_pair(tmp_path, elevation_deg: float) -> dict:
    """The paper's 3 s deployment without and with bending, on the scene's integrator and
    step, launched at this elevation [deg]."""
    return {on: bn.open_recording(bn.run(
        bn.load_scenario("deployment", {"launch.elevation": elevation_deg,
                                        "bending.enabled": on}),
        tmp_path / f"{elevation_deg:g}_{on}.h5").path) for on in (False, True)}


@pytest.mark.slow
def test_default_launch_matches_the_papers_deployment(tmp_path):
    # Reference: Sec. 4.2's words, read as the ranges they allow (docs/launch.md): 90 % of
    # full deployment "just after 2 seconds" with bending (after 2 s and rounding to 2 s:
    # 2.0-2.5 s), "3 seconds" without (whole seconds: 2.5-3.5 s); at 1.5 s the mouth area
    # with bending "approximately 2.5 times" the one without (to a half: 2.25-2.75). And
    # Table 4, which the default launch (56.5 deg above the net plane) must match better than
    # the former default, 45 deg.
    default = bn.load_scenario("deployment").launch.elevation
    runs = deployment_pair(tmp_path, default)
    assert 2.0 <= bn.metrics.deployed_time(runs[True], 0.9) <= 2.5
    assert 2.5 <= bn.metrics.deployed_time(runs[False], 0.9) <= 3.5
    k = int(np.argmin(np.abs(runs[False].time - 1.5)))
    ratio = bn.metrics.mouth_area(runs[True])[k] / bn.metrics.mouth_area(runs[False])[k]
    assert 2.25 <= ratio <= 2.75

    ours = bn.metrics.rmse(runs[False], runs[True])
    former = bn.metrics.rmse(*deployment_pair(tmp_path, 45.0).values())
    for key, paper in TABLE4.items():
        assert abs(ours[key] - paper) < abs(former[key] - paper), key
