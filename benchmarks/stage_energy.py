"""Where a run's energy comes from, stage by stage (docs/tow.md, "The snap blows the run up").

The scene runs as usual up to ``--from``; from there its steps are taken one by one, with the
same kernels in the same order as the compiled loop's pair-list path (winches, implicit
Euler's step, self-contact, debris contact, the debris' rigid motion; the debris' rigid-body
step every ``debris.step``), and the net's mechanical energy (the nodes' kinetic energy, the
threads' and closing cables' elastic energy) measured around each stage. Each stage's change,
summed from ``--from``, is what it did that no force's work explains: the winches' change less
their work; the implicit step's less the work of the external forces (thrust, loads) on its
displacement; the contact stages' as they are (the debris barely moves: the work of its
surface on the nodes is small). A stage that makes energy shows as a rising sum.

    python benchmarks/stage_energy.py OUT [--scene removal] [--from 49] [--to 51]
                                          [--set KEY=VALUE ...]

Writes OUT/stage_energy.json (every 0.01 s: time [s], the sums [J], the energies [J], the
overlap projections so far [-, m], the largest closing-cable tension [N]) and prints every
0.1 s. Implicit Euler, the sequential contact stage, no bending, no breakage and no reel only
(the stages it copies); the pair-list kernels (``simulation.kernels = "pairs"``) and the
scene's integrator throughout (no tow integrator: ``thrust.integrator = ""``) are forced.
"""

from __future__ import annotations

import argparse
import json
import tomllib
from pathlib import Path

import numpy as np

import bulletnet as bn
from bulletnet.kernels.axial import axial_energy
from bulletnet.kernels.bending import integrate_rotation
from bulletnet.kernels.cable import cable_length, elastic_energy, reel
from bulletnet.model.debris import COM, OMEGA, QUAT, VELOCITY
from bulletnet.sim.observers import Observer
from bulletnet.solver import integrators
from bulletnet.solver.contact_stage import debris_stage, ensure_pairs, self_stage

STAGES = ("winches", "implicit_step", "self_contact", "debris_contact")


def net_energy(arrays, pos: np.ndarray, vel: np.ndarray) -> tuple[float, float, float]:
    """(kinetic, threads' elastic, closing cables' elastic) energy of the net [J]."""
    kinetic = 0.5 * float(np.einsum("n,na,na->", arrays.mass, vel, vel))
    threads = float(axial_energy(pos, arrays.pairs, arrays.rest, arrays.k_a))
    cables, c = 0.0, arrays.cables
    if c is not None:
        for k in range(c.rest.shape[0]):
            cables += elastic_energy(cable_length(pos, c, k), c.rest[k], c.rigidity[k])
    return kinetic, threads, cables


class StageAudit(Observer):
    """From the first frame at or after ``start`` [s], steps the run by hand to ``end`` [s],
    auditing each stage; then stops the run."""

    def __init__(self, start: float, end: float):
        self.t_from, self.t_to = start, end
        self.rows: list[dict] = []

    def frame(self, run) -> bool:
        if run.state.time < self.t_from - 1e-9:
            return False
        e, state = run.engine, run.state
        a, w, ca = e.arrays, e.step_work, e.contact.arrays
        pos, vel = state.position, state.velocity
        dt = e.dt
        chunk = max(1, round(e.scenario.debris.step / dt))
        t, steps = state.time, 0
        sums = np.zeros(len(STAGES))
        while t < self.t_to - 0.5 * dt:
            e.between_steps(t, t + chunk * dt)
            ca.com[:], ca.quat[0] = state.debris[COM], state.debris[QUAT]
            ca.velocity[:], ca.omega[0] = state.debris[VELOCITY], state.debris[OMEGA]
            ca.impulse[:] = 0.0
            for _ in range(chunk):
                ensure_pairs(pos, a.radius, ca)
                energies = [sum(net_energy(a, pos, vel))]
                winch = a.cables.work.sum() if a.cables is not None else 0.0
                reel(pos, a.cables, t, dt)
                energies.append(sum(net_energy(a, pos, vel)))
                winch = (a.cables.work.sum() if a.cables is not None else 0.0) - winch
                start = pos.copy()
                integrators.implicit_step(0.0, pos, vel, None, None, a, w, e.base_forces(),
                                          dt, e.cg_tolerance)
                vel += w.dv
                pos += dt * vel
                work = float(np.einsum("na,na->", e.external + a.load, pos - start))
                energies.append(sum(net_energy(a, pos, vel)))
                if ca.flags[1]:
                    self_stage(pos, vel, w.dv, a.mass, a.radius, ca, dt, t)
                energies.append(sum(net_energy(a, pos, vel)))
                debris_stage(pos, vel, w.dv, a.mass, a.radius, a.fixed, ca, dt, t)
                ca.com[:] += dt * ca.velocity
                integrate_rotation(ca.quat, ca.omega, dt)
                energies.append(sum(net_energy(a, pos, vel)))
                sums += np.diff(energies) - (winch, work, 0.0, 0.0)
                steps += 1
                t = run.state.time + steps * dt
                if steps % max(1, round(0.01 / dt)) == 0:
                    self._row(t, sums, net_energy(a, pos, vel), ca, a)
            e.rigid.step(ca.impulse, chunk * dt, state.debris)
        return True

    def _row(self, t, sums, energies, contact, arrays) -> None:
        row = {"time": t, **{f"{name}_J": float(s) for name, s in zip(STAGES, sums,
                                                                       strict=True)},
               "kinetic_J": energies[0], "threads_J": energies[1], "cables_J": energies[2],
               "projections": float(contact.projections[0]),
               "projected_m": float(contact.projections[1]),
               "cable_tension_max_N": (float(arrays.cables.tension.max())
                                       if arrays.cables is not None else 0.0)}
        self.rows.append(row)
        if len(self.rows) % 10 == 0:
            print(f"{t:8.3f} s  " + "  ".join(f"{name} {row[name + '_J']:+12.1f} J"
                                              for name in STAGES)
                  + f"  cables {energies[2]:10.1f} J", flush=True)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("out", type=Path, help="folder for stage_energy.json")
    p.add_argument("--scene", default="removal", help="scene name or .toml [removal]")
    p.add_argument("--from", dest="start", type=float, default=49.0,
                   help="simulated time at which the audit starts [s] [49]")
    p.add_argument("--to", dest="end", type=float, default=51.0,
                   help="simulated time at which it ends [s] [51]")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scene key (TOML value), as bulletnet run --set")
    args = p.parse_args()
    overrides = {k: tomllib.loads(f"v = {v}")["v"]
                 for k, v in (item.split("=", 1) for item in args.set)}
    overrides.update({"scene.duration": args.end, "simulation.kernels": "pairs",
                      "thrust.integrator": "", "thrust.dt": 0.0})  # implicit Euler throughout
    scene = bn.load_scenario(args.scene, overrides)
    if (scene.simulation.integrator != "implicit_euler" or scene.bending.enabled
            or scene.contact.solver != "sequential" or scene.reel.enabled
            or scene.strength.breakage):
        raise SystemExit("stage_energy: implicit Euler, sequential contact, no bending, "
                         "reel or breakage only")
    audit = StageAudit(args.start, args.end)
    bn.run(scene, None, observers=[audit])
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "stage_energy.json").write_text(json.dumps(
        {"scene": args.scene, "overrides": overrides, "from_s": args.start, "to_s": args.end,
         "rows": audit.rows}, indent=1))


if __name__ == "__main__":
    main()
