"""Debris built from parts, each a solid of uniform density at its own pose in the body frame:
frustums along their part frame's y axis (a cylinder has equal radii, a cone a zero radius),
boxes, spheres and closed triangle meshes from files (:mod:`bulletnet.model.mesh`); or a whole
debris from one mesh file.

Mass, centre of mass and inertia are computed from the geometry with trimesh (polygonal
solids of revolution of :data:`SECTIONS` sides, icospheres) and set explicitly on the
PyBullet body (:mod:`bulletnet.engines.debris_body`), whose own estimate from a compound shape's
bounding box is about 2x off for
the Apollo CSM. A body whose products of inertia do not vanish (parts off its axes) gets its
principal axes as PyBullet's inertial frame.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..common.array_cache import cached_arrays
from ..common.errors import ScenarioError
from ..common.resources import data_dir
from .mesh import MESH_SUFFIXES, load_mesh

ASSET_DIR = data_dir("assets")
"""Folder of the shipped debris assets (``apollo_csm`` names ``assets/apollo_csm.toml``)."""

SECTIONS = 256
"""Sides of the polygons approximating circular sections (volume error ~ 1e-4 relative);
spheres are icospheres with at least as many edges around a great circle."""

SHAPES = ("frustum", "box", "sphere", "mesh")
"""Part shapes."""

PRINCIPAL_TOLERANCE = 1e-12
"""Products of inertia below this fraction of the largest moment are round-off of the
tessellation (the CSM's are ~1e-17): the body axes are then taken as principal [-]."""


@dataclass(frozen=True)
class Part:
    name: str
    shape: str
    """One of :data:`SHAPES`."""
    size: tuple[float, ...]
    """Dimensions in the part frame [m]: a frustum's (y_start, y_end, radius_start,
    radius_end) along its y axis, a box's edge lengths (x, y, z) about its centre, a sphere's
    (radius,) about its centre; a mesh's none (its vertices are in the part frame)."""
    mass: float
    """Mass of the part [kg]."""
    position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Origin of the part frame in the body frame [m]."""
    rotation: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Rotation of the part frame in the body frame, a rotation vector [deg]."""
    file: str = ""
    """A mesh part's file (:data:`~bulletnet.model.mesh.MESH_SUFFIXES`, coordinates in [m])."""
    center_of_mass: tuple[float, float, float] | None = None
    """Given centre of mass in the part frame [m] (with :attr:`inertia`: a mesh part for
    contact only, which may be open); None: from the solid."""
    inertia: tuple[tuple[float, ...], ...] | None = None
    """Given inertia tensor about :attr:`center_of_mass`, part axes [kg m^2], (3, 3)."""

    @property
    def closed(self) -> bool:
        """Whether the part is a solid (a mesh part with given mass properties need not be)."""
        return self.inertia is None

    @property
    def matrix(self) -> np.ndarray:
        """Rotation from the part frame to the body frame [-], shape (3, 3)."""
        return rotation_matrix(self.quaternion)

    @property
    def quaternion(self) -> np.ndarray:
        """Rotation from the part frame to the body frame, quaternion x, y, z, w [-], (4,)."""
        return rotation_quaternion(np.radians(self.rotation))

    @property
    def volume(self) -> float:
        """Volume of the exact solid [m^3]."""
        if self.shape == "box":
            return float(np.prod(self.size))
        if self.shape == "sphere":
            return 4.0 / 3.0 * math.pi * self.size[0] ** 3
        if self.shape == "mesh":
            return float(load_mesh(self.file, self.closed).volume)
        y0, y1, r0, r1 = self.size
        return math.pi * (y1 - y0) * (r0 * r0 + r0 * r1 + r1 * r1) / 3.0

    def reach(self, point) -> float:
        """Radius [m] of a sphere about ``point`` (body frame [m], (3,)) that holds the part."""
        c = self.matrix.T @ (np.asarray(point, dtype=float) - self.position)  # part frame
        if self.shape == "box":
            return float(np.linalg.norm(np.abs(c) + 0.5 * np.asarray(self.size)))
        if self.shape == "sphere":
            return float(np.linalg.norm(c)) + self.size[0]
        if self.shape == "mesh":
            vertices = load_mesh(self.file, self.closed).vertices
            return float(np.linalg.norm(vertices - c, axis=1).max())
        y0, y1, r0, r1 = self.size
        return math.hypot(max(r0, r1), max(abs(y0 - c[1]), abs(y1 - c[1]))) + float(
            np.hypot(c[0], c[2]))


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
    principal_moments: np.ndarray
    """Principal moments of inertia [kg m^2], shape (3,)."""
    principal_axes: np.ndarray
    """Principal axes (columns) in the body frame, a rotation [-], shape (3, 3): the identity
    when the products of inertia vanish (:data:`PRINCIPAL_TOLERANCE`)."""
    extents: np.ndarray
    """Edge lengths of the body-frame bounding box of the parts [m], shape (3,)."""

    @functools.cached_property
    def principal_quaternion(self) -> np.ndarray:
        """:attr:`principal_axes` as a quaternion x, y, z, w [-], shape (4,) (computed once:
        the fast engine reads it at every debris step)."""
        return matrix_quaternion(self.principal_axes)


def part_mesh(part: Part, sections: int = SECTIONS, frame: str = "body"):
    """The part as a closed trimesh solid in the body frame (or, ``frame="part"``, its own)
    [m]: a frustum is the convex hull of its two end sections (circles as polygons of
    ``sections`` sides), a sphere an icosphere with at least ``sections`` edges around a
    great circle, a mesh part its file's mesh."""
    import trimesh

    if part.shape == "mesh":
        mesh = load_mesh(part.file, part.closed).copy()
    elif part.shape == "box":
        mesh = trimesh.creation.box(extents=part.size)
    elif part.shape == "sphere":
        subdivisions = max(1, math.ceil(math.log2(sections / 5.0)))
        mesh = trimesh.creation.icosphere(subdivisions=subdivisions, radius=part.size[0])
    else:
        y0, y1, r0, r1 = part.size
        angles = np.linspace(0.0, 2.0 * math.pi, sections, endpoint=False)
        rings = []
        for y, r in ((y0, r0), (y1, r1)):
            if r == 0.0:
                rings.append(np.array([[0.0, y, 0.0]]))
            else:
                rings.append(np.stack([r * np.cos(angles), np.full(sections, y),
                                       r * np.sin(angles)], axis=1))
        mesh = trimesh.Trimesh(vertices=np.vstack(rings)).convex_hull
    if frame == "part":
        return mesh
    transform = np.eye(4)
    transform[:3, :3], transform[:3, 3] = part.matrix, part.position
    return mesh.apply_transform(transform)  # the identity leaves the mesh untouched


def mass_properties(parts: tuple[Part, ...]) -> tuple[float, np.ndarray, np.ndarray]:
    """(mass [kg], centre of mass (3,) [m], inertia about it (3, 3) [kg m^2]) of the parts in
    the body frame, each of uniform density (or its given mass properties, turned into the
    body frame), combined with the parallel-axis theorem."""
    masses, centres, inertias = [], [], []
    for part in parts:
        masses.append(part.mass)
        if not part.closed:
            rot = part.matrix
            centres.append(rot @ part.center_of_mass + part.position)
            inertias.append(rot @ np.asarray(part.inertia) @ rot.T)
            continue
        mesh = part_mesh(part)
        mesh.density = part.mass / mesh.volume
        centres.append(np.asarray(mesh.center_mass))
        inertias.append(np.asarray(mesh.moment_inertia))  # about the part's own centre
    total = float(sum(masses))
    com = sum(m * c for m, c in zip(masses, centres, strict=True)) / total
    inertia = np.zeros((3, 3))
    for m, c, i in zip(masses, centres, inertias, strict=True):
        d = c - com
        inertia += i + m * (np.dot(d, d) * np.eye(3) - np.outer(d, d))
    return total, com, inertia


def principal_frame(inertia: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(principal moments (3,) [kg m^2], principal axes (3, 3) as columns, a rotation) of an
    inertia tensor (3, 3) [kg m^2]; the body axes when its products of inertia are round-off
    (:data:`PRINCIPAL_TOLERANCE`)."""
    diagonal = np.diag(inertia).copy()
    if np.abs(inertia - np.diag(diagonal)).max() <= PRINCIPAL_TOLERANCE * diagonal.max():
        return diagonal, np.eye(3)
    moments, axes = np.linalg.eigh(inertia)
    if np.linalg.det(axes) < 0.0:
        axes[:, 2] = -axes[:, 2]
    return moments, axes


SHAPE_KEYS = {"frustum": ("y_start", "y_end", "radius_start", "radius_end"),
              "box": ("size",), "sphere": ("radius",),
              "mesh": ("file", "center_of_mass", "inertia")}
"""The keys of each shape in an asset's ``[[parts]]`` table: dimensions [m]; a mesh's file
relative to the asset's folder, and for contact only its centre of mass [m] and inertia
[kg m^2] in its part frame."""


def _number(doc: dict, key: str, unit: str, where: str) -> float:
    v = doc.get(key)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise ScenarioError(f"{where}.{key}: expected a finite number [{unit}], got {v!r}")
    return float(v)


def _vector(doc: dict, key: str, unit: str, where: str,
            default=(0.0, 0.0, 0.0)) -> tuple[float, float, float]:
    """``doc[key]``, three finite numbers, or ``default`` if absent (None: required)."""
    v = doc.get(key, None if default is None else list(default))
    if (not isinstance(v, list) or len(v) != 3 or any(
            isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x)
            for x in v)):
        raise ScenarioError(f"{where}.{key}: expected three finite numbers [{unit}], got {v!r}")
    return tuple(float(x) for x in v)


def _part(doc: dict, where: str, folder: Path) -> Part:
    shape = doc.get("shape", "frustum")
    if shape not in SHAPES:
        raise ScenarioError(f"{where}.shape: expected one of {', '.join(SHAPES)}, got "
                            f"{shape!r}")
    known = {"name", "shape", "mass", "density", "position", "rotation", *SHAPE_KEYS[shape]}
    unknown = sorted(set(doc) - known)
    if unknown:
        raise ScenarioError(f"{where}: unknown key '{unknown[0]}' for a {shape} (expected one "
                            f"of: {', '.join(sorted(known))})")
    if shape == "box":
        size = _vector(doc, "size", "m", where, default=None)
        if min(size) <= 0:
            raise ScenarioError(f"{where}.size: edge lengths must be > 0 [m]")
    elif shape == "mesh":
        size = ()
        if not isinstance(doc.get("file"), str):
            raise ScenarioError(f"{where}.file: expected the path of a mesh file")
        given = _given_mass_properties(doc, where)
        load_mesh(str(folder / doc["file"]), closed=given is None)
    elif shape == "sphere":
        size = (_number(doc, "radius", "m", where),)
        if size[0] <= 0:
            raise ScenarioError(f"{where}.radius: expected a positive number [m]")
    else:
        size = tuple(_number(doc, key, "m", where) for key in SHAPE_KEYS[shape])
        if size[1] <= size[0]:
            raise ScenarioError(f"{where}: y_end must exceed y_start")
        if min(size[2:]) < 0 or max(size[2:]) <= 0:
            raise ScenarioError(f"{where}: radii must be >= 0 and not both 0")
    if ("mass" in doc) == ("density" in doc):
        raise ScenarioError(f"{where}: give either mass [kg] or density [kg/m^3]")
    key, unit = ("mass", "kg") if "mass" in doc else ("density", "kg/m^3")
    value = _number(doc, key, unit, where)
    if value <= 0:
        raise ScenarioError(f"{where}.{key}: expected a positive number [{unit}]")
    part = Part(name=str(doc.get("name", "part")), shape=shape, size=size, mass=value,
                position=_vector(doc, "position", "m", where),
                rotation=_vector(doc, "rotation", "deg", where),
                file=str(folder / doc["file"]) if shape == "mesh" else "")
    if shape == "mesh" and given is not None:
        part = dataclasses.replace(part, center_of_mass=given[0], inertia=given[1])
    if key == "density":
        part = dataclasses.replace(part, mass=value * part.volume)
    return part


def _given_mass_properties(doc: dict, where: str):
    """A mesh part's given (centre of mass (3,) [m], inertia (3, 3) [kg m^2]), part frame,
    or None if it has neither (then it must be a closed solid)."""
    keys = [k for k in ("center_of_mass", "inertia") if k in doc]
    if not keys:
        return None
    if len(keys) == 1 or "mass" not in doc:
        raise ScenarioError(f"{where}: a mesh for contact only needs mass [kg], "
                            "center_of_mass [m] and inertia [kg m^2] together")
    com = _vector(doc, "center_of_mass", "m", where, default=None)
    rows = doc["inertia"]
    try:
        inertia = np.array(rows, dtype=float)
    except (TypeError, ValueError):
        inertia = np.zeros(0)
    if (inertia.shape != (3, 3) or not np.isfinite(inertia).all()
            or not np.allclose(inertia, inertia.T, rtol=1e-12, atol=0.0)
            or np.linalg.eigvalsh(inertia).min() <= 0.0):
        raise ScenarioError(f"{where}.inertia: expected a symmetric, positive-definite 3 x 3 "
                            f"table [kg m^2] (rows of 3 numbers), got {rows!r}")
    return com, tuple(map(tuple, inertia.tolist()))


def _solid_properties(parts: tuple[Part, ...]) -> dict[str, np.ndarray]:
    """:func:`mass_properties` of ``parts`` (mass [kg] (), centre of mass [m] (3,), inertia
    [kg m^2] (3, 3)) and the edge lengths of their body-frame bounding box [m] (3,)."""
    mass, com, inertia = mass_properties(parts)
    vertices = np.vstack([part_mesh(p).vertices for p in parts])
    return {"mass": np.array(mass), "center_of_mass": com, "inertia": inertia,
            "extents": vertices.max(axis=0) - vertices.min(axis=0)}


def _kept(what: str, parts: tuple[Part, ...], compute) -> dict[str, np.ndarray]:
    """``compute()``'s arrays, of ``what`` of ``parts``: kept on disk if the parts are all
    primitives (:mod:`bulletnet.common.array_cache`; a mesh part's file may change under its
    name), else computed."""
    if any(p.shape == "mesh" for p in parts):
        return compute()
    return cached_arrays(f"{what} {parts!r}", compute)


def make_debris(name: str, parts: tuple[Part, ...]) -> Debris:
    """A :class:`Debris` of ``parts`` with its computed mass properties (:func:`_kept`)."""
    solid = _kept(f"solid {SECTIONS}", parts, functools.partial(_solid_properties, parts))
    moments, axes = principal_frame(solid["inertia"])
    return Debris(name=name, parts=parts, mass=float(solid["mass"]),
                  center_of_mass=solid["center_of_mass"], inertia=solid["inertia"],
                  principal_moments=moments, principal_axes=axes, extents=solid["extents"])


@functools.lru_cache(maxsize=8)
def load_debris(name_or_path: str, mass: float = 0.0, density: float = 0.0) -> Debris:
    """A debris asset by name (``apollo_csm``) or path, with its computed mass properties
    (cached: treat the result as read-only). A mesh file
    (:data:`~bulletnet.model.mesh.MESH_SUFFIXES`)
    is a debris of one part, of uniform density: its ``mass`` [kg] or ``density``
    [kg/m^3] (one of them, > 0); an asset file has its parts' own."""
    path = Path(name_or_path)
    if path.suffix.lower() in MESH_SUFFIXES:
        if (mass > 0) == (density > 0):
            raise ScenarioError(f"{path}: a mesh debris needs debris.mass [kg] or "
                                "debris.density [kg/m^3] (one of them)")
        part = Part(name=path.stem, shape="mesh", size=(), mass=mass, file=str(path))
        if density > 0:
            part = dataclasses.replace(part, mass=density * part.volume)
        return make_debris(path.stem, (part,))
    if mass > 0 or density > 0:
        raise ScenarioError(f"{path}: debris.mass and debris.density apply to a mesh file "
                            "only (an asset gives its parts' masses)")
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
    parts = tuple(_part(p, f"{path}: parts[{k}]", path.parent) for k, p in enumerate(raw))
    return make_debris(str(doc.get("name", path.stem)), parts)


STATE_SIZE = 13
"""Length of a debris state vector: centre of mass [m] (3), orientation of the body frame,
quaternion x, y, z, w (4), velocity of the centre of mass [m/s] (3), angular velocity, world
frame [rad/s] (3)."""
COM, QUAT, VELOCITY, OMEGA = slice(0, 3), slice(3, 7), slice(7, 10), slice(10, 13)
"""The fields of a debris state vector, by name: ``state[COM]`` the centre of mass [m] (3,),
``state[QUAT]`` the body frame's orientation (x, y, z, w) (4,), ``state[VELOCITY]`` the centre
of mass' velocity [m/s] (3,), ``state[OMEGA]`` the angular velocity, world frame [rad/s]
(3,)."""


def rotation_quaternion(rotation_vector) -> np.ndarray:
    """Unit quaternion (x, y, z, w) of a rotation vector [rad], shape (3,) -> (4,)."""
    r = np.asarray(rotation_vector, dtype=float)
    angle = float(np.linalg.norm(r))
    if angle == 0.0:
        return np.array([0.0, 0.0, 0.0, 1.0])
    return np.append(r / angle * math.sin(angle / 2), math.cos(angle / 2))


def rotation_matrix(q) -> np.ndarray:
    """Rotation matrices of unit quaternions (x, y, z, w): shape (..., 4) -> (..., 3, 3).
    One quaternion in Python floats (the same arithmetic as numpy's on float64, a tenth of
    the time: a run's frames turn the debris' pose this way)."""
    q = np.asarray(q, dtype=float)
    one = q.ndim == 1
    x, y, z, w = q.tolist() if one else np.moveaxis(q, -1, 0)
    rows = ((1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)),
            (2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)),
            (2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)))
    if one:
        return np.array(rows)
    return np.stack([np.stack(row, -1) for row in rows], -2)


