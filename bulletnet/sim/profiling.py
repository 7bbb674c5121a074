"""Where a run's time goes (``bulletnet run --profile``).

Two honest measurements, both off unless asked for:

1. **Sections of the run loop**, timed from outside: the engine's ``advance`` (forces and
   integration, fused in one compiled loop), ``thread_loads`` (the tensions recorded each
   frame), the recorder's ``append`` and its HDF5 ``flush``, and the outcome monitor's
   ``observe`` (the capture score of each frame, scenes with ``[outcome]`` on). :meth:`Profile.wrap`
   replaces those methods on the instances for the run, each section timed exclusive of the
   sections it calls (a flush inside an append counts as I/O, not recording). numba
   compiling kernels its cache lacks inside the loop (a first run's step loop, at the
   first step) is a section of its own (:meth:`Profile.compiled`), not the engine's.
2. **The split inside the compiled step**, from a short calibration after the run on a copy
   of its last state: the same number of steps timed as the force kernels alone (gravity,
   loads, axial threads, bending on its multirate schedule) and as full engine steps, three
   times interleaved; the engine time is shared out between forces and integration in the
   median ratio. With contact, the contact stage is timed alone too (interleaved the same
   way), each call from the same state (:func:`_contact_loop`): steps without it would not
   do, a net without its contacts moves otherwise and its solver's work changes with it.
   Every timing starts from the run's end, the engine's own state included (its contact
   caches, its debris' PyBullet body); it steps the engine on from there, so it comes after
   every other observer has finished (:class:`~bulletnet.sim.observers.StepSplit`).
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numba as nb
import numpy as np

from ..kernels.axial import axial_forces
from ..model.state import NetState
from ..solver import grid as grid_kernels
from ..solver.contact_stage import contact_stage, ensure_pairs
from ..solver.integrators import bending_weight, external_forces

CALIBRATION_S = 0.4
"""Target wall time of each kind of calibration loop, all pairs together [s]."""
PAIRS = 3
"""Interleaved (forces, full steps) timings of the calibration; the median ratio is used, so a
moment of load on a shared machine does not skew the split."""


class Profile:
    """Exclusive wall time [s] of named sections of a run."""

    def __init__(self):
        self.seconds: dict[str, float] = {}
        """Section name -> exclusive wall time [s]."""
        self.active = True
        """Whether calls are timed (:meth:`stop` ends the profile: a run's final close is not
        part of its loop)."""
        self.split: dict | None = None
        """The calibrated split of the engine step (:func:`step_split`), once measured."""
        self._inner = 0.0

    def stop(self) -> None:
        """Stop timing the wrapped methods."""
        self.active = False

    def compiled(self, seconds: float) -> None:
        """numba compiled kernels for ``seconds`` [s] inside the section now timed: counted
        as :data:`COMPILING`, not as that section's (a first run compiles its step loop at
        the first step)."""
        if self.active:
            self.seconds[COMPILING] = self.seconds.get(COMPILING, 0.0) + seconds
            self._inner += seconds  # what the enclosing section leaves out of its own time

    def wrap(self, obj, method: str, section: str) -> None:
        """Time every call of ``obj.method`` into ``section`` from now on (instance only)."""
        call = getattr(obj, method)

        def timed(*args, **kwargs):
            if not self.active:
                return call(*args, **kwargs)
            outer, self._inner = self._inner, 0.0
            start = time.perf_counter()
            try:
                return call(*args, **kwargs)
            finally:
                elapsed = time.perf_counter() - start
                self.seconds[section] = (self.seconds.get(section, 0.0) + elapsed
                                         - self._inner)
                self._inner = outer + elapsed

        setattr(obj, method, timed)


ENGINE = "engine step"
LOADS = "thread loads (recorded tensions)"
RECORDING = "recording (HDF5 append)"
IO = "I/O (HDF5 flush)"
OUTCOME = "capture score (outcome monitor)"
COMPILING = "compiling (numba: kernels not yet cached)"


def instrument(profile: Profile, engine, timed=()) -> None:
    """Time the run's sections (see the module doc): the engine's, and each (object, method
    name, section) of ``timed`` (what the run's observers name,
    :attr:`bulletnet.sim.observers.Observer.timed`)."""
    profile.wrap(engine, "advance", ENGINE)
    profile.wrap(engine, "thread_loads", LOADS)
    for obj, method, section in timed:
        profile.wrap(obj, method, section)


@nb.njit(cache=True, error_model="numpy")
def _force_loop(steps, every, pos, vel, quat, omega, model, work, base, grid, views, dt):
    """The force kernels of ``steps`` steps of ``dt`` [s] on a fixed state, bending on its
    schedule (``quat`` None: no bending): the grid's (``grid`` not None; pos and vel its
    views) or the pair list's."""
    for _ in range(steps):
        weight = 0.0
        if quat is not None:
            weight = bending_weight(True, every, work)
        if grid is not None:
            if quat is not None:
                if weight > 0.0:
                    grid_kernels.bending(grid, views, work.torque)
            grid_kernels.thread_forces(grid, views, dt)
        else:
            external_forces(pos, vel, quat, omega, model, work, base, weight, False)
            axial_forces(pos, vel, model.pairs, model.rest, model.rest_rate, model.k_a,
                         model.c_a, model.bilateral, work.force, work.tension)
        work.step_count[0] += 1


