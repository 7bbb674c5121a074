"""What every engine provides."""

from __future__ import annotations

import dataclasses
import math
from abc import ABC, abstractmethod
from collections.abc import Callable

import numpy as np

from ..kernels.axial import thread_tensions
from ..kernels.breakage import BreakageArrays, breaking_arrays
from ..kernels.cable import CableArrays, cable_arrays
from ..kernels.orbit import OrbitArrays, orbit_arrays
from ..kernels.peaks import PeakArrays, peak_arrays
from ..kernels.peaks import reset as reset_peaks
from ..kernels.reel import ReelArrays, reel_arrays
from ..model.builder import scene_debris
from ..model.net import NetModel
from ..model.scenario import EXPONENTIAL, Scenario
from ..model.state import NetState
from ..solver import contact_stage as contact
from ..solver import integrators
from ..solver.exponential_damping import damping_ratio, node_shares


def rotational_rates(model: NetModel) -> tuple[np.ndarray, np.ndarray]:
    """Per node, the damping rate sum(c_b + c_t l^2) / J_i [1/s] and the squared frequency
    sum(k_b + k_t l^2) / J_i [rad^2/s^2] of its rotation on its threads' bending and
    transverse springs, each shape (N,) (zero for clamped nodes): half the Gershgorin bounds
    of :func:`~bulletnet.solver.integrators.rotational_bounds` over the node's inertia."""
    c_sum, k_sum = (0.5 * b for b in integrators.rotational_bounds(model))
    free = ~model.fixed
    return np.where(free, c_sum / model.inertia, 0.0), np.where(free, k_sum / model.inertia, 0.0)


BENDING_MARGINS = {"symplectic_euler": 0.3, "implicit_euler": 3.5, EXPONENTIAL: 0.3}
"""Bending interval times the fastest rotational rate, per integrator [-]. Measured on the 3 s
deployment: with symplectic Euler at 1e-6 s (n = 7) the bending impulses add less error than
the step's own truncation (tests/test_bending.py). Implicit Euler's rotations are implicit and
its bending springs held: an interval of 9e-5 s (3.5 / rate) added 0.05 mm at 1e-5 s (n = 9:
0.240 against 0.190 mm) and 0.01 mm at 3e-5 s (n = 3: 0.663 against 0.653 mm), for 1.8x and
1.2x less wall time."""


def bending_interval(model: NetModel, dt: float, margin: float) -> int:
    """Steps between evaluations of the bending springs: the largest n with n dt <= margin /
    max_i(rate_i), rate_i the fastest rotational time scale of node i — the damping rate or
    the frequency of :func:`rotational_rates` (clamped nodes excluded)."""
    damping, frequency2 = rotational_rates(model)
    rate = np.maximum(damping, np.sqrt(frequency2)).max()
    if rate <= 0:
        return 1
    return max(1, math.floor(margin / (rate * dt)))


def winch_cables(scenario: Scenario, model: NetModel) -> CableArrays:
    """The model's closing cables with the scene's winches (reel speed, stall tension; they
    stop at ``closing.min_length_ratio`` of the initial rest length), not yet started (the
    run's :class:`~bulletnet.sim.winch.WinchControl` starts them by the scene's trigger)."""
    cl, count = scenario.closing, model.cable_count
    cables = cable_arrays(model.cable_nodes, model.cable_start, model.cable_rest_length,
                          model.cable_rigidity, model.cable_damping_time,
                          np.full(count, cl.reel_speed), np.full(count, cl.stall_tension),
                          cl.min_length_ratio * model.cable_rest_length)
    return cables


def scene_breakage(scenario: Scenario, model: NetModel) -> BreakageArrays | None:
    """The breakage arrays of the model's threads and cables, every element intact, or None
    without ``strength.breakage``."""
    if not scenario.strength.breakage:
        return None
    return breaking_arrays(model.breaking_tension, model.cable_breaking_tension)


def scene_orbit(scenario: Scenario) -> OrbitArrays | None:
    """The scene's reference orbit as the kernels read it, or None without ``[orbit]``."""
    o = scenario.orbit
    return orbit_arrays(o.n, o.radial, o.along_track, o.origin) if o.enabled else None


def scene_reel(scenario: Scenario, model: NetModel) -> ReelArrays | None:
    """The reel at the chaser (``[reel]``) on the model's tether, its last
    ``tether.segments`` threads, not yet started (the run's
    :class:`~bulletnet.sim.tow.ReelControl` starts it by the scene's trigger); None without
    ``[reel]``."""
    r = scenario.reel
    if not r.enabled:
        return None
    return reel_arrays(model.pairs, model.rest_length, model.axial_stiffness,
                       model.axial_damping, scenario.tether.segments, r.speed,
                       r.tension_limit or np.inf, r.min_length, r.max_length or np.inf)


