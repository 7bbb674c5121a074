"""The bullet engine: every node a small PyBullet sphere body; thread forces computed by the
shared kernels and applied as external forces every step; PyBullet integrates.

PyBullet's rigid-body update is semi-implicit Euler (v += dt F / m, then x += dt v), so with
the ``symplectic_euler`` integrator the forces applied are the threads' forces, and with
``implicit_euler`` they are m dv / dt for the implicit increment dv: PyBullet then takes
exactly the implicit step. Threads are forces, not PyBullet constraints: a point-to-point
constraint is bilateral and cannot go slack.

Bodies are created without collision shapes when the scene has no contact, with zero linear
and angular damping, sleeping disabled, and a sphere's inertia 2 m r^2 / 5.
"""

from __future__ import annotations

import contextlib
import os
import sys

import numpy as np

from .. import integrators
from ..state import NetState
from .base import Engine


class BulletEngine(Engine):
    name = "bullet"

    def __init__(self, scenario, model):
        super().__init__(scenario, model)
        with _quiet_stdout():  # pybullet prints its build time and argv on import/connect
            import pybullet
            from pybullet_utils.bullet_client import BulletClient

            self.pb = pybullet
            self.client = BulletClient(connection_mode=pybullet.DIRECT)
        c = self.client
        c.setGravity(*self.gravity)
        c.setPhysicsEngineParameter(numSubSteps=0, deterministicOverlappingPairs=1)
        self.bodies = []
        self._step_set = None
        self.work = integrators.Workspace(model.node_count, model.thread_count)
        self.external = np.zeros((model.node_count, 3))
        self.cg_tolerance = 1e-8
        self.gravity_free = np.zeros(3)  # PyBullet applies gravity itself

    def _create(self, state: NetState) -> None:
        c, m = self.client, self.model
        for i in range(m.node_count):
            shape = -1
            if self.scenario.contact.enabled:
                shape = c.createCollisionShape(self.pb.GEOM_SPHERE, radius=float(m.radius[i]))
            body = c.createMultiBody(baseMass=float(m.mass[i]), baseCollisionShapeIndex=shape,
                                     basePosition=state.position[i].tolist(),
                                     useMaximalCoordinates=True)
            inertia = 0.4 * m.mass[i] * m.radius[i] ** 2
            # mass and inertia must be set together, or PyBullet zeroes the mass
            c.changeDynamics(body, -1, linearDamping=0.0, angularDamping=0.0,
                             mass=float(m.mass[i]), localInertiaDiagonal=[inertia] * 3,
                             activationState=self.pb.ACTIVATION_STATE_DISABLE_SLEEPING)
            c.resetBaseVelocity(body, linearVelocity=state.velocity[i].tolist())
            self.bodies.append(body)

    def _read(self, state: NetState) -> None:
        pose, twist = self.client.getBasePositionAndOrientation, self.client.getBaseVelocity
        state.position[:] = [pose(body)[0] for body in self.bodies]
        state.velocity[:] = [twist(body)[0] for body in self.bodies]

    def advance(self, state: NetState, t_end: float) -> None:
        interval = t_end - state.time
        if interval <= 0:
            return
        if not self.bodies:
            self._create(state)
        steps = self.steps_for(interval)
        dt = interval / steps
        if self._step_set != dt:
            self.client.setPhysicsEngineParameter(fixedTimeStep=dt)
            self._step_set = dt
        m, w, c = self.model, self.work, self.client
        implicit = self.integrator == "implicit_euler"
        apply = c.applyExternalForce
        frame = self.pb.WORLD_FRAME
        for _ in range(steps):
            if implicit:
                integrators.implicit_increment(
                    state.position, state.velocity, m.mass, m.pairs, m.rest_length,
                    m.axial_stiffness, m.axial_damping, self.gravity_free, self.external, dt,
                    self.cg_tolerance, w.force, w.tension, w.along, w.across, w.axis, w.dv,
                    w.cg, w.block_inv, w.cg_iterations)
                force = w.dv * (m.mass[:, None] / dt)
            else:
                integrators.symplectic_increment(
                    state.position, state.velocity, m.mass, m.pairs, m.rest_length,
                    m.axial_stiffness, m.axial_damping, self.gravity_free, self.external, dt,
                    w.force, w.tension, w.dv)
                force = w.force
            for body, f, x in zip(self.bodies, force.tolist(), state.position.tolist(),
                                  strict=True):
                apply(body, -1, f, x, frame)
            c.stepSimulation()
            self.steps += 1
            self._read(state)
            if not np.isfinite(state.position).all():
                break
        state.time = t_end

    def stats(self) -> dict:
        return {"steps": self.steps, "cg_iterations": int(self.work.cg_iterations[0])}

    def close(self) -> None:
        if self.client is not None:
            self.client.disconnect()
            self.client = None


@contextlib.contextmanager
def _quiet_stdout():
    """Silence file descriptors 1 and 2 (C-level prints) for the duration of the block."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = [os.dup(1), os.dup(2)]
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 1)
    os.dup2(devnull, 2)
    try:
        yield
    finally:
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        for fd in (*saved, devnull):
            os.close(fd)
