"""Orbital relative motion against closed forms: a free point mass under the
Hill-Clohessy-Wiltshire (HCW) equations over one orbit, a radial tethered dumbbell's
equilibrium tension and libration, and the grid path against the pair list with an orbit."""

from __future__ import annotations

import math

import numpy as np
import pytest

import bulletnet as bn
from bulletnet.engines import make_engine
from bulletnet.model import scenario
from bulletnet.model.net import NetModel, NodeKind
from bulletnet.model.state import NetState
from tests.conftest import small_scene
from tests.test_grid import assert_identical, final_states


def point_masses(mass, pairs=(), rest=(), stiffness=(), damping=()) -> NetModel:
    """Free point masses joined by tension-only threads (no bending, no cables)."""
    n, p = len(mass), len(pairs)
    zeros = np.zeros(p)
    return NetModel(
        nodes_per_side=0, mass=np.asarray(mass, float), radius=np.full(n, 0.01),
        kind=np.full(n, NodeKind.TETHER, dtype=np.int8),
        pairs=np.asarray(pairs, np.int64).reshape(p, 2), rest_length=np.asarray(rest, float),
        thread_radius=np.full(p, 1e-3), axial_stiffness=np.asarray(stiffness, float),
        axial_damping=np.asarray(damping, float), transverse_stiffness=zeros,
        transverse_damping=zeros, bending_stiffness=zeros, bending_damping=zeros,
        inertia=np.full(n, 1e-6), rest_axis=np.zeros((p, 3)), fixed=np.zeros(n, bool),
        load=np.zeros((n, 3)), bilateral=False)


def scene(**keys) -> scenario.Scenario:
    """A scene from ``section__key=value`` pairs."""
    doc: dict = {}
    for key, value in keys.items():
        section, name = key.split("__")
        doc.setdefault(section, {})[name] = value
    return scenario.from_dict(doc, "<test>")


def run_model(s: scenario.Scenario, model: NetModel, position, velocity, t_end: float,
              frames: int = 10) -> NetState:
    """``model`` from (position, velocity) [m, m/s] to ``t_end`` [s] on ``s``'s engine."""
    state = NetState(0.0, np.array(position, float), np.array(velocity, float))
    engine = make_engine(s, model)
    for t in np.linspace(0.0, t_end, frames + 1)[1:]:
        engine.advance(state, float(t))
    engine.close()
    return state


N_FAST = 2.0 * math.pi / 4.0
"""A mean motion whose orbit takes 4 s [rad/s]: the tests' orbits are short."""
AXES = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
"""Rows: LVLH x, y, z in the scene's frame under the default mapping (radial +x,
along-track +z, so cross-track is +x cross +z = -y)."""


def clohessy_wiltshire(n, r0, v0, t):
    """Reference: the Clohessy-Wiltshire solution of the HCW equations (Clohessy &
    Wiltshire 1960; Vallado, Fundamentals of Astrodynamics, Sec. 6.8): LVLH position and
    velocity at t from (r0, v0)."""
    (x, y, z), (u, v, w) = r0, v0
    s, c = math.sin(n * t), math.cos(n * t)
    pos = [(4 - 3 * c) * x + s / n * u + 2 / n * (1 - c) * v,
           6 * (s - n * t) * x + y - 2 / n * (1 - c) * u + (4 * s - 3 * n * t) / n * v,
           c * z + s / n * w]
    vel = [3 * n * s * x + c * u + 2 * s * v,
           6 * n * (c - 1) * x - 2 * s * u + (4 * c - 3) * v,
           -n * s * z + c * w]
    return np.array(pos), np.array(vel)


@pytest.mark.parametrize("integrator", ["symplectic_euler", "implicit_euler"])
def test_free_point_mass_follows_clohessy_wiltshire_over_one_orbit(integrator):
    # Reference: the Clohessy-Wiltshire solution (above), one orbit of 4 s, through the
    # default scene-to-LVLH mapping. Both integrators are first order, the HCW force explicit:
    # the error halves with the step (measured order within 0.1 of 1) and is below 1e-3 of
    # the motion's size at 1e-4 s.
    r0, v0 = np.array([1.0, 0.5, -0.5]), np.array([0.2, -0.3, 0.4])
    ref_r, ref_v = clohessy_wiltshire(N_FAST, r0, v0, 4.0)
    errors = []
    for dt in (2e-4, 1e-4):
        s = scene(orbit__enabled=True, orbit__mean_motion=N_FAST,
                  simulation__integrator=integrator, simulation__dt=dt, scene__duration=4.0)
        state = run_model(s, point_masses([2.0]), [r0 @ AXES], [v0 @ AXES], 4.0)
        errors.append(max(np.abs(state.position[0] @ AXES.T - ref_r).max(),
                          np.abs(state.velocity[0] @ AXES.T - ref_v).max() / N_FAST))
    scale = np.abs(ref_r).max()
    assert errors[1] < 1e-3 * scale
    assert math.log2(errors[0] / errors[1]) == pytest.approx(1.0, abs=0.1)


