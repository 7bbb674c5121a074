"""The reference engine: scipy's adaptive DOP853 (8th order Runge-Kutta with dense output) on
the same right-hand side as the other engines, at tight tolerances. The paper's MATLAB role.

It is slow on the paper's nets (the thread dampers cap its step near 3e-6 s); use it on short
horizons, or to check the converged fine-step runs that stand in for it."""

from __future__ import annotations

import numpy as np

from ..forces.axial import axial_forces
from ..state import NetState
from .base import Engine


class ReferenceEngine(Engine):
    name = "reference"

    def __init__(self, scenario, model):
        super().__init__(scenario, model)
        self._solver = None
        self._force = np.zeros((model.node_count, 3))
        self._tension = np.zeros(model.thread_count)

    @property
    def integrator(self) -> str:
        return "DOP853"

    @property
    def dt(self) -> float:
        return 0.0

    def _rhs(self, _t: float, y: np.ndarray) -> np.ndarray:
        m = self.model
        n = m.node_count
        pos = y[: 3 * n].reshape(n, 3)
        vel = y[3 * n:].reshape(n, 3)
        force = self._force
        force[:] = m.mass[:, None] * self.gravity
        axial_forces(pos, vel, m.pairs, m.rest_length, m.axial_stiffness, m.axial_damping,
                     force, self._tension)
        return np.concatenate([vel.ravel(), (force / m.mass[:, None]).ravel()])

    def advance(self, state: NetState, t_end: float) -> None:
        from scipy.integrate import DOP853

        sim = self.scenario.simulation
        if self._solver is None:
            y0 = np.concatenate([state.position.ravel(), state.velocity.ravel()])
            self._solver = DOP853(self._rhs, state.time, y0, self.scenario.scene.duration,
                                  rtol=sim.rtol, atol=sim.atol)
        solver = self._solver
        while solver.t < t_end and solver.status == "running":
            solver.step()
            self.steps += 1
        if solver.status == "failed":
            state.position[:] = np.nan
            return
        y = solver.y if solver.t == t_end else solver.dense_output()(t_end)
        n = self.model.node_count
        state.position[:] = y[: 3 * n].reshape(n, 3)
        state.velocity[:] = y[3 * n:].reshape(n, 3)
        state.time = t_end

    def stats(self) -> dict:
        nfev = self._solver.nfev if self._solver is not None else 0
        return {"steps": self.steps, "rhs_evaluations": int(nfev)}
