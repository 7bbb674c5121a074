"""The implicit Euler step's linear solver: preconditioned conjugate gradients, written once
for both layouts of the net's state (the preconditioner block Jacobi, or block D-ILU with
``simulation.preconditioner = "block_dilu"``: :mod:`bulletnet.solver.dilu`).

The pair-list kernels (:func:`bulletnet.solver.integrators.implicit_increment`, (N, 3)
arrays) and the grid's stencils (:func:`bulletnet.solver.grid.implicit_step`, (3, L) rows)
assemble the same system A dv = r, (M + dt C + dt^2 K) dv = dt F - dt^2 K v, each in its own
layout, and hand :func:`solve` the operations that depend on it, as compiled functions of a
``system`` argument of their own and of vectors in that layout:

- ``apply(system, x, out)``: out = A x, the system's matrix times x;
- ``factor(system)``: the block-Jacobi preconditioner, each node's 3 x 3 diagonal block of A
  inverted, kept in the system (or block D-ILU's factor);
- ``precondition(system, r, z, ad, alpha)``: first r <- r - alpha ad (the residual's update,
  element by element), then z = those inverse blocks times r, node by node (zero on a clamped
  node's rows; or block D-ILU's sweeps), returning the sums r . z and r . r of
  :func:`dot_terms` over the nodes in node order, all in one pass (a sum in order is a chain
  of additions; the pass's other work runs beside it: :mod:`bulletnet.common.llvm_options`);
- ``components(x)``: x as component rows, x[a, i] component a of node i, shape (3, >= N):
  the grid's rows themselves, the transpose of a pair-list array.

The dot products and the momentum sums run node by node in node order over the component
rows; the updates of dv and d run element by element over each vector's memory as one flat
array (the grid's padding columns included: zeros that stay zero and that nothing reads), so
that they vectorize in both layouts. Each update is fused into a pass that reads its vectors
anyway: the residual's into ``precondition``, dv's (dv + alpha d, with the d of the product)
into d's (z + beta d). Both paths then do the same arithmetic in the same order and give the
same floating-point results, bit for bit.

:func:`solve` is inlined into each caller (``inline="always"``) and the operations are its
arguments, not closure variables of a factory: numba keys a cached closure on its pickled
closure variables, and a compiled function pickles differently in every process, so such a
closure would be compiled afresh by every run (numba issue 6264).
"""

from __future__ import annotations

import numba as nb
import numpy as np


@nb.njit(cache=True, error_model="numpy", inline="always")
def _dot(a, b, count):
    """sum_i a_i . b_i over nodes i < ``count`` of component rows a and b, node by node."""
    s = 0.0
    for i in range(count):
        s += a[0, i] * b[0, i] + a[1, i] * b[1, i] + a[2, i] * b[2, i]
    return s


@nb.njit(cache=True, error_model="numpy")
def dot_terms(r0, r1, r2, z0, z1, z2):
    """One node's terms of r . z and r . r, as :func:`solve` sums them (``precondition``
    adds them up node by node in node order, in the pass that computes z)."""
    return r0 * z0 + r1 * z1 + r2 * z2, r0 * r0 + r1 * r1 + r2 * r2


@nb.njit(cache=True, error_model="numpy", inline="always")
def solve(apply, factor, precondition, components, system, dv, r, z, d, ad, mass, count, tol,
          iterations, conserve):
    """Solve A dv = r for the velocity increment dv [m/s] of nodes 0 .. ``count`` - 1 by
    preconditioned conjugate gradients (``factor``, ``precondition``) from dv's value on entry
    (the warm start), to the relative residual ``tol`` [-] (|r - A dv| <= tol |r|), in at
    most 4 ``count`` iterations, each counted in ``iterations`` (1,) int64; then, with
    ``conserve``, shift dv by the uniform velocity that makes the step's momentum change m dv
    sum to that of r exactly (the threads' blocks vanish on a uniform velocity; a clamp takes
    up momentum: nothing to conserve). A zero right-hand side gives dv = 0.

    ``apply``, ``factor`` and ``precondition`` compute with ``system``, ``components`` gives
    a vector's component rows (see the module doc). The vectors, C-contiguous in the path's own
    layout ((3, L) rows on the grid, (N, 3) on the pair list): dv [m/s] (in and out); r, the
    right-hand side dt F - dt^2 K v [kg m/s] on entry, the residual on exit; scratch z [m/s],
    d [m/s], ad [kg m/s]. ``mass``: node masses [kg], shape (>= count,)."""
    n = nb.uint64(count)  # unsigned node indices: no negative-index wraparound in the loops
    # node by node (dot products, momentum): component rows; element by element: flat
    dv_n, r_n, d_n, ad_n = components(dv), components(r), components(d), components(ad)
    dv_e, z_e, d_e = dv.reshape(-1), z.reshape(-1), d.reshape(-1)
    size = nb.uint64(d_e.shape[0])
    m0 = m1 = m2 = 0.0  # the step's exact momentum change: sum of dt F (internal forces cancel)
    for i in range(n):  # three sums in node order, their dependency chains interleaved
        m0 += r_n[0, i]
        m1 += r_n[1, i]
        m2 += r_n[2, i]
    rhs_norm = np.sqrt(_dot(r_n, r_n, n))
    if rhs_norm == 0.0:
        dv[:] = 0.0
        return
    factor(system)
    apply(system, dv, ad)
    rz, rr = precondition(system, r, z, ad, 1.0)  # r <- rhs - A dv (warm start; 1.0 x is x)
    for k in range(size):
        d_e[k] = z_e[k]
    for _ in range(4 * count):
        if np.sqrt(rr) <= tol * rhs_norm:
            break
        apply(system, d, ad)
        alpha = rz / _dot(d_n, ad_n, n)
        rz_new, rr = precondition(system, r, z, ad, alpha)  # r <- r - alpha A d, z
        beta = rz_new / rz
        rz = rz_new
        for k in range(size):
            dv_e[k] += alpha * d_e[k]
            d_e[k] = z_e[k] + beta * d_e[k]
        iterations[0] += 1
    if not conserve:
        return
    # The threads' blocks vanish on a uniform velocity, so adding one to dv changes only the
    # momentum residual: choose it so the step conserves momentum exactly, not to CG tolerance.
    total_mass = 0.0
    for i in range(n):
        total_mass += mass[i]
        m0 -= mass[i] * dv_n[0, i]
        m1 -= mass[i] * dv_n[1, i]
        m2 -= mass[i] * dv_n[2, i]
    for i in range(n):
        dv_n[0, i] += m0 / total_mass
    for i in range(n):
        dv_n[1, i] += m1 / total_mass
    for i in range(n):
        dv_n[2, i] += m2 / total_mass
