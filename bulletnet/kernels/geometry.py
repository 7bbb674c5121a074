"""Geometry queries of the debris, compiled with numba: signed distance [m] and outward normal
from a point to a part (frustum, box, sphere, triangle mesh) and to the whole debris, the
parts' rows of the compiled contact loop, and rotation matrices of quaternions.

A part beyond reach is left out by a bound before its exact distance is computed
(:func:`part_distance`'s ``cutoff``: a frustum's bounding cylinder, a mesh's bounding box).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np


@nb.njit(cache=True, error_model="numpy")
def quat_matrix(q, out):
    """Rotation matrix (3, 3) of the unit quaternion q = (x, y, z, w), into ``out``."""
    x, y, z, w = q[0], q[1], q[2], q[3]
    out[0, 0] = 1 - 2 * (y * y + z * z)
    out[0, 1] = 2 * (x * y - z * w)
    out[0, 2] = 2 * (x * z + y * w)
    out[1, 0] = 2 * (x * y + z * w)
    out[1, 1] = 1 - 2 * (x * x + z * z)
    out[1, 2] = 2 * (y * z - x * w)
    out[2, 0] = 2 * (x * z - y * w)
    out[2, 1] = 2 * (y * z + x * w)
    out[2, 2] = 1 - 2 * (x * x + y * y)


NEAR_TIE = 1e-9
"""Relative margin on squared distances within which :func:`frustum_distance` takes a
segment's exact distance (``math.hypot``): a computed square lies a few ulp from the exact
one, so no segment left out could have the least exact distance."""


@nb.njit(cache=True, error_model="numpy")
def _segment(rho, y, ax, ay, bx, by):
    """The point of the segment (ax, ay)-(bx, by) nearest (rho, y): its coordinates, their
    offsets from (rho, y) and the offsets' squared length."""
    ex, ey = bx - ax, by - ay
    length2 = ex * ex + ey * ey
    t = 0.0 if length2 == 0.0 else ((rho - ax) * ex + (y - ay) * ey) / length2
    t = min(1.0, max(0.0, t))
    cx, cy = ax + t * ex, ay + t * ey
    dx, dy = rho - cx, y - cy
    return cx, cy, dx, dy, dx * dx + dy * dy


@nb.njit(cache=True, error_model="numpy")
def frustum_distance(rho, y, y0, y1, r0, r1):
    """Signed distance [m] (negative inside) from the meridian point (rho, y) to the solid
    frustum y0 <= y <= y1, radius r0 -> r1, and the outward normal (n_rho, n_y) there: the
    nearest of its meridian's three segments (base, side, top; the first of equals), its
    outward normal inside, the direction from it outside. Only segments whose squared
    distance lies within :data:`NEAR_TIE` of the least get their exact distance
    (``math.hypot``, ~16 ns each, a latency chain), the side's normal only where it is the
    result's: the same result, bit for bit, as every segment's hypot and normal."""
    c0, e0, dx0, dy0, s0 = _segment(rho, y, 0.0, y0, r0, y0)
    c1, e1, dx1, dy1, s1 = _segment(rho, y, r0, y0, r1, y1)
    c2, e2, dx2, dy2, s2 = _segment(rho, y, r1, y1, 0.0, y1)
    near = min(s0, min(s1, s2)) * (1.0 + NEAR_TIE) + 1e-300  # (+: squares underflowing to 0)
    best, k = np.inf, -1
    for j, s, dx, dy in ((0, s0, dx0, dy0), (1, s1, dx1, dy1), (2, s2, dx2, dy2)):
        if s <= near:
            d = math.hypot(dx, dy)
            if d < best:
                best, k = d, j
    q_rho, q_y = (0.0, 0.0) if k < 0 else ((c0, e0) if k == 0 else ((c1, e1) if k == 1
                                                                    else (c2, e2)))
    inside = y0 <= y <= y1 and rho <= r0 + (r1 - r0) * (y - y0) / (y1 - y0)
    if best > 1e-12 and not inside:
        return best, (rho - q_rho) / best, (y - q_y) / best
    n_rho, n_y = 0.0, (-1.0 if k == 0 else (1.0 if k == 2 else 0.0))  # the segment's normal
    if k == 1:
        side = math.hypot(r1 - r0, y1 - y0)
        n_rho, n_y = (y1 - y0) / side, -(r1 - r0) / side
    return (-best if inside else best), n_rho, n_y


