"""The frozen yardstick: a plain compiled loop of the paper's 3 s deployment.

Kelvin-Voigt tension-only threads over a pair list, symplectic Euler at 1e-6 s, written the
straightforward way (no grid, no vector layout, no tricks) and then left alone: this file is
not changed, and every benchmark that reports speed times it in the same run and records its
SHA-256 (:func:`file_hash`), so that a speed figure is a ratio to something the project's own
changes cannot move. Only the machine (its load, its clock) moves it.

    python benchmarks/yardstick.py          # time it once and print the wall time [s]
"""

from __future__ import annotations

import hashlib
import sys
import time
from pathlib import Path

import numba as nb
import numpy as np

import bulletnet as bn

DT = 1e-6
"""Step [s]."""
DURATION = 3.0
"""Simulated time [s]: the paper's deployment."""


def file_hash() -> str:
    """SHA-256 of this file (hex): the yardstick's identity."""
    return hashlib.sha256(Path(__file__).read_bytes()).hexdigest()


@nb.njit(cache=True)
def plain_loop(pos, vel, inv_mass, pairs, rest, k, c, force, dt, steps):
    """``steps`` symplectic Euler steps of nodes at ``pos`` [m] with velocities ``vel``
    [m/s] (N, 3), joined by tension-only Kelvin-Voigt threads (P, 2) of rest length [m],
    stiffness [N/m] and damping [N s/m], in place."""
    n, p = pos.shape[0], pairs.shape[0]
    for _ in range(steps):
        for i in range(n):
            force[i, 0] = 0.0
            force[i, 1] = 0.0
            force[i, 2] = 0.0
        for t in range(p):
            i, j = pairs[t, 0], pairs[t, 1]
            dx = pos[j, 0] - pos[i, 0]
            dy = pos[j, 1] - pos[i, 1]
            dz = pos[j, 2] - pos[i, 2]
            length = np.sqrt(dx * dx + dy * dy + dz * dz)
            if length <= rest[t]:
                continue
            ex, ey, ez = dx / length, dy / length, dz / length
            rate = ((vel[j, 0] - vel[i, 0]) * ex + (vel[j, 1] - vel[i, 1]) * ey
                    + (vel[j, 2] - vel[i, 2]) * ez)
            tension = k[t] * (length - rest[t]) + c[t] * rate
            if tension <= 0.0:
                continue
            force[i, 0] += tension * ex
            force[i, 1] += tension * ey
            force[i, 2] += tension * ez
            force[j, 0] -= tension * ex
            force[j, 1] -= tension * ey
            force[j, 2] -= tension * ez
        for i in range(n):
            for a in range(3):
                vel[i, a] += dt * inv_mass[i] * force[i, a]
                pos[i, a] += dt * vel[i, a]


def deployment_arrays():
    """The default deployment's net (model and initial state of ``bulletnet``'s scene) as
    the loop's arrays: (pos, vel, inv_mass, pairs, rest, k, c, force)."""
    scene = bn.load_scenario("deployment")
    model = bn.build_model(scene)
    state = bn.initial_state(scene, model)
    return (state.position.copy(), state.velocity.copy(), 1.0 / model.mass,
            model.pairs.copy(), model.rest_length.copy(), model.axial_stiffness.copy(),
            model.axial_damping.copy(), np.zeros_like(state.position))


def run(duration: float = DURATION) -> tuple[float, np.ndarray]:
    """Compile (if needed), then time ``duration`` [s] of the deployment: (wall time [s],
    final positions [m] (N, 3))."""
    warm = deployment_arrays()
    plain_loop(*warm, DT, 1)
    arrays = deployment_arrays()
    start = time.perf_counter()
    plain_loop(*arrays, DT, round(duration / DT))
    return time.perf_counter() - start, arrays[0]


if __name__ == "__main__":
    wall, _ = run()
    print(f"yardstick: {wall:.2f} s for {DURATION:g} s of the deployment at {DT:g} s "
          f"(sha256 {file_hash()[:16]})")
    sys.exit(0)
