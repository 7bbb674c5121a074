"""Debris from triangle meshes: the mesh query against the same shape from primitives, bad
meshes refused, a whole debris from a mesh file, a node resting on a mesh face (Eq. 6), the
bullet engine's convex decomposition, and a capture with the CSM as a mesh."""

from __future__ import annotations

import math

import numpy as np
import pytest

import bulletnet as bn
import bulletnet.model.builder
import bulletnet.model.debris
from bulletnet.common.errors import ScenarioError
from bulletnet.kernels.geometry import debris_distance
from bulletnet.model.debris import Part, load_debris, make_debris
from bulletnet.solver import contact_stage as contact


@pytest.fixture
def box_file(tmp_path):
    """A 4 x 2 x 6 m box as an STL file (12 triangles)."""
    import trimesh

    path = tmp_path / "box.stl"
    trimesh.creation.box(extents=(4.0, 2.0, 6.0)).export(path)
    return path


def test_box_mesh_is_the_box_primitive(box_file):
    # Reference: the closed-form box (checked against brute force in test_primitives); a
    # mesh of the same box has no tessellation error, so distance and normal agree to
    # round-off inside and outside, at a pose off the body axes.
    pose = {"position": (0.3, -0.2, 0.5), "rotation": (20.0, -35.0, 50.0)}
    mesh = Part("m", "mesh", (), 1.0, file=str(box_file), **pose)
    box = Part("b", "box", (4.0, 2.0, 6.0), 1.0, **pose)
    (rm, mm), (rb, mb) = contact.debris_geometry((mesh,)), contact.debris_geometry((box,))
    n1, n2 = np.empty(3), np.empty(3)
    rng = np.random.default_rng(15)
    inside = 0
    for p in rng.uniform(-4.0, 4.0, size=(400, 3)):
        d1 = debris_distance(p, np.zeros(3), np.eye(3), rm, mm, n1)
        d2 = debris_distance(p, np.zeros(3), np.eye(3), rb, mb, n2)
        assert d1 == pytest.approx(d2, abs=1e-12)
        np.testing.assert_allclose(n1, n2, atol=1e-9)
        inside += d2 < 0
    assert inside > 20


def test_csm_mesh_matches_the_primitives_within_its_tessellation():
    # Reference: the CSM of three frustums (exact signed distance): its revolved 96-section
    # mesh (assets/meshes/apollo_csm.obj) lies inside the circles by at most the 96-gon's
    # sagitta r (1 - cos(pi / 96)) = 1.0 mm, so outside the two distances agree within it
    # (and the 1e-6 m to which the file rounds its vertices).
    # (Inside, the union of primitives gives each part's own depth, not the solid's.)
    mesh, prims = load_debris("apollo_csm_mesh"), load_debris("apollo_csm")
    (rm, mm), (rp, mp) = (contact.debris_geometry(d.parts) for d in (mesh, prims))
    sagitta = 1.95 * (1 - math.cos(math.pi / 96))
    n1, n2 = np.empty(3), np.empty(3)
    rng = np.random.default_rng(15)
    checked = 0
    for p in rng.uniform([-4.0, -8.0, -4.0], [4.0, 8.0, 4.0], size=(600, 3)):
        exact = debris_distance(p, np.zeros(3), np.eye(3), rp, mp, n2)
        if exact <= 0.0:
            continue
        ours = debris_distance(p, np.zeros(3), np.eye(3), rm, mm, n1)
        assert -1e-6 <= ours - exact <= sagitta + 1e-6  # the file keeps 6 decimals [m]
        checked += 1
    assert checked > 400


def write(path, mesh):
    mesh.export(path)
    return str(path)


