"""The dynamic state of the net. No parameters live here (they are on :class:`NetModel`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class NetState:
    time: float
    """Simulated time [s]."""
    position: np.ndarray
    """Node positions [m], shape (N, 3), float64, C-contiguous."""
    velocity: np.ndarray
    """Node velocities [m/s], shape (N, 3), float64, C-contiguous."""

    def copy(self) -> NetState:
        return NetState(self.time, self.position.copy(), self.velocity.copy())
