"""What the CG tolerance leaves of the implicit step's error, by preconditioner.

The solver stops at a relative residual |r - A dv| <= tol |r| whatever its preconditioner;
the error it leaves in dv depends on where that residual lies (a residual in the system's
soft modes hides a larger error). Here the capture with bending and the closing capture run
on the pair list to each snapshot time (``--at``, several), where the step's system is taken
as the solver assembled it (its matrix from the solver's own product, its warm start and its
solution: :class:`cg_step.PairSystemAt`); its exact solution x* (dense LU, to round-off) is
the reference. From the solver's warm start, plain PCG with block Jacobi and with block
D-ILU + Woodbury (:func:`cg_step.woodbury_dilu`, what the ``block_dilu`` preconditioner
applies) runs to each tolerance of ``--tolerances``; each reports its iterations, the
relative residual it reached, and its error against x*: in the system's energy norm
|e|_A / |x*|_A (A = M + dt C + dt^2 K, so |e|_A^2 / 2 is the step's kinetic-energy error
[J], also given) and per node (the largest component [m/s]). Writes ``OUT/cg_error.json``:

    python benchmarks/cg_error.py benchmarks/results [--at 10 30 60]
"""

from __future__ import annotations

import json

import numpy as np
from cg_step import (
    PairSystemAt,
    block_jacobi,
    cable_rank_one,
    direct_neighbours,
    plain_pcg,
    woodbury_dilu,
)
from common import machine, output_dir, parser

import bulletnet as bn


def pcg_error(a, b, x0, tol: float, precondition, exact) -> dict:
    """Plain PCG (:func:`cg_step.plain_pcg`) from x0 to |b - A x| <= tol |b|: its iterations, the
    relative residual reached, and the error x - ``exact`` (see module doc)."""
    x, k = plain_pcg(a, b, x0, tol, precondition)
    e = x - exact
    energy = float(e @ a @ e)
    return {"iterations": k,
            "relative_residual": float(np.linalg.norm(b - a @ x) / np.linalg.norm(b)),
            "relative_error_energy_norm": float(np.sqrt(energy / (exact @ a @ exact))),
            "energy_error_J": 0.5 * energy,
            "largest_node_error_m_s": float(np.abs(e).max())}


def errors_at(taken: dict, tolerances: list[float]) -> dict:
    """:func:`pcg_error` for both preconditioners and every tolerance, on one step's system
    (``taken``: :class:`cg_step.PairSystemAt`). The right-hand side is A times the solver's
    solution, so that x* is known to round-off and the warm start's residual is the one the
    solver met (to the solver's own tolerance)."""
    a = taken["matrix"]
    n = a.shape[0] // 3
    b = a @ taken["solution"]
    exact = np.linalg.solve(a, b)
    methods = {
        "block_jacobi": block_jacobi(a),
        "block_dilu": woodbury_dilu(a, direct_neighbours(n, taken), cable_rank_one(taken, n))}
    return {"warm_start_relative_residual": float(
                np.linalg.norm(b - a @ taken["warm"]) / np.linalg.norm(b)),
            "solver_iterations": taken["solver_iterations"],
            "by_tolerance": {f"{tol:g}": {name: pcg_error(a, b, taken["warm"], tol, f, exact)
                                          for name, f in methods.items()}
                             for tol in tolerances}}


def main() -> int:
    p = parser(__doc__.split("\n\n")[0])
    p.add_argument("--at", type=float, nargs="+", default=[10.0, 30.0, 60.0],
                   help="snapshot times [s]")
    p.add_argument("--tolerances", type=float, nargs="+", default=[3e-4, 1e-4, 3e-5],
                   help="relative residuals to stop at [-]")
    args = p.parse_args()
    out = output_dir(args)
    doc = {"what": __doc__.split("\n\n")[0], "machine": machine(), "cases": {}}
    for name, scene_name, overrides in (("capture_bending", "capture", {"bending.enabled": True}),
                                        ("capture_closing", "capture_closing", {})):
        for at in args.at:
            scene = bn.load_scenario(scene_name, {**overrides, "scene.duration": at + 1.0,
                                                  "simulation.kernels": "pairs"})
            system = PairSystemAt(at)
            bn.run(scene, None, observers=[system])
            case = {"scene": scene_name, "overrides": overrides, "t_s": at,
                    "cg_tolerance": system.taken["tol"],
                    "preconditioner": scene.simulation.preconditioner,
                    **errors_at(system.taken, args.tolerances)}
            doc["cases"][f"{name}_{at:g}s"] = case
            print(f"{name} at {at:g} s: {json.dumps(case['by_tolerance'])}", flush=True)
    (out / "cg_error.json").write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
