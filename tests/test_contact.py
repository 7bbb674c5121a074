"""Contact (Eq. 6, Eq. 12): the exact per-step normal motion against an ODE reference and
static equilibrium, sphere-sphere momentum, friction against Coulomb's law, the debris'
signed distance against geometry, and the debris alone in the capture scene."""

from __future__ import annotations

import math

import numba as nb
import numpy as np
import pytest
from conftest import small_capture
from scipy.integrate import solve_ivp

import bulletnet as bn
from bulletnet.kernels.contact import normal_step
from bulletnet.kernels.geometry import debris_distance, frustum_distance
from bulletnet.model.debris import Debris, Part, load_debris
from bulletnet.solver import contact_stage as contact

K, C, M = 4.449e9, 62.0, 2.18e-3  # Table 5-6 spacecraft-inner node pair, an inner node [kg]


def ode_rebound(u0: float, k: float, c: float, m: float):
    """Reference: m s'' = -k s - c s' from touch-down at speed u0 < 0, integrated by DOP853
    to lift-off (contact force -k s - c s' = 0, Eq. 6 with no adhesion): (exit speed [m/s],
    contact time [s])."""
    def lift(_t, y):
        return -k * y[0] - c * y[1]
    lift.terminal, lift.direction = True, -1
    sol = solve_ivp(lambda _t, y: [y[1], (-k * y[0] - c * y[1]) / m], (0.0, 1e-3),
                    [0.0, u0], method="DOP853", rtol=1e-12, atol=1e-18, events=lift,
                    first_step=1e-10)
    return sol.y_events[0][0][1], sol.t_events[0][0]


@pytest.mark.parametrize("dt", [1e-5, 1e-4, 1.0 / 60.0])
def test_rebound_matches_the_contact_ode_at_any_step(dt):
    # Reference: the ODE of Eq. 6 integrated to lift-off; the step only carries the node
    # before and after the ~2 us contact, so exit speed and contact time are exact.
    u_exit, t_contact = ode_rebound(-1.0, K, C, M)
    s, u, tc = normal_step(0.5 * dt * 1.0, -1.0, 0.0, K, C, M, dt)  # touches mid-step
    assert u == pytest.approx(u_exit, rel=1e-9)
    assert tc == pytest.approx(t_contact, rel=1e-9)
    # restitution of the damped oscillator's half period, exp(-pi xi / sqrt(1 - xi^2)),
    # differs only by the lift-off at zero force (before the overlap closes): O(xi^2)
    xi = C / (2 * math.sqrt(K * M))
    assert u == pytest.approx(math.exp(-math.pi * xi / math.sqrt(1 - xi**2)), abs=4 * xi**2)


@pytest.mark.parametrize("dt", [1e-6, 1e-4, 1e-2])
def test_pressed_sphere_settles_at_the_static_penetration(dt):
    # Reference: static equilibrium of Eq. 6, k_c delta = m a (delta = m a / k_c).
    a = -50.0  # [m/s^2] pressing on the surface
    s, u = 0.0, 0.0
    for _ in range(int(round(2e-3 / dt)) + 1):  # 2 ms: ~20 damping times 2 m / c
        s, u, _ = normal_step(s, u, a, K, C, M, dt)
    assert s == pytest.approx(M * a / K, rel=1e-6)


def plane_debris() -> Debris:
    """A 100 m wide, 1 m thick disc: its cap at body y = 0 is a plane with normal +y."""
    part = Part("disc", "frustum", (-1.0, 0.0, 50.0, 50.0), 1e6)
    return Debris(name="plane", parts=(part,), mass=1e6, center_of_mass=np.array([0, -0.5, 0]),
                  inertia=np.eye(3) * 1e9, principal_moments=np.full(3, 1e9),
                  principal_axes=np.eye(3), extents=np.array([100.0, 1.0, 100.0]))