PART_COLUMNS = 17
"""Length of a debris part's row in the compiled contact loop: shape code (column 0), the
rotation from the part frame to the body frame, row-major (1-9) [-], the part frame's origin
in the body frame (10-12) [m] and the shape's dimensions (13-16) [m]: a frustum's y_start,
y_end, radius_start, radius_end along its y axis; a box's half edge lengths x, y, z (and 0);
a sphere's radius (and 0, 0, 0); a triangle mesh's root node in the
:class:`~bulletnet.model.mesh.MeshArrays` (and 0, 0, 0)."""
FRUSTUM, BOX, SPHERE, MESH = 0.0, 1.0, 2.0, 3.0
"""Shape codes of a part row (column 0)."""


@nb.njit(cache=True, error_model="numpy")
def box_distance(x, y, z, hx, hy, hz):
    """Signed distance [m] (negative inside) from the point (x, y, z) [m] to the box
    |x| <= hx, |y| <= hy, |z| <= hz [m] centred at the origin, and the outward normal
    (nx, ny, nz) there: towards the closest point outside, of the nearest face inside (on a
    face, edge or corner: of the first face in x, y, z order with the largest offset)."""
    qx, qy, qz = abs(x) - hx, abs(y) - hy, abs(z) - hz
    sx = 1.0 if x >= 0.0 else -1.0
    sy = 1.0 if y >= 0.0 else -1.0
    sz = 1.0 if z >= 0.0 else -1.0
    if qx > 0.0 or qy > 0.0 or qz > 0.0:
        ox, oy, oz = max(qx, 0.0), max(qy, 0.0), max(qz, 0.0)
        d = math.sqrt(ox * ox + oy * oy + oz * oz)
        return d, sx * ox / d, sy * oy / d, sz * oz / d
    if qx >= qy and qx >= qz:
        return qx, sx, 0.0, 0.0
    if qy >= qz:
        return qy, 0.0, sy, 0.0
    return qz, 0.0, 0.0, sz


@nb.njit(cache=True, error_model="numpy")
def sphere_distance(x, y, z, r):
    """Signed distance [m] from the point (x, y, z) [m] to the ball of radius r [m] at the
    origin, and the outward normal (nx, ny, nz) there (+y at the centre)."""
    length = math.sqrt(x * x + y * y + z * z)
    if length == 0.0:
        return -r, 0.0, 1.0, 0.0
    return length - r, x / length, y / length, z / length


@nb.njit(cache=True, error_model="numpy")
def _corner_dots(x, y, z, tri, k):
    """(p - corner k) . (b - a) and (p - corner k) . (c - a) for p = (x, y, z) and the
    triangle ``tri`` (3, 3), rows a, b, c."""
    px, py, pz = x - tri[k, 0], y - tri[k, 1], z - tri[k, 2]
    ab = ac = 0.0
    for a, q in enumerate((px, py, pz)):
        ab += (tri[1, a] - tri[0, a]) * q
        ac += (tri[2, a] - tri[0, a]) * q
    return ab, ac


@nb.njit(cache=True, error_model="numpy")
def _between(tri, i, j, t):
    """The point of ``tri`` (3, 3) a fraction t of the way from corner i to corner j."""
    return (tri[i, 0] + t * (tri[j, 0] - tri[i, 0]), tri[i, 1] + t * (tri[j, 1] - tri[i, 1]),
            tri[i, 2] + t * (tri[j, 2] - tri[i, 2]))


