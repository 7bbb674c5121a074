"""Triangle-mesh debris parts: loading and checking a mesh file, and the arrays of its
signed-distance query in the compiled contact loop
(:func:`~bulletnet.kernels.geometry.mesh_distance`).

The query finds the exact closest point on the mesh through a bounding-volume hierarchy of
its triangles (axis-aligned boxes, split at the median centroid along the longest axis,
:data:`LEAF_SIZE` triangles a leaf) and takes the sign from the angle-weighted pseudo-normal
of the closest feature (face, edge or vertex; Baerentzen and Aanaes 2005), which is exact for
a closed, consistently oriented mesh: hence the checks of :func:`load_mesh`. Chosen over a
precomputed distance field by measurement (``benchmarks/mesh_query.py``, assets/README.md):
1-2 us a query for a 960-triangle mesh, against a grid's 0.05-0.4 us that at 2 cm spacing
still misses depths by millimetres and turns normals by up to 90 deg at sharp edges, and
needs hundreds of MB dense.
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ..common.errors import ScenarioError

MESH_SUFFIXES = (".stl", ".obj", ".glb", ".gltf", ".ply")
"""Mesh file types a debris part or a whole debris may be given as."""

LEAF_SIZE = 4
"""Most triangles in a leaf of the hierarchy [-]."""


STACK = 64
"""Most nodes a descent of a hierarchy holds at once: one more than its depth, which the
halving split keeps near log2 of the triangle count."""


class MeshArrays(NamedTuple):
    """Every mesh part of a debris in its part frame, for the compiled contact loop: B nodes
    of the hierarchies and T triangles in all (a part row holds its root node's index)."""

    boxes: np.ndarray
    """Bounds of each node, lowest x, y, z then highest [m], shape (B, 6)."""
    tree: np.ndarray
    """Each node's children (left, right; -1 for a leaf) and its leaf's first triangle and
    triangle count [-], shape (B, 4), int64."""
    triangles: np.ndarray
    """Triangle corners a, b, c [m], shape (T, 3, 3)."""
    normals: np.ndarray
    """Unit pseudo-normals of each triangle's features: the face, the edges ab, bc, ca
    (mean of the two faces' normals) and the corners a, b, c (angle-weighted) [-],
    shape (T, 7, 3)."""
    stack: np.ndarray
    """Scratch space of a descent of the hierarchy (nodes still to visit) [-], shape
    (:data:`STACK`,), int64: the compiled distance query allocates nothing."""


def no_meshes() -> MeshArrays:
    """Empty mesh arrays (a debris without mesh parts: the same compiled loop)."""
    return MeshArrays(boxes=np.zeros((0, 6)), tree=np.zeros((0, 4), dtype=np.int64),
                      triangles=np.zeros((0, 3, 3)), normals=np.zeros((0, 7, 3)),
                      stack=np.zeros(STACK, dtype=np.int64))


@functools.lru_cache(maxsize=16)
def load_mesh(path: str, closed: bool = True):
    """The triangle mesh of a file (``MESH_SUFFIXES``; coordinates in [m]), cached: treat it
    as read-only. It must be consistently wound and, if ``closed``, watertight and facing
    outwards; else a one-line :class:`ScenarioError` says what to do. An open mesh (a sheet,
    a shell with holes) has the side its faces' normals point to as its outside."""
    import trimesh

    p = Path(path)
    if p.suffix.lower() not in MESH_SUFFIXES:
        raise ScenarioError(f"{p}: not a mesh file (expected {', '.join(MESH_SUFFIXES)})")
    if not p.is_file():
        raise ScenarioError(f"{p}: no such mesh file")
    try:
        mesh = trimesh.load(p, force="mesh", process=True)
    except Exception as exc:  # trimesh raises many kinds on a bad file
        raise ScenarioError(f"{p}: cannot read the mesh: "
                            f"{(str(exc).splitlines() or [type(exc).__name__])[0]}") from None
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise ScenarioError(f"{p}: holds no triangles")
    if not mesh.is_winding_consistent:
        raise ScenarioError(f"{p}: the mesh's faces are not consistently wound (its outside "
                            "is undefined): fix the winding (trimesh.repair.fix_winding, or "
                            "MeshLab)")
    if closed and not mesh.is_watertight:
        raise ScenarioError(
            f"{p}: the mesh is not closed (no inside, no volume): close its holes "
            "(trimesh.repair.fill_holes, or MeshLab), give the part its mass, center_of_mass "
            "and inertia to use it for contact only, or build the debris from primitives")
    if closed and mesh.volume <= 0.0:
        raise ScenarioError(f"{p}: the mesh is inside out (volume {mesh.volume:.3g} m^3): "
                            "flip its faces (trimesh's Trimesh.invert)")
    return mesh


def pseudo_normals(mesh) -> np.ndarray:
    """Unit pseudo-normals (T, 7, 3) of a closed mesh's triangles (see :class:`MeshArrays`)."""
    faces, face_normals = mesh.faces, mesh.face_normals
    out = np.empty((len(faces), 7, 3))
    out[:, 0] = face_normals
    edge_sum = np.zeros((len(mesh.edges_unique), 3))
    edge_of = mesh.edges_unique_inverse.reshape(-1, 3)  # faces' edges ab, bc, ca
    np.add.at(edge_sum, edge_of, face_normals[:, None, :])
    out[:, 1:4] = edge_sum[edge_of]
    vertex_sum = np.zeros((len(mesh.vertices), 3))
    np.add.at(vertex_sum, faces, mesh.face_angles[..., None] * face_normals[:, None, :])
    out[:, 4:7] = vertex_sum[faces]
    out /= np.linalg.norm(out, axis=2, keepdims=True)
    return out


def build(meshes) -> tuple[MeshArrays, list[int]]:
    """The :class:`MeshArrays` of closed meshes (each in its part frame) and each one's root
    node index."""
    if not meshes:
        return no_meshes(), []
    boxes, tree, triangles, normals, roots = [], [], [], [], []
    first = 0
    for mesh in meshes:
        tri = np.asarray(mesh.triangles)
        pn = pseudo_normals(mesh)
        order: list[int] = []
        roots.append(len(boxes))
        _split(tri, np.arange(len(tri)), boxes, tree, order, first)
        triangles.append(tri[order])
        normals.append(pn[order])
        first += len(tri)
    return MeshArrays(boxes=np.array(boxes), tree=np.array(tree, dtype=np.int64),
                      triangles=np.concatenate(triangles), normals=np.concatenate(normals),
                      stack=np.zeros(STACK, dtype=np.int64)), roots


def _split(tri, index, boxes, tree, order, first) -> int:
    """Append the node of triangles ``index`` (and its subtree) and return its index."""
    corners = tri[index].reshape(-1, 3)
    node = len(boxes)
    boxes.append(np.concatenate([corners.min(axis=0), corners.max(axis=0)]))
    tree.append([-1, -1, first + len(order), len(index)])
    if len(index) <= LEAF_SIZE:
        order.extend(index.tolist())
        return node
    centroids = tri[index].mean(axis=1)
    axis = int(np.argmax(centroids.max(axis=0) - centroids.min(axis=0)))
    ranked = index[np.argsort(centroids[:, axis], kind="stable")]
    half = len(ranked) // 2
    left = _split(tri, ranked[:half], boxes, tree, order, first)
    right = _split(tri, ranked[half:], boxes, tree, order, first)
    tree[node] = [left, right, -1, 0]
    return node
