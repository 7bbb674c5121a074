"""The reel at the chaser: the main tether's deployed length changed during a run, compiled
with numba.

The tether is a chain of S threads from the net (or the bridle's junction) to the chaser,
the model's last S threads, the chaser's last. Its deployed length L is their rest lengths'
sum; the reel keeps them equal, each l_0 = L / S, with the tether's law at that length: the
stiffness k = E A / l_0 and the damping c = tau k (tau = 2 xi / omega_ref, the threads'
law), as built for a tether of length L. The nodes keep their masses (the line reeled in
stays lumped on them: its mass is not moved to the chaser's drum).

After every step from its start time on, the reel sets L for the next step from the state
the step ended in:

- its motor shortens L by ``speed`` dt (reel-in, ``speed`` > 0; pay-out, ``speed`` < 0),
  not below ``min_length`` nor above ``max_length``;
- its brake, with a ``tension_limit`` T_lim, then pays out (lengthens L) just enough that
  the tension of the last thread, the chaser's, is not above T_lim at that state: an ideal
  slipping brake on a drum without inertia. With l and l' the last thread's length and
  lengthening rate, l_p = L_old / S and B = 1 + tau / dt, its tension (Eq. 3 on the strain
  rate, below, with l_0' = (l_0 - l_p) / dt) at rest length l_0 is

      T(l_0) = (E A / l_0) (l + tau l' + tau l_p / dt - B l_0),

  decreasing in l_0; it is T_lim at l_0 = E A (l + tau l' + tau l_p / dt) / (E A B + T_lim),
  and the thread is slack from l_0 = l on. The least of the two is the least rest length at
  which the tension is at most T_lim: the brake makes l_0 at least that. It pays out no
  further than ``max_length`` (the drum is empty).

The dampers act on the strain rate, l' - l_0', with l_0' = L' / S over the step (the reel
hands the thread kernels each thread's rest-length rate, :mod:`bulletnet.kernels.axial`), as
a closing cable's: a line paid out or reeled in as fast as its ends follow is not damped.
(On l' alone, a line paid out at S T_lim / c could carry nothing but its damper's force,
and the brake would let it go slack.)

The reel's work is, at each change of L, the change of the tether's elastic energy
E A (l - l_0)^2 / (2 l_0) at the step's end positions, plus each taut thread's damper force
times the rest length it lost (the closing winches' work): the mechanical energy may change
by that work (negative while the brake pays out: it takes energy out) and by the other
forces', and no more.

A failed tether thread (``strength.breakage``: its stiffness zeroed) has cut the chaser
loose: the reel then stops. A scene without a reel passes None: each kernel's body is pruned
by numba on the argument's type, so it compiles none of this and its steps call nothing.
"""

from __future__ import annotations

from typing import NamedTuple

import numba as nb
import numpy as np

from .axial import kelvin_voigt
from .cable import elastic_energy


class ReelArrays(NamedTuple):
    """The reel and the tether it reels, as the compiled kernels read them, for a tether of
    S threads (:func:`reel_arrays`). The first seven fields are the scene's; the rest is
    written by the kernels."""

    pairs: np.ndarray
    """End nodes of the tether's threads, from the net's side to the chaser (the last
    thread's second node) [-], shape (S, 2), int64."""
    rigidity: float
    """The tether's axial rigidity E A [N]."""
    damping_time: float
    """Its threads' c / k, 2 xi / omega_ref [s]."""
    speed: float
    """Speed at which the motor shortens the deployed length [m/s]: reel-in > 0, pay-out
    < 0."""
    tension_limit: float
    """Tension of the chaser's thread above which the brake pays out [N]; +inf: none."""
    min_length: float
    """Least deployed length, where the motor stops reeling in [m]."""
    max_length: float
    """Largest deployed length, where the line runs out [m]; +inf: none."""
    start_time: np.ndarray
    """Time from which the reel acts [s], shape (1,); +inf until started."""
    length: np.ndarray
    """Deployed length L, the tether's rest lengths summed [m], shape (1,)."""
    work: np.ndarray
    """Work done by the reel so far [J], shape (1,)."""


