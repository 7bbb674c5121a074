"""Breakage: an element whose tension reaches its breaking tension fails for good, compiled
with numba (``strength.breakage``, docs/strength.md).

After every step the run loop compares each element's tension of that step (the one its
force was computed from, at the step's start) with its breaking tension T_b. A thread at or
over T_b fails: its axial stiffness and damping, and the bending springs across it (k_t,
c_t, k_b, c_b), are set to zero in the arrays the steps read, so from the next step on its
tension is exactly zero (Eq. 3 with k = c = 0), it carries no force and its implicit-Euler
blocks vanish. A closing cable at or over T_b fails the same way: its rigidity E A goes to
zero and its winch stops (reel speed zero). The failure time recorded is the start of the
step whose tension reached T_b [s]; the elastic energy the element held at the end of that
step, k (l - l_0)^2 / 2 (a cable's E A (L - L_0)^2 / (2 L_0)), leaves the mechanical energy
with it and is summed.

A scene without breakage passes None for :class:`BreakageArrays`: every kernel here begins
``if breakage is None: return`` and compiles to nothing.
"""

from __future__ import annotations

from typing import NamedTuple

import numba as nb
import numpy as np

from .cable import cable_length, elastic_energy


class BreakageArrays(NamedTuple):
    """What fails and when, for P threads and C closing cables (:func:`breakage_arrays`)."""

    limit: np.ndarray
    """Breaking tension of each thread [N], shape (P,)."""
    failure_time: np.ndarray
    """When each thread failed [s], shape (P,); -1 while intact."""
    cable_limit: np.ndarray
    """Breaking tension of each closing cable [N], shape (C,)."""
    cable_failure_time: np.ndarray
    """When each cable failed [s], shape (C,); -1 while intact."""
    energy: np.ndarray
    """Elastic energy the failed elements held when they failed, summed [J], shape (1,)."""


def breaking_arrays(limit: np.ndarray, cable_limit: np.ndarray) -> BreakageArrays:
    """Breakage arrays of threads and cables of breaking tensions ``limit`` (P,) and
    ``cable_limit`` (C,) [N], every element intact."""
    return BreakageArrays(
        limit=np.asarray(limit, dtype=float).copy(), failure_time=np.full(len(limit), -1.0),
        cable_limit=np.asarray(cable_limit, dtype=float).copy(),
        cable_failure_time=np.full(len(cable_limit), -1.0), energy=np.zeros(1))


@nb.njit(cache=True, error_model="numpy", inline="always")
def fail_thread(p, pos, pairs, rest, k_a, c_a, k_t, c_t, k_b, c_b, breakage, t):
    """Thread p fails at time ``t`` [s]: its failure time, the energy k (l - l_0)^2 / 2 [J]
    it holds at ``pos`` [m] (N, 3) added to the breakage's, and its axial and bending
    parameters zeroed."""
    i, j = pairs[p, 0], pairs[p, 1]
    dx, dy, dz = pos[j, 0] - pos[i, 0], pos[j, 1] - pos[i, 1], pos[j, 2] - pos[i, 2]
    stretch = max(np.sqrt(dx * dx + dy * dy + dz * dz) - rest[p], 0.0)
    breakage.energy[0] += 0.5 * k_a[p] * stretch * stretch
    breakage.failure_time[p] = t
    k_a[p] = 0.0
    c_a[p] = 0.0
    k_t[p] = 0.0
    c_t[p] = 0.0
    k_b[p] = 0.0
    c_b[p] = 0.0


@nb.njit(cache=True, error_model="numpy")
def break_threads(pos, pairs, rest, tension, k_a, c_a, k_t, c_t, k_b, c_b, breakage, t):
    """Every intact thread whose ``tension`` (P,) [N] of the step from ``t`` [s] reached its
    breaking tension fails (:func:`fail_thread`; positions ``pos`` [m] (N, 3) at the step's
    end). Nothing without breakage (``breakage`` None: compiles to nothing)."""
    if breakage is None:
        return
    limit, failed = breakage.limit, breakage.failure_time
    for p in range(pairs.shape[0]):
        if tension[p] >= limit[p] and failed[p] < 0.0:
            fail_thread(p, pos, pairs, rest, k_a, c_a, k_t, c_t, k_b, c_b, breakage, t)


@nb.njit(cache=True, error_model="numpy")
def break_cables(pos, cables, breakage, t):
    """Every intact closing cable whose last tension [N] reached its breaking tension fails
    at ``t`` [s]: its failure time, its elastic energy [J] at ``pos`` [m] (N, 3) summed, its
    rigidity and its winch's reel speed zeroed. Nothing without cables or breakage."""
    if cables is None or breakage is None:
        return
    limit, failed = breakage.cable_limit, breakage.cable_failure_time
    for c in range(limit.shape[0]):
        if cables.tension[c] >= limit[c] and failed[c] < 0.0:
            failed[c] = t
            breakage.energy[0] += elastic_energy(cable_length(pos, cables, c), cables.rest[c],
                                                 cables.rigidity[c])
            cables.rigidity[c] = 0.0
            cables.reel_speed[c] = 0.0
