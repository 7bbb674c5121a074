"""Where the plain deployment's grid step goes, against the machine's own bounds.

The 3 s deployment (``scenarios/deployment.toml``: symplectic Euler at 1e-6 s, the grid
path, its threads' running maxima kept) runs to ``--at``; there, inside compiled loops on
that state (best of 5 loops of 200 000 calls each, in ``--rounds`` interleaved rounds):

1. the step as the run takes it (:func:`bulletnet.solver.grid.free_steps` with the peaks)
   and its passes: the two tension stencils, the node pass (each node's forces summed in the
   pair list's order, then v and x updated), the running maxima and the four corner threads
   (pair-list kernels);
2. the stencils' work built up, over the same threads and rows: (a) the sqrt and reciprocal
   of each thread's length alone, one row stored (the bound's arithmetic on the stencils'
   shifted rows); (b) the whole tension law (velocities and parameters loaded, direction,
   rate, Eq. 3), T alone stored; (c) the stencils themselves (T e into three rows);
3. the bounds beside them: the sqrt/division bound (``common.sqrt_division_bound``, ns a
   thread) and the bandwidth of a triad over arrays as large as the rows the step touches
   (its working set, :func:`working_set`), which with the bytes the step's passes read and
   write (counted in :data:`PASS_BYTES`) gives the step's traffic floor;
4. three passes' floors: the stencils' (the larger of the sqrt/division bound for their
   threads and their traffic), the running maxima's (their traffic) and the corner threads'
   (the bound's loop over as few values as there are corner threads, which runs scalar);
   and the step with those three at their floors and the node pass as measured
   (``step_at_floors_us``). The node pass has no floor here: with eight loads to two stores
   it moves its bytes faster than the triad (two to one) measures, so the triad's floor
   would lie above it.

Also the frozen yardstick, once a round (its step: its wall time over its 3e6 steps).
Writes ``OUT/grid_step.json``:

    python benchmarks/grid_step.py benchmarks/results [--at 1.0] [--rounds 3]
"""

from __future__ import annotations

import json
import statistics

import numba as nb
import numpy as np
from common import (
    DEPLOYMENT_THREADS,
    At,
    Yardsticks,
    best_us,
    machine,
    output_dir,
    parser,
    sqrt_division_bound,
    triad_bandwidth,
)

import bulletnet as bn
from bulletnet.common import llvm_options
from bulletnet.solver import grid as G
from bulletnet.solver.grid import ONE, U

CALLS = 200_000
"""Calls of a pass in one timed loop [-]."""

PASS_BYTES = {"stencils": 18, "node_pass": 11, "peaks": 5}
"""Doubles each pass reads plus writes per thread (the stencils: both nodes' x and v, rest,
k, c; T e written; the peaks: T e and the running maximum read, it written) or per node
component (the node pass: base, other, 1/m, four threads' T e, v and x read; v, x
written; one fewer where the base rows are all zero and not read,
:func:`bulletnet.solver.grid.base_rows`)."""


@nb.njit(error_model="numpy", inline="always")
def _sqrt_reciprocal(x, off, out, count, ns):
    """The bound's arithmetic on a stencil's rows: each thread's length and its reciprocal."""
    for t in range(count):
        j = t + off
        length = np.sqrt((x[0, j] - x[0, t]) ** 2 + (x[1, j] - x[1, t]) ** 2
                         + (x[2, j] - x[2, t]) ** 2)
        out[0, t + ns] = 1.0 / length + length


@nb.njit(error_model="numpy", inline="always")
def _tension_only(x, v, off, rest, k, c, out, count, ns):
    """The whole tension law of a stencil's threads, T alone stored."""
    for t in range(count):
        out[0, t + ns] = G._row_tension(x, v, t, t + off, rest, k, c)[0]


