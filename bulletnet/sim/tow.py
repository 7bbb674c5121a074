"""The tow: the chaser's burn, its reel and the judge of the tow's outcome, as observers of
the run loop.

- :class:`ThrustControl` starts the burn by the scene's trigger (``[thrust]``: a time, or a
  delay after the frame at which the capture is decided ``captured``: :class:`Trigger`)
  and, as an engine step hook, sets the chaser's external force to the profile's mean over
  the steps to come (the fast engine's chunks of ``debris.step``, 1/240 s by default;
  bullet's steps): the impulse delivered is the profile's to round-off
  (:mod:`bulletnet.model.thrust`). With ``strength.breakage`` on, a failed tether thread
  ends the burn (the chaser is cut loose).
- :class:`TowOutcome` judges the tow from the burn's start on, frame by frame
  (:class:`~bulletnet.analysis.tow_score.TowMonitor`), and adds its outcome and measures to
  the recording.
- :class:`ReelControl` starts the reel at the chaser (``[reel]``) by the same rules; the
  engine reels from then on (:mod:`bulletnet.kernels.reel`).
"""

from __future__ import annotations

import math

import numpy as np

from ..analysis.capture_score import OutcomeMonitor, ScoreGeometry, score
from ..analysis.tow_score import TowMonitor
from ..model.debris import COM, OMEGA, QUAT, body_origin
from ..model.net import ElementKind, thread_kinds
from ..model.thrust import ThrustProfile, axial_mode
from .observers import Observer, Run


class Trigger:
    """When a part of the tow starts, by its table's ``trigger``, ``trigger_time`` [s] and
    ``trigger_delay`` [s] (``[thrust]``, ``[reel]``): at the trigger time (``time``), or the
    delay after the frame at which ``capture`` decides the capture ``captured``
    (``captured``; ``capture`` None for ``time``)."""

    def __init__(self, rules, capture: OutcomeMonitor | None):
        self.rules = rules
        self.capture = capture

    def start_time(self) -> float | None:
        """The start time [s], once it is known; None before."""
        if self.rules.trigger == "time":
            return self.rules.trigger_time
        if self.capture is not None and self.capture.outcome == "captured":
            return self.capture.time + self.rules.trigger_delay
        return None


class ThrustControl(Observer):
    """Starts and applies the chaser's burn (module doc); ``capture`` judges the capture
    for trigger ``captured`` (None for trigger ``time``)."""

    def __init__(self, scenario, model, engine, capture: OutcomeMonitor | None):
        self.rules = scenario.thrust
        self.trigger = Trigger(self.rules, capture)
        self.mode = axial_mode(scenario, model,
                               0.0 if engine.debris is None else engine.debris.mass)
        """The tether's axial mode the shaper is tuned to."""
        direction = np.asarray(self.rules.direction, dtype=float)
        self.direction = direction / np.linalg.norm(direction)
        self.chaser = model.node_count - 1
        """The chaser's node: the tether's far end, the model's last node."""
        self.profile: ThrustProfile | None = None
        """The burn, once started."""
        self.tether = (np.flatnonzero(thread_kinds(model.pairs, model.kind)
                                      == ElementKind.TETHER)
                       if engine.breakage is not None else None)
        """The main tether's threads (with ``strength.breakage`` on; None without): once one
        has failed the chaser is cut loose and the burn ends (no thrust from the step
        hook after)."""
        self.switched = False
        """Whether the tow's integrator and step (``thrust.integrator``, ``thrust.dt``) are
        in force."""

    def start(self, run: Run) -> None:
        self._begin()
        self._switch(run)
        run.engine.step_hooks.append(lambda: self._apply(run.engine))

    def _switch(self, run: Run) -> None:
        """From the first frame at or after the burn's start: the tow's integrator and step,
        if the scene gives them."""
        p, rules = self.profile, self.rules
        if (p is None or self.switched or run.state.time < p.times[0] - 1e-9
                or not (rules.integrator or rules.dt)):
            return
        run.engine.switch_integrator(rules.integrator, rules.dt)
        self.switched = True

    def _begin(self) -> None:
        """Start the burn once its trigger's start time is known."""
        start = self.trigger.start_time() if self.profile is None else None
        if start is not None:
            self.profile = ThrustProfile(self.rules, start, self.mode.omega, self.mode.zeta)

    def _apply(self, engine) -> None:
        p = self.profile
        if p is None:
            return
        if p.end == math.inf and self.tether is not None and bool(
                (engine.breakage.failure_time[self.tether] >= 0).any()):
            p.end = engine.span[0]  # a failed tether ends the burn, from these steps on
        engine.external[self.chaser] = p.mean(*engine.span) * self.direction

    def frame(self, run: Run) -> bool:
        self._begin()
        self._switch(run)
        return False

    def finish(self, run: Run, status: str, attrs: dict) -> None:
        m, p = self.mode, self.profile
        attrs.update(
            thrust_integrator=run.engine.integrator if self.switched else "",
            thrust_dt_s=run.engine.dt if self.switched else 0.0,
            thrust_start_s=-1.0 if p is None else float(p.times[0]),
            thrust_impulse_Ns=0.0 if p is None else p.impulse(run.state.time),
            thrust_cut_s=-1.0 if p is None or p.end == math.inf else float(p.end),
            thrust_axial_frequency_rad_s=m.omega, thrust_damping_ratio=m.zeta,
            thrust_towed_mass_kg=m.towed_mass, thrust_chaser_mass_kg=m.chaser_mass,
            thrust_tether_stiffness_N_m=m.stiffness)