def matrix_quaternion(matrix) -> np.ndarray:
    """Unit quaternion (x, y, z, w) of a rotation matrix (3, 3); the identity gives
    (0, 0, 0, 1) exactly."""
    from scipy.spatial.transform import Rotation

    if np.array_equal(matrix, np.eye(3)):
        return np.array([0.0, 0.0, 0.0, 1.0])
    return Rotation.from_matrix(matrix).as_quat()


def quaternion_product(a, b) -> np.ndarray:
    """Hamilton product a b of quaternions (x, y, z, w), shape (4,): rotation b, then a."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return np.array([aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw,
                     aw * bw - ax * bx - ay * by - az * bz])


def initial_state(scene, debris: Debris) -> np.ndarray:
    """Debris state (:data:`STATE_SIZE`,) from a scene's ``[debris]`` table (origin position
    [m], rotation vector [deg], velocity [m/s], angular velocity [deg/s])."""
    q = rotation_quaternion(np.radians(scene.rotation))
    com = np.asarray(scene.position) + rotation_matrix(q) @ debris.center_of_mass
    return np.concatenate([com, q, scene.velocity, np.radians(scene.angular_velocity)])


def body_origin(state: np.ndarray, debris: Debris) -> np.ndarray:
    """World position [m] (3,) of the body-frame origin of a debris in ``state``."""
    return state[COM] - rotation_matrix(state[QUAT]) @ debris.center_of_mass


def _surface(parts: tuple[Part, ...], sections: int) -> dict[str, np.ndarray]:
    """The parts' surface in their body frame: vertices (V, 3) [m], faces (F, 3)."""
    import trimesh

    mesh = trimesh.util.concatenate([part_mesh(p, sections) for p in parts])
    return {"vertices": np.asarray(mesh.vertices),
            "faces": np.asarray(mesh.faces, dtype=np.int64)}


def visual_mesh(debris: Debris, sections: int = 48) -> tuple[np.ndarray, np.ndarray]:
    """(vertices (V, 3) [m], faces (F, 3)) of the debris' surface in its body frame
    (:func:`_kept`)."""
    mesh = _kept(f"surface {sections}", debris.parts,
                 functools.partial(_surface, debris.parts, sections))
    return mesh["vertices"], mesh["faces"]