@llvm_options.interleave  # compiled as the free loop that these passes stand for
@nb.njit(error_model="numpy", _nrt=False)
def _probe(g, level, calls):
    """``calls`` times both stencils' work up to ``level`` (0: sqrt and reciprocal, 1: the
    tension law, 2: the stencils), into the th and tv rows."""
    ns, x, v = U(g.ns), g.x, g.v
    h, w = U(g.h_rest.shape[0]), U(g.v_rest.shape[0])
    for _ in range(calls):
        if level == 0:
            _sqrt_reciprocal(x, ONE, g.th, h, ns)
            _sqrt_reciprocal(x, ns, g.tv, w, ns)
        elif level == 1:
            _tension_only(x, v, ONE, g.h_rest, g.h_k, g.h_c, g.th, h, ns)
            _tension_only(x, v, ns, g.v_rest, g.v_k, g.v_c, g.tv, w, ns)
        else:
            G._tension_stencil(x, v, ONE, g.h_rest, g.h_k, g.h_c, g.th, h, ns)
            G._tension_stencil(x, v, ns, g.v_rest, g.v_k, g.v_c, g.tv, w, ns)


@llvm_options.interleave  # compiled as the free loop that these passes stand for
@nb.njit(error_model="numpy", _nrt=False)
def _node_pass(g, dt, calls, base):
    """``calls`` node passes of the free step (no bending, no increment kept; ``base`` as
    the run passes it, :func:`bulletnet.solver.grid.base_rows`)."""
    for _ in range(calls):
        G.node_pass(g, dt, None, False, base)


@llvm_options.interleave  # compiled as the free loop that these passes stand for
@nb.njit(error_model="numpy", _nrt=False)
def _peaks(g, peaks, calls):
    for _ in range(calls):
        G.track_peaks(g, peaks)


@llvm_options.interleave  # compiled as the free loop that these passes stand for
@nb.njit(error_model="numpy", _nrt=False)
def _others(g, views, dt, calls):
    for _ in range(calls):
        G._other_threads(g, views, dt, False)


def working_set(g, peaks, base) -> int:
    """Bytes of the rows a free step reads or writes: x, v, ``base`` (where it is read: not
    None), other, 1/m, the threads' T e and parameters, the running maxima."""
    rows = (g.x, g.v, g.other, g.inv_mass, g.th, g.tv, g.h_rest, g.h_k, g.h_c, g.v_rest,
            g.v_k, g.v_c, peaks.rows)
    return sum(r.nbytes for r in rows) + (0 if base is None else base.nbytes)