@nb.njit(cache=True, error_model="numpy")
def _contact_loop(steps, stage, pos, vel, dv, mass, radius, fixed, contact, dt, t, start):
    """``steps`` contact stages of the fast engine's loop (the Verlet list's check and
    :func:`~bulletnet.solver.contact_stage.contact_stage`), each from the same ``start``: the
    nodes' positions [m], velocities [m/s] and velocity increments [m/s] (N, 3), the debris'
    centre of mass [m] (3,) and orientation (1, 4), and the gaps [m] each node and each pair
    last predicted and each node's distance cache, restored before each stage (``stage``
    False: restored only, the loop's cost without the stage)."""
    p, v, u, com, quat, gap, clear, clear_at, pair_gap = start
    for _ in range(steps):
        pos[:] = p
        vel[:] = v
        dv[:] = u
        contact.com[:] = com
        contact.quat[:] = quat
        contact.debris_gap[:] = gap
        contact.clear[:] = clear
        contact.clear_at[:] = clear_at
        contact.pair_gap[:] = pair_gap
        if stage:
            ensure_pairs(pos, radius, contact)
            contact_stage(pos, vel, dv, mass, radius, fixed, contact, dt, t)


def _writable(arrays, seen=None) -> list[np.ndarray]:
    """The writable arrays of a tuple of arrays, named tuples and None, and of the tuples in
    it, each once (the engine's tuples share arrays: its workspace and the grid's)."""
    seen = set() if seen is None else seen
    out = []
    for x in arrays:
        if isinstance(x, np.ndarray):
            if x.flags.writeable and id(x) not in seen:
                seen.add(id(x))
                out.append(x)
        elif isinstance(x, tuple):
            out += _writable(x, seen)
    return out


def _seconds(run: Callable[[], None]) -> float:
    start = time.perf_counter()
    run()
    return time.perf_counter() - start