@nb.njit(cache=True, error_model="numpy")
def triangle_closest(x, y, z, tri):
    """Closest point (cx, cy, cz) [m] to (x, y, z) [m] on the triangle ``tri`` (3, 3) [m]
    (rows a, b, c), and its feature: 0 the face, 1-3 the edges ab, bc, ca, 4-6 the corners
    a, b, c (Ericson, Real-Time Collision Detection, 5.1.5)."""
    d1, d2 = _corner_dots(x, y, z, tri, 0)
    d3, d4 = _corner_dots(x, y, z, tri, 1)
    d5, d6 = _corner_dots(x, y, z, tri, 2)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    # each test is a whole Voronoi region of the triangle's features: their order is free
    if d1 <= 0.0 and d2 <= 0.0:
        i, j, t, feature = 0, 0, 0.0, 4
    elif d3 >= 0.0 and d4 <= d3:
        i, j, t, feature = 1, 1, 0.0, 5
    elif d6 >= 0.0 and d5 <= d6:
        i, j, t, feature = 2, 2, 0.0, 6
    elif vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        i, j, t, feature = 0, 1, d1 / (d1 - d3), 1
    elif vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        i, j, t, feature = 0, 2, d2 / (d2 - d6), 3
    elif va <= 0.0 and d4 - d3 >= 0.0 and d5 - d6 >= 0.0:
        i, j, t, feature = 1, 2, (d4 - d3) / ((d4 - d3) + (d5 - d6)), 2
    else:  # the face: a + v (b - a) + w (c - a)
        v, w = vb / (va + vb + vc), vc / (va + vb + vc)
        bx, by, bz = _between(tri, 0, 1, v)
        return (bx + w * (tri[2, 0] - tri[0, 0]), by + w * (tri[2, 1] - tri[0, 1]),
                bz + w * (tri[2, 2] - tri[0, 2]), 0)
    cx, cy, cz = _between(tri, i, j, t)
    return cx, cy, cz, feature


@nb.njit(cache=True, error_model="numpy")
def _box_gap2(box, x, y, z):
    """Squared distance [m^2] from (x, y, z) [m] to the box (lowest x, y, z, highest x, y,
    z) [m]; 0 inside."""
    gx = max(box[0] - x, 0.0, x - box[3])
    gy = max(box[1] - y, 0.0, y - box[4])
    gz = max(box[2] - z, 0.0, z - box[5])
    return gx * gx + gy * gy + gz * gz


@nb.njit(cache=True, error_model="numpy", _nrt=False)
def mesh_distance(x, y, z, root, mesh):
    """Signed distance [m] from (x, y, z) [m] to the closed triangle mesh whose hierarchy
    starts at node ``root`` of ``mesh`` (:class:`~bulletnet.model.mesh.MeshArrays`), and the
    outward normal there: the exact closest point, found by descending the hierarchy past
    every box farther than the best so far; inside where the point lies behind the closest
    feature's pseudo-normal."""
    tree, stack = mesh.tree, mesh.stack
    stack[0], top = root, 1
    best, cx, cy, cz, feature, tri = np.inf, 0.0, 0.0, 0.0, 0, -1
    while top > 0:
        top -= 1
        node = stack[top]
        if _box_gap2(mesh.boxes[node], x, y, z) >= best:
            continue
        left, right = tree[node, 0], tree[node, 1]
        if left >= 0:  # the nearer child on top: it is searched first
            if _box_gap2(mesh.boxes[left], x, y, z) < _box_gap2(mesh.boxes[right], x, y, z):
                left, right = right, left
            stack[top], stack[top + 1] = left, right
            top += 2
            continue
        for t in range(tree[node, 2], tree[node, 2] + tree[node, 3]):
            qx, qy, qz, f = triangle_closest(x, y, z, mesh.triangles[t])
            d2 = (x - qx) ** 2 + (y - qy) ** 2 + (z - qz) ** 2
            if d2 < best:
                best, cx, cy, cz, feature, tri = d2, qx, qy, qz, f, t
    pn = mesh.normals[tri, feature]
    ox, oy, oz = x - cx, y - cy, z - cz
    sign = 1.0 if ox * pn[0] + oy * pn[1] + oz * pn[2] >= 0.0 else -1.0
    d = math.sqrt(best)
    if d <= 1e-12:
        return 0.0, pn[0], pn[1], pn[2]
    return sign * d, sign * ox / d, sign * oy / d, sign * oz / d