def contact_world(**overrides):
    """A 2 x 2 net scene with contact (Tables 5-6 pairs of the capture materials; the exact
    law unless overridden), its model and contact arrays with a static plane debris at the
    origin."""
    scene = bn.load_scenario("capture", {"net.nodes_per_side": 2, "contact.model": "exact",
                                         **overrides})
    model = bn.build_model(scene)
    setup = contact.setup(scene, model, plane_debris())
    a = setup.arrays
    a.com[:] = (0.0, -0.5, 0.0)  # centre of mass: body origin at the world origin
    return scene, model, setup


def step_node_on_plane(model, setup, pos, vel, accel, dt, steps):
    """Symplectic Euler free steps of node 0 under ``accel`` [m/s^2], then the debris contact
    (the scene's solver); the other nodes are far away."""
    dv = np.zeros_like(vel)
    for k in range(steps):
        dv[:] = 0.0
        dv[0] = accel * dt
        vel += dv
        pos += dt * vel
        contact.contact_stage(pos, vel, dv, model.mass, model.radius, model.fixed,
                              setup.arrays, dt, k * dt)


FRICTION_SOLVERS = [{}, {"contact.solver": "coupled", "contact.model": "implicit",
                        "contact.tolerance": 1e-13}]
"""The debris contact's friction as the sequential stage and as the coupled solve (to end
gaps of 1e-13 m, below the resting overlap, 6.1e-12 m) apply it."""


def placed(model, y0: float, v0=(0.0, 0.0, 0.0)):
    pos = np.tile([0.0, 1e3, 0.0], (model.node_count, 1)) + np.arange(model.node_count)[:, None]
    pos[0] = (0.0, y0, 0.0)
    vel = np.zeros_like(pos)
    vel[0] = v0
    return pos, vel


def test_node_rests_on_the_debris_at_its_pair_penetration():
    # Reference: k_c delta = m g for the spacecraft-corner node pair of Table 5.
    scene, model, setup = contact_world()
    k_sc = contact.pair_tables(scene, model)[0][0, contact.CLASS_OF_KIND[bn.NodeKind(
        model.kind[0])]]
    r, m, g = model.radius[0], model.mass[0], 9.81
    pos, vel = placed(model, r)  # touching, at rest (dropped, it would bounce: e = 0.97)
    step_node_on_plane(model, setup, pos, vel, np.array([0.0, -g, 0.0]), 1e-4, 100)
    assert r - pos[0, 1] == pytest.approx(m * g / k_sc, rel=1e-6)
    assert abs(vel[0, 1]) < 1e-9


@pytest.mark.parametrize("solver", FRICTION_SOLVERS)
@pytest.mark.parametrize("push", [0.5, 0.9])
def test_node_sticks_below_static_friction(push, solver):
    # Reference: Coulomb (Eq. 12): a tangential pull below mu_s N leaves the node at rest,
    # also between mu_k N and mu_s N (0.9 mu_s N; mu_k = mu_s / 1.25).
    scene, model, setup = contact_world(**solver, **{"contact.self_contact": False})
    mu_s = scene.friction.aluminium_net
    g = 9.81
    pos, vel = placed(model, model.radius[0] - model.mass[0] * g / 4.243e9)
    step_node_on_plane(model, setup, pos, vel, np.array([push * mu_s * g, -g, 0.0]), 1e-4,
                       500)
    assert abs(vel[0, 0]) < 1e-9 and abs(pos[0, 0]) < 1e-9


