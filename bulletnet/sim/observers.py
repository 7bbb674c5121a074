"""What watches a run: the run loop advances the engine frame by frame and hands each frame
to its observers, in order: the winch control (:mod:`bulletnet.sim.winch`), the recorder, the
outcome monitor, the profiler. A new phase of a run (a tow, a failure monitor) is a new
observer, not a new branch in the loop.

An observer's life (:class:`Observer`): ``frame`` at every frame, the initial one included;
``start`` once after the initial frame, before the first step; ``between_steps`` if it asks
the engine for it (:attr:`bulletnet.engines.base.Engine.step_hooks`: each chunk of the fast
engine, each step of bullet, for what must act inside a frame); ``finish`` once at the end,
whatever the status, adding the attributes the run's result and recording carry (in
:attr:`Observer.finish_order`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..analysis.capture_score import OutcomeMonitor, ScoreGeometry
from ..analysis.metrics import failures
from ..engines.base import Engine
from ..model.debris import QUAT, VELOCITY, body_origin
from ..model.net import NetModel, thread_kinds
from ..model.scenario import Scenario
from ..model.state import NetState
from ..recording.writer import Recorder
from .profiling import IO, OUTCOME, RECORDING, Profile, instrument, step_split


@dataclass
class Run:
    """What observers see of a run."""

    scenario: Scenario
    model: NetModel
    engine: Engine
    state: NetState
    """The state, advanced in place."""
    contacts: dict = field(default_factory=dict)
    """The engine's contact loads of the interval ending at this frame
    (:meth:`~bulletnet.engines.base.Engine.contact_loads`, read once a frame)."""


class Observer:
    """Watches a run (see the module doc); every hook does nothing unless overridden."""

    timed: tuple = ()
    """(object, method name, profile section) of the calls a profile times
    (:func:`bulletnet.sim.profiling.instrument`)."""
    finish_order = 0
    """Observers finish in this order (then in list order): the profiler first (-1: it
    stops timing before the others finish), the recorder after the others (1: it writes what
    they add), the profile's calibration of the step last (2: it steps the engine on)."""

    def frame(self, run: Run) -> bool:
        """See the frame just reached; True: the run stops here (completed)."""
        return False

    def start(self, run: Run) -> None:
        """Once, after the initial frame, before the first step."""

    def finish(self, run: Run, status: str, attrs: dict) -> None:
        """Once, at the end (``status`` completed, interrupted or diverged): add to
        ``attrs`` what the run's result and recording carry (the recorder, last, writes
        them)."""


class Recording(Observer):
    """Records every frame to an HDF5 file (:class:`~bulletnet.recording.writer.Recorder`)
    and closes it, with the run's attributes, whatever the status."""

    finish_order = 1

    def __init__(self, recorder: Recorder):
        self.recorder = recorder
        self.timed = ((recorder, "append", RECORDING), (recorder, "flush", IO))
        self.path = None
        """The recording closed, once finished."""

    def frame(self, run: Run) -> bool:
        engine = run.engine
        self.recorder.append(run.state, *engine.thread_loads(run.state), run.contacts,
                             engine.cable_loads(), engine.peak_tensions(), engine.reel_loads())
        return False

    def finish(self, run: Run, status: str, attrs: dict) -> None:
        failed = run.engine.failure_times()
        datasets = {} if failed is None else {"threads/failure_time": (failed["threads"], "s")}
        if failed is not None and run.model.cable_count:
            datasets["cables/failure_time"] = (failed["cables"], "s")
        contact = {}
        if run.scenario.contact.enabled:
            first = run.engine.contact_loads()["first_contact"]
            contact = {"first_contact_s": first[0], "first_self_contact_s": first[1]}
        rest = {k: v for k, v in attrs.items() if k != "message"}
        self.path = self.recorder.close(status, attrs.get("message", ""), datasets, **contact,
                                        **rest)


class Outcome(Observer):
    """Judges each frame's capture (:class:`~bulletnet.analysis.capture_score.OutcomeMonitor`);
    with ``stop_when_decided``, stops the run at the frame that decides it."""

    def __init__(self, scenario: Scenario, model: NetModel, engine: Engine,
                 samples: np.ndarray):
        self.monitor = OutcomeMonitor(scenario.outcome, ScoreGeometry.of(
            model, samples, engine.debris.center_of_mass))
        self.timed = ((self.monitor, "observe", OUTCOME),)
        self.stop = scenario.outcome.stop_when_decided

    def frame(self, run: Run) -> bool:
        state, debris = run.state, run.engine.debris
        self.monitor.observe(state.time, state.position, state.velocity,
                             body_origin(state.debris, debris), state.debris[QUAT],
                             state.debris[VELOCITY],
                             int(np.count_nonzero(run.contacts["node_force"])), judge_only=True)
        return self.monitor.decided and self.stop

    def finish(self, run: Run, status: str, attrs: dict) -> None:
        m = self.monitor
        m.finish(status == "completed")
        attrs.update(outcome=m.outcome, outcome_time_s=m.time, outcome_reason=m.reason)


class Profiling(Observer):
    """Times the run's sections from the first step on (:mod:`bulletnet.sim.profiling`): the
    engine's and those the other ``observers`` name; stops timing before the others finish."""

    finish_order = -1

    def __init__(self, profile: Profile, observers: list[Observer]):
        self.profile = profile
        self.observers = observers

    def start(self, run: Run) -> None:
        instrument(self.profile, run.engine, [t for o in self.observers for t in o.timed])

    def finish(self, run: Run, status: str, attrs: dict) -> None:
        self.profile.stop()


class StepSplit(Observer):
    """At a completed run's end, the profile's split of the engine step
    (:func:`~bulletnet.sim.profiling.step_split`), measured after every other observer has
    finished (2): its calibration steps the engine on, from a copy of the last state, and
    what that changes in the engine (a first contact, a broken thread, the winches) must not
    reach the run's result or recording."""

    finish_order = 2

    def __init__(self, profile: Profile):
        self.profile = profile

    def finish(self, run: Run, status: str, attrs: dict) -> None:
        if status == "completed":
            self.profile.split = step_split(run.engine, run.state)


class Breakage(Observer):
    """With ``strength.breakage`` on: at the end, what failed into the run's attributes
    (:func:`~bulletnet.analysis.metrics.failures`: counts, the first failure's time, kind
    and element, the elastic energy lost [J]); the recorder writes the failure times."""

    def finish(self, run: Run, status: str, attrs: dict) -> None:
        failed = run.engine.failure_times()
        attrs.update(failures(failed["threads"], failed["cables"],
                              thread_kinds(run.model.pairs, run.model.kind),
                              failed["energy_J"]))
