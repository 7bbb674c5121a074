"""The fast engine: the whole net, and its contact, integrated in compiled loops; PyBullet
only for the debris' rigid-body dynamics, in a world of its own (no PyBullet world at all in
a scene without debris).

With debris, the run advances in chunks of ``debris.step``: the compiled loop moves the
debris rigidly at its current velocity and sums the net's contact impulses on it; PyBullet
then applies them as a constant force and torque over the chunk and takes one step of the
debris (5 orders of magnitude heavier than a node: its velocity changes little in a chunk).
"""

from __future__ import annotations

import numpy as np

from .. import contact, integrators
from ..debris import RigidDebris
from ..state import NetState
from .base import Engine


class FastEngine(Engine):
    name = "fast"

    def __init__(self, scenario, model):
        super().__init__(scenario, model)
        self.rigid = None
        """The debris' PyBullet world (created on the first step)."""

    def advance(self, state: NetState, t_end: float) -> None:
        interval = t_end - state.time
        if interval <= 0:
            return
        steps = self.steps_for(interval)
        dt = interval / steps
        has_debris = self.debris is not None  # (with contact off it still moves)
        chunk = max(1, round(self.scenario.debris.step / dt)) if has_debris else steps
        if has_debris and self.rigid is None:
            self.rigid = RigidDebris(self.debris, state.debris)
        quat, omega = self.rotations(state)
        a = self.contact.arrays
        done = 0
        while done < steps:
            todo = min(chunk, steps - done)
            if has_debris:
                a.com[:], a.quat[0] = state.debris[:3], state.debris[3:7]
                a.velocity[:], a.omega[0] = state.debris[7:10], state.debris[10:]
                a.impulse[:] = 0.0
            taken = integrators.advance(
                integrators.INTEGRATOR_IDS[self.integrator], self.bending, self.bending_every,
                todo, state.position, state.velocity, quat, omega, self.arrays,
                self.work, self.gravity, self.external, dt, self.cg_tolerance, a,
                state.time + done * dt)
            if taken < todo:  # the self-contact list is full: grow it, go on
                self.contact = contact.grow_pair_list(self.contact)
                a = self.contact.arrays
            if has_debris and taken:
                self.rigid.step(a.impulse, taken * dt, state.debris)
            done += taken
            self._impulse_time += taken * dt
            if not np.isfinite(state.position).all():
                break
        self.steps += done
        state.time = t_end

    def close(self) -> None:
        if self.rigid is not None:
            self.rigid.close()
            self.rigid = None
