"""The bullet engine: every node a small PyBullet sphere body; thread forces computed by the
shared kernels and applied as external forces every step; PyBullet integrates.

PyBullet's rigid-body update is semi-implicit Euler (v += dt F / m, then x += dt v; likewise
for the angular velocity and the orientation), so the engine applies m dv / dt for the
integrator's velocity increment dv (for ``symplectic_euler`` that is the net force itself) and
the bending torques: PyBullet then takes exactly the integrator's step. Threads are forces,
not PyBullet constraints: a point-to-point constraint is bilateral and cannot go slack.

Bodies are created without collision shapes when the scene has no contact, with zero linear
and angular damping, sleeping disabled, and a sphere's inertia 2 m r^2 / 5.

With contact, PyBullet does it all: node spheres and the debris (a compound of convex hulls
of its primitives, a dynamic body) collide in PyBullet's constraint solver, which treats a
contact's stiffness and damping implicitly (through its error reduction and constraint force
mixing), with per-body values fitted to the paper's pairs (:mod:`.bullet_materials`) and one
friction coefficient per pair (static = kinetic). The contact forces PyBullet reports are
recorded like the fast engine's.
"""

from __future__ import annotations

import numpy as np

from ..kernels.breakage import break_cables, break_threads
from ..kernels.cable import reel
from ..kernels.peaks import track_cables, track_threads
from ..kernels.reel import reel_tether
from ..model.debris import COM, OMEGA, QUAT, VELOCITY, body_origin
from ..model.net import NodeKind
from ..model.state import NetState
from ..solver import integrators
from ..solver.contact_stage import CLASS_OF_KIND
from .base import Engine
from .bullet_materials import fit
from .debris_body import collision_shape, create_body, orbit_load, read_state
from .quiet import bullet_client, pybullet


