"""Debris primitives at any pose: signed distance and normal against a brute-force reference,
the time a node touches a box's face, edge and corner, a node resting and sliding on a tilted
box face (Eq. 6, Eq. 12)."""

from __future__ import annotations

import math

import numpy as np
import pytest

import bulletnet as bn
import bulletnet.model.debris
from bulletnet.kernels.geometry import debris_distance
from bulletnet.model.debris import Part, make_debris, part_mesh
from bulletnet.solver import contact_stage as contact

RNG_SEED = 15

POSED = [
    Part("box", "box", (1.0, 3.0, 0.4), 1.0, (0.3, -0.2, 0.5), (20.0, -35.0, 50.0)),
    Part("sphere", "sphere", (0.8,), 1.0, (-0.4, 0.6, 0.1)),
    Part("frustum", "frustum", (-1.0, 1.5, 1.2, 0.4), 1.0, (0.2, 0.1, -0.3), (60.0, 10.0, -25.0)),
    Part("cone", "frustum", (0.0, 2.0, 1.0, 0.0), 1.0, (0.0, 0.0, 0.0), (0.0, 0.0, 90.0)),
]


def brute_force(mesh, points):
    """Reference: the signed distance [m] of each point to a closed convex triangle mesh by
    the exact closest point on every triangle (negative inside: behind every face's plane),
    the outward normal from the closest point, and whether that normal is unambiguous (no
    other triangle within 1e-6 m of the distance pointing elsewhere: off the medial axis)."""
    import trimesh

    tri = mesh.triangles
    count = len(points)
    closest = trimesh.triangles.closest_point(
        np.repeat(tri[None], count, 0).reshape(-1, 3, 3), np.repeat(points, len(tri), 0))
    offset = np.repeat(points, len(tri), 0) - closest
    dist = np.linalg.norm(offset, axis=1).reshape(count, len(tri))
    best = dist.argmin(axis=1)
    d = dist[np.arange(count), best]
    inside = ((points[:, None, :] - tri[None, :, 0, :]) * mesh.face_normals[None]).sum(2)
    inside = (inside < 0).all(axis=1)
    offset = offset.reshape(count, len(tri), 3)
    direction = offset / np.maximum(dist, 1e-300)[..., None]
    normal = direction[np.arange(count), best] * np.where(inside, -1.0, 1.0)[:, None]
    near = dist <= d[:, None] + 1e-6
    agree = np.einsum("ptk,pk->pt", direction, direction[np.arange(count), best]) > 1 - 1e-6
    return np.where(inside, -d, d), normal, ~(near & ~agree).any(axis=1)


@pytest.mark.parametrize("part", POSED, ids=[p.name for p in POSED])
def test_primitive_distance_and_normal_against_brute_force(part):
    # Reference: exact closest points on a fine tessellation of the same solid (brute_force);
    # the tolerance is the tessellation's distance from the true surface: 0 for a box, the
    # sagitta r (1 - cos(pi / n)) of an n-gon for a frustum, the icosphere's for a sphere.
    sections = 512
    mesh = part_mesh(part, sections)
    radius = max(part.size) if part.shape != "box" else 0.0
    chord = {"box": 0.0, "frustum": radius * (1 - math.cos(math.pi / sections)),
             "sphere": part.size[0] - np.linalg.norm(
                 mesh.triangles_center - part.position, axis=1).min()}[part.shape]
    rng = np.random.default_rng(RNG_SEED)
    lo, hi = mesh.bounds
    points = rng.uniform(lo - 0.5, hi + 0.5, size=(60, 3))
    d_ref, n_ref, clear = brute_force(mesh, points)
    rows, mesh = contact.debris_geometry((part,))
    n = np.empty(3)
    origin, rot = np.array([1.0, -2.0, 0.5]), bn.model.debris.rotation_matrix(
        bn.model.debris.rotation_quaternion([0.3, -0.4, 0.2]))  # a body frame off the world's
    for p, d, nr, ok in zip(points, d_ref, n_ref, clear, strict=True):
        ours = debris_distance(origin + rot @ p, origin, rot, rows, mesh, n)
        assert ours == pytest.approx(d, abs=chord + 1e-12)
        if ok and abs(d) > 1e-3:
            # the facet's normal differs from the surface's by at most the facet angle
            assert rot.T @ n @ nr > math.cos(4 * math.pi / sections) - 1e-12
    assert clear.sum() > 40 and (d_ref < 0).sum() > 5  # points inside and outside checked


