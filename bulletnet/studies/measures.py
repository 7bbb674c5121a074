"""Summary measures of a recording for sweeps and studies: a column name (with its unit) ->
a function of the recording (:data:`Measures`); the deployment's and the capture's sets."""

from __future__ import annotations

from collections.abc import Callable

from ..recording.reader import Recording


def final_mouth_area(rec: Recording) -> float:
    """Mouth area at the last frame [m^2]."""
    from ..analysis.metrics import mouth_area

    return float(mouth_area(rec)[-1])


def deployed_90(rec: Recording) -> float | None:
    """Time to 90 % deployed [s] (mouth area >= 0.9 L^2), None if not within the run."""
    from ..analysis.metrics import deployed_time

    return deployed_time(rec, 0.9)


def max_corner_tension(rec: Recording) -> float:
    """Largest tension in any corner thread over the recorded frames [N]."""
    from ..model.net import corner_threads

    return float(rec.tension[:, corner_threads(rec.pairs, rec.kind)].max())


def max_wrap(rec: Recording) -> float:
    """Largest wrap of the debris by the net over the recorded frames [-]
    (:func:`bulletnet.analysis.metrics.wrap`)."""
    from ..analysis.metrics import wrap

    return float(wrap(rec).max())


def max_nodes_in_contact(rec: Recording) -> int:
    """Most nodes touching the debris in one frame interval [-]."""
    from ..analysis.metrics import nodes_in_contact

    return int(nodes_in_contact(rec).max())


def outcome(rec: Recording) -> str | None:
    """The capture's outcome, where the recording keeps one (root attribute ``outcome``);
    else None."""
    value = rec.attrs.get("outcome")
    return None if value is None else str(value)


def _first_contact(rec: Recording) -> float | None:
    from ..analysis.metrics import first_contact_time

    return first_contact_time(rec)


def _leave(rec: Recording) -> float | None:
    from ..analysis.metrics import leave_time

    return leave_time(rec)


def min_safety_factor(rec: Recording) -> float | None:
    """The run's least safety factor: breaking tension over the largest tension, min over the
    elements [-] (:func:`bulletnet.analysis.metrics.safety`); None if none was ever taut."""
    from ..analysis.metrics import safety

    return safety(rec)["least_safety_factor"]


def overloaded_elements(rec: Recording) -> int:
    """Elements (threads and closing cables) at or over their breaking tension in some
    frame [-] (:func:`bulletnet.analysis.metrics.safety`)."""
    from ..analysis.metrics import safety

    return safety(rec)["overloaded_elements"]


def overloaded(rec: Recording) -> bool:
    """Whether any element reached its breaking tension (a study's report gives the
    probability of it)."""
    return overloaded_elements(rec) > 0


def broken_threads(rec: Recording) -> int | None:
    """Threads that failed in a run with ``strength.breakage`` on [-]
    (:func:`bulletnet.analysis.metrics.breakage`); None without breakage."""
    from ..analysis.metrics import breakage

    doc = breakage(rec)
    return None if doc is None else doc["broken_threads"]


def broken_cables(rec: Recording) -> int | None:
    """Closing cables that failed (``strength.breakage`` on) [-]; None without breakage."""
    from ..analysis.metrics import breakage

    doc = breakage(rec)
    return None if doc is None else doc["broken_cables"]


def first_break(rec: Recording) -> float | None:
    """When the first element failed (``strength.breakage`` on) [s]; None if none did."""
    from ..analysis.metrics import breakage

    doc = breakage(rec)
    return None if doc is None or doc["first_break_s"] < 0 else doc["first_break_s"]


def any_broken(rec: Recording) -> bool | None:
    """Whether any element failed (``strength.breakage`` on; a study's report gives the
    probability of it); None without breakage."""
    threads, cables = broken_threads(rec), broken_cables(rec)
    return None if threads is None else threads + cables > 0


def _tow_attribute(name: str, unset: float | None = None):
    """A measure reading the tow's root attribute ``name`` (docs/recordings.md); None where
    the recording has none, or where it holds ``unset`` (the tow never started)."""
    def measure(rec: Recording):
        value = rec.attrs.get(name)
        if value is None or (unset is not None and value == unset):
            return None
        return value.item() if hasattr(value, "item") else value
    measure.__doc__ = f"The recording's ``{name}`` attribute (None without one)."
    return measure