@pytest.mark.parametrize("asset", ["apollo_csm", "apollo_csm_mesh"])
def test_distance_with_a_cutoff_is_exact_within_it(asset):
    # Reference: the distance without a cutoff. The contact stage asks only whether a node
    # is within its reach, so parts a bound puts beyond the cutoff are left out; wherever
    # the distance is within the cutoff it must come out bit for bit the same (normal too),
    # and beyond it, as beyond.
    rows, mesh = contact.debris_geometry(load_debris(asset).parts)
    n1, n2 = np.empty(3), np.empty(3)
    rng = np.random.default_rng(3)
    near = far = 0
    for p in rng.uniform([-3.0, -7.0, -3.0], [3.0, 7.0, 3.0], size=(800, 3)):
        exact = debris_distance(p, np.zeros(3), np.eye(3), rows, mesh, n1)
        for cutoff in (0.0, 0.05, 0.5):
            cut = debris_distance(p, np.zeros(3), np.eye(3), rows, mesh, n2, cutoff)
            if exact <= cutoff:
                assert cut == exact and (n2 == n1).all()
                near += 1
            else:
                assert cut > cutoff
                far += 1
    assert near > 300 and far > 300


def test_bad_meshes_are_refused_with_one_line(tmp_path):
    # Reference: a mesh with a hole has no inside, an inverted one a negative volume; each
    # is refused naming the file and what to do.
    import trimesh

    box = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    holed = trimesh.Trimesh(box.vertices, box.faces[1:])
    inverted = box.copy()
    inverted.invert()
    for name, mesh, needle in (("holed.stl", holed, "not closed"),
                               ("inverted.ply", inverted, "inside out")):
        path = write(tmp_path / name, mesh)
        with pytest.raises(ScenarioError, match=needle) as err:
            load_debris(path, 1.0)
        assert path in str(err.value) and "\n" not in str(err.value)
    with pytest.raises(ScenarioError, match="debris.mass"):
        load_debris(write(tmp_path / "box.obj", box))


def test_asset_mixes_mesh_parts_and_primitives(tmp_path, box_file):
    # Reference: the union of the parts (the smallest distance) and the sum of their masses;
    # the mesh part's file is found relative to the asset.
    asset = tmp_path / "mixed.toml"
    asset.write_text('[[parts]]\nshape = "mesh"\nfile = "box.stl"\nmass = 100.0\n'
                     'position = [0.0, 0.0, 5.0]\n\n[[parts]]\nshape = "sphere"\n'
                     'radius = 1.0\nmass = 50.0\n', encoding="utf-8")
    debris = load_debris(str(asset))
    assert debris.mass == 150.0
    rows, mesh = contact.debris_geometry(debris.parts)
    n = np.empty(3)
    for p, expected in (((0.0, 0.0, 1.5), 0.5), ((0.0, 0.0, 2.5), -0.5), ((0.0, 3.0, 5.0), 2.0)):
        d = debris_distance(np.array(p), np.zeros(3), np.eye(3), rows, mesh, n)
        assert d == pytest.approx(expected, abs=1e-12)


def test_scene_points_debris_asset_at_a_mesh_file(box_file):
    # Reference: uniform density, mass = density x volume (48 m^3); the centre of mass of a
    # box is its centre, its inertia m (b^2 + c^2) / 12 about x.
    scene = bn.load_scenario("capture", {"debris.asset": str(box_file),
                                         "debris.density": 100.0})
    debris = bn.model.builder.scene_debris(scene)
    assert debris.mass == pytest.approx(4800.0, rel=1e-12)
    np.testing.assert_allclose(debris.center_of_mass, 0.0, atol=1e-12)
    assert debris.inertia[0, 0] == pytest.approx(4800.0 * (4.0 + 36.0) / 12.0, rel=1e-12)


