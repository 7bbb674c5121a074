"""Debris built from primitives: axisymmetric frustums along the body y axis (a cylinder has
equal radii, a cone a zero radius), each a solid of uniform density.

Mass, centre of mass and inertia are computed from the geometry with trimesh (polygonal
solids of revolution, :data:`SECTIONS` sides) and set explicitly on the PyBullet body, whose own
estimate from a compound shape's bounding box is about 2x off for the Apollo CSM.
"""

from __future__ import annotations

import functools
import math
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import ScenarioError

ASSET_DIR = Path(__file__).resolve().parent.parent / "assets"
"""Folder of the shipped debris assets (``apollo_csm`` names ``assets/apollo_csm.toml``)."""

SECTIONS = 256
"""Sides of the polygons approximating circular sections (volume error ~ 1e-4 relative)."""


@dataclass(frozen=True)
class Part:
    name: str
    y_start: float
    """Start of the part along the body y axis [m]."""
    y_end: float
    """End of the part along the body y axis [m], > y_start."""
    radius_start: float
    """Radius at y_start [m]."""
    radius_end: float
    """Radius at y_end [m]."""
    mass: float
    """Mass of the part [kg]."""


@dataclass(frozen=True)
class Debris:
    name: str
    parts: tuple[Part, ...]
    mass: float
    """Total mass [kg]."""
    center_of_mass: np.ndarray
    """Centre of mass in the body frame [m], shape (3,)."""
    inertia: np.ndarray
    """Inertia tensor about the centre of mass, body axes [kg m^2], shape (3, 3)."""
    length: float
    """Extent along the body y axis [m]."""
    diameter: float
    """Largest diameter [m]."""


def part_mesh(part: Part, sections: int = SECTIONS):
    """The part as a closed trimesh solid (convex hull of its two end sections, circles as
    polygons of ``sections`` sides), in [m]."""
    import trimesh

    angles = np.linspace(0.0, 2.0 * math.pi, sections, endpoint=False)
    rings = []
    for y, r in ((part.y_start, part.radius_start), (part.y_end, part.radius_end)):
        if r == 0.0:
            rings.append(np.array([[0.0, y, 0.0]]))
        else:
            rings.append(np.stack([r * np.cos(angles), np.full(sections, y),
                                   r * np.sin(angles)], axis=1))
    return trimesh.Trimesh(vertices=np.vstack(rings)).convex_hull


def mass_properties(parts: tuple[Part, ...]) -> tuple[float, np.ndarray, np.ndarray]:
    """(mass [kg], centre of mass (3,) [m], inertia about it (3, 3) [kg m^2]) of the parts,
    each of uniform density, combined with the parallel-axis theorem."""
    masses, centres, inertias = [], [], []
    for part in parts:
        mesh = part_mesh(part)
        mesh.density = part.mass / mesh.volume
        masses.append(part.mass)
        centres.append(np.asarray(mesh.center_mass))
        inertias.append(np.asarray(mesh.moment_inertia))  # about the part's own centre
    total = float(sum(masses))
    com = sum(m * c for m, c in zip(masses, centres, strict=True)) / total
    inertia = np.zeros((3, 3))
    for m, c, i in zip(masses, centres, inertias, strict=True):
        d = c - com
        inertia += i + m * (np.dot(d, d) * np.eye(3) - np.outer(d, d))
    return total, com, inertia


