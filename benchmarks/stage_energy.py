"""Where a run's energy comes from, stage by stage (docs/tow.md, "The snap blows the run up").

The scene runs as usual up to ``--from``; from there its steps are taken one by one, with the
same kernels in the same order as the compiled loop's pair-list path (winches, implicit
Euler's step, self-contact, debris contact, the debris' rigid motion; the debris' rigid-body
step every ``debris.step``), and the net's mechanical energy (the nodes' kinetic energy, the
threads' and closing cables' elastic energy) measured around each stage. Each stage's change,
summed from ``--from``, is what it did that no force's work explains: the winches' change less
their work; the implicit step's less the work of the external forces (thrust, loads) on its
displacement; the contact stages' as they are; and the debris' own energy change, from the
impulses the net gives it (first order: J . v + L . w, its velocity v and angular velocity w
held over the chunk), since a turning debris' surface does work on the nodes it carries. A
stage that makes energy shows as a rising sum; their total is what the steps since ``--from``
made.

The stages trade large amounts in a cinched bag (a node pressed on the debris or on another
node: the implicit step draws it in and the contact stage puts it back, a few joules each way
every step), so a rising total is localized step by step: ``--first-gain J`` stops at the
first step whose total exceeds J and records where it went: the energies at the step's
start, after the winches and the implicit step, and at its end, for the five threads whose
energy rose most (with their elastic tension at the end [N]) and for every closing cable;
the eight nodes the node-node and the debris contact stages moved most; the overlap
projections of both stages in the step.

    python benchmarks/stage_energy.py OUT [--scene removal] [--from 49] [--to 51]
                                          [--first-gain J] [--set KEY=VALUE ...]

Writes OUT/stage_energy.json (every 0.01 s: time [s], the sums [J], the energies [J], the
overlap projections so far [-, m], the largest closing-cable tension [N]; with
``--first-gain``, the step found) and prints every 0.1 s. Implicit Euler, the sequential
contact stage, no bending, no breakage and no reel only (the stages it copies); the
pair-list kernels (``simulation.kernels = "pairs"``) and the scene's integrator throughout
(no tow integrator: ``thrust.integrator = ""``) are forced.
"""

from __future__ import annotations

import argparse
import json
import tomllib
from pathlib import Path

import numpy as np

import bulletnet as bn
from bulletnet.kernels.axial import thread_energies
from bulletnet.kernels.bending import integrate_rotation
from bulletnet.kernels.cable import cable_length, elastic_energy, reel
from bulletnet.model.debris import COM, OMEGA, QUAT, VELOCITY
from bulletnet.sim.observers import Observer
from bulletnet.solver import integrators
from bulletnet.solver.contact_stage import debris_stage, ensure_pairs, self_stage

STAGES = ("winches", "implicit_step", "self_contact", "debris_contact", "debris")


def energy_parts(arrays, pos: np.ndarray, vel: np.ndarray) -> tuple[np.ndarray, ...]:
    """The net's energies [J] part by part: each node's kinetic (N,), each thread's elastic
    (P,), each closing cable's elastic (K,)."""
    kinetic = 0.5 * arrays.mass * np.einsum("na,na->n", vel, vel)
    threads = thread_energies(pos, arrays.pairs, arrays.rest, arrays.k_a)
    c = arrays.cables
    cables = np.array([] if c is None else
                      [elastic_energy(cable_length(pos, c, k), c.rest[k], c.rigidity[k])
                       for k in range(c.rest.shape[0])])
    return kinetic, threads, cables


def totals(parts: tuple[np.ndarray, ...]) -> tuple[float, float, float]:
    """(kinetic, threads' elastic, closing cables' elastic) energy of the net [J], from its
    :func:`energy_parts`."""
    return tuple(float(part.sum()) for part in parts)