def box_world(rotation=(0.0, 0.0, 0.0)):
    """A 2 x 2 net scene with contact (Tables 5-6 pairs, the exact law), its model and the
    contact arrays of a static 4 x 2 x 6 m box debris centred on the world origin, turned by
    ``rotation`` (rotation vector [deg])."""
    scene = bn.load_scenario("capture", {"net.nodes_per_side": 2, "contact.model": "exact"})
    model = bn.build_model(scene)
    box = make_debris("box", (Part("box", "box", (4.0, 2.0, 6.0), 1e6),))
    setup = contact.setup(scene, model, box)
    setup.arrays.com[:] = box.center_of_mass
    setup.arrays.quat[0] = bn.model.debris.rotation_quaternion(np.radians(rotation))
    return scene, model, setup


def run_node(model, setup, start, velocity, accel, dt, steps):
    """Node 0 from ``start`` [m] at ``velocity`` [m/s] under ``accel`` [m/s^2] (symplectic
    Euler free steps, then the debris contact stage); the other nodes far away. Returns
    the final position and velocity of node 0."""
    pos = np.tile([0.0, 1e3, 0.0], (model.node_count, 1)) + np.arange(model.node_count)[:, None]
    vel = np.zeros_like(pos)
    pos[0], vel[0] = start, velocity
    dv = np.zeros_like(vel)
    for k in range(steps):
        dv[:] = 0.0
        dv[0] = np.asarray(accel) * dt
        vel += dv
        pos += dt * vel
        contact.debris_stage(pos, vel, dv, model.mass, model.radius, model.fixed,
                             setup.arrays, dt, k * dt)
    return pos[0], vel[0]


@pytest.mark.parametrize("feature", [(1.0, 0.0, 0.0), (1.0, 1.0, 0.0), (1.0, 1.0, 1.0)],
                         ids=["face", "edge", "corner"])
def test_node_touches_box_face_edge_and_corner_when_geometry_says(feature):
    # Reference: straight-line flight towards the closest point of a face, an edge or a
    # corner of the 4 x 2 x 6 box: the sphere touches after (distance - r) / speed, and the
    # step in which the run records its first contact is the one holding that instant.
    _, model, setup = box_world()
    f = np.asarray(feature)
    target = f * np.array([2.0, 1.0, 3.0])  # centre of the face, middle of the edge, corner
    direction = f / np.linalg.norm(f)
    start, speed, dt = target + 0.3 * direction, 1.7, 1e-3
    run_node(model, setup, start, -speed * direction, np.zeros(3), dt, 400)
    touch = (0.3 - model.radius[0]) / speed
    first = setup.arrays.first_contact[0]
    assert first - dt < touch <= first


def test_node_rests_on_a_tilted_box_face_at_its_pair_penetration():
    # Reference: static equilibrium of Eq. 6, k_c delta = m a, on the top face of a box
    # turned 30 deg about x, pressed along its normal.
    scene, model, setup = box_world((30.0, 0.0, 0.0))
    rot = bn.model.debris.rotation_matrix(setup.arrays.quat[0])
    normal = rot @ [0.0, 1.0, 0.0]
    k_c = contact.pair_tables(scene, model)[0][0, contact.CLASS_OF_KIND[bn.NodeKind(
        model.kind[0])]]
    r, m, a = model.radius[0], model.mass[0], 9.81
    pos, vel = run_node(model, setup, (1.0 + r) * normal + rot @ [0.5, 0.0, 1.0], np.zeros(3),
                        -a * normal, 1e-4, 200)
    assert r - (pos @ normal - 1.0) == pytest.approx(m * a / k_c, rel=1e-6)
    assert abs(vel @ normal) < 1e-9