def _part(doc: dict, where: str) -> Part:
    known = {"name", "shape", "y_start", "y_end", "radius_start", "radius_end", "mass"}
    unknown = sorted(set(doc) - known)
    if unknown:
        raise ScenarioError(f"{where}: unknown key '{unknown[0]}' (expected one of: "
                            f"{', '.join(sorted(known))})")
    if doc.get("shape", "frustum") != "frustum":
        raise ScenarioError(f"{where}.shape: expected \"frustum\", got {doc['shape']!r}")
    values = {}
    for key, unit in (("y_start", "m"), ("y_end", "m"), ("radius_start", "m"),
                      ("radius_end", "m"), ("mass", "kg")):
        v = doc.get(key)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise ScenarioError(f"{where}.{key}: expected a finite number [{unit}], got {v!r}")
        values[key] = float(v)
    if values["y_end"] <= values["y_start"]:
        raise ScenarioError(f"{where}: y_end must exceed y_start")
    if min(values["radius_start"], values["radius_end"]) < 0 or max(
            values["radius_start"], values["radius_end"]) <= 0:
        raise ScenarioError(f"{where}: radii must be >= 0 and not both 0")
    if values["mass"] <= 0:
        raise ScenarioError(f"{where}.mass: expected a positive number [kg]")
    return Part(name=str(doc.get("name", "part")), **values)


@functools.lru_cache(maxsize=8)
def load_debris(name_or_path: str) -> Debris:
    """A debris asset by name (``apollo_csm``) or path, with its computed mass properties
    (cached: treat the result as read-only)."""
    path = Path(name_or_path)
    if not path.is_file():
        path = ASSET_DIR / f"{name_or_path}.toml"
    if not path.is_file():
        raise ScenarioError(f"{name_or_path}: no such debris asset")
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise ScenarioError(f"{path}: cannot read: {exc}") from None
    raw = doc.get("parts")
    if not isinstance(raw, list) or not raw:
        raise ScenarioError(f"{path}: expected one or more [[parts]] tables")
    parts = tuple(_part(p, f"{path}: parts[{k}]") for k, p in enumerate(raw))
    mass, com, inertia = mass_properties(parts)
    return Debris(
        name=str(doc.get("name", path.stem)), parts=parts, mass=mass, center_of_mass=com,
        inertia=inertia,
        length=max(p.y_end for p in parts) - min(p.y_start for p in parts),
        diameter=2 * max(max(p.radius_start, p.radius_end) for p in parts))


def create_body(client, debris: Debris, position, orientation=(0.0, 0.0, 0.0, 1.0),
                linear_velocity=(0.0, 0.0, 0.0), angular_velocity=(0.0, 0.0, 0.0),
                collision_shape: int = -1) -> int:
    """A dynamic PyBullet body for ``debris`` with its body-frame origin at ``position`` [m]
    and ``orientation`` (quaternion x, y, z, w), moving at the given velocities [m/s, rad/s]
    (world frame). Mass and the principal inertia are set explicitly (the body is axisymmetric
    about y, so the body axes are principal), with sleeping and damping off."""
    import pybullet

    body = client.createMultiBody(
        baseMass=debris.mass, baseCollisionShapeIndex=collision_shape,
        basePosition=list(position), baseOrientation=list(orientation),
        baseInertialFramePosition=debris.center_of_mass.tolist())
    client.changeDynamics(body, -1, mass=debris.mass,
                          localInertiaDiagonal=np.diag(debris.inertia).tolist(),
                          linearDamping=0.0, angularDamping=0.0,
                          activationState=pybullet.ACTIVATION_STATE_DISABLE_SLEEPING)
    client.resetBaseVelocity(body, list(linear_velocity), list(angular_velocity))
    return body


STATE_SIZE = 13
"""Length of a debris state vector: centre of mass [m] (3), orientation quaternion x, y, z, w
(4), velocity of the centre of mass [m/s] (3), angular velocity, world frame [rad/s] (3)."""


def rotation_quaternion(rotation_vector) -> np.ndarray:
    """Unit quaternion (x, y, z, w) of a rotation vector [rad], shape (3,) -> (4,)."""
    r = np.asarray(rotation_vector, dtype=float)
    angle = float(np.linalg.norm(r))
    if angle == 0.0:
        return np.array([0.0, 0.0, 0.0, 1.0])
    return np.append(r / angle * math.sin(angle / 2), math.cos(angle / 2))


