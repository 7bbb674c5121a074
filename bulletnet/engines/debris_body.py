"""The debris as a PyBullet rigid body: its body and compound collision shape in a PyBullet
world, its state read back, and :class:`RigidDebris` (the fast engine's debris dynamics: a
PyBullet world of its own)."""

from __future__ import annotations

import math
import tempfile
from pathlib import Path

import numpy as np

from ..kernels.orbit import OrbitArrays, debris_load
from ..model.debris import (
    COM,
    OMEGA,
    QUAT,
    VELOCITY,
    Debris,
    body_origin,
    part_mesh,
    quaternion_product,
    rotation_matrix,
    rotation_quaternion,
)
from .quiet import bullet_client, pybullet, quiet_stdout


def create_body(client, debris: Debris, position, orientation=(0.0, 0.0, 0.0, 1.0),
                linear_velocity=(0.0, 0.0, 0.0), angular_velocity=(0.0, 0.0, 0.0),
                collision_shape: int = -1) -> int:
    """A dynamic PyBullet body for ``debris`` with its body-frame origin at ``position`` [m]
    and ``orientation`` (quaternion x, y, z, w), moving at the given velocities [m/s, rad/s]
    (world frame). Mass and the principal moments are set explicitly, on an inertial frame at
    the centre of mass along the principal axes, with sleeping and damping off. PyBullet then
    reports the inertial frame's pose: :func:`read_state` turns it back into the body's."""
    body = client.createMultiBody(
        baseMass=debris.mass, baseCollisionShapeIndex=collision_shape,
        basePosition=list(position), baseOrientation=list(orientation),
        baseInertialFramePosition=debris.center_of_mass.tolist(),
        baseInertialFrameOrientation=debris.principal_quaternion.tolist())
    client.changeDynamics(body, -1, mass=debris.mass,
                          localInertiaDiagonal=debris.principal_moments.tolist(),
                          linearDamping=0.0, angularDamping=0.0,
                          activationState=pybullet().ACTIVATION_STATE_DISABLE_SLEEPING)
    client.resetBaseVelocity(body, list(linear_velocity), list(angular_velocity))
    return body


def collision_shape(client, debris: Debris, sections: int = 48) -> int:
    """A PyBullet compound collision shape of the parts at their poses in the body frame:
    boxes, spheres and cylinders as PyBullet's own primitives, other frustums as convex hulls
    (polygons of ``sections`` sides), a convex or open mesh as its hull and a non-convex solid
    one as the hulls of its convex decomposition by ``pybullet.vhacd`` (PyBullet builds compounds of
    meshes from files only: OBJ files in a temporary folder)."""

    pb = pybullet()
    shapes, frames = [], []
    kw = {"halfExtents": [], "radii": [], "lengths": [], "fileNames": []}
    with tempfile.TemporaryDirectory() as folder:
        for k, part in enumerate(debris.parts):
            position, orientation = np.asarray(part.position), part.quaternion
            half, radius, length, name = [0.0] * 3, 0.0, 0.0, ""
            if part.shape == "box":
                shapes.append(pb.GEOM_BOX)
                half = (0.5 * np.asarray(part.size)).tolist()
            elif part.shape == "sphere":
                shapes.append(pb.GEOM_SPHERE)
                radius = part.size[0]
            elif part.shape == "frustum" and part.size[2] == part.size[3]:
                shapes.append(pb.GEOM_CYLINDER)  # a cylinder; PyBullet's is along z
                radius, length = part.size[2], part.size[1] - part.size[0]
                position = position + part.matrix[:, 1] * 0.5 * (part.size[0] + part.size[1])
                z_to_y = rotation_quaternion([-0.5 * math.pi, 0.0, 0.0])
                orientation = quaternion_product(orientation, z_to_y)
            else:
                shapes.append(pb.GEOM_MESH)
                name = str(Path(folder) / f"part{k}.obj")
                mesh = part_mesh(part, sections, frame="part")
                mesh.export(name)
                if part.shape == "mesh" and part.closed and not mesh.is_convex:
                    # PyBullet collides with each mesh's convex hull: split a solid into
                    # convex pieces first (the file then holds one hull per piece; an open
                    # mesh keeps its hull)
                    with quiet_stdout():
                        pb.vhacd(name, name, str(Path(folder) / "vhacd.log"))
            for key, value in zip(kw, (half, radius, length, name), strict=True):
                kw[key].append(value)
            frames.append((position.tolist(), orientation.tolist()))
        return client.createCollisionShapeArray(
            shapeTypes=shapes, meshScales=[[1.0, 1.0, 1.0]] * len(shapes),
            collisionFramePositions=[f[0] for f in frames],
            collisionFrameOrientations=[f[1] for f in frames], **kw)