def reel_arrays(pairs: np.ndarray, rest: np.ndarray, stiffness: np.ndarray,
                damping: np.ndarray, segments: int, speed: float, tension_limit: float,
                min_length: float, max_length: float) -> ReelArrays:
    """The reel of the tether that is the last ``segments`` threads of ``pairs`` (P, 2),
    ``rest`` [m], ``stiffness`` [N/m] and ``damping`` [N s/m] (P,) each (their E A and c / k
    read from the last thread), at ``speed`` [m/s], with the brake's ``tension_limit`` [N]
    (+inf: none) and the deployed length's limits [m] (+inf: none), not yet started."""
    chain = slice(pairs.shape[0] - segments, None)
    return ReelArrays(
        pairs=np.ascontiguousarray(pairs[chain], dtype=np.int64),
        rigidity=float(stiffness[-1] * rest[-1]),
        damping_time=float(damping[-1] / stiffness[-1]), speed=float(speed),
        tension_limit=float(tension_limit), min_length=float(min_length),
        max_length=float(max_length), start_time=np.full(1, np.inf),
        length=np.full(1, float(rest[chain].sum())), work=np.zeros(1))


@nb.njit(cache=True, error_model="numpy")
def _length_rate(pos, vel, i, j):
    """Length [m] of the thread from node i to node j and its lengthening rate [m/s]."""
    dx, dy, dz = pos[j, 0] - pos[i, 0], pos[j, 1] - pos[i, 1], pos[j, 2] - pos[i, 2]
    length = np.sqrt(dx * dx + dy * dy + dz * dz)
    rate = ((vel[j, 0] - vel[i, 0]) * dx + (vel[j, 1] - vel[i, 1]) * dy
            + (vel[j, 2] - vel[i, 2]) * dz) / length
    return length, rate


@nb.njit(cache=True, error_model="numpy")
def reel_tether(pos, vel, reel, rest, rest_rate, k, c, t, dt):
    """The reel after a step from ``t`` [s] of ``dt`` [s] that ended at ``pos`` [m], ``vel``
    [m/s] (N, 3) (module doc): from its start time on, the deployed length for the next
    step by the motor and the brake and the reel's work into ``reel``, and the tether's
    rest lengths [m], their rates [m/s], stiffness [N/m] and damping [N s/m] into the last
    S entries of ``rest``, ``rest_rate``, ``k`` and ``c`` (the arrays the steps read).
    Without a reel (None) nothing, and nothing is compiled."""
    if reel is None:  # no reel: this specialization compiles to nothing
        return
    if t < reel.start_time[0]:
        return
    count = reel.pairs.shape[0]
    first = rest.shape[0] - count
    for p in range(first, first + count):
        if k[p] == 0.0:  # a failed thread: the chaser is cut loose, the reel stops
            return
    ea, tau = reel.rigidity, reel.damping_time
    old = reel.length[0]
    segment = old / count
    new = min(max(old - reel.speed * dt, reel.min_length), reel.max_length)
    if reel.tension_limit < np.inf:  # the brake: the least length at which T <= T_lim
        length, rate = _length_rate(pos, vel, reel.pairs[count - 1, 0],
                                    reel.pairs[count - 1, 1])
        at_limit = (ea * (length + tau * rate + tau * segment / dt)
                    / (ea * (1.0 + tau / dt) + reel.tension_limit))
        new = min(max(new, count * min(at_limit, length)), reel.max_length)
    shortened = segment - new / count  # each thread's rest length lost [m]
    work = 0.0
    for q in range(count):
        p = first + q
        length, rate = _length_rate(pos, vel, reel.pairs[q, 0], reel.pairs[q, 1])
        strain_rate = rate - rest_rate[p]
        damper = c[p] * strain_rate if kelvin_voigt(length, strain_rate, rest[p], k[p], c[p],
                                                    False) != 0.0 else 0.0
        work += (elastic_energy(length, new / count, ea) - elastic_energy(length, segment, ea)
                 + damper * shortened)
    reel.length[0] = new
    reel.work[0] += work
    stiffness = ea * count / new
    for p in range(first, first + count):
        rest[p] = new / count
        rest_rate[p] = -shortened / dt
        k[p] = stiffness
        c[p] = tau * stiffness
