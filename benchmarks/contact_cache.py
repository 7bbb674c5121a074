"""The debris contact stage of a tow with and without its distance cache, against the yardsticks.

The removal (``scenarios/removal.toml``) runs to ``--at`` (in its tow: the net cinched on
the CSM, the chaser pulling; symplectic Euler at 8e-6 s); there its contact arrays and
state are taken, and the debris stage (:func:`bulletnet.solver.contact_stage.debris_stage`)
is stepped on them inside one compiled loop (no Python call between steps), in turn with the
cache off (``contact.skin`` 0 in the stage's arrays: every node within the debris' bounding
sphere is queried every step) and on (the scene's skin), repeats interleaved, each beside a
timing of the frozen yardstick. The nodes are held at the snapshot's state between calls,
as in a step most nodes move micrometres. Also counted: nodes out of the bounding sphere,
skipped by the cache, queried. Writes ``OUT/contact_cache.json``:

    python benchmarks/contact_cache.py benchmarks/results [--at 39] [--repeats 3]
"""

from __future__ import annotations

import json
import math
import statistics
import time

import numba as nb
import numpy as np
from common import At, Yardsticks, machine, output_dir, parser

import bulletnet as bn
from bulletnet.solver.contact_stage import debris_stage
from bulletnet.solver.debris_gap import CLEAR_MARGIN, debris_pose, surface_speed

CALLS = 2000
"""Debris-stage calls in one timed loop [-]."""


class Snapshot(At):
    """Takes the engine's state and contact arrays at the first frame at or after ``at`` [s]
    and stops the run."""

    def act(self, e, s):
        return {"pos": s.position.copy(), "vel": s.velocity.copy(),
                "dv": e.step_work.dv.copy(), "mass": e.arrays.mass,
                "radius": e.arrays.radius, "fixed": e.arrays.fixed,
                "contact": e.contact.arrays, "dt": e.dt, "t": s.time}


@nb.njit(cache=True)
def debris_stage_calls(pos, vel, dv, mass, radius, fixed, contact, dt, t, calls, work_pos,
                       work_vel):
    """``calls`` debris stages, each from the snapshot's (pos, vel)."""
    for _ in range(calls):
        work_pos[:] = pos
        work_vel[:] = vel
        debris_stage(work_pos, work_vel, dv, mass, radius, fixed, contact, dt, t)


@nb.njit(cache=True)
def _kinds(pos, vel, dv, radius, fixed, contact, dt, out):
    """How the cache as it stands treats each node (0: out of the bounding sphere, 1:
    skipped by the cache, 2: queried, -1: no debris contact), with the tests of
    :func:`bulletnet.solver.debris_gap.start_gap`."""
    rot, origin = debris_pose(contact.com, contact.quat, contact.com_body)
    speed = surface_speed(contact)
    for i in range(pos.shape[0]):
        if fixed[i] or contact.node_class[i] < 0:
            out[i] = -1
            continue
        p0 = pos[i] - dt * vel[i]
        reach = dt * (math.sqrt(np.sum(vel[i] ** 2)) + math.sqrt(np.sum(dv[i] ** 2)) + speed)
        reach += 1e-9
        if math.sqrt(np.sum((p0 - contact.com) ** 2)) - contact.bound[0] - radius[i] > reach:
            out[i] = 0
            continue
        b = rot.T @ (p0 - origin)
        room = contact.clear[i] - reach - CLEAR_MARGIN
        out[i] = 1 if room > 0.0 and np.sum((b - contact.clear_at[i]) ** 2) < room * room else 2


def main() -> None:
    p = parser(__doc__.split("\n\n")[0])
    p.add_argument("--at", type=float, default=39.0, help="snapshot time in the tow [s] [39]")
    args = p.parse_args()
    out = output_dir(args)
    scene = bn.load_scenario("removal", {"scene.duration": args.at + 1.0})
    snap = Snapshot(args.at)
    bn.run(scene, None, observers=[snap])
    s = snap.taken
    c = s["contact"]
    skin = float(c.params[1])
    call = (s["pos"], s["vel"], s["dv"], s["mass"], s["radius"], s["fixed"], c, s["dt"], s["t"])
    work = (np.empty_like(s["pos"]), np.empty_like(s["vel"]))
    yard = Yardsticks()
    walls = {"off": [], "on": []}
    for _ in range(args.repeats):
        yard.time()
        for name, value in (("off", 0.0), ("on", skin)):
            c.params[1] = value
            c.clear[:] = -np.inf
            debris_stage_calls(*call, 1, *work)  # (compiles once; fills the cache)
            start = time.perf_counter()
            debris_stage_calls(*call, CALLS, *work)
            walls[name].append((time.perf_counter() - start) / CALLS)
    kinds = np.empty(s["pos"].shape[0], dtype=np.int64)
    _kinds(s["pos"], s["vel"], s["dv"], s["radius"], s["fixed"], c, s["dt"], kinds)
    median = {name: statistics.median(w) for name, w in walls.items()}
    result = {
        "what": "debris contact stage on the removal's tow state, cache off and on",
        "date": time.strftime("%Y-%m-%d %H:%M"), "machine": machine(),
        "at_s": s["t"], "dt_s": s["dt"], "skin_m": skin, "calls": CALLS,
        "nodes": {"total": int(kinds.size), "no_contact": int((kinds == -1).sum()),
                  "out_of_bounding_sphere": int((kinds == 0).sum()),
                  "skipped_by_cache": int((kinds == 1).sum()),
                  "queried": int((kinds == 2).sum())},
        "stage_us": {name: {"median": 1e6 * m, "all": [1e6 * w for w in walls[name]]}
                     for name, m in median.items()},
        "speedup": median["off"] / median["on"],
        "per_yardstick": {name: m / yard.median for name, m in median.items()},
        "yardsticks": yard.doc(),
    }
    (out / "contact_cache.json").write_text(json.dumps(result, indent=1) + "\n")
    print(f"debris stage at {s['t']:.2f} s: cache off {1e6 * median['off']:.1f} us, on "
          f"{1e6 * median['on']:.1f} us ({result['speedup']:.2f}x); nodes {result['nodes']};"
          f" yardstick {yard.median:.2f} s -> {out / 'contact_cache.json'}")


if __name__ == "__main__":
    main()
