"""Contact of the net's spheres with the debris and with each other (Eq. 6 and Eq. 12),
compiled with numba.

Normal force (Eq. 6, no adhesion): F = k_c delta + c_c d(delta)/dt while the spheres overlap
(delta > 0) and F > 0, zero otherwise, with each pair's own k_c and c_c (Tables 5-6). At the
paper's k_c ~ 4e9 N/m on a 2 g node the contact lasts ~2 us; no practical step resolves that,
and an explicit penalty needs steps below 1e-6 s. So the normal motion of a node in contact
is integrated *exactly* over each step: with the other forces on the node held at their
step value, the relative normal coordinate obeys a linear damped oscillator while in contact
and free flight otherwise, and :func:`normal_step` follows it through every touch-down and
lift-off inside the step in closed form. Any step then gives the contact's own rebound
(restitution exp(-pi xi / sqrt(1 - xi^2))), its static penetration F / k_c and its contact
time; what a large step loses is only the variation of the *other* forces within the step.

``contact.model = "implicit"`` replaces this by a backward-Euler step of the same law
(:func:`implicit_normal_step`), which is what a constraint solver does (Vortex, PyBullet):
stable too, but at practical steps it ends every impact inelastically.

Friction (Eq. 12): regularized Coulomb. Below the static bound the tangential relative
velocity is damped viscously with the inverse slip coefficient 1/s [N s/m] over the time in
contact (exact exponential decay); if the impulse that takes exceeds mu_s times the normal
impulse, the node slides and receives mu_k times the normal impulse against its slip (never
more than stops it). It is isotropic in the tangent plane (the paper's Vortex applies it per
component of a contact frame).

The debris is a rigid body moving at constant velocity over a step; the impulses on it are
summed (force and moment about its centre of mass) for its own dynamics.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

MAX_EVENTS = 16
"""Touch-down / lift-off events followed within one step before the rest of the step is
taken in the current phase [-]."""


@nb.njit(cache=True, error_model="numpy")
def _first_root(c2, c1, c0, t_max):
    """Smallest root t in (0, t_max] of c2 t^2 + c1 t + c0 = 0, or -1.0 if none."""
    eps = 1e-13 * t_max
    best = -1.0
    if c2 == 0.0:
        if c1 != 0.0:
            t = -c0 / c1
            if eps < t <= t_max:
                best = t
        return best
    disc = c1 * c1 - 4.0 * c2 * c0
    if disc < 0.0:
        return -1.0
    q = -0.5 * (c1 + math.copysign(math.sqrt(disc), c1))
    roots = (q / c2, c0 / q if q != 0.0 else -1.0)
    for t in roots:
        if eps < t <= t_max and (best < 0.0 or t < best):
            best = t
    return best


@nb.njit(cache=True, error_model="numpy")
def _oscillator(s, u, a, k, c, m, t):
    """Gap s [m] and gap rate u [m/s] after time t [s] in contact, from (s, u): the damped
    oscillator m s'' = m a - k s - c s' (underdamped: c^2 < 4 k m)."""
    s_eq = m * a / k
    sigma = c / (2.0 * m)
    wd = math.sqrt(k / m - sigma * sigma)
    y0 = s - s_eq
    b = (u + sigma * y0) / wd
    e = math.exp(-sigma * t)
    cs, sn = math.cos(wd * t), math.sin(wd * t)
    y = e * (y0 * cs + b * sn)
    v = e * ((b * wd - sigma * y0) * cs - (y0 * wd + sigma * b) * sn)
    return s_eq + y, v


@nb.njit(cache=True, error_model="numpy")
def _force(s, u, k, c):
    """Contact force -k s - c u [N] at gap s [m] (negative: overlap) and gap rate u [m/s]."""
    return -k * s - c * u