@pytest.mark.parametrize("solver", FRICTION_SOLVERS)
def test_node_slides_with_kinetic_friction(solver):
    # Reference: Coulomb (Eq. 12): sliding decelerates at mu_k g; the node stops after
    # v0 / (mu_k g) [s] having slid v0^2 / (2 mu_k g) [m]. (The coupled solve bounds a
    # contact's first step by mu_s: 1e-4 s at (mu_s - mu_k) g, 2.9e-5 m/s, 6e-5 of v0.)
    scene, model, setup = contact_world(**solver, **{"contact.self_contact": False})
    mu_k = scene.friction.aluminium_net / scene.friction.kinetic_ratio
    g, v0, dt = 9.81, 0.5, 1e-4
    pos, vel = placed(model, model.radius[0] - model.mass[0] * g / 4.243e9, (v0, 0.0, 0.0))
    t_stop = v0 / (mu_k * g)
    step_node_on_plane(model, setup, pos, vel, np.array([0.0, -g, 0.0]), dt,
                       int(0.5 * t_stop / dt))
    assert vel[0, 0] == pytest.approx(v0 - mu_k * g * 0.5 * t_stop, rel=1e-3)
    step_node_on_plane(model, setup, pos, vel, np.array([0.0, -g, 0.0]), dt, int(t_stop / dt))
    assert pos[0, 0] == pytest.approx(v0**2 / (2 * mu_k * g), rel=2e-3)
    assert abs(vel[0, 0]) < 1e-9


def fall_onto_debris(debris, skin: float, steps: int = 600):
    """Nodes of a 12 x 12 capture net scattered in a shell about the spinning ``debris``,
    falling onto it at 2 m/s under a 5 m/s^2 pull to its centre (1e-3 s steps, the debris
    contact stage with the exact law and friction; ``skin`` [m] widens the distance
    queries, 0: no distance cache). The contact arrays at the end and how many node
    queries were made."""
    scene = bn.load_scenario("capture", {"net.nodes_per_side": 12, "contact.model": "exact"})
    model = bn.build_model(scene)
    a = contact.setup(scene, model, debris).arrays
    a.params[1] = skin
    a.flags[1] = False  # the debris only
    a.com[:] = debris.center_of_mass
    a.omega[0] = (0.3, -0.2, 0.1)  # [rad/s]
    rng = np.random.default_rng(7)
    inward = rng.normal(size=(model.node_count, 3))
    inward /= -np.linalg.norm(inward, axis=1)[:, None]
    pos = a.com - inward * rng.uniform(0.3, 1.2, (model.node_count, 1)) * a.bound[0]
    vel, dv, dt = 2.0 * inward, 5.0 * 1e-3 * inward, 1e-3
    queries = 0
    for k in range(steps):
        vel += dv
        pos += dt * vel
        before = a.clear_at.copy()
        contact.contact_stage(pos, vel, dv, model.mass, model.radius, model.fixed, a, dt,
                              k * dt)
        queries += int(np.any(a.clear_at != before, axis=1).sum())
    return pos, vel, a, queries


@pytest.mark.parametrize("asset", ["apollo_csm", "apollo_csm_mesh"])
def test_distance_cache_skips_only_queries_out_of_reach(asset):
    # Reference: the debris contact stage without the cache (every node within the bounding
    # sphere queried every step). Nodes falling onto the spinning CSM (primitives; its mesh):
    # the cache must leave positions, velocities, predicted gaps, impulses and projections
    # the same bit for bit, from fewer queries.
    debris = load_debris(asset)
    pos0, vel0, plain, asked = fall_onto_debris(debris, 0.0)
    pos1, vel1, cached, fewer = fall_onto_debris(debris, 0.05)
    assert plain.first_contact[0] > 0.0 and plain.projections[0] > 0  # they hit it
    assert np.array_equal(pos0, pos1) and np.array_equal(vel0, vel1)
    for name in ("debris_gap", "impulse", "node_impulse", "projections", "com", "quat"):
        assert np.array_equal(getattr(plain, name), getattr(cached, name)), name
    assert fewer < 0.5 * asked, (fewer, asked)


