"""The LLVM options the package's kernels are compiled with: in-order sums vectorized, and the
free net's vector loops interleaved.

**In-order sums.** The implicit solver's dot products are summed node by node in node order
(:mod:`bulletnet.solver.pcg`), so that the grid and the pair list give the same bits: one
chain of dependent additions. By default LLVM's loop vectorizer leaves any loop that carries
such a sum scalar, whatever else the loop does, since vectorizing the sum the usual way would
reorder its additions. With ``-force-ordered-reductions`` it vectorizes the rest of the loop
and adds each vector's terms to the sum one after another, in the loop's order (an in-order
vector reduction): the same additions in the same order, so the same results bit for bit.
A pass that writes vectors and sums their terms then costs about the sum's chain of additions
alone: the preconditioning with the two sums r . z and r . r that follow it, one pass over the
nodes, took 1.08 us scalar and 0.50 us so (470 nodes; as two passes, 0.89 us). It is set for
the whole process (it changes no result of any loop, only whether LLVM vectorizes it).

**Interleaved vector loops.** A thread stencil's iteration is one long chain of dependent
operations (loads, differences, square root, division, the tension law, stores), which the
core overlaps with the next iterations' only as far as its out-of-order window reaches; on a
CPU whose square root and division are quick beside the rest (AVX2's Zen 3) the chains, not
the divider, set the pace. With ``-force-vector-interleave=2`` LLVM's vectorizer unrolls each
vector loop to two independent vectors an iteration, so two chains are in flight from the
start: the same operations on the same values, the same bits. It pays in the free net's
symplectic loop (the deployments: the step 3.9 -> 3.1 sqrt/division bounds on the znver3,
docs/speed.md), not in the captures' loops, which ran slower with it (their short loops over
a diagonal of the net, block D-ILU's sweeps, probably leave more to the scalar remainder at 8
values an iteration; not measured apart). So it is set only while numba compiles a function
registered with :func:`interleave` (a listener on numba's ``numba:compile`` event; a function
compiled within that compile for the first time, and cached for other callers, is compiled
without it): the user's own kernels, the benchmarks' frozen yardstick and sqrt/division
bound, and the rest of the package compile as LLVM chooses.

:func:`enable` is called when :mod:`bulletnet.kernels` or :mod:`bulletnet.solver` is
imported, before any kernel is compiled (every module with kernels imports one of them).
Kernels compiled without these options compute the same, more slowly.
"""

from __future__ import annotations

import functools

import llvmlite.binding as ll
from numba.core import event

INTERLEAVE = 2
"""Vectors an iteration of a registered function's vector loops [-] (LLVM's own choice: 0)."""

_INTERLEAVED: set = set()
"""The Python functions of the dispatchers registered with :func:`interleave`."""


def interleave(dispatcher):
    """Have numba compile ``dispatcher`` (an ``nb.njit`` function) with its vector loops
    interleaved :data:`INTERLEAVE` times; returns it."""
    enable()
    _INTERLEAVED.add(dispatcher.py_func)
    return dispatcher


class _Interleaved(event.Listener):
    """A ``numba:compile`` listener: LLVM's ``-force-vector-interleave`` follows the function
    whose compile is innermost, :data:`INTERLEAVE` for a registered one, 0 for any other."""

    def __init__(self):
        self.stack: list[int] = []

    def _set(self) -> None:
        count = self.stack[-1] if self.stack else 0
        ll.set_option("bulletnet", f"-force-vector-interleave={count}")

    def on_start(self, e: event.Event) -> None:
        registered = getattr(e.data.get("dispatcher"), "py_func", None) in _INTERLEAVED
        self.stack.append(INTERLEAVE if registered else 0)
        self._set()

    def on_end(self, e: event.Event) -> None:
        self.stack.pop()
        self._set()


@functools.cache
def enable() -> None:
    """Set LLVM's ``-force-ordered-reductions`` in this process and install the listener
    that interleaves the registered functions' vector loops (once a process)."""
    ll.set_option("bulletnet", "-force-ordered-reductions")
    event.register("numba:compile", _Interleaved())