def test_node_rests_on_a_mesh_face_at_its_pair_penetration(box_file):
    # Reference: static equilibrium of Eq. 6, k_c delta = m a, on the top face of the box
    # mesh turned 30 deg about x.
    scene = bn.load_scenario("capture", {"net.nodes_per_side": 2, "contact.model": "exact"})
    model = bn.build_model(scene)
    box = make_debris("box", (Part("box", "mesh", (), 1e6, file=str(box_file)),))
    setup = contact.setup(scene, model, box)
    a = setup.arrays
    a.com[:] = box.center_of_mass
    a.quat[0] = bn.model.debris.rotation_quaternion(np.radians([30.0, 0.0, 0.0]))
    normal = bn.model.debris.rotation_matrix(a.quat[0]) @ [0.0, 1.0, 0.0]
    k_c = contact.pair_tables(scene, model)[0][0, contact.CLASS_OF_KIND[bn.NodeKind(
        model.kind[0])]]
    r, m, g, dt = model.radius[0], model.mass[0], 9.81, 1e-4
    pos = np.tile([0.0, 1e3, 0.0], (model.node_count, 1)) + np.arange(model.node_count)[:, None]
    pos[0] = (1.0 + r) * normal
    vel, dv = np.zeros_like(pos), np.zeros_like(pos)
    for k in range(200):
        dv[:] = 0.0
        dv[0] = -g * dt * normal
        vel += dv
        pos += dt * vel
        contact.debris_stage(pos, vel, dv, model.mass, model.radius, model.fixed, a, dt, k * dt)
    assert r - (pos[0] @ normal - 1.0) == pytest.approx(m * g / k_c, rel=1e-6)
    assert abs(vel[0] @ normal) < 1e-9


def test_bullet_engine_decomposes_a_non_convex_mesh():
    # Reference: the exact distance to the CSM mesh. PyBullet collides with convex hulls:
    # the V-HACD pieces of the non-convex CSM fill part of the step between nozzle and
    # service module, so PyBullet's distances from outside are at most that much shorter
    # (measured: 2-7 cm) and never longer than the margin.
    import pybullet
    from pybullet_utils.bullet_client import BulletClient

    from bulletnet.engines.debris_body import collision_shape, create_body

    debris = load_debris("apollo_csm_mesh")
    client = BulletClient(pybullet.DIRECT)
    body = create_body(client, debris, [0.0, 0.0, 0.0],
                       collision_shape=collision_shape(client, debris))
    assert len(client.getCollisionShapeData(body, -1)) > 1  # several convex pieces
    probe = client.createMultiBody(0.0, client.createCollisionShape(pybullet.GEOM_SPHERE,
                                                                    radius=0.05))
    rows, mesh = contact.debris_geometry(debris.parts)
    n = np.empty(3)
    errors = []
    for p in np.random.default_rng(15).uniform([-4, -8, -4], [4, 8, 4], size=(300, 3)):
        exact = debris_distance(p, np.zeros(3), np.eye(3), rows, mesh, n)
        if 0.1 < exact < 1.5:
            client.resetBasePositionAndOrientation(probe, p.tolist(), [0, 0, 0, 1])
            hits = client.getClosestPoints(body, probe, 2.0)
            errors.append(min(h[8] for h in hits) + 0.05 - exact)
    client.disconnect()
    errors = np.array(errors)
    assert errors.size > 50 and errors.max() < 0.005 and errors.min() > -0.15