def test_sphere_pair_rebound_conserves_momentum_and_restitution():
    # References: momentum conservation (action = reaction) and the pair's contact ODE with
    # the reduced mass m_c = m1 m2 / (m1 + m2) (Eq. 11) and the pair's k_c, c_c (Tables 5-6).
    scene, model, setup = contact_world(**{"contact.self_contact": True})
    a = setup.arrays
    a.flags[0] = False  # no debris: nodes only
    i, j = 0, model.node_count - 1  # a corner node and a corner mass
    pos = np.tile([0.0, 1e3, 0.0], (model.node_count, 1)) + 10 * np.arange(
        model.node_count)[:, None]
    gap, dt, speed = 1e-5, 1e-4, 1.0
    pos[i] = (0.0, 0.0, 0.0)
    pos[j] = (model.radius[i] + model.radius[j] + gap, 0.0, 0.0)
    vel = np.zeros_like(pos)
    vel[i, 0] = speed
    p_before = model.mass @ vel
    dv = np.zeros_like(vel)
    for k in range(3):
        pos += dt * vel
        assert contact.ensure_pairs(pos - dt * vel, model.radius, a)
        contact.self_stage(pos, vel, dv, model.mass, model.radius, a, dt, k * dt)
    np.testing.assert_allclose(model.mass @ vel, p_before, rtol=0, atol=1e-15)
    ci, cj = (contact.CLASS_OF_KIND[bn.NodeKind(model.kind[n])] for n in (i, j))
    k_c, c_c = (t[ci, cj] for t in contact.pair_tables(scene, model)[:2])
    mc = model.mass[i] * model.mass[j] / (model.mass[i] + model.mass[j])
    u_exit, _ = ode_rebound(-speed, k_c, c_c, mc)
    assert vel[j, 0] - vel[i, 0] == pytest.approx(u_exit, rel=1e-9)


def test_debris_distance_of_a_frustum():
    # Reference: geometry of the command-module frustum (y 2.3 -> 5.5, r 1.95 -> 0.42).
    part, mesh = contact.debris_geometry((Part("cm", "frustum", (2.3, 5.5, 1.95, 0.42), 1.0),))
    rot, origin, n = np.eye(3), np.zeros(3), np.empty(3)

    def distance(p):
        return debris_distance(p, origin, rot, part, mesh, n)

    assert distance(np.array([0.0, 6.5, 0.0])) == pytest.approx(1.0)
    np.testing.assert_allclose(n, [0, 1, 0], atol=1e-12)
    assert distance(np.array([0.0, 1.3, 1.0])) == pytest.approx(1.0)
    # on the slanted side, 0.1 m out along its normal
    normal = np.array([3.2, 1.53, 0.0]) / math.hypot(3.2, 1.53)
    on_side = np.array([(1.95 + 0.42) / 2, (2.3 + 5.5) / 2, 0.0])
    assert distance(on_side + 0.1 * normal) == pytest.approx(0.1)
    np.testing.assert_allclose(n, normal, atol=1e-12)
    assert distance(on_side - 0.1 * normal) == pytest.approx(-0.1)


@nb.njit(error_model="numpy")
def _every_segment(rho, y, y0, y1, r0, r1):
    """Reference for frustum_distance: every segment's exact distance (math.hypot, compiled
    as the kernel's) and normal, the nearest kept, the first of equals."""
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


@pytest.mark.parametrize("shape", [(2.3, 5.5, 1.95, 0.42), (-3.8, 2.3, 1.95, 1.95),
                                   (0.0, 2.0, 1.0, 0.0), (-1e-3, 1e-3, 2e-3, 5e-4)])
def test_frustum_distance_is_every_segments_bit_for_bit(shape):
    # Reference: the distance as every segment's math.hypot gives it (_every_segment); the
    # kernel takes the hypot of the near-least segments only, and must give the same bits,
    # also where segments tie (the meridian's corners, its bisectors, the axis, the surface).
    y0, y1, r0, r1 = shape
    rng = np.random.default_rng(7)
    size = max(y1 - y0, r0, r1)
    rho = np.abs(rng.normal(0.5 * max(r0, r1), size, 20000))
    y = rng.uniform(y0 - size, y1 + size, 20000)
    corners = [(0.0, y0), (r0, y0), (r1, y1), (0.0, y1)]
    ties = [(r + e, h + f) for r, h in corners for e in (-1e-17, 0.0, 1e-9, 0.3)
            for f in (-0.3, -1e-9, 0.0, 1e-17, 0.3)]
    ties += [(t * r0 + (1 - t) * r1, t * y0 + (1 - t) * y1) for t in np.linspace(0, 1, 41)]
    ties += [(r0 + d, y0 - d) for d in (1e-12, 1e-3, 0.5)]  # equidistant from base and side
    ties += [(0.0, 0.5 * (y0 + y1)), (1e-300, y0), (np.nan, y0), (np.inf, y1)]
    points = list(zip(rho, y, strict=True)) + ties
    for p in points:
        got, want = frustum_distance(*p, *shape), _every_segment(*p, *shape)
        np.testing.assert_array_equal(np.array(got), np.array(want), err_msg=str(p))
        assert [math.copysign(1.0, v) for v in got] == [math.copysign(1.0, v) for v in want]


