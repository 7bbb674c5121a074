"""The reference engine: scipy's adaptive DOP853 (8th order Runge-Kutta with dense output) on
the same right-hand side as the other engines, at tight tolerances. The paper's MATLAB role.

It is slow on the paper's nets (the thread dampers cap its step near 3e-6 s); use it on short
horizons, or to check the converged fine-step runs that stand in for it. With bending the
state carries quaternions, integrated as dq/dt = (w, 0) q / 2 and renormalized when used."""

from __future__ import annotations

import numpy as np

from ..common.errors import ScenarioError
from ..model.state import NetState
from ..solver import integrators
from .base import Engine


def quaternion_rate(quat: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """dq/dt = (w, 0) (x) q / 2 for world-frame angular velocities, shape (N, 4)."""
    x, y, z, w = quat.T
    wx, wy, wz = omega.T
    return 0.5 * np.stack([wx * w + wy * z - wz * y,
                           wy * w + wz * x - wx * z,
                           wz * w + wx * y - wy * x,
                           -(wx * x + wy * y + wz * z)], axis=1)


class ReferenceEngine(Engine):
    name = "reference"

    handles_contact = False

    def __init__(self, scenario, model):
        if scenario.contact.enabled:
            raise ScenarioError(f"{scenario.source}: the reference engine has no contact; "
                                "use --engine fast or bullet (or contact.enabled = false)")
        if scenario.strength.breakage:
            raise ScenarioError(f"{scenario.source}: the reference engine has no breakage; "
                                "use --engine fast or bullet (or strength.breakage = false)")
        super().__init__(scenario, model)
        self._solver = None
        self._free = ~model.fixed[:, None]
        self._base = self.base_forces()
        """The forces that do not depend on the state [N], (N, 3), as :meth:`advance` last
        found them (nothing changes them while it integrates: this engine calls no hooks)."""

    @property
    def integrator(self) -> str:
        return "DOP853"

    def _split(self, y: np.ndarray):
        n = self.model.node_count
        pos = y[: 3 * n].reshape(n, 3)
        vel = y[3 * n: 6 * n].reshape(n, 3)
        if not self.bending:
            return pos, vel, None, None
        quat = y[6 * n: 10 * n].reshape(n, 4)
        quat = quat / np.linalg.norm(quat, axis=1)[:, None]
        return pos, vel, quat, y[10 * n:].reshape(n, 3)

    def _rhs(self, _t: float, y: np.ndarray) -> np.ndarray:
        m, w = self.model, self.work
        pos, vel, quat, omega = self._split(y)
        # symplectic Euler's increment with dt = 1: dv is the acceleration [m/s^2]
        integrators.increment(False)(1.0 if self.bending else 0.0, pos, vel, quat, omega,
                                     self.arrays, w, self._base, 1.0, 0.0)
        parts = [vel * self._free, w.dv]
        if self.bending:
            alpha = w.torque / m.inertia[:, None] * self._free
            parts += [quaternion_rate(quat, omega * self._free), alpha]
        return np.concatenate([p.ravel() for p in parts])

    def advance(self, state: NetState, t_end: float) -> None:
        from scipy.integrate import DOP853

        sim = self.scenario.simulation
        self._base = self.base_forces()  # once, not at every evaluation of the right-hand side
        if self._solver is None:
            parts = [state.position, state.velocity]
            if self.bending:
                parts += [state.orientation, state.angular_velocity]
            y0 = np.concatenate([p.ravel() for p in parts])
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
        pos, vel, quat, omega = self._split(y)
        state.position[:] = pos
        state.velocity[:] = vel
        if self.bending:
            state.orientation[:] = quat
            state.angular_velocity[:] = omega
        state.time = t_end

    def stats(self) -> dict:
        nfev = self._solver.nfev if self._solver is not None else 0
        return {"steps": self.steps, "rhs_evaluations": int(nfev)}
