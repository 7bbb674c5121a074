"""Debris built from primitives: axisymmetric frustums along the body y axis (a cylinder has
equal radii, a cone a zero radius), each a solid of uniform density.

Mass, centre of mass and inertia are computed from the geometry with trimesh (polygonal
solids of revolution, :data:`SECTIONS` sides) and set explicitly on the PyBullet body, whose own
estimate from a compound shape's bounding box is about 2x off for the Apollo CSM.
"""

from __future__ import annotations

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


def part_mesh(part: Part):
    """The part as a closed trimesh solid (convex hull of its two end sections), in [m]."""
    import trimesh

    angles = np.linspace(0.0, 2.0 * math.pi, SECTIONS, endpoint=False)
    rings = []
    for y, r in ((part.y_start, part.radius_start), (part.y_end, part.radius_end)):
        if r == 0.0:
            rings.append(np.array([[0.0, y, 0.0]]))
        else:
            rings.append(np.stack([r * np.cos(angles), np.full(SECTIONS, y),
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


def load_debris(name_or_path: str) -> Debris:
    """A debris asset by name (``apollo_csm``) or path, with its computed mass properties."""
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