def test_debris_alone_keeps_its_spin_and_mass_properties(tmp_path):
    # References: torque-free rotation about a principal axis (spin rate and angular
    # momentum constant) over the paper's 120 s; the recorded mass and inertia are the
    # asset's computed ones (bulletnet.model.debris, checked against quadrature in test_debris).
    # (The net, far away, is the small capture's: its size is a compile-time constant of
    # block D-ILU, so another would compile a step loop of its own. The debris at rest.)
    scene = small_capture(**{
        "debris.position": [0.0, 0.0, 1e4], "debris.velocity": [0.0, 0.0, 0.0],
        "scene.duration": 120.0, "simulation.dt": 0.01, "simulation.record_rate": 1.0})
    rec_path = bn.run(scene, tmp_path / "alone.h5").path
    import h5py

    with h5py.File(rec_path) as f:
        w = f["debris/angular_velocity"][()]
        inertia = f["debris"].attrs["inertia"]
        mass = f["debris"].attrs["mass"]
        count = f["contacts/count"][()]
    debris = bn.load_debris("apollo_csm")
    assert mass == debris.mass == pytest.approx(11900.0)
    np.testing.assert_array_equal(inertia, debris.inertia)
    np.testing.assert_allclose(w, np.tile([0, 0, math.radians(5.0)], (w.shape[0], 1)),
                               rtol=0, atol=1e-12)
    assert not count.any()


def test_wrap_of_a_flat_net_is_its_solid_angle():
    # Reference: the solid angle of a square of side a seen from distance d on its axis,
    # Omega = 4 arcsin(a^2 / (a^2 + 4 d^2)), over 4 pi; and a plane far wider than its
    # distance covers half of all directions.
    from bulletnet.analysis.capture_score import wrap_fraction

    ns = 21
    for side, expected in ((20.0, 4 * math.asin(400.0 / 800.0) / (4 * math.pi)),
                           (2e4, 4 * math.asin(4e8 / (4e8 + 400.0)) / (4 * math.pi))):
        r, c = np.divmod(np.arange(ns * ns), ns)
        points = np.stack([(c / (ns - 1) - 0.5) * side, (r / (ns - 1) - 0.5) * side,
                           np.full(ns * ns, -10.0)], axis=1)
        assert wrap_fraction(points, ns, np.zeros(3), 4000) == pytest.approx(expected, abs=2e-3)