class RigidDebris:
    """The debris as a dynamic PyBullet body in a world of its own (the fast engine's
    debris dynamics): net impulses in, rigid motion out."""

    def __init__(self, debris: Debris, state: np.ndarray):
        self.pb = pybullet()
        self.debris = debris
        self.client = bullet_client()
        self.client.setGravity(0.0, 0.0, 0.0)
        self.body = create_body(self.client, debris, body_origin(state, debris), state[QUAT],
                                state[VELOCITY], state[OMEGA])
        self.world = self.client._client
        """PyBullet's id of this world: :meth:`step` calls the module's functions with it, as
        the client does, without the client's lookup of each function at each call."""
        self._step = None
        self._com = self.client.getBasePositionAndOrientation(self.body)[0]
        """The body's centre of mass [m] as PyBullet last reported it (nothing else moves
        the body: :meth:`step` keeps it)."""

    def step(self, impulse: np.ndarray, interval: float, state: np.ndarray) -> None:
        """Apply ``impulse`` (6,) (force [N s], moment about the centre of mass [N m s],
        world frame) as constant force and torque over ``interval`` [s], step, and write the
        new debris state (:data:`~bulletnet.model.debris.STATE_SIZE`,) into ``state``."""
        pb, world, body = self.pb, self.world, self.body
        if self._step != interval:
            pb.setPhysicsEngineParameter(fixedTimeStep=interval, numSubSteps=0,
                                         physicsClientId=world)
            self._step = interval
        load = (impulse / interval).tolist()  # force [N], torque [N m]
        pb.applyExternalForce(body, -1, load[:3], self._com, pb.WORLD_FRAME,
                              physicsClientId=world)
        pb.applyExternalTorque(body, -1, load[3:], pb.WORLD_FRAME, physicsClientId=world)
        pb.stepSimulation(physicsClientId=world)
        self._com, q = pb.getBasePositionAndOrientation(body, physicsClientId=world)
        write_state(state, self.debris, self._com, q,
                    *pb.getBaseVelocity(body, physicsClientId=world))

    def close(self) -> None:
        self.client.disconnect()
        self.world = -1  # (PyBullet reuses the id for the next world)


def orbit_load(orbit: OrbitArrays, debris: Debris, state: np.ndarray) -> np.ndarray:
    """The reference orbit's HCW force [N] on ``debris`` in ``state`` (at its centre of mass)
    and its gravity-gradient and rotating frame's torque [N m]
    (:func:`~bulletnet.kernels.orbit.debris_load`; its inertia turned into the scene's
    frame), shape (6,)."""
    rot = rotation_matrix(state[QUAT])
    return debris_load(orbit, debris.mass, rot @ debris.inertia @ rot.T, state[COM],
                       state[VELOCITY], state[OMEGA])


def read_state(client, body: int, state: np.ndarray, debris: Debris) -> None:
    """Write the state (:data:`~bulletnet.model.debris.STATE_SIZE`,) of ``debris``' PyBullet body
    into ``state`` (:func:`write_state`)."""
    com, q = client.getBasePositionAndOrientation(body)
    write_state(state, debris, com, q, *client.getBaseVelocity(body))


def write_state(state: np.ndarray, debris: Debris, com, q, v, w) -> None:
    """Write into ``state`` (:data:`~bulletnet.model.debris.STATE_SIZE`,) the debris' state from
    its PyBullet body's centre of mass [m], orientation (x, y, z, w), velocity [m/s] and angular
    velocity [rad/s]: PyBullet's orientation is its inertial frame's, the body frame's times
    the principal axes' rotation."""
    p = debris.principal_quaternion
    if p[3] != 1.0:  # principal axes off the body axes (else q as it is, zeros' signs too)
        q = quaternion_product(q, (-p[0], -p[1], -p[2], p[3]))
    state[:] = (*com, *q, *v, *w)
