"""Compiled leaves: the forces of threads, bending springs and cables, contact laws, geometry
queries.

Small scalar helpers (a thread's law, a block entry, a segment's distance) are plain
``nb.njit`` functions, left to LLVM's inliner, which inlines them into the loops that call
them before it vectorizes those (the same instructions, the same bits).
``inline="always"`` (numba's own inlining, which copies and types the callee's body again at
every call site) is kept where LLVM would not inline (a function passed the grid's arrays
field by field, a loop over nodes) or the loops run slower without it (the bending springs'
rotations); on the rest it cost compile time only: the preconditioner's factor, 9.8 s to
compile with its entries inlined so, 2.3 s without (docs/development.md)."""

import numba as nb

from ..common import llvm_options

llvm_options.enable()  # before any kernel is compiled

U = nb.uint64
"""Indices are unsigned in the kernels: numba then skips the negative-index wraparound, which
would turn every shifted load into a gather, and creates no array views (each view costs an
atomic reference count increment and decrement)."""
