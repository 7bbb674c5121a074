"""Block D-ILU with Woodbury for the cables (:mod:`bulletnet.solver.dilu`), the implicit
step's ``block_dilu`` preconditioner.

References: its definition, assembled densely in numpy from the system's own matrix (the
solver's product on unit vectors); the block-Jacobi preconditioner, which solves the same
systems to the same tolerance (the preconditioner must change the iterations, not the
solution); the pair-list path, which the grid path must equal bit for bit.
"""

from __future__ import annotations

import numpy as np
import pytest

import bulletnet as bn
from bulletnet.engines import make_engine
from bulletnet.solver import dilu, integrators
from tests.conftest import small_capture, small_scene
from tests.test_grid import assert_identical, final_states

CLOSING = {"net.nodes_per_side": 7, "closing.enabled": True, "closing.length_ratio": 0.5,
           "closing.reel_speed": 2.0, "closing.trigger": "time", "closing.trigger_time": 0.3,
           "simulation.integrator": "implicit_euler", "simulation.dt": 3e-5}
"""A 7 x 7 net with four closing cables short enough to be taut as it opens (their rank-one
parts in the system) and winches from 0.3 s (as in tests/test_grid.py)."""


def stepped(scene, until: float):
    """An engine and its state after ``until`` [s] of ``scene`` (winches started at 0.3 s)."""
    model = bn.build_model(scene)
    engine = make_engine(scene, model)
    state = bn.initial_state(scene, model)
    engine.start_winches(0.3)
    engine.advance(state, until)
    return engine, state


def dense(system, n: int) -> np.ndarray:
    """The system's matrix [kg], 3N x 3N node-major, from the solver's own product."""
    matrix, unit, column = np.zeros((3 * n, 3 * n)), np.zeros((n, 3)), np.zeros((n, 3))
    for k in range(3 * n):
        unit.reshape(-1)[k] = 1.0
        integrators._apply_blocks(system, unit, column)
        matrix[:, k] = column.reshape(-1)
        unit.reshape(-1)[k] = 0.0
    return matrix


def reference(matrix, edges, order, g, along) -> np.ndarray:
    """P = M0 + G diag(along) G^T densely (module doc of bulletnet.solver.dilu) for the
    system ``matrix`` [kg] (3N x 3N), its direct couplings ``edges`` (node pairs), the
    elimination ``order`` (N,) and the cables' gradients ``g`` (3N, C) and ``along`` [kg]
    (C,): A0 = A less the rank-one parts; its couplings split by the order into L (the later
    node's row); D_i = A0_ii - sum over L's blocks of A0_ij D_j^-1 A0_ji; M0 = (D + L) D^-1
    (D + L)^T."""
    n = order.size
    a0 = (matrix - g @ np.diag(along) @ g.T).reshape(n, 3, n, 3)
    rank = np.empty(n, dtype=int)
    rank[order] = np.arange(n)
    lower = [[] for _ in range(n)]
    for i, j in edges:
        first, last = sorted((i, j), key=lambda node: rank[node])
        lower[last].append(first)
    d, low = np.zeros((n, 3, n, 3)), np.zeros((n, 3, n, 3))
    inverse = np.zeros((n, 3, 3))
    for i in order:
        block = a0[i, :, i, :].copy()
        for j in lower[i]:
            block -= a0[i, :, j, :] @ inverse[j] @ a0[j, :, i, :]
            low[i, :, j, :] = a0[i, :, j, :]
        d[i, :, i, :], inverse[i] = block, np.linalg.inv(block)
    d, low = d.reshape(3 * n, 3 * n), low.reshape(3 * n, 3 * n)
    return (d + low) @ np.linalg.inv(d) @ (d + low).T + g @ np.diag(along) @ g.T


def preconditioned(engine, cables, seed: int) -> tuple:
    """The engine's pair-list system at its last step, factored by block D-ILU, its matrix,
    and z = P^-1 r for a random r (zero on clamped nodes, as the solver keeps it), with the
    sums r . z and r . r the solver's preconditioning returns."""
    a, w, n = engine.arrays, engine.step_work, engine.model.node_count
    system = integrators.PairSystem(a.mass, a.fixed, a.pairs, w.along, w.across, w.axis,
                                    w.block_inv, cables, a.dilu)
    integrators._block_jacobi(system)  # the factor: block D-ILU's, on this system
    r = np.random.default_rng(seed).normal(size=(n, 3))
    r[a.fixed] = 0.0
    z, ad = np.zeros((n, 3)), np.zeros((n, 3))
    sums = integrators._precondition(system, r, z, ad, 0.0)
    return dense(system._replace(dilu=None), n), r, z, sums


def test_dilu_is_its_definition():
    engine, state = stepped(small_scene(**CLOSING, **{
        "simulation.kernels": "pairs", "simulation.preconditioner": "block_dilu"}), 0.3)
    model, cables, w = engine.model, engine.arrays.cables, engine.step_work
    while not (cables.along > 0).all() and state.time < 1.0:  # the cables snap taut and
        engine.advance(state, state.time + 3e-4)  # slack as the net bounces on them
    assert (cables.along > 0).all()  # every cable taut: four rank-one parts
    matrix, r, z, (rz, rr) = preconditioned(engine, cables, 1)
    n = model.node_count
    g = np.zeros((3 * n, cables.rest.size))
    for c in range(cables.rest.size):
        for v in range(cables.start[c], cables.start[c + 1]):
            g[3 * cables.nodes[v]:3 * cables.nodes[v] + 3, c] += cables.grad[v]
    live = (w.along != 0.0) | (w.across != 0.0)
    edges = {tuple(p) for p in model.pairs[live]}
    edges |= {(cables.nodes[v], cables.nodes[v + 1]) for c in range(cables.rest.size)
              for v in range(cables.start[c], cables.start[c + 1] - 1)}
    p = reference(matrix, edges, dilu.elimination_order(model), g, cables.along)
    expected = np.linalg.solve(p, r.reshape(-1))
    # exact linear algebra both ways: agreement to the round-off of a system of this size
    np.testing.assert_allclose(z.reshape(-1), expected, rtol=0,
                               atol=1e-12 * np.abs(expected).max())
    assert rz == pytest.approx(float(r.reshape(-1) @ z.reshape(-1)), rel=1e-12)
    assert rr == pytest.approx(float(r.reshape(-1) @ r.reshape(-1)), rel=1e-12)
    engine.close()


