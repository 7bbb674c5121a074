"""LLVM told to vectorize loops that carry an in-order floating-point sum, keeping its order.

The implicit solver's dot products are summed node by node in node order
(:mod:`bulletnet.solver.pcg`), so that the grid and the pair list give the same bits: one
chain of dependent additions. By default LLVM's loop vectorizer leaves any loop that carries
such a sum scalar, whatever else the loop does, since vectorizing the sum the usual way would
reorder its additions. With ``-force-ordered-reductions`` it vectorizes the rest of the loop
and adds each vector's terms to the sum one after another, in the loop's order (an in-order
vector reduction): the same additions in the same order, so the same results bit for bit.
A pass that writes vectors and sums their terms then costs about the sum's chain of additions
alone: the preconditioning with the two sums r . z and r . r that follow it, one pass over the
nodes, took 1.08 us scalar and 0.50 us so (470 nodes; as two passes, 0.89 us).

It is an option of the LLVM in the process, read when a loop is compiled: :func:`enable` is
called when :mod:`bulletnet.kernels` or :mod:`bulletnet.solver` is imported, before any
kernel is compiled (every module with kernels imports one of them). Kernels compiled without
it compute the same, more slowly.
"""

from __future__ import annotations


def enable() -> None:
    """Set LLVM's ``-force-ordered-reductions`` in this process (again: no effect)."""
    import llvmlite.binding as ll

    ll.set_option("bulletnet", "-force-ordered-reductions")