def step_split(engine, state: NetState) -> dict | None:
    """Calibrated share of the force kernels in one engine step, or None for an engine without
    fixed steps, on a copy of the run's last ``state``. Returns ``{"steps",
    "force_s_per_step", "step_s_per_step", "time_s"}`` [-, s, s, s]: the median-ratio pair of
    :data:`PAIRS` interleaved timings, and the state's time; with the fast engine's contact
    also ``"contact_s_per_step"`` [s] (its contact stage alone, :func:`_contact_loop`) and
    ``"near_debris"`` [-], the nodes within a step's reach of the debris there: contact costs
    what that state has (none once the net has left the debris). It steps the engine on:
    call it once the run is over."""
    if engine.steps == 0 or engine.dt <= 0:
        return None
    from ..solver.integrators import workspace

    work = workspace(engine.model.node_count, engine.model.thread_count)
    quat, omega = engine.rotations(state)

    c = getattr(engine, "contact_arrays", None)  # (the fast engine's, if it has contact)
    held = tuple(getattr(engine, name, None) for name in (
        "arrays", "grid", "contact_arrays", "work", "step_work", "breakage", "peaks"))
    saved = [(x, x.copy()) for x in _writable(held)]

    def rewind():
        """The engine's own state back at the run's end: every array its kernels write (the
        contact stage's caches and Verlet list, the winches' and the reel's rest lengths, a
        thread broken since, the last velocity increment, ...), and the debris' PyBullet body
        made again at the state's pose (a timing starting from where the last one left the
        debris would see it jump)."""
        for array, copy in saved:
            array[...] = copy
        rigid = getattr(engine, "rigid", None)
        if rigid is not None:
            rigid.close()
            engine.rigid = type(rigid)(engine.debris, state.debris)

    def advance(steps):
        """Seconds of ``steps`` engine steps from (a copy of) the run's last state."""
        rewind()
        copy = state.copy()
        return _seconds(lambda: engine.advance(copy, copy.time + steps * engine.dt))

    grid = getattr(engine, "grid", None)
    if grid is not None:  # the grid's force kernels, on its rows (they hold the last state)
        views = engine.views
        pos, vel = views.position, views.velocity
    else:
        views = None
        pos, vel = state.position.copy(), state.velocity.copy()
    if quat is not None:
        quat, omega = quat.copy(), omega.copy()

    def forces(steps):
        _force_loop(steps, engine.bending_every, pos, vel, quat, omega, engine.arrays, work,
                    engine.base_forces(), grid, views, engine.dt)

    if c is not None:
        a, dv = engine.arrays, engine.step_work.dv
        start = tuple(x.copy() for x in (pos, vel, dv, c.com, c.quat, c.debris_gap, c.clear,
                                         c.clear_at, c.pair_gap))
        near = int(np.isfinite(c.debris_gap).sum()) if c.flags[0] else 0

        def touch(stage):
            return lambda steps: _contact_loop(steps, stage, pos, vel, dv, a.mass, a.radius,
                                               a.fixed, c, engine.dt, state.time, start)

    def contact_s(steps):
        rewind()
        return _seconds(lambda: touch(True)(steps)) - _seconds(lambda: touch(False)(steps))

    forces(1)  # warm
    advance(1)
    if c is not None:
        contact_s(1)
    per_step = advance(100) / 100
    steps = max(100, int(CALIBRATION_S / PAIRS / max(per_step, 1e-9)))
    timings = sorted(((_seconds(lambda: forces(steps)), advance(steps),
                       contact_s(steps) if c is not None else 0.0)
                      for _ in range(PAIRS)), key=lambda t: t[0] / t[1])
    force_s, step_s, touch_s = timings[PAIRS // 2]
    out = {"steps": PAIRS * steps, "force_s_per_step": force_s / steps,
           "step_s_per_step": step_s / steps, "time_s": state.time}
    if c is not None:
        out["contact_s_per_step"] = max(0.0, touch_s) / steps
        out["near_debris"] = near
    return out


def report(profile: Profile, total_s: float, contact: bool) -> list[str]:
    """The profile as lines of text: seconds and share of ``total_s`` [s] (the run loop's wall
    time) per section, the engine step shared out between forces and integration by the
    calibrated split; ``contact`` says whether the scene has contact."""
    split = profile.split
    sections = dict(profile.seconds)
    engine = sections.pop(ENGINE, 0.0)
    rows = []
    if split is not None:
        share = min(1.0, split["force_s_per_step"] / split["step_s_per_step"])
        touch = min(1.0 - share, split.get("contact_s_per_step", 0.0)
                    / split["step_s_per_step"])
        rows += [("forces (gravity, threads, bending)", engine * share),
                 ("integration (velocity/position update, solver)",
                  engine * (1 - share - touch))]
        if contact:
            rows.append(("contact (collision, normal law, friction)", engine * touch))
    else:
        rows.append((ENGINE + " (adaptive: not split)", engine))
    rows += [(name, sections.get(name, 0.0))
             for name in (LOADS, RECORDING, IO, OUTCOME, COMPILING)
             if name not in (OUTCOME, COMPILING) or name in sections]
    rows.append(("other (divergence checks, progress)",
                 max(0.0, total_s - engine - sum(sections.values()))))
    lines = [f"profile: {total_s:.3f} s wall in the run loop"]
    for name, seconds in rows:
        lines.append(f"  {name:<48} {seconds:9.3f} s  {100 * seconds / max(total_s, 1e-12):5.1f} %")
    if split is not None:
        where = f"the run's last state, t = {split['time_s']:.4g} s"
        if "near_debris" in split:  # contact costs what the state has: say what it had
            where += f", {split['near_debris']} nodes within a step's reach of the debris"
        touch = split.get("contact_s_per_step")
        parts = f"forces {split['force_s_per_step'] * 1e6:.3g} us" + (
            "" if touch is None else f", contact {touch * 1e6:.3g} us")
        lines.append(f"  (split of the engine step from {split['steps']} calibration steps at "
                     f"{where}: {parts} of {split['step_s_per_step'] * 1e6:.3g} us a step)")
    if not contact:
        lines.append("  contact: none, the scene has no contact")
    return lines