def test_dilu_leaves_clamped_nodes_out():
    # the cantilever clamps its root nodes: their rows of A are the identity and z is zero
    # there; on the others, the definition with the clamped nodes and their couplings dropped
    scene = bn.load_scenario("cantilever", {"simulation.integrator": "implicit_euler",
                                            "simulation.preconditioner": "block_dilu"})
    model = bn.build_model(scene)
    engine = make_engine(scene, model)
    engine.advance(bn.initial_state(scene, model), 0.01)
    free, w = ~model.fixed, engine.step_work
    assert model.fixed.any()
    matrix, r, z, _ = preconditioned(engine, None, 2)
    assert (z[model.fixed] == 0.0).all()
    n, m, index = model.node_count, int(free.sum()), np.cumsum(free) - 1
    matrix = matrix.reshape(n, 3, n, 3)[free][:, :, free]
    live = ((w.along != 0.0) | (w.across != 0.0)) & free[model.pairs].all(axis=1)
    p = reference(matrix.reshape(3 * m, 3 * m), index[model.pairs[live]],
                  index[dilu.elimination_order(model)], np.zeros((3 * m, 0)), np.zeros(0))
    expected = np.linalg.solve(p, r[free].reshape(-1))
    np.testing.assert_allclose(z[free].reshape(-1), expected, rtol=0,
                               atol=1e-12 * np.abs(expected).max())
    engine.close()


def test_dilu_changes_the_iterations_not_the_solution():
    # the same closing net solved with each preconditioner to a relative residual of 1e-10:
    # the runs agree to the solver's tolerance (a preconditioner that solved another system
    # would move the nodes by dt^2 |F| / m a step), and block D-ILU takes fewer iterations
    states, iterations = [], []
    for pre in ("block_jacobi", "block_dilu"):
        engine, state = stepped(small_scene(**CLOSING, **{
            "simulation.preconditioner": pre, "simulation.cg_tolerance": 1e-10}), 0.4)
        states.append(state)
        iterations.append(int(engine.work.cg_iterations[0]))
        engine.close()
    np.testing.assert_allclose(states[0].position, states[1].position, rtol=0, atol=1e-9)
    assert iterations[1] < iterations[0] / 2


@pytest.mark.parametrize("bending", [False, True])
def test_dilu_grid_equals_pairs_through_contact(bending):
    # both layouts call the same kernels on the same values: bit for bit (tests/test_grid.py)
    pairs, on_grid = final_states(lambda kernels: small_capture(**{
        "scene.duration": 0.8, "bending.enabled": bending, "simulation.kernels": kernels,
        "simulation.preconditioner": "block_dilu"}))
    assert pairs.debris[9] != 0.0 or pairs.debris[7] != 0.0  # the net has pushed the debris
    assert_identical(pairs, on_grid)


@pytest.mark.parametrize("folded", [True, False])
def test_dilu_grid_agrees_with_pairs_with_closing_and_tether(folded, monkeypatch):
    # tests/test_grid.py's comparison with closing cables and a tether, under block D-ILU: a
    # node with grid threads and other elements sums them in another order on each path, so
    # the runs agree to round-off (measured 4e-15 m), not bit for bit. Each solve stops at a
    # relative residual of 1e-4, where its iterate depends on the preconditioner: one that
    # differed between the paths (a coupling or a cable's rank-one part left out on one)
    # would part them by about that, and change the iteration count. Folded (dilu's module
    # doc), the grid path reads its threads' blocks from its rows and the pair list adds them
    # thread by thread; not folded (as for a net whose grid nodes have other couplings), both
    # sweep every node by rank
    if not folded:
        monkeypatch.setattr(dilu, "_fold", lambda model, order, later, earlier, up:
                            dilu.no_fold(order.size, later.size))
    runs = []
    for kernels in ("pairs", "grid"):
        engine, state = stepped(small_scene(**CLOSING, **{
            "simulation.kernels": kernels, "simulation.preconditioner": "block_dilu",
            "tether.enabled": True, "tether.attach": "bridle", "tether.segments": 3,
            "tether.length": 1.0, "tether.chaser_distance": 1.0, "tether.chaser_mass": 1.0}),
            0.4)
        assert engine.kernels == kernels and engine.cables.work.min() > 0.0
        if kernels == "grid":
            assert len(engine.grid.dilu.slots) == (7 if folded else 0)
        runs.append((state, int(engine.work.cg_iterations[0])))
        engine.close()
    (pairs, pairs_iterations), (on_grid, grid_iterations) = runs
    np.testing.assert_allclose(pairs.position, on_grid.position, rtol=0, atol=1e-9)
    assert pairs_iterations == grid_iterations
