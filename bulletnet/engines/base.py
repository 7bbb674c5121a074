"""What every engine provides."""

from __future__ import annotations

import math
from abc import ABC, abstractmethod

import numpy as np

from ..forces.axial import axial_forces
from ..model import NetModel
from ..scenario import Scenario
from ..state import NetState

DEFAULT_DT = {"symplectic_euler": 1e-6, "implicit_euler": 1e-5}
"""Default step of the fixed-step integrators [s] (see README: accuracy against the reference)."""


class Engine(ABC):
    """Advances a :class:`NetState` in place. Engines hold no state of the net but their own
    scratch space (and, for ``bullet``, the PyBullet world mirroring it)."""

    name = "base"

    def __init__(self, scenario: Scenario, model: NetModel):
        self.scenario = scenario
        self.model = model
        self.gravity = np.asarray(scenario.scene.gravity, dtype=float)
        """Gravitational acceleration [m/s^2], shape (3,)."""
        self.steps = 0
        """Steps taken so far [-]."""

    @property
    def integrator(self) -> str:
        return self.scenario.simulation.integrator

    @property
    def dt(self) -> float:
        """Requested step [s] (the engine may shorten it to divide the record interval)."""
        return self.scenario.simulation.dt or DEFAULT_DT[self.integrator]

    def steps_for(self, interval: float) -> int:
        """Whole number of steps covering ``interval`` [s] with steps no longer than :attr:`dt`."""
        return max(1, math.ceil(interval / self.dt - 1e-9))

    @abstractmethod
    def advance(self, state: NetState, t_end: float) -> None:
        """Integrate ``state`` in place from ``state.time`` to ``t_end`` [s]."""

    def tension(self, state: NetState) -> np.ndarray:
        """Axial tension of every thread at ``state`` [N], shape (P,) (Eq. 3)."""
        m = self.model
        tension = np.zeros(m.thread_count)
        axial_forces(state.position, state.velocity, m.pairs, m.rest_length,
                     m.axial_stiffness, m.axial_damping, np.zeros_like(state.position), tension)
        return tension

    def stats(self) -> dict:
        """Counters of the run so far (steps, solver iterations)."""
        return {"steps": self.steps}

    def close(self) -> None:
        """Release engine resources (the PyBullet world)."""