@nb.njit(cache=True, error_model="numpy")
def _lift_off(s, u, a, k, c, m, t_max):
    """First time in (0, t_max] at which the contact force of an oscillator starting in
    contact at (s, u) falls to zero, or -1.0 if it stays positive. The force is
    F_eq + exp(-sigma t) R cos(wd t - phi); its minima rise monotonically towards F_eq, so
    only the first minimum needs checking, and the root is bracketed by it and the
    maximum (or start) before it."""
    sigma = c / (2.0 * m)
    wd = math.sqrt(k / m - sigma * sigma)
    # F(t) - F_eq = exp(-sigma t) (P cos wd t + Q sin wd t)
    s_eq = m * a / k
    y0 = s - s_eq
    b = (u + sigma * y0) / wd
    p = -k * y0 - c * (b * wd - sigma * y0)
    q = -k * b + c * (y0 * wd + sigma * b)
    if p == 0.0 and q == 0.0:
        return -1.0 if -k * s_eq > 0.0 else 1e-13 * t_max
    phi = math.atan2(q, p)
    theta = -math.atan2(sigma, wd)  # extrema at wd t - phi = theta + n pi
    n0 = math.floor(-(theta + phi) / math.pi) + 1
    t_a = (theta + n0 * math.pi + phi) / wd
    t_b = t_a + math.pi / wd
    fa = _force(*_oscillator(s, u, a, k, c, m, t_a), k, c)
    fb = _force(*_oscillator(s, u, a, k, c, m, t_b), k, c)
    if fa <= fb:
        lo, hi, f_min = 0.0, t_a, fa
    else:
        lo, hi, f_min = t_a, t_b, fb
    if f_min > 0.0 or lo >= t_max:
        return -1.0
    if _force(*_oscillator(s, u, a, k, c, m, min(hi, t_max)), k, c) > 0.0:
        return -1.0
    for _ in range(80):  # bisection on the monotone bracket [lo, hi]
        mid = 0.5 * (lo + hi)
        if _force(*_oscillator(s, u, a, k, c, m, mid), k, c) > 0.0:
            lo = mid
        else:
            hi = mid
        if hi - lo <= 1e-15 * hi:
            break
    return hi


@nb.njit(cache=True, error_model="numpy")
def normal_step(s, u, a, k, c, m, dt):
    """Exact normal motion over one step ``dt`` [s] of a sphere against a surface: gap s [m]
    (negative: overlap), gap rate u [m/s], other forces' acceleration along the normal
    a [m/s^2] (constant over the step), pair stiffness k [N/m], damping c [N s/m] and
    (reduced) mass m [kg]. Returns (s, u, time in contact [s]) at the end of the step."""
    rem = dt
    contact_time = 0.0
    in_contact = s <= 0.0 and _force(s, u, k, c) > 0.0
    for _ in range(MAX_EVENTS):
        if rem <= 0.0:
            break
        if in_contact:
            t = _lift_off(s, u, a, k, c, m, rem)
            step = rem if t < 0.0 else t
            s, u = _oscillator(s, u, a, k, c, m, step)
            contact_time += step
            rem -= step
            in_contact = False
            continue
        # free flight: s + u t + a t^2 / 2; contact starts when the gap closes (from
        # outside) or, inside the overlap, when the force turns positive
        if s > 0.0:
            t = _first_root(0.5 * a, u, s, rem)
        elif s == 0.0 and (u < 0.0 or (u == 0.0 and a < 0.0)):
            t = 0.0  # touching and pressing on: contact starts now
        elif s < 0.0 and _force(s, u, k, c) == 0.0 and -k * u - c * a > 0.0:
            t = 0.0  # the force is zero and rising: contact starts now
        elif s == 0.0:
            t = _first_root(0.5 * a, u, s, rem)
        else:
            t = _first_root(-0.5 * k * a, -(k * u + c * a), -(k * s + c * u), rem)
            t_out = _first_root(0.5 * a, u, s, rem)
            if t_out > 0.0 and (t < 0.0 or t_out < t):  # leaves the overlap first
                u = u + a * t_out
                s = 0.0
                rem -= t_out
                continue
        if t < 0.0:
            s, u = s + u * rem + 0.5 * a * rem * rem, u + a * rem
            rem = 0.0
            break
        s, u = s + u * t + 0.5 * a * t * t, u + a * t
        if s > 0.0:
            s = 0.0
        rem -= t
        in_contact = True
    if rem > 0.0:  # event budget spent: finish in the current phase
        if in_contact:
            s, u = _oscillator(s, u, a, k, c, m, rem)
            contact_time += rem
        else:
            s, u = s + u * rem + 0.5 * a * rem * rem, u + a * rem
    return s, u, contact_time