def test_wrap_cones_skip_no_ray_that_crosses_the_net():
    # Reference: the Moller-Trumbore test of every ray against every triangle, in numpy (the
    # same operations, in the same order, on whole arrays); the compiled count tests a ray
    # only against the triangles whose cone of directions may hold it. Crumpled nets round
    # the origin, some corners at it, some triangles seen across more than a right angle, and
    # nets far off, whose triangles' cones are narrow (a cone 0.02 too narrow in its cosine
    # fails here).
    from bulletnet.analysis.capture_score import _covered, fibonacci_sphere, net_triangles

    def brute(points, tri, rays):
        a, b, c = points[tri[:, 0]], points[tri[:, 1]], points[tri[:, 2]]
        e1, e2 = b - a, c - a
        d = rays[:, None, :]
        p = np.stack([d[..., 1] * e2[:, 2] - d[..., 2] * e2[:, 1],
                      d[..., 2] * e2[:, 0] - d[..., 0] * e2[:, 2],
                      d[..., 0] * e2[:, 1] - d[..., 1] * e2[:, 0]], axis=-1)
        det = p[..., 0] * e1[:, 0] + p[..., 1] * e1[:, 1] + p[..., 2] * e1[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            u = -(a[:, 0] * p[..., 0] + a[:, 1] * p[..., 1] + a[:, 2] * p[..., 2]) / det
            q = -np.stack([a[:, 1] * e1[:, 2] - a[:, 2] * e1[:, 1],
                           a[:, 2] * e1[:, 0] - a[:, 0] * e1[:, 2],
                           a[:, 0] * e1[:, 1] - a[:, 1] * e1[:, 0]], axis=-1)
            v = (d[..., 0] * q[:, 0] + d[..., 1] * q[:, 1] + d[..., 2] * q[:, 2]) / det
            t = (e2[:, 0] * q[:, 0] + e2[:, 1] * q[:, 1] + e2[:, 2] * q[:, 2]) / det
        hit = ((np.abs(det) >= 1e-15) & (u >= 0.0) & (u <= 1.0) & (v >= 0.0) & (u + v <= 1.0)
               & (t > 0.0))
        return hit.any(axis=1).sum() / rays.shape[0]

    rng = np.random.default_rng(7)
    tri, rays = net_triangles(11), fibonacci_sphere(500)
    covered = []
    for k in range(40):
        offset = rng.normal(size=3) * 3 * (k % 5)
        points = rng.normal(size=(121, 3)) * rng.uniform(0.2, 4.0) + offset
        points[rng.integers(121, size=k % 4)] = 0.0
        covered.append(_covered(points, tri, rays))
        assert covered[-1] == brute(points, tri, rays)
    assert len(set(covered)) > 20 and max(covered) > 0.5  # the draws are not alike


def test_implicit_law_ends_an_impact_inelastically():
    # Reference: backward Euler on Eq. 6 (a constraint solver's treatment): the touch-down
    # speed after one step is m u0 / (m + dt c + dt^2 k), ~1e-6 of u0 at dt = 1e-4, and the
    # node then rests at the surface (no rebound), unlike the exact law's e = 0.97.
    from bulletnet.kernels.contact import implicit_normal_step

    dt = 1e-4
    s, u, tc = implicit_normal_step(0.0, -1.0, 0.0, K, C, M, dt)  # touching, approaching
    assert u == pytest.approx(-M / (M + dt * C + dt * dt * K)) and tc == dt
    for _ in range(5):
        s, u, _ = implicit_normal_step(s, u, 0.0, K, C, M, dt)
    assert 0 <= u < 1e-4 and abs(s) <= 6 * dt * u  # leaves at ~5e-5 m/s, not at 0.97 m/s


SLAB = """name = "slab"
[[parts]]
y_start = -1.0
y_end = 0.0
radius_start = 50.0
radius_end = 50.0
mass = 1e12
"""


@pytest.mark.parametrize("solver", ["sequential", "coupled"])
def test_net_rests_on_the_debris_at_each_pair_penetration(tmp_path, solver):
    # Reference: static equilibrium of Eq. 6 on the whole engine (fast): each node and
    # corner mass of a slack net resting on a flat debris (a 1e12 kg slab, so that it does
    # not yield) under 9.81 m/s^2 sinks by m g / k_c with its own pair's k_c (Table 5).
    # The implicit law settles at once (the exact one rebounds at e = 0.97 for a long time;
    # its static penetration is tested on the kernel above).
    (tmp_path / "slab.toml").write_text(SLAB)
    overrides = {"net.nodes_per_side": 2, "debris.asset": str(tmp_path / "slab.toml"),
                 "debris.rotation": [90.0, 0.0, 0.0], "debris.position": [0.0, 0.0, 0.0],
                 "debris.angular_velocity": [0.0, 0.0, 0.0], "launch.corner_speed": 0.0,
                 "scene.gravity": [0.0, 0.0, -9.81], "scene.duration": 1.0,
                 "contact.model": "implicit", "contact.self_contact": False,
                 "contact.solver": solver, "contact.tolerance": 1e-13}
    scene = bn.load_scenario("capture", overrides)
    model = bn.build_model(scene)  # the corner masses (largest spheres) start touching
    scene = scene.with_overrides({"net.center": [0.0, 0.0, float(model.radius.max())]})
    state = bn.run(scene).state
    top = state.debris[2] + 0.5  # the slab's centre of mass is 0.5 m below its top
    k = contact.pair_tables(scene, model)[0]
    cls = [contact.CLASS_OF_KIND[bn.NodeKind(kind)] for kind in model.kind]
    # (the coupled solve to its tolerance on gaps, 1e-13 m, below the smallest sink, 5.6e-12
    # m: here about 1e-14 m)
    np.testing.assert_allclose(model.radius - (state.position[:, 2] - top),
                               model.mass * 9.81 / k[0, cls],
                               rtol=1e-4 if solver == "sequential" else 0.0,
                               atol=0.0 if solver == "sequential" else scene.contact.tolerance)


@pytest.mark.parametrize("law", ["exact", "implicit"])
def test_pressed_sphere_pair_settles_at_its_pair_penetration(law):
    # Reference: static equilibrium of Eq. 6 for a sphere pair (Eq. 9-10 stiffness of the
    # pair, Table 5): two nodes pushed together by opposite forces F overlap by F / k_c.
    scene, model, setup = contact_world(**{"contact.self_contact": True,
                                           "contact.model": law})
    a = setup.arrays
    a.flags[0] = False  # nodes only
    i, j = 0, model.node_count - 1  # a corner node and a corner mass
    pos = np.tile([0.0, 1e3, 0.0], (model.node_count, 1)) + 10 * np.arange(
        model.node_count)[:, None]
    pos[i] = (0.0, 0.0, 0.0)
    pos[j] = (model.radius[i] + model.radius[j], 0.0, 0.0)
    vel = np.zeros_like(pos)
    force, dt = 0.05, 1e-5  # [N], [s]
    dv = np.zeros_like(vel)
    for k in range(20000):  # 0.2 s: many damping times of the pair
        dv[:] = 0.0
        dv[i, 0], dv[j, 0] = force / model.mass[i] * dt, -force / model.mass[j] * dt
        vel += dv
        pos += dt * vel
        assert contact.ensure_pairs(pos - dt * vel, model.radius, a)
        contact.self_stage(pos, vel, dv, model.mass, model.radius, a, dt, k * dt)
    ci, cj = (contact.CLASS_OF_KIND[bn.NodeKind(model.kind[n])] for n in (i, j))
    k_c = contact.pair_tables(scene, model)[0][ci, cj]
    overlap = model.radius[i] + model.radius[j] - (pos[j, 0] - pos[i, 0])
    assert overlap == pytest.approx(force / k_c, rel=1e-4)


def test_capture_with_bending_never_gains_energy(tmp_path):
    # Reference: energy conservation. Every force of the model is passive (tension-only
    # Kelvin-Voigt threads, damped bending springs, the contact law, friction) and what
    # metrics.energy leaves out (node rotation, bending and contact springs) is zero at the
    # start and never negative, so the recorded energy can never exceed its initial value.
    # 13 s of the paper's capture cover first contact (~8.5 s) and the start of the wrap, where
    # the "exact" law beside implicit-Euler threads gained tens of joules.
    scene = bn.load_scenario("capture", {"bending.enabled": True, "scene.duration": 13.0})
    rec = bn.open_recording(bn.run(scene, tmp_path / "capture.h5").path)
    assert rec.status == "completed" and bn.metrics.first_contact_time(rec) is not None
    e = bn.metrics.energy(rec)
    assert np.max(e[1:] - e[0]) <= 1e-12 * e[0]  # round-off of the sum