def test_capture_of_the_mesh_csm_matches_the_primitive_csm(tmp_path):
    # Reference: the same capture (tests/conftest.small_capture) against the CSM of uniform
    # density from primitives: the same mass properties within the 96-gon's volume error, the
    # same surface within its 1 mm sagitta, so the same first contact (within a record
    # interval) and, in aggregate, the same contacts. The nodes' bounces are sensitive to
    # the geometry: the total normal impulse of this short capture differs by 9 % between
    # the uniform CSM and the CSM of assets/apollo_csm.toml, whose parts have their own
    # densities; the bars are 10 % on the most nodes in contact and 15 % on the impulse.
    # At 5e-4 s, where the mesh CSM's impulse is converged (5.6-5.9 N s from 1e-3 to
    # 1.25e-4 s) and assets/apollo_csm.toml's is within 25 % of its finest (6.9 against 5.5
    # N s at 1.25e-4 s; docs/capture.md, "Step, stability and sensitivity").
    from tests.conftest import small_capture

    uniform = tmp_path / "uniform_csm.toml"
    uniform.write_text("\n".join(
        f'[[parts]]\ny_start = {y0}\ny_end = {y1}\nradius_start = {r0}\nradius_end = {r1}\n'
        f"density = {11900.0 / load_debris('apollo_csm_mesh').parts[0].volume}\n"
        for y0, y1, r0, r1 in ((-5.5, -3.8, 1.25, 0.5), (-3.8, 2.3, 1.95, 1.95),
                               (2.3, 5.5, 1.95, 0.42))), encoding="utf-8")
    runs = {}
    for label, asset in (("mesh", "apollo_csm_mesh"), ("primitives", str(uniform))):
        scene = small_capture().with_overrides({"debris.asset": asset, "simulation.dt": 5e-4})
        runs[label] = bn.open_recording(bn.run(scene, tmp_path / f"{label}.h5").path)
    mesh, prims = runs["mesh"], runs["primitives"]
    interval = 1.0 / 20.0
    assert abs(mesh.attrs["first_contact_s"] - prims.attrs["first_contact_s"]) <= interval
    count = [r.contacts["count"].max() for r in (mesh, prims)]
    assert count[1] > 10 and count[0] == pytest.approx(count[1], rel=0.1)
    load = [r.contacts["normal_force"].sum() * interval for r in (mesh, prims)]
    assert load[1] > 0.0 and load[0] == pytest.approx(load[1], rel=0.15)


def test_open_mesh_for_contact_only_with_given_mass_properties(tmp_path):
    # Reference: the given mass properties turned into the body frame (R c + t, R I R^T);
    # an open mesh's outside is its normals' side: below and beside the cup (a box without
    # its top face) as outside the closed-form box, and inside above its bottom. (Near the
    # open rim the side follows the nearest wall: a node coming in through the opening
    # would be taken as inside.)
    import trimesh

    box = trimesh.creation.box(extents=(2.0, 2.0, 2.0))
    top = np.nonzero(box.face_normals[:, 2] > 0.5)[0]
    cup = trimesh.Trimesh(box.vertices, np.delete(box.faces, top, axis=0))
    cup.export(tmp_path / "cup.ply")
    inertia = [[3.0, 0.0, 0.0], [0.0, 4.0, 0.0], [0.0, 0.0, 5.0]]
    asset = tmp_path / "cup.toml"
    asset.write_text('[[parts]]\nshape = "mesh"\nfile = "cup.ply"\nmass = 10.0\n'
                     'center_of_mass = [0.0, 0.0, -0.2]\nrotation = [0.0, 0.0, 90.0]\n'
                     f'inertia = {inertia}\nposition = [1.0, 0.0, 0.0]\n', encoding="utf-8")
    debris = load_debris(str(asset))
    np.testing.assert_allclose(debris.center_of_mass, [1.0, 0.0, -0.2], atol=1e-12)
    np.testing.assert_allclose(np.diag(debris.inertia), [4.0, 3.0, 5.0], atol=1e-12)
    rows, mesh = contact.debris_geometry(debris.parts)
    n = np.empty(3)
    for p, expected in (((1.0, 0.0, -1.5), 0.5), ((3.5, 0.0, 0.0), 1.5), ((1.0, 0.0, -0.5), -0.5)):
        d = debris_distance(np.array(p), np.zeros(3), np.eye(3), rows, mesh, n)
        assert d == pytest.approx(expected, abs=1e-12)
    with pytest.raises(ScenarioError, match="not closed"):
        load_debris(str(tmp_path / "cup.ply"), 10.0)
    asset.write_text('[[parts]]\nshape = "mesh"\nfile = "cup.ply"\nmass = 10.0\n'
                     'inertia = [[1.0, 2.0, 0.0], [2.0, 1.0, 0.0], [0.0, 0.0, 1.0]]\n'
                     'center_of_mass = [0.0, 0.0, 0.0]\n', encoding="utf-8")
    load_debris.cache_clear()
    with pytest.raises(ScenarioError, match="positive-definite"):
        load_debris(str(asset))
