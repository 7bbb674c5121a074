"""Compiled leaves: the forces of threads, bending springs and cables, contact laws, geometry
queries."""

import numba as nb

from ..common import ordered_sums

ordered_sums.enable()  # before any kernel is compiled

U = nb.uint64
"""Indices are unsigned in the kernels: numba then skips the negative-index wraparound, which
would turn every shifted load into a gather, and creates no array views (each view costs an
atomic reference count increment and decrement)."""
