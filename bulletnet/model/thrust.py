"""The chaser's thrust profile and the tether's axial mode it is shaped for.

A burn is a unit step (or a linear ramp of ``rise_time``) at its start, minus the same at
its end (``burn_time`` later, if given), convolved with an input shaper (with a
``pretension`` F_p: a step of F_p at the start, the rise of the rest, F - F_p, shaped,
``pretension_time`` later, and the whole thrust's fall shaped ``burn_time`` after that): the
step itself, or the zero-vibration (ZV) or zero-vibration-derivative (ZVD) shaper of the
tow's axial mode (Singer & Seering 1990). For a mode of undamped frequency w [rad/s] and
damping ratio z, with K = exp(-z pi / sqrt(1 - z^2)) and T the damped half period pi / (w
sqrt(1 - z^2)):

- ZV: impulses 1 / (1 + K), K / (1 + K) at 0, T;
- ZVD: impulses 1 / (1 + K)^2, 2 K / (1 + K)^2, K^2 / (1 + K)^2 at 0, T, 2 T.

A shaped step then leaves no residual vibration of that mode (ZVD: none either, to first
order, for a small error in w). The engine applies the profile's mean over each interval
between its step hooks (the fast engine's chunks, ``debris.step``; bullet's steps): the
profile's integral is exact, so the impulse delivered is the profile's to round-off.

The tow's axial mode (:func:`axial_mode`): the chaser, of mass m_c, against the captured
mass m_d on the tether's stiffness k = E A / L (its segments in series),
w = sqrt(k (1 / m_c + 1 / m_d)); the tether's damper (c = 2 xi k / omega_ref, the threads'
law) gives z = xi w / omega_ref.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .net import NetModel
from .scenario import Scenario, Thrust


def shaper(profile: str, omega: float, zeta: float) -> tuple[np.ndarray, np.ndarray]:
    """The input shaper of ``profile`` (step, ramp: none; zv, zvd) for a mode of undamped
    frequency ``omega`` [rad/s] and damping ratio ``zeta`` [-]: (impulse times [s],
    amplitudes [-] summing to 1)."""
    if profile in ("step", "ramp"):
        return np.zeros(1), np.ones(1)
    root = math.sqrt(1.0 - zeta * zeta)
    k = math.exp(-zeta * math.pi / root)
    half = math.pi / (omega * root)
    if profile == "zv":
        return np.array([0.0, half]), np.array([1.0, k]) / (1.0 + k)
    return np.array([0.0, half, 2.0 * half]), np.array([1.0, 2.0 * k, k * k]) / (1.0 + k) ** 2


@dataclass(frozen=True)
class AxialMode:
    """The tow's axial mode (:func:`axial_mode`)."""

    stiffness: float
    """k = E A / L of the whole tether [N/m]."""
    chaser_mass: float
    """m_c [kg]."""
    towed_mass: float
    """m_d [kg]."""
    omega: float
    """Undamped frequency sqrt(k (1 / m_c + 1 / m_d)) [rad/s]."""
    zeta: float
    """Damping ratio [-]."""


def axial_mode(s: Scenario, model: NetModel, debris_mass: float) -> AxialMode:
    """The tow's axial mode of scene ``s`` (module doc): m_c the chaser node's mass (the
    chaser and half the tether's last segment), m_d the captured mass — the debris'
    ``debris_mass`` [kg] plus every other node (the net, its cables, the tether's nodes)."""
    t = s.tether
    k = t.young_modulus * math.pi * (t.diameter / 2) ** 2 / t.length
    m_c = float(model.mass[-1])
    m_d = debris_mass + float(model.mass[:-1].sum())
    omega = math.sqrt(k * (1.0 / m_c + 1.0 / m_d))
    return AxialMode(stiffness=k, chaser_mass=m_c, towed_mass=m_d, omega=omega,
                     zeta=t.damping_ratio * omega / s.damping.axial_reference_frequency)


class ThrustProfile:
    """The thrust [N] of a burn started at ``start`` [s] (``rules``: the scene's
    ``[thrust]``), shaped for an axial mode of ``omega`` [rad/s] and ``zeta`` [-]."""

    def __init__(self, rules: Thrust, start: float, omega: float, zeta: float):
        shape_times, shape = shaper(rules.profile, omega, zeta)
        rise = start + rules.pretension_time if rules.pretension > 0 else start
        low = rules.pretension / rules.force
        times, amplitudes = [shape_times + rise], [(1.0 - low) * shape]
        if rules.pretension > 0:  # the low step first, then the shaped rise to full thrust
            times.insert(0, np.array([start]))
            amplitudes.insert(0, np.array([low]))
        if rules.burn_time > 0:  # the whole thrust falls, shaped
            times.append(shape_times + rise + rules.burn_time)
            amplitudes.append(-shape)
        self.times, self.amplitudes = np.concatenate(times), np.concatenate(amplitudes)
        """Starts [s] and amplitudes [-] of the unit steps (or ramps) making the profile."""
        self.rise = rules.rise_time if rules.profile == "ramp" else 0.0
        """Rise of each step [s] (0: a step)."""
        self.force = rules.force
        """Full thrust [N]."""
        self.end = math.inf
        """When the burn was cut short [s] (a failed tether ends it): no thrust from then on;
        inf: never."""

    def impulse(self, t: float) -> float:
        """The thrust's integral from the start to ``t`` [N s] (to :attr:`end` at most)."""
        s = np.maximum(min(t, self.end) - self.times, 0.0)
        if self.rise > 0:
            s = np.where(s < self.rise, s * s / (2.0 * self.rise), s - 0.5 * self.rise)
        return self.force * float(self.amplitudes @ s)

    def mean(self, t0: float, t1: float) -> float:
        """The mean thrust over [t0, t1] [N] (t1 > t0), from the exact integral."""
        return (self.impulse(t1) - self.impulse(t0)) / (t1 - t0)
