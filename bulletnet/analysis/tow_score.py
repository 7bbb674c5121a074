"""The tow's outcome and measures, judged frame by frame from the start of the burn (as the
capture's :class:`~bulletnet.analysis.capture_score.OutcomeMonitor` judges a capture).

Each frame gives the tether's tension at the chaser (its last segment) [N], the distance from
the chaser to the debris' centre of mass [m], the debris' enclosed fraction E
(:func:`~bulletnet.analysis.capture_score.score`) and its angular speed [rad/s]. Rules (the
scene's ``[tow]``):

- ``collided``: the distance falls below ``safe_distance`` (the debris overruns the chaser);
- ``slipped``: E falls below ``enclosed_fraction`` (the debris leaves the net), or the
  distance exceeds ``lost_distance`` (if set: the net has torn or let go and the chaser
  leaves the debris behind);
- ``towed``: neither, by the end of a completed run;
- ``undecided``: the burn never started, or the run stopped before its end.

The first outcome decided is final. The measures run over the whole tow, from the burn's
start to the end of the run: peak and mean tension, the snaps (a frame with the tether slack,
at or below ``slack_tension``, followed by a taut one: each snap's peak is the largest
tension until the tether is slack again), the least distance, the debris' largest angular
speed. Sampled at the recorded frames: a snap shorter than a frame interval is missed and a
peak between frames is not seen.
"""

from __future__ import annotations

import math

from ..model.scenario import TowRules

REASONS = {
    "collided": "the chaser came within {value:.2f} m of the debris' centre of mass",
    "slipped": "the debris left the net: enclosed fraction {value:.3f}",
    "lost": "the debris no longer follows: the chaser {value:.2f} m from it",
    "towed": "held and clear of the chaser from {since:.2f} s to the end, {end:.2f} s",
    "not started": "the burn had not started by the end, {end:.2f} s",
    "stopped": "the run stopped at {end:.2f} s, before its end",
}
"""The reasons a :class:`TowMonitor` gives, by case."""


class TowMonitor:
    """Judges a tow frame by frame (module doc) and keeps its measures."""

    def __init__(self, rules: TowRules):
        self.rules = rules
        self.outcome = "undecided"
        """``towed``, ``slipped``, ``collided`` or ``undecided``."""
        self.time = -1.0
        """When the outcome was decided [s]; -1 while undecided."""
        self.reason = ""
        """Why, in words (:data:`REASONS`)."""
        self.start = -1.0
        """The first frame judged (the burn's start) [s]; -1 before."""
        self.frames = 0
        """Frames judged [-]."""
        self.peak_tension = 0.0
        """Largest tether tension at the chaser [N]."""
        self.tension_sum = 0.0
        """Sum of the frames' tensions [N] (the mean is this over :attr:`frames`)."""
        self.snaps = 0
        """Slack-to-taut transitions [-]."""
        self.snap_peak = 0.0
        """Largest tension of a snap, until the tether is slack again [N]."""
        self.least_distance = math.inf
        """Least chaser-to-debris distance [m]."""
        self.largest_rate = 0.0
        """The debris' largest angular speed [rad/s]."""
        self._slack = False
        self._snapping = False
        self._last_time = 0.0

    @property
    def mean_tension(self) -> float:
        """Mean tether tension over the frames judged [N]; 0 before any."""
        return self.tension_sum / self.frames if self.frames else 0.0

    def update(self, t: float, tension: float, distance: float, enclosed: float,
               rate: float) -> None:
        """Judge the frame at ``t`` [s] of the tow: tether tension at the chaser [N],
        chaser-to-debris distance [m], enclosed fraction [-], debris angular speed [rad/s]."""
        r = self.rules
        if self.frames == 0:
            self.start = t
        self.frames += 1
        self._last_time = t
        self.peak_tension = max(self.peak_tension, tension)
        self.tension_sum += tension
        self.least_distance = min(self.least_distance, distance)
        self.largest_rate = max(self.largest_rate, rate)
        slack = tension <= r.slack_tension
        if self._slack and not slack:
            self.snaps += 1
            self._snapping = True
        if slack:
            self._snapping = False
        elif self._snapping:
            self.snap_peak = max(self.snap_peak, tension)
        self._slack = slack
        if self.outcome != "undecided":
            return
        if distance < r.safe_distance:
            self._decide("collided", t, distance)
        elif enclosed < r.enclosed_fraction:
            self._decide("slipped", t, enclosed)
        elif r.lost_distance > 0.0 and distance > r.lost_distance:
            self._decide("slipped", t, distance, "lost")

    def _decide(self, outcome: str, t: float, value: float, case: str = "") -> None:
        self.outcome, self.time = outcome, t
        self.reason = REASONS[case or outcome].format(value=value)

    def finish(self, completed: bool, end: float) -> None:
        """The run ended at ``end`` [s] (``completed``: it reached its end): an undecided tow
        that started is ``towed`` if the run completed."""
        if self.outcome != "undecided":
            return
        key = "not started" if self.frames == 0 else "towed" if completed else "stopped"
        if key == "towed":
            self.outcome, self.time = "towed", self._last_time
        self.reason = REASONS[key].format(since=self.start, end=end)

    def attributes(self) -> dict:
        """The outcome and measures as a recording's attributes (docs/recordings.md)."""
        return {"tow_outcome": self.outcome, "tow_outcome_time_s": self.time,
                "tow_outcome_reason": self.reason, "tow_start_s": self.start,
                "tow_peak_tension_N": self.peak_tension, "tow_mean_tension_N": self.mean_tension,
                "tow_snaps": self.snaps, "tow_snap_peak_N": self.snap_peak,
                "tow_least_distance_m": (self.least_distance if self.frames else -1.0),
                "tow_largest_debris_rate_deg_s": math.degrees(self.largest_rate)}