class StepParts(At):
    """At the first frame at or after ``at`` [s]: the step, its passes, the stencil probes
    and the bounds, ``rounds`` times interleaved (see the module doc); then stops the run."""

    def __init__(self, at: float, rounds: int, yard: Yardsticks):
        super().__init__(at)
        self.rounds, self.yard = rounds, yard

    def act(self, e, state):
        g, views, peaks, dt = e.grid, e.views, e.peaks, e.dt
        G.load(g, state, e.base_forces())
        x0, v0 = g.x.copy(), g.v.copy()
        loop = G.free_steps(False)
        base = G.base_rows(g)  # as the run passes it

        def fresh(call):  # every timed loop starts from the snapshot (the steps move it)
            def timed_call(calls):
                g.x[:], g.v[:] = x0, v0
                call(calls)
            return timed_call

        parts = {
            "step": fresh(lambda k: loop(g, views, k, dt, 0.0, e.work.cg_iterations, peaks,
                                            base)),
            "stencils": lambda k: _probe(g, 2, k),
            "node_pass": fresh(lambda k: _node_pass(g, dt, k, base)),
            "peaks": lambda k: _peaks(g, peaks, k),
            "other_threads": lambda k: _others(g, views, dt, k),
            "probe_sqrt_reciprocal": lambda k: _probe(g, 0, k),
            "probe_tension_law": lambda k: _probe(g, 1, k),
        }
        rows = 3 * g.x.shape[1]  # node components in the node pass
        threads = g.h_rest.shape[0] + g.v_rest.shape[0]
        node_doubles = PASS_BYTES["node_pass"] - (base is None)
        traffic = 8 * (threads * (PASS_BYTES["stencils"] + PASS_BYTES["peaks"])
                       + rows * node_doubles)
        working = working_set(g, peaks, base)
        corners = g.o_pairs.shape[0]
        times = {name: [] for name in parts}
        bounds, corner_bounds, bandwidths = [], [], []
        for _ in range(self.rounds):
            self.yard.time()
            bounds.append(1e-3 * sqrt_division_bound(threads=DEPLOYMENT_THREADS)
                          * DEPLOYMENT_THREADS)
            corner_bounds.append(1e-3 * sqrt_division_bound(threads=corners) * corners)
            bandwidth, arrays = triad_bandwidth(working, 256, CALLS // 10)
            bandwidths.append(bandwidth)
            for name, call in parts.items():
                times[name].append(best_us(call, CALLS))
        g.x[:], g.v[:] = x0, v0
        us = {name: statistics.median(t) for name, t in times.items()}
        bound = statistics.median(bounds)
        bandwidth = statistics.median(bandwidths)
        plain = 1e6 * statistics.median(self.yard.walls) / 3e6

        def moved(doubles):  # [us] for the bytes of ``doubles`` float64 at the bandwidth
            return 8 * doubles / bandwidth * 1e-3

        floors = {"stencils": max(bound / DEPLOYMENT_THREADS * threads,
                                  moved(threads * PASS_BYTES["stencils"])),
                  "peaks": moved(threads * PASS_BYTES["peaks"]),
                  "other_threads": statistics.median(corner_bounds)}
        at_floors = sum(floors.values()) + us["node_pass"]
        return {
            "t_s": state.time, "threads": threads, "node_rows": rows,
            "us": us, "us_all": times,
            "sqrt_division_bound_us_per_step": bound, "bound_us_all": bounds,
            "x_bound": {name: t / bound for name, t in us.items()},
            "plain_loop_us_per_step": plain,
            "x_plain_loop": {name: t / plain for name, t in us.items()},
            "step_bytes": traffic, "working_set_bytes": working,
            "triad_arrays_bytes": arrays, "bandwidths_GB_s_all": bandwidths,
            "bandwidth_GB_s": bandwidth, "traffic_floor_us": traffic / bandwidth * 1e-3,
            "corner_bound_us_all": corner_bounds, "floor_us": floors,
            "step_at_floors_us": at_floors, "step_at_floors_x_bound": at_floors / bound,
            "target_us": 2.5 * bound}


def main() -> int:
    p = parser(__doc__.split("\n\n")[0])
    p.add_argument("--at", type=float, default=1.0, help="snapshot time [s]")
    p.add_argument("--rounds", type=int, default=3, help="interleaved rounds (medians)")
    args = p.parse_args()
    out = output_dir(args)
    yard = Yardsticks()
    scene = bn.load_scenario("deployment", {"simulation.kernels": "grid",
                                            "scene.duration": args.at + 0.1})
    parts = StepParts(args.at, args.rounds, yard)
    bn.run(scene, None, observers=[parts])
    doc = {"machine": machine(), "scene": "deployment", **parts.taken,
           "yardsticks": yard.doc()}
    (out / "grid_step.json").write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
    t = parts.taken
    for name, value in t["us"].items():
        floor = t["floor_us"].get(name)
        print(f"{name:24s} {value:7.3f} us  {t['x_bound'][name]:5.2f} x bound"
              + ("" if floor is None else f"   floor {floor:.3f} us"))
    print(f"the step with three passes at their floors {t['step_at_floors_us']:.3f} us, "
          f"{t['step_at_floors_x_bound']:.2f} x bound")
    print(f"bound {t['sqrt_division_bound_us_per_step']:.3f} us, traffic floor "
          f"{t['traffic_floor_us']:.3f} us ({t['bandwidth_GB_s']:.0f} GB/s over "
          f"{t['step_bytes']} bytes), target {t['target_us']:.3f} us, plain loop "
          f"{t['plain_loop_us_per_step']:.3f} us a step")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