def rotation_matrix(q) -> np.ndarray:
    """Rotation matrices of unit quaternions (x, y, z, w): shape (..., 4) -> (..., 3, 3)."""
    x, y, z, w = np.moveaxis(np.asarray(q, dtype=float), -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1)],
        -2)


def initial_state(scene, debris: Debris) -> np.ndarray:
    """Debris state (:data:`STATE_SIZE`,) from a scene's ``[debris]`` table (origin position
    [m], rotation vector [deg], velocity [m/s], angular velocity [deg/s])."""
    q = rotation_quaternion(np.radians(scene.rotation))
    com = np.asarray(scene.position) + rotation_matrix(q) @ debris.center_of_mass
    return np.concatenate([com, q, scene.velocity, np.radians(scene.angular_velocity)])


def body_origin(state: np.ndarray, debris: Debris) -> np.ndarray:
    """World position [m] (3,) of the body-frame origin (the geometric centre) of a debris
    in ``state``."""
    return state[:3] - rotation_matrix(state[3:7]) @ debris.center_of_mass


def visual_mesh(debris: Debris, sections: int = 48) -> tuple[np.ndarray, np.ndarray]:
    """(vertices (V, 3) [m], faces (F, 3)) of the debris' surface in its body frame."""
    import trimesh

    meshes = [part_mesh(p, sections) for p in debris.parts]
    mesh = trimesh.util.concatenate(meshes)
    return np.asarray(mesh.vertices), np.asarray(mesh.faces, dtype=np.int64)


def collision_shape(client, debris: Debris, sections: int = 48) -> int:
    """A PyBullet compound collision shape: one convex hull per part, in the body frame
    (PyBullet builds compounds of meshes from files only: OBJ files in a temporary folder)."""
    import tempfile

    import pybullet

    with tempfile.TemporaryDirectory() as folder:
        names = []
        for k, part in enumerate(debris.parts):
            names.append(str(Path(folder) / f"part{k}.obj"))
            part_mesh(part, sections).export(names[-1])
        return client.createCollisionShapeArray(
            shapeTypes=[pybullet.GEOM_MESH] * len(names), fileNames=names)


class RigidDebris:
    """The debris as a dynamic PyBullet body in a world of its own (the fast engine's
    debris dynamics): net impulses in, rigid motion out."""

    def __init__(self, debris: Debris, state: np.ndarray):
        import pybullet
        from pybullet_utils.bullet_client import BulletClient

        self.pybullet = pybullet
        self.client = BulletClient(connection_mode=pybullet.DIRECT)
        self.client.setGravity(0.0, 0.0, 0.0)
        self.body = create_body(self.client, debris, body_origin(state, debris), state[3:7],
                                state[7:10], state[10:13])
        self._step = None

    def step(self, impulse: np.ndarray, interval: float, state: np.ndarray) -> None:
        """Apply ``impulse`` (6,) (force [N s], moment about the centre of mass [N m s],
        world frame) as constant force and torque over ``interval`` [s], step, and write the
        new debris state (:data:`STATE_SIZE`,) into ``state``."""
        c = self.client
        if self._step != interval:
            c.setPhysicsEngineParameter(fixedTimeStep=interval, numSubSteps=0)
            self._step = interval
        com, _ = c.getBasePositionAndOrientation(self.body)
        frame = self.pybullet.WORLD_FRAME
        c.applyExternalForce(self.body, -1, (impulse[:3] / interval).tolist(), com, frame)
        c.applyExternalTorque(self.body, -1, (impulse[3:] / interval).tolist(), frame)
        c.stepSimulation()
        read_state(c, self.body, state)

    def close(self) -> None:
        self.client.disconnect()


def read_state(client, body: int, state: np.ndarray) -> None:
    """Write a PyBullet body's state (:data:`STATE_SIZE`,) into ``state``."""
    com, q = client.getBasePositionAndOrientation(body)
    v, w = client.getBaseVelocity(body)
    state[:] = (*com, *q, *v, *w)