def test_node_slides_down_a_tilted_box_face_with_kinetic_friction():
    # Reference: Coulomb (Eq. 12) on an incline of angle theta (tan theta > mu_s): the node
    # accelerates down the slope at g (sin theta - mu_k cos theta).
    scene, model, setup = box_world((0.0, 0.0, 25.0))  # top face tilted 25 deg about z
    theta = math.radians(25.0)
    mu_k = scene.friction.aluminium_net / scene.friction.kinetic_ratio
    assert math.tan(theta) > scene.friction.aluminium_net
    rot = bn.model.debris.rotation_matrix(setup.arrays.quat[0])
    normal, down = rot @ [0.0, 1.0, 0.0], rot @ [-1.0, 0.0, 0.0]
    g, dt, steps = 9.81, 1e-4, 5000
    r, m = model.radius[0], model.mass[0]
    k_c = contact.pair_tables(scene, model)[0][0, contact.CLASS_OF_KIND[bn.NodeKind(
        model.kind[0])]]
    start = (1.0 + r - m * g * math.cos(theta) / k_c) * normal  # at its static penetration
    pos, vel = run_node(model, setup, start, np.zeros(3), [0.0, -g, 0.0], dt, steps)
    accel = g * (math.sin(theta) - mu_k * math.cos(theta))
    t = steps * dt
    assert vel @ down == pytest.approx(accel * t, rel=1e-3)
    assert (pos - start) @ down == pytest.approx(0.5 * accel * t * t, rel=2e-3)
    assert abs(vel @ normal) < 1e-9


@pytest.mark.parametrize("engine", ["fast", "bullet"])
def test_envisat_tumble_is_recorded_on_its_surface(tmp_path, engine):
    # References: a torque-free spin about a principal axis keeps its axis and rate, the body
    # turning by exp(w t) from its start; and the recorded mesh at the recorded pose lies on
    # the surface the fast engine's contact loop sees (boxes: distance 0 to round-off).
    # Envisat's principal axes are off its body axes (PyBullet's inertial frame is the
    # principal one), so this checks the frames the engines hand over.
    from scipy.spatial.transform import Rotation

    scene = bn.load_scenario("capture_envisat", {
        "net.nodes_per_side": 2, "debris.position": [0.0, 0.0, 1e4], "scene.duration": 4.0,
        "simulation.engine": engine, "simulation.dt": 0.004, "simulation.record_rate": 1.0,
        "contact.enabled": engine == "fast", "outcome.enabled": engine == "fast"})
    envisat = bn.load_debris("envisat")
    axis = Rotation.from_rotvec(np.radians(scene.debris.rotation)).apply(
        envisat.principal_axes[:, 2])
    scene = scene.with_overrides({"debris.angular_velocity": (2.7 * axis).tolist()})
    rec = bn.open_recording(bn.run(scene, tmp_path / "tumble.h5").path)
    d = rec.debris
    w = np.radians(2.7) * axis
    start = Rotation.from_rotvec(np.radians(scene.debris.rotation))
    for k, t in enumerate(rec.time):
        expected = Rotation.from_rotvec(w * t) * start
        turned = (Rotation.from_quat(d["orientation"][k]) * expected.inv()).magnitude()
        assert turned < 1e-6
        np.testing.assert_allclose(d["angular_velocity"][k], w, atol=1e-9)
    (rows, mesh), n = contact.debris_geometry(envisat.parts), np.empty(3)
    rot = Rotation.from_quat(d["orientation"][-1]).as_matrix()
    world = d["position"][-1] + d["mesh_vertices"] @ rot.T
    for p in world[::7]:
        assert abs(debris_distance(p, d["position"][-1], rot, rows, mesh, n)) < 1e-9