def localize(arrays, contact, parts, moves, speeds, projections, t: float,
             total: float) -> dict:
    """Where a step's energy went: ``parts`` the :func:`energy_parts` at the step's start,
    after the implicit step and at its end; ``moves`` how far each node [m] the node-node and
    the debris stage moved it; ``speeds`` each node's speed [m/s] at those three points."""
    (k0, t0, c0), (k1, t1, c1), (k2, t2, c2) = parts
    tension = np.sqrt(2.0 * t2 * arrays.k_a)  # k x, from the elastic energy k x^2 / 2
    rose = np.argsort(t2 - t0)[::-1][:5]
    moved = np.argsort(moves[0] + moves[1])[::-1][:8]
    return {
        "time_s": t, "gain_J": total, "projections": projections.tolist(),
        "kinetic_J": [float(k0.sum()), float(k1.sum()), float(k2.sum())],
        "threads_J": [float(t0.sum()), float(t1.sum()), float(t2.sum())],
        "cables_J": [c0.tolist(), c1.tolist(), c2.tolist()],
        "cable_tension_N": [] if arrays.cables is None else arrays.cables.tension.tolist(),
        "threads": [{"thread": int(p), "nodes": arrays.pairs[p].tolist(),
                     "energy_J": [float(t0[p]), float(t1[p]), float(t2[p])],
                     "tension_N": float(tension[p])} for p in rose],
        "nodes": [{"node": int(i), "moved_by_self_contact_mm": 1e3 * float(moves[0][i]),
                   "moved_by_debris_contact_mm": 1e3 * float(moves[1][i]),
                   "predicted_debris_gap_m": float(contact.debris_gap[i]),
                   "speed_m_s": [float(s[i]) for s in speeds]} for i in moved]}


class StageAudit(Observer):
    """From the first frame at or after ``start`` [s], steps the run by hand to ``end`` [s],
    auditing each stage; then stops the run."""

    def __init__(self, start: float, end: float, first_gain: float | None = None):
        self.t_from, self.t_to, self.first_gain = start, end, first_gain
        self.rows: list[dict] = []
        self.found: dict | None = None

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
                parts, speeds = [energy_parts(a, pos, vel)], [np.linalg.norm(vel, axis=1)]
                projections = ca.projections.copy()
                energies = [sum(totals(parts[-1]))]
                winch = a.cables.work.sum() if a.cables is not None else 0.0
                reel(pos, a.cables, t, dt)
                energies.append(sum(totals(energy_parts(a, pos, vel))))
                winch = (a.cables.work.sum() if a.cables is not None else 0.0) - winch
                start = pos.copy()
                integrators.implicit_step(0.0, pos, vel, None, None, a, w, e.base_forces(),
                                          dt, e.cg_tolerance)
                vel += w.dv
                pos += dt * vel
                work = float(np.einsum("na,na->", e.external + a.load, pos - start))
                parts.append(energy_parts(a, pos, vel))
                speeds.append(np.linalg.norm(vel, axis=1))
                energies.append(sum(totals(parts[-1])))
                free = pos.copy()
                if ca.flags[1]:
                    self_stage(pos, vel, w.dv, a.mass, a.radius, ca, dt, t)
                energies.append(sum(totals(energy_parts(a, pos, vel))))
                apart, impulse = pos.copy(), ca.impulse.copy()
                debris_stage(pos, vel, w.dv, a.mass, a.radius, a.fixed, ca, dt, t)
                ca.com[:] += dt * ca.velocity
                integrate_rotation(ca.quat, ca.omega, dt)
                parts.append(energy_parts(a, pos, vel))
                speeds.append(np.linalg.norm(vel, axis=1))
                energies.append(sum(totals(parts[-1])))
                given = ca.impulse - impulse
                debris = float(given[:3] @ ca.velocity + given[3:] @ ca.omega[0])
                change = np.append(np.diff(energies) - (winch, work, 0.0, 0.0), debris)
                sums += change
                steps += 1
                if self.first_gain is not None and change.sum() > self.first_gain:
                    moves = (np.linalg.norm(apart - free, axis=1),
                             np.linalg.norm(pos - apart, axis=1))
                    self.found = localize(a, ca, parts, moves, speeds,
                                          ca.projections - projections, t,
                                          float(change.sum()))
                    print(json.dumps(self.found, indent=1))
                    self._row(t + dt, sums, totals(parts[-1]), ca, a)
                    return True
                t = run.state.time + steps * dt
                if steps % max(1, round(0.01 / dt)) == 0:
                    self._row(t, sums, totals(parts[-1]), ca, a)
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
    p.add_argument("--first-gain", type=float, default=None, metavar="J",
                   help="stop at the first step that makes more than J [J] and record where "
                        "it went")
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
    audit = StageAudit(args.start, args.end, args.first_gain)
    bn.run(scene, None, observers=[audit])
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "stage_energy.json").write_text(json.dumps(
        {"scene": args.scene, "overrides": overrides, "from_s": args.start, "to_s": args.end,
         "first_gain_J": args.first_gain, "found": audit.found, "rows": audit.rows}, indent=1))


if __name__ == "__main__":
    main()