class BulletEngine(Engine):
    name = "bullet"
    handles_contact = False

    def __init__(self, scenario, model):
        super().__init__(scenario, model)
        self.pb = pybullet()
        self.client = bullet_client()
        c = self.client
        c.setGravity(0.0, 0.0, 0.0)  # gravity is in the forces we apply (one implementation)
        c.setPhysicsEngineParameter(numSubSteps=0, deterministicOverlappingPairs=1)
        self.bodies = []
        self.debris_body = None
        self._step_set = None
        self.materials = (fit(scenario, model, self.debris is not None)
                          if scenario.contact.enabled else None)
        """Per-body contact values fitted to the pair tables (with contact)."""

    def _create(self, state: NetState) -> None:
        c, m = self.client, self.model
        for i in range(m.node_count):
            shape = -1
            cls = CLASS_OF_KIND[NodeKind(m.kind[i])]
            if self.scenario.contact.enabled and cls >= 0:
                shape = c.createCollisionShape(self.pb.GEOM_SPHERE, radius=float(m.radius[i]))
            # a multibody base, not a maximal-coordinates body: PyBullet 3.2.7 applies
            # applyExternalTorque on the latter one step late (measured on a single body)
            body = c.createMultiBody(baseMass=float(m.mass[i]), baseCollisionShapeIndex=shape,
                                     basePosition=state.position[i].tolist())
            # mass and inertia must be set together, or PyBullet zeroes the mass
            c.changeDynamics(body, -1, linearDamping=0.0, angularDamping=0.0,
                             mass=float(m.mass[i]), localInertiaDiagonal=[m.inertia[i]] * 3,
                             activationState=self.pb.ACTIVATION_STATE_DISABLE_SLEEPING)
            c.resetBaseVelocity(body, linearVelocity=state.velocity[i].tolist())
            if m.fixed[i]:  # a clamp is a rigid joint: a PyBullet fixed constraint to the world
                c.createConstraint(body, -1, -1, -1, self.pb.JOINT_FIXED, [0, 0, 0], [0, 0, 0],
                                   state.position[i].tolist())
            if self.materials is not None and cls >= 0:
                self._set_material(body, cls)
            self.bodies.append(body)
        if self.debris is not None:
            shape = (collision_shape(c, self.debris) if self.scenario.contact.enabled
                     else -1)
            self.debris_body = create_body(c, self.debris, body_origin(state.debris, self.debris),
                                           state.debris[QUAT], state.debris[VELOCITY],
                                           state.debris[OMEGA], collision_shape=shape)
            if self.materials is not None:
                self._set_material(self.debris_body, 0)
        if self.scenario.contact.enabled and not self.scenario.contact.self_contact:
            for body in self.bodies:  # nodes (group 1) collide with the debris (group 2) only
                c.setCollisionFilterGroupMask(body, -1, 1, 2)
            if self.debris_body is not None:
                c.setCollisionFilterGroupMask(self.debris_body, -1, 2, 1)
        self._node_of_body = {body: i for i, body in enumerate(self.bodies)}

    def _set_material(self, body: int, cls: int) -> None:
        mat = self.materials
        self.client.changeDynamics(body, -1, contactStiffness=float(mat.stiffness[cls]),
                                   contactDamping=float(mat.damping[cls]),
                                   lateralFriction=float(mat.friction[cls]), restitution=0.0,
                                   rollingFriction=0.0, spinningFriction=0.0)

    def _read(self, state: NetState) -> None:
        pose, twist = self.client.getBasePositionAndOrientation, self.client.getBaseVelocity
        poses = [pose(body) for body in self.bodies]
        twists = [twist(body) for body in self.bodies]
        state.position[:] = [p[0] for p in poses]
        state.velocity[:] = [t[0] for t in twists]
        if self.bending:
            state.orientation[:] = [p[1] for p in poses]
            state.angular_velocity[:] = [t[1] for t in twists]

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
        c, w = self.client, self.work
        method = integrators.INTEGRATOR_IDS[self.integrator]
        held = self.implicit
        increment = integrators.increment(self.implicit)
        apply, apply_torque = c.applyExternalForce, c.applyExternalTorque
        frame = self.pb.WORLD_FRAME
        mass_over_dt = self.model.mass[:, None] / dt
        first_step = self.steps
        for k in range(steps):
            self.between_steps(state.time + k * dt, state.time + (k + 1) * dt)
            base = self.base_forces()  # after the hooks, which may change the external forces
            reel(state.position, self.arrays.cables,
                 state.time + (self.steps - first_step) * dt, dt)
            quat, omega = self.rotations(state)
            weight = integrators.bending_weight(self.bending, self.bending_every, w)
            increment(weight, state.position, state.velocity, quat, omega, self.arrays, w,
                      base, dt, self.cg_tolerance)
            track_threads(w.tension, self.peaks, 0)  # the step's own tensions
            track_cables(self.arrays.cables, self.peaks)
            force = w.dv * mass_over_dt
            for body, f, x in zip(self.bodies, force.tolist(), state.position.tolist(),
                                  strict=True):
                apply(body, -1, f, x, frame)
            if weight > 0.0:
                integrators.angular_gains(method, weight, dt, self.arrays, w.gain)
            if self.bending and (held or weight > 0.0):  # an impulse, or held (see advance)
                # PyBullet's update is dt tau / J: the fast engine's gain, as torque
                scale = w.gain * (self.model.inertia / dt * (1.0 if held else weight))
                torque = w.torque * scale[:, None]
                for body, tau in zip(self.bodies, torque.tolist(), strict=True):
                    apply_torque(body, -1, tau, frame)
            if self.arrays.orbit is not None and self.debris_body is not None:
                self._orbit_debris(state)
            c.stepSimulation()
            self.steps += 1
            if self.materials is not None:
                self._collect_contacts(dt, state.time + (self.steps - first_step) * dt)
            self._read(state)
            if self.breakage is not None:  # the step's tensions, at its end's positions
                a, t = self.arrays, state.time + (self.steps - first_step - 1) * dt
                break_threads(state.position, a.pairs, a.rest, w.tension, a.k_a, a.c_a, a.k_t,
                              a.c_t, a.k_b, a.c_b, self.breakage, t)
                break_cables(state.position, a.cables, self.breakage, t)
            if self.arrays.reel is not None:  # the tether's rest lengths for the next step
                a = self.arrays
                reel_tether(state.position, state.velocity, a.reel, a.rest, a.rest_rate, a.k_a,
                            a.c_a, state.time + k * dt, dt)
            if not np.isfinite(state.position).all():
                break
        if self.debris_body is not None:
            read_state(c, self.debris_body, state.debris, self.debris)
        self._impulse_time += interval
        state.time = t_end

    def _orbit_debris(self, state: NetState) -> None:
        """Apply the orbit's HCW force and gravity-gradient torque to the debris' body, at its
        state before this step (:func:`~bulletnet.engines.debris_body.orbit_load`)."""
        c = self.client
        read_state(c, self.debris_body, state.debris, self.debris)
        load = orbit_load(self.arrays.orbit, self.debris, state.debris).tolist()
        c.applyExternalForce(self.debris_body, -1, load[:3], state.debris[COM].tolist(),
                             self.pb.WORLD_FRAME)
        c.applyExternalTorque(self.debris_body, -1, load[3:], self.pb.WORLD_FRAME)

    def _collect_contacts(self, dt: float, t: float) -> None:
        """Add the step's PyBullet contact impulses (normal force x dt) to the per-node
        accumulators: debris contacts to ``node_impulse``, node pairs to ``self_impulse``."""
        a = self.contact.arrays
        node = self._node_of_body
        for point in self.client.getContactPoints():
            body_a, body_b, force = point[1], point[2], point[9]
            if force <= 0.0:
                continue
            if self.debris_body in (body_a, body_b):
                other = body_b if body_a == self.debris_body else body_a
                a.node_impulse[node[other]] += force * dt
                if a.first_contact[0] < 0:
                    a.first_contact[0] = t
            else:
                a.self_impulse[node[body_a]] += force * dt
                a.self_impulse[node[body_b]] += force * dt
                if a.first_contact[1] < 0:
                    a.first_contact[1] = t

    def close(self) -> None:
        if self.client is not None:
            self.client.disconnect()
            self.client = None
