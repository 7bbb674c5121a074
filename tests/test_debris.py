"""The debris asset: mass properties against exact integrals, the PyBullet body, free spin."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad

from bulletnet.engines.debris_body import create_body
from bulletnet.model.debris import SECTIONS, Part, load_debris, mass_properties


def exact_part(part: Part):
    """Reference: mass properties of a solid frustum by quadrature over thin disks, dm =
    rho pi r(y)^2 dy, dI_axial = r^2 dm / 2, dI_transverse = (r^2 / 4 + y^2) dm about y = 0."""
    y_start, y_end, radius_start, radius_end = part.size

    def r(y):
        s = (y - y_start) / (y_end - y_start)
        return radius_start + s * (radius_end - radius_start)

    def integral(f):
        return quad(f, y_start, y_end, epsabs=0, epsrel=1e-13)[0]

    volume = integral(lambda y: math.pi * r(y) ** 2)
    rho = part.mass / volume
    y_c = integral(lambda y: rho * math.pi * r(y) ** 2 * y) / part.mass
    axial = integral(lambda y: rho * math.pi * r(y) ** 4 / 2)
    transverse = integral(lambda y: rho * math.pi * r(y) ** 2 * (r(y) ** 2 / 4 + y**2))
    return y_c, axial, transverse - part.mass * y_c**2


# polygons of SECTIONS sides inscribed in the circles: area short by (2 pi / n)^2 / 6 = 1e-4
# relative at n = 256, r^4 terms by twice that; the bars below allow 3x that.
POLYGON = 3 * 2 * (2 * math.pi / SECTIONS) ** 2 / 6


@pytest.mark.parametrize("part", [
    Part("cylinder", "frustum", (-3.8, 2.3, 1.95, 1.95), 6110.0),
    Part("frustum", "frustum", (2.3, 5.5, 1.95, 0.42), 5560.0),
    Part("cone", "frustum", (0.0, 2.0, 1.0, 0.0), 10.0),
])
def test_part_mass_properties_against_quadrature(part):
    mass, com, inertia = mass_properties((part,))
    y_c, axial, transverse = exact_part(part)
    assert mass == part.mass
    assert com[1] == pytest.approx(y_c, abs=POLYGON * (part.size[1] - part.size[0]))
    assert abs(com[0]) < 1e-12 and abs(com[2]) < 1e-12
    assert inertia[1, 1] == pytest.approx(axial, rel=POLYGON)
    assert inertia[0, 0] == pytest.approx(transverse, rel=POLYGON)
    assert inertia[2, 2] == pytest.approx(transverse, rel=POLYGON)


def test_apollo_csm_matches_the_paper_and_the_parallel_axis_theorem():
    # Reference: Sec. 5 (11900 kg, 11 m long, 3.9 m diameter) and the parallel-axis theorem
    # applied to the quadrature references of each part.
    csm = load_debris("apollo_csm")
    assert csm.mass == pytest.approx(11900.0, rel=1e-12)
    np.testing.assert_allclose(csm.extents, [3.9, 11.0, 3.9], rtol=1e-12)
    exact = [exact_part(p) for p in csm.parts]
    y_com = sum(p.mass * e[0] for p, e in zip(csm.parts, exact, strict=True)) / csm.mass
    axial = sum(e[1] for e in exact)
    transverse = sum(e[2] + p.mass * (e[0] - y_com) ** 2
                     for p, e in zip(csm.parts, exact, strict=True))
    assert csm.center_of_mass[1] == pytest.approx(y_com, abs=POLYGON * 11.0)
    assert csm.inertia[1, 1] == pytest.approx(axial, rel=POLYGON)
    assert csm.inertia[0, 0] == pytest.approx(transverse, rel=POLYGON)
    off_diagonal = csm.inertia - np.diag(np.diag(csm.inertia))
    assert np.abs(off_diagonal).max() < 1e-9 * csm.inertia.max()  # body axes are principal


def spin(csm, dt, tilt_deg, duration=120.0):
    """Relative change of the world angular momentum and of the spin rate over ``duration``
    for the CSM spinning at 5 deg/s about z, tilted by ``tilt_deg`` towards its long axis."""
    import pybullet
    from pybullet_utils.bullet_client import BulletClient

    client = BulletClient(pybullet.DIRECT)
    client.setGravity(0, 0, 0)
    client.setPhysicsEngineParameter(fixedTimeStep=dt, numSubSteps=0)
    tilt = math.radians(tilt_deg)
    omega = math.radians(5.0) * np.array([0.0, math.sin(tilt), math.cos(tilt)])
    body = create_body(client, csm, [0.0, 0.0, 10.0], angular_velocity=omega)
    info = client.getDynamicsInfo(body, -1)
    mass, inertia = info[0], info[2]
    assert mass == csm.mass and np.allclose(inertia, np.diag(csm.inertia), rtol=1e-12)

    def momentum():
        q = client.getBasePositionAndOrientation(body)[1]
        rot = np.array(client.getMatrixFromQuaternion(q)).reshape(3, 3)
        w = np.array(client.getBaseVelocity(body)[1])
        return rot @ np.diag(inertia) @ rot.T @ w, np.linalg.norm(w)

    l0, w0 = momentum()
    for _ in range(round(duration / dt)):
        client.stepSimulation()
    l1, w1 = momentum()
    client.disconnect()
    return np.linalg.norm(l1 - l0) / np.linalg.norm(l0), abs(w1 - w0) / w0


def test_debris_spin_conserved_over_120_s():
    # Reference: torque-free rigid body. The paper's spin (5 deg/s about z, a principal axis)
    # is steady: conserved to round-off. A tilted spin precesses; PyBullet's first-order
    # rotation update then keeps angular momentum to O(dt): halving dt halves the drift.
    csm = load_debris("apollo_csm")
    assert max(spin(csm, 1 / 240, 0.0)) < 1e-12
    coarse, fine = spin(csm, 1 / 240, 10.0)[0], spin(csm, 1 / 480, 10.0)[0]
    assert coarse < 1e-3
    assert math.log2(coarse / fine) == pytest.approx(1.0, abs=0.1)


def test_tumbling_box_and_panel_flips_as_eulers_equations_say():
    # Reference: Euler's equations of a torque-free rigid body in its principal frame,
    # I1 w1' = (I2 - I3) w2 w3 (and cyclic), integrated by scipy's DOP853. A spin about the
    # intermediate axis is unstable: a 5 % perturbation flips it after ~59 s. The debris is
    # a bus and a panel turned 30 deg off its axes (products of inertia: PyBullet's inertial
    # frame is the principal one); PyBullet's first-order rotation update keeps angular
    # momentum and energy to O(dt): 3e-4 and 5e-4 at 1/240 s over 80 s.
    from scipy.integrate import solve_ivp

    from bulletnet.engines.debris_body import RigidDebris
    from bulletnet.model.debris import make_debris, rotation_matrix

    debris = make_debris("box_and_panel", (
        Part("bus", "box", (2.0, 1.0, 1.5), 1000.0),
        Part("panel", "box", (0.05, 4.0, 1.0), 100.0, (0.0, 2.6, 0.0), (0.0, 30.0, 0.0))))
    moments, axes = debris.principal_moments, debris.principal_axes
    assert np.abs(debris.inertia - np.diag(np.diag(debris.inertia))).max() > 1.0
    w0 = np.array([0.01, 0.2, 0.0])  # [rad/s] principal frame: about the intermediate axis
    state = np.concatenate([np.zeros(3), [0.0, 0.0, 0.0, 1.0], np.zeros(3), axes @ w0])
    rigid = RigidDebris(debris, state.copy())
    dt, duration = 1.0 / 240.0, 80.0
    times = dt * np.arange(1, round(duration / dt) + 1)
    ours = np.empty((times.size, 3))
    for k in range(times.size):
        rigid.step(np.zeros(6), dt, state)
        ours[k] = axes.T @ rotation_matrix(state[3:7]).T @ state[10:13]  # principal frame
    rigid.close()
    i1, i2, i3 = moments

    def euler(_t, w):
        return [(i2 - i3) * w[1] * w[2] / i1, (i3 - i1) * w[2] * w[0] / i2,
                (i1 - i2) * w[0] * w[1] / i3]

    ref = solve_ivp(euler, (0.0, duration), w0, method="DOP853", rtol=1e-11, atol=1e-14,
                    t_eval=times).y.T

    def flips(w):
        return times[np.nonzero(np.diff(np.sign(w[:, 1])))[0]]

    assert flips(ref).size >= 1 and flips(ours).size == flips(ref).size
    np.testing.assert_allclose(flips(ours), flips(ref), atol=0.1)
    np.testing.assert_allclose(ours, ref, atol=5e-4)
    rot = rotation_matrix(state[3:7])
    l0, l1 = debris.inertia @ axes @ w0, rot @ debris.inertia @ rot.T @ state[10:13]
    assert np.linalg.norm(l1 - l0) / np.linalg.norm(l0) < 1e-3
    e0, e1 = 0.5 * (axes @ w0) @ l0, 0.5 * state[10:13] @ l1
    assert abs(e1 - e0) / e0 < 1e-3


def test_asset_parts_with_density_and_bad_parts(tmp_path):
    # Reference: a box's volume is the product of its edges (mass = density x volume); bad
    # parts are refused with a one-line error naming the part and the key.
    from bulletnet.common.errors import ScenarioError

    good = tmp_path / "good.toml"
    good.write_text('[[parts]]\nshape = "box"\nsize = [1.0, 2.0, 3.0]\ndensity = 100.0\n'
                    'position = [1.0, 0.0, 0.0]\n', encoding="utf-8")
    debris = load_debris(str(good))
    assert debris.mass == pytest.approx(600.0, rel=1e-15)
    np.testing.assert_allclose(debris.center_of_mass, [1.0, 0.0, 0.0], atol=1e-12)
    for body, message in (('shape = "box"\nmass = 1.0', "parts[0].size: expected three"),
                          ('shape = "sphere"\nradius = 1.0', "give either mass"),
                          ('shape = "cube"\nmass = 1.0', "parts[0].shape: expected one of"),
                          ('shape = "sphere"\nradius = 1.0\nmass = 1.0\nsize = [1, 1, 1]',
                           "unknown key 'size' for a sphere")):
        bad = tmp_path / "bad.toml"
        bad.write_text(f"[[parts]]\n{body}\n", encoding="utf-8")
        load_debris.cache_clear()
        with pytest.raises(ScenarioError, match=message.replace("[", r"\[")):
            load_debris(str(bad))


def test_pybullet_compound_matches_the_parts_at_their_poses():
    # Reference: the exact signed distance of the parts (checked against brute force in
    # test_primitives): PyBullet's closest points from probe spheres outside the compound of
    # boxes, a sphere, a cylinder and a cone's convex hull agree within the cone's 48-gon
    # sagitta, r (1 - cos(pi / 48)) = 2.1 mm, and PyBullet's convex margin.
    import pybullet
    from pybullet_utils.bullet_client import BulletClient

    from bulletnet.engines.debris_body import collision_shape
    from bulletnet.kernels.geometry import debris_distance
    from bulletnet.model.debris import make_debris
    from bulletnet.solver.contact_stage import debris_geometry

    debris = make_debris("mixed", (
        Part("box", "box", (1.0, 3.0, 0.4), 10.0, (0.3, -0.2, 0.5), (20.0, -35.0, 50.0)),
        Part("ball", "sphere", (0.8,), 5.0, (-2.0, 0.6, 0.1)),
        Part("drum", "frustum", (-1.0, 1.5, 0.6, 0.6), 5.0, (0.2, 2.0, -0.3), (60.0, 10.0, 0.0)),
        Part("cone", "frustum", (0.0, 2.0, 1.0, 0.0), 1.0, (0.0, -2.0, 0.0), (0.0, 0.0, 90.0))))
    client = BulletClient(pybullet.DIRECT)
    body = create_body(client, debris, [0.0, 0.0, 0.0], collision_shape=collision_shape(
        client, debris))
    probe_radius = 0.05
    probe = client.createMultiBody(0.0, client.createCollisionShape(
        pybullet.GEOM_SPHERE, radius=probe_radius))
    (rows, mesh), normal = debris_geometry(debris.parts), np.empty(3)
    rng = np.random.default_rng(15)
    checked = 0
    for point in rng.uniform(-4.0, 4.0, size=(300, 3)):
        exact = debris_distance(point, np.zeros(3), np.eye(3), rows, mesh, normal)
        if not 0.1 < exact < 1.5:
            continue
        client.resetBasePositionAndOrientation(probe, point.tolist(), [0.0, 0.0, 0.0, 1.0])
        hits = client.getClosestPoints(body, probe, 2.0)
        assert hits, point
        ours = min(h[8] for h in hits) + probe_radius
        assert ours == pytest.approx(exact, abs=1.0 * (1 - math.cos(math.pi / 48)) + 2e-3)
        checked += 1
    client.disconnect()
    assert checked > 50


def test_envisat_asset_matches_its_published_envelope():
    # Reference: ESA's in-orbit envelope, 26 x 10 x 5 m, and mass budget, 8211 kg at launch
    # less 319 kg of fuel (assets/envisat.toml).
    envisat = load_debris("envisat")
    assert envisat.mass == pytest.approx(8211.0 - 319.0, rel=1e-12)
    np.testing.assert_allclose(envisat.extents, [26.0, 10.0, 5.0], rtol=1e-12)
    axes = envisat.principal_axes
    np.testing.assert_allclose(axes @ np.diag(envisat.principal_moments) @ axes.T,
                               envisat.inertia, rtol=0, atol=1e-9 * envisat.inertia.max())
    assert np.linalg.det(axes) == pytest.approx(1.0)


def test_rotation_matrix_of_one_quaternion_is_the_batched_one_and_scipys():
    # reference: the batched (numpy) evaluation of the same formula, bit for bit, and scipy's
    # Rotation to round-off: the single-quaternion path is Python floats for the run's frames
    from scipy.spatial.transform import Rotation

    from bulletnet.model.debris import rotation_matrix

    q = np.random.default_rng(5).normal(size=(200, 4))
    q /= np.linalg.norm(q, axis=1)[:, None]
    batched = rotation_matrix(q)
    for k in range(len(q)):
        assert np.array_equal(rotation_matrix(q[k]), batched[k])
    np.testing.assert_allclose(batched, Rotation.from_quat(q).as_matrix(), atol=1e-15)
    assert np.array_equal(rotation_matrix([0, 0, 0, 1]), np.eye(3))