class TowOutcome(Observer):
    """Judges the tow from the start of ``thrust``'s burn (module doc)."""

    def __init__(self, scenario, geometry: ScoreGeometry, thrust: ThrustControl):
        self.monitor = TowMonitor(scenario.tow)
        self.geometry = geometry
        self.thrust = thrust
        self.stop = scenario.tow.stop_when_decided

    def frame(self, run: Run) -> bool:
        self._judge(run)
        if not self.stop:
            return False
        capture = self.thrust.trigger.capture
        no_burn = (self.thrust.profile is None and capture is not None and capture.decided
                   and capture.outcome != "captured")
        return no_burn or self.monitor.outcome in ("slipped", "collided")

    def _judge(self, run: Run) -> None:
        p, state, engine = self.thrust.profile, run.state, run.engine
        if p is None or state.time < p.times[0]:
            return
        debris = state.debris
        tension = engine.thread_loads(state)[0][-1]  # the chaser's segment, the last thread
        enclosed = score(state.position, body_origin(debris, engine.debris), debris[QUAT],
                         self.geometry).enclosed
        self.monitor.update(state.time, float(tension),
                            float(np.linalg.norm(state.position[-1] - debris[COM])),
                            enclosed, float(np.linalg.norm(debris[OMEGA])))

    def finish(self, run: Run, status: str, attrs: dict) -> None:
        self.monitor.finish(status == "completed", run.state.time)
        attrs.update(self.monitor.attributes())


class ReelControl(Observer):
    """Starts the reel at the chaser (``[reel]``) by its :class:`Trigger`; ``capture`` judges
    the capture for trigger ``captured`` (None for trigger ``time``). At the end, its start
    time into the run's attributes (``reel_start_s`` [s], -1: never started)."""

    def __init__(self, scenario, capture: OutcomeMonitor | None):
        self.trigger = Trigger(scenario.reel, capture)

    def frame(self, run: Run) -> bool:
        start = None if run.engine.reel_started else self.trigger.start_time()
        if start is not None:
            run.engine.start_reel(start)
        return False

    def finish(self, run: Run, status: str, attrs: dict) -> None:
        reel = run.engine.arrays.reel
        attrs["reel_start_s"] = float(reel.start_time[0]) if run.engine.reel_started else -1.0
