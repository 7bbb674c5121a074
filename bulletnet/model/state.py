"""The dynamic state of the net. No parameters live here (they are on :class:`NetModel`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class NetState:
    time: float
    """Simulated time [s]."""
    position: np.ndarray
    """Node positions [m], shape (N, 3), float64, C-contiguous."""
    velocity: np.ndarray
    """Node velocities [m/s], shape (N, 3), float64, C-contiguous."""
    orientation: np.ndarray | None = field(default=None)
    """Node orientations, unit quaternions (x, y, z, w) [-], shape (N, 4); only with bending."""
    angular_velocity: np.ndarray | None = field(default=None)
    """Node angular velocities, world frame [rad/s], shape (N, 3); only with bending."""
    debris: np.ndarray | None = field(default=None)
    """The debris' rigid-body state, shape (13,): centre of mass [m] (3), orientation
    quaternion x, y, z, w (4), velocity [m/s] (3), angular velocity, world frame [rad/s] (3);
    only in scenes with debris."""

    @property
    def oriented(self) -> bool:
        """Whether the nodes carry orientations (bending on)."""
        return self.orientation is not None

    def copy(self) -> NetState:
        def dup(a):
            return None if a is None else a.copy()

        return NetState(self.time, self.position.copy(), self.velocity.copy(),
                        dup(self.orientation), dup(self.angular_velocity), dup(self.debris))
