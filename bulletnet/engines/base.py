"""What every engine provides."""

from __future__ import annotations

import math
from abc import ABC, abstractmethod

import numpy as np

from .. import integrators
from ..model import NetModel
from ..scenario import Scenario
from ..state import NetState


def rotational_rates(model: NetModel) -> tuple[np.ndarray, np.ndarray]:
    """Per node, the damping rate sum(c_b + c_t l^2) / J_i [1/s] and the squared frequency
    sum(k_b + k_t l^2) / J_i [rad^2/s^2] of its rotation on its threads' bending and
    transverse springs, each shape (N,) (zero for clamped nodes)."""
    stiffness = model.bending_stiffness + model.transverse_stiffness * model.rest_length**2
    damping = model.bending_damping + model.transverse_damping * model.rest_length**2
    k_sum = np.zeros(model.node_count)
    c_sum = np.zeros(model.node_count)
    for end in (0, 1):
        np.add.at(k_sum, model.pairs[:, end], stiffness)
        np.add.at(c_sum, model.pairs[:, end], damping)
    free = ~model.fixed
    return np.where(free, c_sum / model.inertia, 0.0), np.where(free, k_sum / model.inertia, 0.0)


def bending_interval(model: NetModel, dt: float, margin: float = 0.3) -> int:
    """Steps between bending impulses: the largest n with n dt <= margin / max_i(rate_i), rate_i
    the fastest rotational time scale of node i — the damping rate or the frequency of
    :func:`rotational_rates` (clamped nodes excluded)."""
    damping, frequency2 = rotational_rates(model)
    rate = np.maximum(damping, np.sqrt(frequency2)).max()
    if rate <= 0:
        return 1
    return max(1, math.floor(margin / (rate * dt)))


class Engine(ABC):
    """Advances a :class:`NetState` in place. Engines hold no state of the net but their own
    scratch space (and, for ``bullet``, the PyBullet world mirroring it)."""

    name = "base"

    def __init__(self, scenario: Scenario, model: NetModel):
        self.scenario = scenario
        self.model = model
        self.arrays = integrators.model_arrays(model)
        self.work = integrators.Workspace(model.node_count, model.thread_count)
        self._loads_work = integrators.Workspace(model.node_count, model.thread_count)
        """Scratch space of :meth:`thread_loads` (the stepping workspace keeps its warm start)."""
        self.bending = scenario.bending.enabled
        """Whether nodes carry orientations and the bending springs act."""
        self.bending_every = scenario.bending.every or (
            bending_interval(model, self.dt) if self.dt > 0 else 1)
        """Steps between evaluations of the bending forces (applied as impulses) [-]."""
        self.gravity = np.asarray(scenario.scene.gravity, dtype=float)
        """Gravitational acceleration [m/s^2], shape (3,)."""
        self.external = np.zeros((model.node_count, 3))
        """External forces besides gravity and the model's loads [N], shape (N, 3)."""
        self.cg_tolerance = 1e-8
        """Relative residual at which the implicit solve stops [-]."""
        self.steps = 0
        """Steps taken so far [-]."""

    @property
    def integrator(self) -> str:
        return self.scenario.simulation.integrator

    @property
    def dt(self) -> float:
        """Requested step [s] (the engine may shorten it to divide the record interval)."""
        return self.scenario.simulation.step

    def steps_for(self, interval: float) -> int:
        """Whole number of steps covering ``interval`` [s] with steps no longer than :attr:`dt`."""
        return max(1, math.ceil(interval / self.dt - 1e-9))

    def rotations(self, state: NetState) -> tuple[np.ndarray, np.ndarray]:
        """(orientation (N, 4), angular velocity (N, 3)) for the kernels; empty without bending."""
        if self.bending:
            return state.orientation, state.angular_velocity
        return np.zeros((0, 4)), np.zeros((0, 3))

    @abstractmethod
    def advance(self, state: NetState, t_end: float) -> None:
        """Integrate ``state`` in place from ``state.time`` to ``t_end`` [s]."""

    def thread_loads(self, state: NetState) -> tuple[np.ndarray, np.ndarray]:
        """Axial tension (Eq. 3) and shear force magnitude of every thread at ``state`` [N],
        each shape (P,); the shear is zero without bending."""
        work = self._loads_work
        quat, omega = self.rotations(state)
        integrators.increment(integrators.SYMPLECTIC_EULER, 1.0 if self.bending else 0.0,
                              state.position, state.velocity, quat, omega, self.arrays,
                              work.arrays(), self.gravity, self.external, 1.0, 0.0)
        return work.tension.copy(), work.shear.copy()

    def stats(self) -> dict:
        """Counters of the run so far (steps, solver iterations)."""
        return {"steps": self.steps, "cg_iterations": int(self.work.cg_iterations[0])}

    def close(self) -> None:  # noqa: B027 (optional hook; only bullet holds resources)
        """Release engine resources (the PyBullet world)."""
