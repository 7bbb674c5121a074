"""The fast engine: the whole net integrated in compiled loops; no PyBullet world when the
scene has no contact."""

from __future__ import annotations

import numpy as np

from .. import integrators
from ..state import NetState
from .base import Engine


class FastEngine(Engine):
    name = "fast"

    def __init__(self, scenario, model):
        super().__init__(scenario, model)
        self.work = integrators.Workspace(model.node_count, model.thread_count)
        self.external = np.zeros((model.node_count, 3))
        """External forces other than gravity [N], shape (N, 3)."""
        self.cg_tolerance = 1e-8
        """Relative residual at which the implicit solve stops [-]."""

    def advance(self, state: NetState, t_end: float) -> None:
        interval = t_end - state.time
        if interval <= 0:
            return
        steps = self.steps_for(interval)
        m, w = self.model, self.work
        taken = integrators.advance(
            integrators.INTEGRATOR_IDS[self.integrator], steps, state.position, state.velocity,
            m.mass, m.pairs, m.rest_length, m.axial_stiffness, m.axial_damping, self.gravity,
            self.external, interval / steps, self.cg_tolerance, w.force, w.tension, w.along,
            w.across, w.axis, w.dv, w.cg, w.block_inv, w.cg_iterations)
        self.steps += taken
        state.time = t_end if taken == steps else state.time + taken * interval / steps

    def stats(self) -> dict:
        return {"steps": self.steps, "cg_iterations": int(self.work.cg_iterations[0])}
