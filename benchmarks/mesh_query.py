"""Mesh contact query: the triangle hierarchy with exact closest points (what bulletnet uses,
:func:`bulletnet.kernels.geometry.mesh_distance`) against a precomputed distance field (signed
distances on a regular grid, trilinear interpolation, the interpolant's gradient as normal).

For the CSM mesh (assets/apollo_csm_mesh.toml, 960 triangles) and a finer sphere (20480
triangles): the cost of one query inside a compiled loop, and for the grid at several
spacings the error of depth and normal against the exact query at points within 5 cm of the
surface (where contact happens), its memory dense and as a narrow band (cells within
``BAND`` of the surface), and the time to build it.

Writes OUT/mesh_query.json. Usage: python benchmarks/mesh_query.py [OUT]
"""

from __future__ import annotations

import json
import math
import time

import numba as nb
import numpy as np
from common import output_dir, parser

import bulletnet as bn
from bulletnet.kernels.geometry import debris_distance
from bulletnet.model.debris import Part, make_debris
from bulletnet.solver.contact_stage import debris_geometry

BAND = 0.1
"""Half width of a narrow band worth storing [m]."""
SPACINGS = (0.08, 0.04, 0.02)
"""Grid spacings tried [m]."""


@nb.njit(cache=True)
def exact(points, rows, mesh, out, normals):
    """Exact query at each point (N, 3): distances into ``out`` (N,), normals (N, 3)."""
    n = np.empty(3)
    for i in range(points.shape[0]):
        out[i] = debris_distance(points[i], np.zeros(3), np.eye(3), rows, mesh, n)
        normals[i] = n


@nb.njit(cache=True)
def grid_query(points, grid, lo, h, out, normals):
    """Trilinear interpolation of the grid (nx, ny, nz) of spacing h [m] from corner lo,
    and the normalized gradient of the interpolant."""
    for i in range(points.shape[0]):
        f = (points[i] - lo) / h
        ix, iy, iz = int(f[0]), int(f[1]), int(f[2])
        tx, ty, tz = f[0] - ix, f[1] - iy, f[2] - iz
        d = gx = gy = gz = 0.0
        for cx in range(2):
            wx, dwx = (tx, 1.0) if cx else (1.0 - tx, -1.0)
            for cy in range(2):
                wy, dwy = (ty, 1.0) if cy else (1.0 - ty, -1.0)
                for cz in range(2):
                    wz, dwz = (tz, 1.0) if cz else (1.0 - tz, -1.0)
                    v = grid[ix + cx, iy + cy, iz + cz]
                    d += wx * wy * wz * v
                    gx += dwx * wy * wz * v
                    gy += wx * dwy * wz * v
                    gz += wx * wy * dwz * v
        g = math.sqrt(gx * gx + gy * gy + gz * gz)
        out[i] = d
        normals[i, 0], normals[i, 1], normals[i, 2] = gx / g, gy / g, gz / g


def per_query(fn, *args) -> float:
    """Median wall time of one query [s] over 5 calls of ``fn`` on 20000 points."""
    fn(*args)  # compile
    times = []
    for _ in range(5):
        t = time.perf_counter()
        fn(*args)
        times.append(time.perf_counter() - t)
    return float(np.median(times)) / args[0].shape[0]


def near_surface(rows, mesh, lo, hi, count, rng):
    """``count`` random points within 5 cm of the surface, inside or outside."""
    found = []
    while sum(len(f) for f in found) < count:
        p = rng.uniform(lo, hi, size=(20 * count, 3))
        d, n = np.empty(len(p)), np.empty((len(p), 3))
        exact(p, rows, mesh, d, n)
        found.append(p[np.abs(d) < 0.05])
    return np.concatenate(found)[:count]


def measure(name, debris) -> dict:
    rows, mesh = debris_geometry(debris.parts)
    rng = np.random.default_rng(15)
    corners = np.asarray(debris.extents) / 2 + BAND + 0.2
    lo, hi = -corners, corners
    points = near_surface(rows, mesh, lo + 0.2, hi - 0.2, 20000, rng)
    d_ref, n_ref = np.empty(len(points)), np.empty((len(points), 3))
    result = {"triangles": int(mesh.triangles.shape[0]),
              "exact_query_s": per_query(exact, points, rows, mesh, d_ref, n_ref),
              "exact_memory_bytes": int(sum(a.nbytes for a in mesh)), "grid": []}
    for h in SPACINGS:
        axes = [np.arange(a, b + h, h) for a, b in zip(lo, hi, strict=True)]
        nodes = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
        t = time.perf_counter()
        values, scratch = np.empty(len(nodes)), np.empty((len(nodes), 3))
        exact(nodes, rows, mesh, values, scratch)
        build_s = time.perf_counter() - t
        grid = values.reshape([len(a) for a in axes])
        d, n = np.empty(len(points)), np.empty((len(points), 3))
        cost = per_query(grid_query, points, grid, lo, h, d, n)
        angle = np.degrees(np.arccos(np.clip((n * n_ref).sum(1), -1.0, 1.0)))
        result["grid"].append({
            "spacing_m": h, "query_s": cost, "build_s": build_s,
            "dense_bytes": int(grid.nbytes),
            "band_bytes": int(np.count_nonzero(np.abs(values) < BAND) * 8),
            "depth_error_max_m": float(np.abs(d - d_ref).max()),
            "depth_error_p99_m": float(np.percentile(np.abs(d - d_ref), 99)),
            "normal_error_max_deg": float(angle.max()),
            "normal_error_p99_deg": float(np.percentile(angle, 99))})
    print(f"{name}: {result['triangles']} triangles, exact query "
          f"{result['exact_query_s'] * 1e9:.0f} ns, {result['exact_memory_bytes'] / 1e3:.0f} kB")
    for g in result["grid"]:
        print(f"  grid {g['spacing_m'] * 100:.0f} cm: query {g['query_s'] * 1e9:.0f} ns, "
              f"depth error max {g['depth_error_max_m'] * 1e3:.2f} mm "
              f"(99 % {g['depth_error_p99_m'] * 1e3:.2f}), normal max "
              f"{g['normal_error_max_deg']:.1f} deg (99 % {g['normal_error_p99_deg']:.1f}), "
              f"{g['dense_bytes'] / 1e6:.0f} MB dense, {g['band_bytes'] / 1e6:.1f} MB band, "
              f"built in {g['build_s']:.1f} s")
    return result


def main() -> None:
    import trimesh

    args = parser(__doc__).parse_args()
    out = output_dir(args)
    sphere = out / "sphere.stl"
    trimesh.creation.icosphere(subdivisions=5, radius=2.0).export(sphere)
    results = {"csm": measure("CSM mesh", bn.load_debris("apollo_csm_mesh")),
               "sphere": measure("sphere", make_debris(
                   "sphere", (Part("sphere", "mesh", (), 1.0, file=str(sphere)),)))}
    (out / "mesh_query.json").write_text(json.dumps(results, indent=2), encoding="utf-8")


if __name__ == "__main__":
    main()