def _energy_gain(rec: Recording) -> float:
    from ..analysis.metrics import energy_gain

    return energy_gain(rec)


def tow_outcome(rec: Recording) -> str | None:
    """The tow's outcome (root attribute ``tow_outcome``: towed, slipped, collided or
    undecided); None where the recording has none."""
    value = rec.attrs.get("tow_outcome")
    return None if value is None else str(value)


Measures = dict[str, Callable[[Recording], float | int | str | bool | None]]
"""Summary measures of a recording: column name (with its unit) -> function of the recording;
None where a run never reaches it."""


STRENGTH_MEASURES: Measures = {
    "min_safety_factor": min_safety_factor,
    "overloaded_elements": overloaded_elements,
    "overloaded": overloaded,
}
"""Summary measures of every recording's safety margins: the least safety factor [-], the
elements that reached their breaking tension [-] and whether any did (true/false)."""

BREAKAGE_MEASURES: Measures = {
    "broken_threads": broken_threads,
    "broken_cables": broken_cables,
    "first_break_s": first_break,
    "any_broken": any_broken,
}
"""Summary measures of a run with ``strength.breakage`` on: threads and cables that failed
[-], the first failure [s] (None: none) and whether any element failed (true/false)."""

SUMMARY_MEASURES: Measures = {
    "final_mouth_area_m2": final_mouth_area,
    "deployed_90pct_s": deployed_90,
    "max_corner_tension_N": max_corner_tension,
    **STRENGTH_MEASURES,
}
"""Summary measures of a deployment's recording; keys carry the unit."""


CAPTURE_MEASURES: Measures = {
    "first_contact_s": _first_contact,
    "max_wrap": max_wrap,
    "max_nodes_in_contact": max_nodes_in_contact,
    "leave_s": _leave,
    "outcome": outcome,
    "max_energy_gain_J": _energy_gain,
    **STRENGTH_MEASURES,
}
"""Summary measures of a capture's recording (a scene with debris and contact): first
contact [s], largest wrap [-], most nodes in contact [-], leave time [s] (None: still on the
debris at the end), the outcome (None until the recording keeps one), the largest rise of
the mechanical energy above its start and the work done [J]
(:func:`bulletnet.analysis.metrics.energy_gain`: a sound run has none; a study shows which
runs were not) and :data:`STRENGTH_MEASURES`."""


TOW_MEASURES: Measures = {
    "tow_outcome": tow_outcome,
    "tow_start_s": _tow_attribute("tow_start_s", -1.0),
    "tow_decided_s": _tow_attribute("tow_outcome_time_s", -1.0),
    "tow_peak_tension_N": _tow_attribute("tow_peak_tension_N"),
    "tow_mean_tension_N": _tow_attribute("tow_mean_tension_N"),
    "tow_snaps": _tow_attribute("tow_snaps"),
    "tow_snap_peak_N": _tow_attribute("tow_snap_peak_N"),
    "tow_least_distance_m": _tow_attribute("tow_least_distance_m", -1.0),
    "tow_largest_debris_rate_deg_s": _tow_attribute("tow_largest_debris_rate_deg_s"),
}
"""Summary measures of a tow (a scene with ``[tow]`` judged, docs/tow.md): its outcome, the
burn's start [s] and when the outcome was decided [s] (None: never started), the tether's
peak and mean tension at the chaser [N], the snaps [-] and the largest snap's peak [N], the
least chaser-to-debris distance [m] (None: never started) and the debris' largest angular
speed [deg/s], all from the recording's ``tow_*`` attributes (a tow's scene is a capture's:
:data:`CAPTURE_MEASURES` with them, its energy check too)."""


def summary_measures(scenario) -> Measures:
    """The measures that fit a scene: :data:`CAPTURE_MEASURES` with debris and contact, else
    :data:`SUMMARY_MEASURES`; with ``[tow]`` judged, :data:`TOW_MEASURES` too; with
    ``strength.breakage`` on, :data:`BREAKAGE_MEASURES` too."""
    measures = CAPTURE_MEASURES if scenario.debris.asset and scenario.contact.enabled \
        else SUMMARY_MEASURES
    if scenario.tow.enabled:
        measures = {**measures, **TOW_MEASURES}
    return {**measures, **BREAKAGE_MEASURES} if scenario.strength.breakage else measures

