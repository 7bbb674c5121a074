"""The fast engine: the whole net, and its contact, integrated in compiled loops; PyBullet
only for the debris' rigid-body dynamics, in a world of its own (no PyBullet world at all in
a scene without debris).

With debris, the run advances in chunks of ``debris.step``: the compiled loop moves the
debris rigidly at its current velocity and sums the net's contact impulses on it; PyBullet
then applies them as a constant force and torque over the chunk and takes one step of the
debris (5 orders of magnitude heavier than a node: its velocity changes little in a chunk).
"""

from __future__ import annotations

import math

import numpy as np

from ..common.direct_call import DirectCall
from ..kernels.axial import axial_forces
from ..kernels.peaks import peak_arrays
from ..model.debris import COM, OMEGA, QUAT, VELOCITY
from ..model.state import NetState
from ..solver import contact_stage as contact
from ..solver import grid as grid_kernels
from ..solver import integrators
from .base import Engine
from .debris_body import RigidDebris, orbit_load


class FastEngine(Engine):
    name = "fast"

    def __init__(self, scenario, model):
        super().__init__(scenario, model)
        self.rigid = None
        """The debris' PyBullet world (created on the first step)."""
        self._direct: DirectCall | None = None
        """The compiled loop in use, called directly (:meth:`_loop_call`)."""
        use_grid = (scenario.simulation.kernels == "grid" and self.dt > 0
                    and grid_kernels.applies(model))
        self.grid = (grid_kernels.build(model, self.arrays.cables, self.arrays.orbit,
                                        self.arrays.rest_rate, self.arrays.dilu)
                     if use_grid else None)
        """The net's grid threads and structure-of-arrays state (None: the pair-list path)."""
        if use_grid:  # (built from the model: exponential Euler's dampers set for the step)
            grid_kernels.scale_damping(self.grid, model.pairs, self.damping_factor)
        self.views = grid_kernels.views(self.grid) if use_grid else None
        """(N, 3) views of the grid's rows (None on the pair-list path)."""
        self.step_work = self.work._replace(dv=self.views.dv) if use_grid else self.work
        """The workspace the steps use (on the grid: its velocity increment, which the
        contact stage reads, is the grid's rows)."""
        if use_grid:  # the grid threads' running maxima in rows laid out as the grid's
            self.peaks = peak_arrays(model.thread_count, model.cable_count,
                                     self.grid.peak_rows)
            self._peak_columns = grid_kernels.peak_columns(self.grid, model.pairs)

    def _scale_damping(self, factor: np.ndarray) -> None:
        super()._scale_damping(factor)
        if getattr(self, "grid", None) is not None:  # (None while the base class sets up)
            grid_kernels.scale_damping(self.grid, self.model.pairs, factor)

    @property
    def kernels(self) -> str:
        """The thread kernels in use: grid or pairs."""
        return "pairs" if self.grid is None else "grid"

    @property
    def free(self) -> bool:
        """Whether the net is free: on the grid, with no bending, contact, cables, breakage or
        reel. Its steps are then :func:`bulletnet.solver.grid.free_steps` alone."""
        return (self.grid is not None and not self.bending and self.contact_arrays is None
                and self.arrays.cables is None and self.breakage is None
                and self.arrays.reel is None)

    @property
    def contact_arrays(self):
        """The contact stage's arrays, or None if no contact is on (none is compiled)."""
        a = self.contact.arrays
        return a if a.flags.any() else None

    def _loop_arrays(self, state: NetState) -> tuple:
        """(pos, vel, quat, omega) as the compiled loop steps them: the grid's views of its
        rows (which :func:`bulletnet.solver.grid.load` fills), or the state's own arrays on the pair
        list; (quat, omega) None without bending."""
        if self.grid is None:
            return (state.position, state.velocity, *self.rotations(state))
        v = self.views
        return (v.position, v.velocity, *((v.quat, v.omega) if self.bending else (None, None)))

    def _thread_peaks(self) -> np.ndarray:
        """Each thread's largest tension since the last reset [N], shape (P,): on the grid a
        grid thread's is the square root of its largest squared |T e|."""
        out = self.peaks.thread.copy()
        if self.grid is not None:
            rows, columns = self._peak_columns
            out[:rows.size] = np.sqrt(self.peaks.rows[rows, columns])
        return out

    def kernel_groups(self, state: NetState) -> dict[str, list[tuple]]:
        """The compiled kernels the loop of this engine calls, by group, each as (dispatcher,
        the arguments the loop passes it): ``step`` (the threads' step on this path; none on
        the grid with symplectic Euler, whose step is inlined into the loop whole, so the
        loop's own compilation is its), with bending on the grid ``bending``, with contact
        ``contact`` (the contact stage), with a tow on another integrator
        (``thrust.integrator``) ``tow`` (that integrator's loop), and ``frame`` (the thread
        loads each recorded frame computes, :meth:`loads_calls`). For compiling groups apart,
        on both cores (:mod:`bulletnet.sim.compile_ahead`); empty for a free net, whose first
        run compiles little."""
        if self.free:
            return {}
        pos, vel, quat, omega = self._loop_arrays(state)
        groups = {"frame": self.loads_calls(state)}
        if self.grid is not None:
            if self.implicit:
                groups["step"] = [(grid_kernels.implicit_step, (
                    self.grid, self.views, self.dt, self.cg_tolerance, self.work.cg_iterations))]
        else:  # the increment is inlined into the loop: the kernels it calls
            a, w = self.arrays, self.step_work
            groups["step"] = ([(integrators.implicit_increment, (pos, vel, a, w, self.dt,
                                                                 self.cg_tolerance))]
                              if self.implicit else
                              [(axial_forces, (pos, vel, a.pairs, a.rest, a.rest_rate, a.k_a,
                                               a.c_a, a.bilateral, w.force, w.tension))])
        tow = self.scenario.thrust
        if tow.enabled and tow.integrator and (tow.integrator == "implicit_euler") != self.implicit:
            groups["tow"] = [(integrators.advance(self.grid is not None, not self.implicit), (
                self.bending_every, 1, pos, vel, quat, omega, self.arrays, self.step_work,
                self.base_forces(), self.dt, self.cg_tolerance, self.contact_arrays,
                0.0, self.grid, self.views, self.breakage, self.peaks))]
        if self.grid is not None and self.bending:
            groups["bending"] = [(grid_kernels.bending, (self.grid, self.views,
                                                         self.work.torque))]
        contact_arrays = self.contact_arrays
        if contact_arrays is not None:
            a = self.arrays
            groups["contact"] = [
                (contact.ensure_pairs, (pos, a.radius, contact_arrays)),
                (contact.contact_stage, (pos, vel, self.step_work.dv, a.mass, a.radius,
                                         a.fixed, contact_arrays, self.dt, 0.0))]
        return groups

    def advance(self, state: NetState, t_end: float) -> None:
        interval = t_end - state.time
        if interval <= 0:
            return
        steps = self.steps_for(interval)
        dt = interval / steps
        has_debris = self.debris is not None  # (with contact off it still moves)
        chunked = has_debris or bool(self.step_hooks)  # (hooks act between chunks)
        chunk = max(1, round(self.scenario.debris.step / dt)) if chunked else steps
        if has_debris and self.rigid is None:
            self.rigid = RigidDebris(self.debris, state.debris)
        a = self.contact.arrays
        on_grid = self.grid is not None
        base = self.base_forces()
        if on_grid:
            grid_kernels.load(self.grid, state, base)
        pos, vel, quat, omega = self._loop_arrays(state)
        # every position as one flat array (the grid's rows: their padding stays zero)
        flat = (self.grid.x if on_grid else pos).reshape(-1)
        free = self.free
        loop = None if free else integrators.advance(on_grid, self.implicit)
        contact_arrays = self.contact_arrays
        debris = state.debris
        compiled = None  # the loop's compiled version for this call's arguments
        done = 0
        while done < steps:
            todo = min(chunk, steps - done)
            self.between_steps(state.time + done * dt, state.time + (done + todo) * dt)
            if self.step_hooks:  # a hook may have changed the external forces
                base = self.base_forces()
                if on_grid:
                    grid_kernels.load_forces(self.grid, base)
            if has_debris:
                a.com[:], a.quat[0] = debris[COM], debris[QUAT]
                a.velocity[:], a.omega[0] = debris[VELOCITY], debris[OMEGA]
                a.impulse[:] = 0.0
            if free:
                grid_kernels.free_steps(self.implicit)(self.grid, self.views, todo, dt,
                                                       self.cg_tolerance,
                                                       self.work.cg_iterations, self.peaks,
                                                       grid_kernels.base_rows(self.grid))
                self.step_work.step_count[0] += todo
                taken = todo
            else:
                args = (self.bending_every, todo, pos, vel, quat, omega, self.arrays,
                        self.step_work, base, dt, self.cg_tolerance, contact_arrays,
                        state.time + done * dt, self.grid, self.views, self.breakage,
                        self.peaks)
                if compiled is None:  # (the arguments' kinds hold until the list grows)
                    compiled = self._loop_call(loop).resolve(args)
                taken = compiled(*args)
            if taken < todo:  # the self-contact list is full: grow it, go on
                self.contact = contact.grow_pair_list(self.contact)
                a, contact_arrays = self.contact.arrays, self.contact_arrays
                compiled = None
            if has_debris and taken:
                if self.arrays.orbit is not None:  # held over the chunk, as the net's impulses
                    a.impulse[:] += taken * dt * orbit_load(self.arrays.orbit, self.debris,
                                                            debris)
                self.rigid.step(a.impulse, taken * dt, debris)
            done += taken
            self._impulse_time += taken * dt
            # not finite iff a position is not (or |x| > 1e154 m: diverged as well); a third
            # of np.isfinite's time, a check at each of a capture's 30 000 chunks
            if not math.isfinite(np.dot(flat, flat)):
                break
        if on_grid:
            grid_kernels.store(self.grid, state)
            self._store_reel()
        self.steps += done
        state.time = t_end

    def _loop_call(self, loop) -> DirectCall:
        """``loop`` called without numba's dispatch at every chunk (:mod:`bulletnet.common.
        direct_call`): a capture returns to Python every few steps for the debris'
        dynamics."""
        if self._direct is None or self._direct.dispatcher is not loop:
            self._direct = DirectCall(loop)  # (another integrator: another loop)
        return self._direct

    def _store_reel(self) -> None:
        """Copy the tether's rest lengths, their rates, stiffness and damping, which the reel
        sets in the grid's other threads, into the pair list's arrays (:meth:`thread_loads`
        reads them); nothing without a reel."""
        reel, a, g = self.arrays.reel, self.arrays, self.grid
        if reel is None:
            return
        tether = slice(-reel.pairs.shape[0], None)
        for mine, rows in ((a.rest, g.o_rest), (a.rest_rate, g.o_rest_rate), (a.k_a, g.o_k),
                           (a.c_a, g.o_c)):
            mine[tether] = rows[tether]

    def close(self) -> None:
        if self.rigid is not None:
            self.rigid.close()
            self.rigid = None