def test_orbit_mean_motion_from_altitude():
    # Reference: Kepler's third law, n = sqrt(mu / a^3): 400 km above the equatorial
    # radius, a = 6778.1 km, a period of 92.56 min
    s = scene(orbit__enabled=True, orbit__altitude=400e3)
    assert 2 * math.pi / s.orbit.n / 60 == pytest.approx(92.56, abs=0.01)
    assert scene(orbit__mean_motion=1e-3).orbit.n == 1e-3


M1, M2, REST = 3.0, 1.0, 2.0
"""The dumbbell's masses [kg] and its thread's rest length [m]."""
MU = M1 * M2 / (M1 + M2)
"""Its reduced mass [kg]."""


def dumbbell(length, angle=0.0):
    """Positions (2, 3) [m] of the dumbbell's masses ``length`` apart with their centre of
    mass at the LVLH origin, in the orbit plane at ``angle`` [rad] from the local vertical
    (scene x radial, z along-track)."""
    e = np.array([math.cos(angle), 0.0, math.sin(angle)])
    return np.outer(np.array([-M2, M1]) / (M1 + M2) * length, e)


def dumbbell_in_orbit(integrator, k):
    """(scene, model, stretched length [m]) of the dumbbell on a thread of stiffness ``k``
    [N/m] in the 4 s orbit, for 8 s at 1e-4 s; the length is the equilibrium's, along the
    local vertical, L0 / (1 - 3 n^2 mu / k)."""
    model = point_masses([M1, M2], [(0, 1)], [REST], [k], [20.0])
    s = scene(orbit__enabled=True, orbit__mean_motion=N_FAST, simulation__integrator=integrator,
              simulation__dt=1e-4, scene__duration=8.0)
    return s, model, REST / (1 - 3 * N_FAST**2 * MU / k)


@pytest.mark.parametrize("integrator", ["symplectic_euler", "implicit_euler"])
def test_radial_dumbbell_holds_the_gravity_gradient_tension(integrator):
    # Reference: a dumbbell of masses m1, m2 on a thread along the local vertical, at rest
    # in LVLH, is in equilibrium when the thread holds the gravity gradient's pull,
    # T = 3 n^2 mu L (mu = m1 m2 / (m1 + m2) the reduced mass, L the stretched length
    # L0 / (1 - 3 n^2 mu / k); Beletsky & Levin, Dynamics of Space Tether Systems, 1993).
    # Placed there at rest it stays for two orbits: any error in the HCW force would set
    # the thread oscillating.
    s, model, length = dumbbell_in_orbit(integrator, 200.0)
    state = run_model(s, model, dumbbell(length), np.zeros((2, 3)), 8.0)
    tension = make_engine(s, model).thread_loads(state)[0][0]
    assert tension == pytest.approx(3 * N_FAST**2 * MU * length, rel=1e-9)
    np.testing.assert_allclose(state.position, dumbbell(length), rtol=0, atol=1e-9)


@pytest.mark.parametrize("integrator", ["symplectic_euler", "implicit_euler"])
def test_radial_dumbbell_librates_in_plane_at_root_three_n(integrator):
    # Reference: the in-plane libration of a rigid dumbbell about the local vertical, small
    # angles: theta'' = -3 n^2 theta, frequency sqrt(3) n (Beletsky & Levin 1993). A stiff
    # thread (axial mode 40x faster) tilted 0.05 rad, released at rest in LVLH; the period
    # from the angle's zero crossings over two orbits, within 0.5 %.
    s, model, length = dumbbell_in_orbit(integrator, 2e4)
    state = NetState(0.0, dumbbell(length, 0.05), np.zeros((2, 3)))
    engine = make_engine(s, model)
    times = np.linspace(0.0, 8.0, 801)
    angle = [0.05]
    for t in times[1:]:
        engine.advance(state, float(t))
        d = state.position[1] - state.position[0]
        angle.append(math.atan2(d[2], d[0]))
    angle = np.array(angle)
    k_ = np.nonzero(np.sign(angle[1:]) != np.sign(angle[:-1]))[0]
    crossings = times[k_] - angle[k_] * (times[k_ + 1] - times[k_]) / (angle[k_ + 1] - angle[k_])
    period = 2.0 * np.diff(crossings).mean()
    assert len(crossings) >= 5
    assert period == pytest.approx(2 * math.pi / (math.sqrt(3) * N_FAST), rel=5e-3)


@pytest.mark.parametrize("integrator", ["symplectic_euler", "implicit_euler"])
def test_grid_equals_pairs_in_orbit(integrator):
    # Reference: the pair-list path (tests/test_grid.py); the HCW forces are the same kernel
    # on both paths, added after every other element's: bit for bit.
    dt = 1e-6 if integrator == "symplectic_euler" else 3e-5
    pairs, on_grid = final_states(lambda kernels: small_scene(**{
        "net.nodes_per_side": 5, "simulation.kernels": kernels, "scene.duration": 0.2,
        "simulation.integrator": integrator, "simulation.dt": dt, "orbit.enabled": True,
        "orbit.mean_motion": 2.0, "orbit.origin": [0.0, 0.0, -3.0]}))
    assert_identical(pairs, on_grid)


def test_orbit_refuses_axes_that_are_not_orthogonal():
    with pytest.raises(bn.ScenarioError, match="orbit.along_track: expected a direction "
                                               "orthogonal"):
        scene(orbit__enabled=True, orbit__along_track=[1.0, 0.0, 1.0])