@nb.njit(cache=True, error_model="numpy")
def implicit_normal_step(s, u, a, k, c, m, dt):
    """Backward Euler on Eq. 6 over one step, as a constraint solver treats contact (Vortex,
    PyBullet): the force acts if it is positive at the step's end with the gap there
    negative. At dt^2 k >> m this removes the overlap in one step and ends the approach:
    a perfectly inelastic touch-down whatever the pair's damping. Same arguments and
    returns as :func:`normal_step` (contact time: the whole step if in contact)."""
    u1 = (m * (u + a * dt) - dt * k * s) / (m + dt * c + dt * dt * k)
    s1 = s + dt * u1
    if s1 < 0.0 and _force(s1, u1, k, c) > 0.0:
        return s1, u1, dt
    u1 = u + a * dt
    return s + dt * u1, u1, 0.0


@nb.njit(cache=True, error_model="numpy")
def friction_impulse(speed, normal_impulse, contact_time, m, slip, mu_s, mu_k):
    """Magnitude [N s] of the friction impulse against a tangential slip ``speed`` [m/s]
    (Eq. 12): the viscous stick over ``contact_time`` [s] with the inverse slip coefficient
    1 / ``slip`` [N s/m] if it stays within mu_s times ``normal_impulse`` [N s], else mu_k
    times it, at most what stops the slip."""
    if speed <= 0.0 or contact_time <= 0.0:
        return 0.0
    stick = m * speed * -math.expm1(-contact_time / (m * slip))
    if stick <= mu_s * normal_impulse:
        return stick
    return min(mu_k * normal_impulse, m * speed)


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


@nb.njit(cache=True, error_model="numpy")
def frustum_distance(rho, y, y0, y1, r0, r1):
    """Signed distance [m] (negative inside) from the meridian point (rho, y) to the solid
    frustum y0 <= y <= y1, radius r0 -> r1, and the outward normal (n_rho, n_y) there."""
    best, n_rho, n_y, q_rho, q_y = np.inf, 0.0, 0.0, 0.0, 0.0
    side = math.hypot(r1 - r0, y1 - y0)
    segments = ((0.0, y0, r0, y0, 0.0, -1.0),
                (r0, y0, r1, y1, (y1 - y0) / side, -(r1 - r0) / side),
                (r1, y1, 0.0, y1, 0.0, 1.0))
    for ax, ay, bx, by, nx, ny in segments:
        ex, ey = bx - ax, by - ay
        length2 = ex * ex + ey * ey
        t = 0.0 if length2 == 0.0 else ((rho - ax) * ex + (y - ay) * ey) / length2
        t = min(1.0, max(0.0, t))
        cx, cy = ax + t * ex, ay + t * ey
        d = math.hypot(rho - cx, y - cy)
        if d < best:
            best, n_rho, n_y, q_rho, q_y = d, nx, ny, cx, cy
    inside = y0 <= y <= y1 and rho <= r0 + (r1 - r0) * (y - y0) / (y1 - y0)
    if inside:
        return -best, n_rho, n_y
    if best > 1e-12:
        n_rho, n_y = (rho - q_rho) / best, (y - q_y) / best
    return best, n_rho, n_y


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


@nb.njit(cache=True, error_model="numpy", inline="always")
def _corner_dots(x, y, z, tri, k):
    """(p - corner k) . (b - a) and (p - corner k) . (c - a) for p = (x, y, z) and the
    triangle ``tri`` (3, 3), rows a, b, c."""
    px, py, pz = x - tri[k, 0], y - tri[k, 1], z - tri[k, 2]
    ab = ac = 0.0
    for a, q in enumerate((px, py, pz)):
        ab += (tri[1, a] - tri[0, a]) * q
        ac += (tri[2, a] - tri[0, a]) * q
    return ab, ac


@nb.njit(cache=True, error_model="numpy", inline="always")
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


@nb.njit(cache=True, error_model="numpy", inline="always")
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
