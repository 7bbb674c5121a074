"""The fast engine: the whole net integrated in compiled loops; no PyBullet world when the
scene has no contact."""

from __future__ import annotations

from .. import integrators
from ..state import NetState
from .base import Engine


class FastEngine(Engine):
    name = "fast"

    def advance(self, state: NetState, t_end: float) -> None:
        interval = t_end - state.time
        if interval <= 0:
            return
        steps = self.steps_for(interval)
        quat, omega = self.rotations(state)
        integrators.advance(
            integrators.INTEGRATOR_IDS[self.integrator], self.bending, self.bending_every, steps,
            state.position,
            state.velocity, quat, omega, self.arrays, self.work.arrays(), self.gravity,
            self.external, interval / steps, self.cg_tolerance)
        self.steps += steps
        state.time = t_end
