"""When the closing winches start: the three triggers of ``[closing]`` in one place.

- ``time``: at ``closing.trigger_time`` [s];
- ``contact``: ``closing.trigger_delay`` [s] after the net first touches the debris, to the
  step (the compiled contact stage records the first contact's time; the control reads it
  between steps, so the start is never late by more than one chunk of the fast engine);
- ``wrap``: at the first frame whose wrap fraction
  (:func:`~bulletnet.analysis.capture_score.wrap_fraction`) reaches ``closing.trigger_wrap``.

The engine reels the cables from the start time on (:func:`bulletnet.kernels.cable.reel`);
a start time is set once.
"""

from __future__ import annotations

from ..analysis.capture_score import wrap_fraction
from ..model.debris import COM
from .observers import Observer, Run


class WinchControl(Observer):
    """Starts the winches of a scene with ``[closing]`` on by its trigger."""

    def __init__(self, scenario):
        self.closing = scenario.closing

    def start(self, run: Run) -> None:
        cl, engine = self.closing, run.engine
        if cl.trigger == "time":
            engine.start_winches(cl.trigger_time)
        elif cl.trigger == "contact":
            engine.step_hooks.append(lambda: self._after_contact(engine))

    def _after_contact(self, engine) -> None:
        first = engine.contact.arrays.first_contact[0]
        if first >= 0.0:
            engine.start_winches(first + self.closing.trigger_delay)

    def frame(self, run: Run) -> bool:
        engine, state = run.engine, run.state
        if (self.closing.trigger == "wrap" and not engine.winches_started
                and wrap_fraction(state.position, run.model.nodes_per_side,
                                  state.debris[COM]) >= self.closing.trigger_wrap):
            engine.start_winches(state.time)
        return False