class Engine(ABC):
    """Advances a :class:`NetState` in place. Engines hold no state of the net but their own
    scratch space (and, for ``bullet``, the PyBullet world mirroring it)."""

    name = "base"

    def __init__(self, scenario: Scenario, model: NetModel):
        self.scenario = scenario
        self.model = model
        self.cables = winch_cables(scenario, model)
        """The closing cables and their winches, as the kernels read and write them."""
        self.arrays = integrators.model_arrays(model, self.cables, scene_orbit(scenario),
                                               scene_reel(scenario, model),
                                               scenario.simulation.preconditioner)
        self.breakage = scene_breakage(scenario, model)
        """What fails and when (:mod:`bulletnet.kernels.breakage`); None without breakage."""
        written = set()  # the thread arrays the kernels write: the engine's own copies
        if self.breakage is not None:  # a failed thread's parameters zeroed
            written |= {"k_a", "c_a", "k_t", "c_t", "k_b", "c_b"}
        if self.arrays.reel is not None:  # the reeled tether's rest length, stiffness, damping
            written |= {"rest", "k_a", "c_a"}
        if written:
            a = self.arrays
            self.arrays = a._replace(**{name: getattr(a, name).copy() for name in written})
        self.peaks: PeakArrays = peak_arrays(model.thread_count, model.cable_count)
        """Each element's largest tension in the steps since :meth:`peak_tensions` last read
        them (:mod:`bulletnet.kernels.peaks`)."""
        self.work = integrators.workspace(model.node_count, model.thread_count)
        self._loads_work = integrators.workspace(model.node_count, model.thread_count)
        """Scratch space of :meth:`thread_loads` (the stepping workspace keeps its warm start)."""
        self.bending = scenario.bending.enabled
        """Whether nodes carry orientations and the bending springs act."""
        self.bending_every = scenario.bending.every or (
            bending_interval(model, self.dt, BENDING_MARGINS[self.integrator])
            if self.dt > 0 else 1)
        """Steps between evaluations of the bending springs [-]: impulses with symplectic
        Euler, held forces and torques with implicit Euler (:func:`integrators.advance`)."""
        self.gravity = np.asarray(scenario.scene.gravity, dtype=float)
        """Gravitational acceleration [m/s^2], shape (3,)."""
        self.external = np.zeros((model.node_count, 3))
        """External forces besides gravity and the model's loads [N], shape (N, 3)."""
        self.cg_tolerance = scenario.simulation.cg_tolerance
        """Relative residual at which the implicit solve stops [-]."""
        self.steps = 0
        """Steps taken so far [-]."""
        self.debris = scene_debris(scenario)
        """The scene's debris (:class:`~bulletnet.model.debris.Debris`) or None."""
        self.contact = contact.setup(scenario, model, self.debris, self.handles_contact)
        """Contact arrays of the compiled stage (all off where this engine leaves contact
        to PyBullet)."""
        self._impulse_time = 0.0
        """Simulated time since the contact impulses were last read [s]."""
        self.step_hooks: list[Callable[[], None]] = []
        """Called between steps, in order: each chunk of the fast engine (``debris.step``,
        in a scene with debris or hooks), each step of bullet; what must act inside a frame
        (:mod:`bulletnet.sim.observers`). A hook may change :attr:`external`."""
        self.span = (0.0, 0.0)
        """Start and end [s] of the steps the engine takes next, until the next call of the
        step hooks."""
        self.damping_factor = np.ones(model.thread_count)
        """Each thread's damping over the model's, c_eff / c [-], shape (P,): 1 but on
        ``exponential_euler`` (:mod:`bulletnet.solver.exponential_damping`)."""
        self._set_damping()

    def base_forces(self) -> np.ndarray:
        """The forces that do not depend on the state, gravity, the model's loads and the
        external forces, m g + load + external [N], shape (N, 3)."""
        return self.model.mass[:, None] * self.gravity + self.model.load + self.external

    def between_steps(self, start: float, end: float) -> None:
        """Call the :attr:`step_hooks` before the steps from ``start`` to ``end`` [s] (engines
        call this between steps)."""
        self.span = (start, end)
        for hook in self.step_hooks:
            hook()

    @property
    def winches_started(self) -> bool:
        """Whether the winches' start time has been set (by a trigger or the scene)."""
        return bool(self.cables.start_time[0] < np.inf)

    def start_winches(self, t: float) -> None:
        """Start the winches at time ``t`` [s], unless they have been started already."""
        if not self.winches_started:
            self.cables.start_time[0] = t

    @property
    def reel_started(self) -> bool:
        """Whether the reel's start time has been set (by its trigger); False without a
        reel."""
        reel = self.arrays.reel
        return reel is not None and bool(reel.start_time[0] < np.inf)

    def start_reel(self, t: float) -> None:
        """Start the reel at the chaser at time ``t`` [s], unless it has been started
        already."""
        if not self.reel_started:
            self.arrays.reel.start_time[0] = t

    def reel_loads(self) -> dict | None:
        """The reel at the chaser after the last step: the tether's deployed ``length`` [m]
        and the reel's ``work`` so far [J], floats; None without a reel."""
        reel = self.arrays.reel
        if reel is None:
            return None
        return {"length": float(reel.length[0]), "work": float(reel.work[0])}

    def cable_loads(self) -> dict:
        """The closing cables at the last force evaluation, each shape (C,): ``tension`` [N],
        ``length`` [m], ``rest_length`` [m] and the winches' ``work`` so far [J]."""
        c = self.cables
        return {"tension": c.tension.copy(), "length": c.length.copy(),
                "rest_length": c.rest.copy(), "work": c.work.copy()}

    def peak_tensions(self) -> tuple[np.ndarray, np.ndarray]:
        """Each thread's (P,) and each closing cable's (C,) largest tension [N] in the steps
        taken since the last call (0 if none: an engine that keeps no peaks, or no step), the
        tension each step computed its forces from; resets them."""
        threads, cables = self._thread_peaks(), self.peaks.cable.copy()
        reset_peaks(self.peaks)
        return threads, cables

    def _thread_peaks(self) -> np.ndarray:
        """Each thread's largest tension since the last reset [N], shape (P,)."""
        return self.peaks.thread.copy()

    def failure_times(self) -> dict | None:
        """When each element failed [s], -1 if intact: ``threads`` (P,) and ``cables`` (C,);
        and ``energy_J``, the elastic energy the failed elements held when they failed [J].
        None without breakage."""
        b = self.breakage
        if b is None:
            return None
        return {"threads": b.failure_time.copy(), "cables": b.cable_failure_time.copy(),
                "energy_J": float(b.energy[0])}

    handles_contact = True
    """Whether the engine applies contact with the compiled stage (bullet: PyBullet does)."""

    def contact_loads(self) -> dict:
        """Contact since the last call, as mean forces over that interval: ``node_force``
        (N,) debris contact normal force on each node [N], ``self_force`` (N,) node-node
        normal force [N]; and ``first_contact`` (2,) times of the first debris and the first
        node-node contact [s] (-1: none yet). Resets the accumulators."""
        a = self.contact.arrays
        span = max(self._impulse_time, 1e-300)
        out = {"node_force": a.node_impulse / span, "self_force": a.self_impulse / span,
               "first_contact": a.first_contact.copy()}
        a.node_impulse[:] = 0.0
        a.self_impulse[:] = 0.0
        self._impulse_time = 0.0
        return out

    @property
    def integrator(self) -> str:
        return self.scenario.simulation.integrator

    @property
    def implicit(self) -> bool:
        """Whether the integrator is implicit Euler (else symplectic Euler)."""
        return integrators.INTEGRATOR_IDS[self.integrator] == integrators.IMPLICIT_EULER

    @property
    def dt(self) -> float:
        """Requested step [s] (the engine may shorten it to divide the record interval)."""
        return self.scenario.simulation.step

    def switch_integrator(self, integrator: str, dt: float) -> None:
        """Go on with ``integrator`` ('' keeps the current one) at steps of ``dt`` [s] (0 keeps
        the current step) from the next :meth:`advance` (the tow's: ``thrust.integrator``,
        ``thrust.dt``)."""
        sim = self.scenario.simulation
        sim = dataclasses.replace(sim, integrator=integrator or sim.integrator,
                                  dt=dt or sim.dt)
        self.scenario = dataclasses.replace(self.scenario, simulation=sim)
        self._set_damping()
        if self.bending and not self.scenario.bending.every:
            self.bending_every = bending_interval(self.model, self.dt,
                                                  BENDING_MARGINS[self.integrator])

    def _set_damping(self) -> None:
        """The dampers for the integrator and step in force
        (:mod:`bulletnet.solver.exponential_damping`): on the explicit integrators the closing
        cables' dampers relax over the step, from their vertices' shares d / m of their
        nodes' dampers (``CableArrays.share``), and on ``exponential_euler`` the threads' too
        (their c_eff, :func:`~bulletnet.solver.exponential_damping.damping_ratio`); on
        implicit Euler (and the reference engine's integrators) the model's dampers."""
        a = self.arrays
        c = a.c_a / self.damping_factor  # the model's (a failed thread's stays 0)
        cables = None if a.cables is None else a.cables.nodes
        explicit = integrators.INTEGRATOR_IDS.get(self.integrator) == integrators.SYMPLECTIC_EULER
        share = (node_shares(c, a.pairs, a.mass, a.fixed, cables) if explicit
                 else np.zeros_like(a.mass))
        factor = (damping_ratio(c, a.pairs, share, self.dt) if self.integrator == EXPONENTIAL
                  else np.ones_like(c))
        if not np.array_equal(factor, self.damping_factor):
            self._scale_damping(factor / self.damping_factor)
            self.damping_factor = factor
        if cables is not None:
            a.cables.share[:] = share[cables]

    def _scale_damping(self, factor: np.ndarray) -> None:
        """Multiply each thread's damping by ``factor`` [-], shape (P,), where the kernels
        read it."""
        if self.arrays.c_a is self.model.axial_damping:  # the engine's own copy, once
            self.arrays = self.arrays._replace(c_a=self.arrays.c_a.copy())
        self.arrays.c_a[:] *= factor

    def steps_for(self, interval: float) -> int:
        """Whole number of steps covering ``interval`` [s] with steps no longer than :attr:`dt`."""
        return max(1, math.ceil(interval / self.dt - 1e-9))

    def rotations(self, state: NetState) -> tuple[np.ndarray | None, np.ndarray | None]:
        """(orientation (N, 4), angular velocity [rad/s] (N, 3)) for the kernels; (None, None)
        without bending (the kernels then compile no bending code)."""
        if self.bending:
            return state.orientation, state.angular_velocity
        return None, None

    def kernel_groups(self, state: NetState) -> dict[str, list[tuple]]:
        """The compiled kernels this engine's steps call, by group, as (dispatcher, arguments)
        (:mod:`bulletnet.sim.compile_ahead`); none unless an engine says (the fast engine does)."""
        return {}

    @abstractmethod
    def advance(self, state: NetState, t_end: float) -> None:
        """Integrate ``state`` in place from ``state.time`` to ``t_end`` [s]."""

    def thread_loads(self, state: NetState) -> tuple[np.ndarray, np.ndarray]:
        """Axial tension (Eq. 3) and shear force magnitude of every thread at ``state`` [N],
        each shape (P,); the shear is zero without bending."""
        for kernel, args in self.loads_calls(state):
            kernel(*args)
        return self._loads_work.tension.copy(), self._loads_work.shear.copy()

    def loads_calls(self, state: NetState) -> list[tuple]:
        """The compiled calls :meth:`thread_loads` makes at ``state``, as (dispatcher,
        arguments), into a workspace of their own: each thread's tension
        (:func:`~bulletnet.kernels.axial.thread_tensions`) and, with bending, the bending
        springs afresh for the shear. Nothing the run reads is written (the cables' kernel,
        whose tension and damper force the winches read at the next step, is not called),
        and no force is summed, so a run's first frame compiles two small kernels."""
        work, model = self._loads_work, self.arrays
        calls = [(thread_tensions, (state.position, state.velocity, model.pairs, model.rest,
                                    model.rest_rate, model.k_a, model.c_a, model.bilateral,
                                    work.tension))]
        quat, omega = self.rotations(state)
        if quat is not None:
            calls.append((integrators.evaluate_bending,
                          (state.position, state.velocity, quat, omega, model, work)))
        return calls

    def stats(self) -> dict:
        """Counters of the run so far (steps, solver iterations; with contact, the overlap
        projections and their total distance [m], and the self-contact list builds)."""
        out = {"steps": self.steps, "cg_iterations": int(self.work.cg_iterations[0])}
        if self.contact.enabled:
            a = self.contact.arrays
            out.update(overlap_projections=int(a.projections[0]),
                       overlap_projected_m=float(a.projections[1]),
                       pair_list_builds=int(a.pair_meta[2]))
            if a.solve is not None:
                out.update(contact_sweeps=int(a.solve.stats[0]),
                           contact_unconverged=int(a.solve.stats[1]),
                           contact_candidates=int(a.solve.stats[2]))
        return out

    def close(self) -> None:  # noqa: B027 (optional hook; only bullet holds resources)
        """Release engine resources (the PyBullet world)."""
