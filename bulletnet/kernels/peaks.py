"""Each element's largest tension between frames, compiled with numba (docs/strength.md).

Frames, taken at a scene's record rate, miss the microsecond snaps of a thread's damper.
After every step the run loop keeps, per thread and per closing cable, the largest tension
of any step since the recorder last read them: the tension the step computed its forces
from (the state at the step's start), as the breakage check reads it
(:mod:`bulletnet.kernels.breakage`). The recorder reads them at each frame, takes the larger
of them and the frame's own tension, and resets them (``/threads/peak_tension``,
``/cables/peak_tension``).

On the pair list a thread's running maximum is its tension; on the grid
(:mod:`bulletnet.solver.grid`) a grid thread's is kept as the squared length of its stored
T e in rows laid out as the grid's (:attr:`PeakArrays.rows`), the cheapest pass over them
(no square root per step; the square root of the largest square is the largest length).

A loop given None for :class:`PeakArrays` keeps nothing: every kernel here begins ``if peaks
is None: return`` and compiles to nothing.

The running maximum is ``np.maximum`` (a NaN tension, from a diverging step, makes the peak
NaN), not ``max`` or a comparison and a store: LLVM turns those into masked vector stores,
which AMD's Zen 3 runs microcoded, three times slower over a row than the blend np.maximum
compiles to (docs/speed.md).
"""

from __future__ import annotations

from typing import NamedTuple

import numba as nb
import numpy as np


class PeakArrays(NamedTuple):
    """The largest tensions since the last reset, for P threads and C closing cables
    (:func:`peak_arrays`)."""

    thread: np.ndarray
    """Each thread's largest tension [N], shape (P,) (on the grid: its other threads only,
    at their places in the thread list)."""
    cable: np.ndarray
    """Each closing cable's largest tension [N], shape (C,)."""
    rows: np.ndarray
    """On the grid, each grid thread's largest squared |T e| [N^2], h(i) in row 0 and v(i)
    in row 1 at column Ns + i (the layout of :attr:`bulletnet.solver.grid.Grid.th`), shape
    (2, W); (2, 0) on the pair list."""


def peak_arrays(threads: int, cables: int, rows: np.ndarray | None = None) -> PeakArrays:
    """Zeroed peak arrays of ``threads`` threads and ``cables`` cables, keeping the grid
    threads' maxima in ``rows`` (2, W), zeroed here: the grid's own
    (:attr:`bulletnet.solver.grid.Grid.peak_rows`, carved with its other rows, so that their
    place relative to the T e rows the peaks pass reads is the same in every run); None: the
    pair list, (2, 0)."""
    if rows is None:
        rows = np.zeros((2, 0))
    rows[:] = 0.0
    return PeakArrays(thread=np.zeros(threads), cable=np.zeros(cables), rows=rows)


def reset(peaks: PeakArrays) -> None:
    """Zero every running maximum (a new interval begins)."""
    peaks.thread[:] = 0.0
    peaks.cable[:] = 0.0
    peaks.rows[:] = 0.0


@nb.njit(cache=True, error_model="numpy")
def track_cables(cables, peaks):
    """Each closing cable's running maximum <- the larger of it and the cable's last tension
    [N]. Nothing without cables or peaks."""
    if cables is None or peaks is None:
        return
    tension, top = cables.tension, peaks.cable
    for c in range(top.shape[0]):
        top[c] = np.maximum(top[c], tension[c])


@nb.njit(cache=True, error_model="numpy")
def track_threads(tension, peaks, start):
    """Thread ``start + p``'s running maximum <- the larger of it and ``tension[p]`` [N]
    (tension (Q,)). Nothing without peaks."""
    if peaks is None:
        return
    top = peaks.thread
    for p in range(tension.shape[0]):
        top[start + p] = np.maximum(top[start + p], tension[p])