BOUND_MARGIN = 1e-9
"""How far beyond the cutoff [m] a part's lower bound must lie for :func:`part_distance` to
leave the part out: far above the round-off of either, so a part left out is one whose
distance would have compared as beyond the cutoff too."""


@nb.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def part_distance(row, bx, by, bz, mesh, cutoff):
    """Signed distance [m] from the body-frame point (bx, by, bz) [m] to the part of
    ``row`` (:data:`PART_COLUMNS`,) (a mesh part's triangles in ``mesh``, a
    :class:`~bulletnet.model.mesh.MeshArrays`), and the outward normal there in the body frame; or
    (inf, 0, 1, 0) if a lower bound of the distance already lies beyond ``cutoff`` [m]
    (a frustum's bounding cylinder; a mesh's bounding box, from outside)."""
    dx, dy, dz = bx - row[10], by - row[11], bz - row[12]
    x = row[1] * dx + row[4] * dy + row[7] * dz  # the part frame: R^T (b - t)
    y = row[2] * dx + row[5] * dy + row[8] * dz
    z = row[3] * dx + row[6] * dy + row[9] * dz
    cutoff += BOUND_MARGIN
    if row[0] == BOX:
        d, nx, ny, nz = box_distance(x, y, z, row[13], row[14], row[15])
    elif row[0] == SPHERE:
        d, nx, ny, nz = sphere_distance(x, y, z, row[13])
    elif row[0] == MESH:
        if _box_gap2(mesh.boxes[int(row[13])], x, y, z) > cutoff * cutoff:
            return np.inf, 0.0, 1.0, 0.0
        d, nx, ny, nz = mesh_distance(x, y, z, int(row[13]), mesh)
    else:
        outer = max(row[15], row[16]) + cutoff  # the bounding cylinder's, squared below
        if max(row[13] - y, y - row[14]) > cutoff or x * x + z * z > outer * outer:
            return np.inf, 0.0, 1.0, 0.0
        rho = math.hypot(x, z)
        ex, ez = (x / rho, z / rho) if rho > 1e-12 else (1.0, 0.0)
        d, n_rho, ny = frustum_distance(rho, y, row[13], row[14], row[15], row[16])
        nx, nz = n_rho * ex, n_rho * ez
    return (d, row[1] * nx + row[2] * ny + row[3] * nz, row[4] * nx + row[5] * ny
            + row[6] * nz, row[7] * nx + row[8] * ny + row[9] * nz)


@nb.njit(cache=True, error_model="numpy", _nrt=False)
def debris_distance(p, origin, rot, parts, mesh, normal, cutoff=np.inf):
    """Signed distance [m] from world point p (3,) to the debris whose body frame sits at
    ``origin`` (3,) [m] with rotation ``rot`` (3, 3); ``parts`` (K, :data:`PART_COLUMNS`)
    are its parts, ``mesh`` (:class:`~bulletnet.model.mesh.MeshArrays`) its mesh parts' triangles.
    The outward world normal goes into ``normal`` (3,). Parts are united by
    the smallest distance (exact outside the debris). Parts shown by a bound to lie beyond
    ``cutoff`` [m] (default: none) are left out (:func:`part_distance`): the result is the
    same wherever it is at most ``cutoff``, and inf if every part is left out. Compiled
    without reference counting (``_nrt=False``, as are the functions it calls): the contact
    stage calls it for every node near the debris, and counting the references of its
    array views cost more than the bounds themselves."""
    bx = by = bz = 0.0
    for a in range(3):
        d = p[a] - origin[a]
        bx += rot[a, 0] * d
        by += rot[a, 1] * d
        bz += rot[a, 2] * d
    best, nbx, nby, nbz = np.inf, 0.0, 1.0, 0.0
    for k in range(parts.shape[0]):
        d, nx, ny, nz = part_distance(parts[k], bx, by, bz, mesh, cutoff)
        if d < best:
            best, nbx, nby, nbz = d, nx, ny, nz
    for a in range(3):
        normal[a] = rot[a, 0] * nbx + rot[a, 1] * nby + rot[a, 2] * nbz
    return best
