"""Run a scene: scenario -> model -> engine -> recorder."""

from __future__ import annotations

import contextlib
import dataclasses
import math
import os
import signal
import threading
import time as _time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..analysis.capture_score import ScoreGeometry, interior_samples
from ..analysis.stability import Limits, analytical_limits, cable_frequency
from ..common import interrupt
from ..common.errors import BulletnetError, DivergenceError, ScenarioError
from ..common.kernel_cache import import_numba_arrays, watch_compilation
from ..engines import make_engine
from ..model.builder import build_model, initial_state
from ..model.scenario import Scenario, to_toml
from ..model.state import NetState
from ..recording.writer import Recorder
from .compile_ahead import compile_ahead, stop_helper
from .observers import Breakage, Observer, Outcome, Profiling, Recording, Run, StepSplit
from .profiling import Profile
from .tow import ReelControl, ThrustControl, TowOutcome
from .winch import WinchControl

MAX_RECORDING_BYTES = 2e9
"""Recordings estimated larger than this [bytes] need ``force`` (or a lower record rate)."""

Progress = Callable[[float, float, float], None]
"""Called after each recorded frame with (simulated time [s], duration [s], wall time [s])."""


@dataclass
class RunResult:
    path: Path | None
    """The recording written, if any."""
    status: str
    """completed, interrupted or diverged."""
    state: NetState
    """The last state reached."""
    wall_time_s: float
    """Wall-clock time of the integration [s]."""
    stats: dict
    """Engine counters (steps, solver iterations)."""
    frames: int
    """Frames recorded [-]."""
    outcome: str = ""
    """The capture's outcome in a scene with ``[outcome]`` on (captured, escaped, missed or
    undecided; :class:`~bulletnet.analysis.capture_score.OutcomeMonitor`); "" otherwise."""
    outcome_time_s: float = -1.0
    """When the outcome was decided [s]; -1 if undecided or not judged."""
    outcome_reason: str = ""
    """Why, in words (:data:`bulletnet.analysis.capture_score.REASONS`); "" if not judged."""
    compile_time_s: float = 0.0
    """Of ``wall_time_s``, the time numba spent compiling kernels its cache lacked [s]: a
    first run compiles its step loop inside the run loop (0 once they are cached)."""


def frame_times(duration: float, record_rate: float) -> np.ndarray:
    """Sample times [s]: every 1 / record_rate from 0, plus ``duration`` itself, shape (T,)."""
    count = math.floor(duration * record_rate + 1e-9)
    times = np.arange(count + 1) / record_rate
    if duration - times[-1] > 1e-9 * max(1.0, duration):
        times = np.append(times, duration)
    return times


def recording_bytes(scenario: Scenario, n: int, p: int) -> float:
    """Estimated size of a run's recording [bytes] for ``n`` nodes and ``p`` threads: float64
    series per frame (time, positions, velocities, tensions, shear forces; orientations and
    angular velocities with bending; debris pose and velocities, and contact forces, in scenes
    that have them)."""
    per_frame = (1 + 6 * n + 2 * p + (7 * n if scenario.bending.enabled else 0)
                 + (13 if scenario.debris.asset else 0)
                 + (n + 3 if scenario.contact.enabled else 0))
    frames = frame_times(scenario.scene.duration, scenario.simulation.record_rate).size
    return 8.0 * per_frame * frames


@contextlib.contextmanager
def _signals_deferred():
    """Ignore SIGINT and SIGTERM inside the block (a second Ctrl-C while the recording is
    being closed must not leave it half written); a no-op off the main thread."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    saved = {sig: signal.signal(sig, signal.SIG_IGN) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for sig, handler in saved.items():
            signal.signal(sig, handler)


def speed_limit(s: Scenario, state: NetState) -> float:
    """Node speed [m/s] above which a run is taken to have diverged: 100 times the largest
    speed the scene can explain (initial speeds plus free fall over the whole duration)."""
    g = float(np.linalg.norm(s.scene.gravity))
    v0 = float(np.linalg.norm(state.velocity, axis=1).max())
    return 100.0 * (v0 + g * s.scene.duration + 1.0)


def _check(state: NetState, limit: float) -> str:
    """Why ``state`` has diverged (non-finite, or a node faster than ``limit`` [m/s]), or "".
    A diverging state's speeds may overflow (inf): that is the finding, not a warning."""
    if not np.isfinite(state.position).all() or not np.isfinite(state.velocity).all():
        return "non-finite state"
    with np.errstate(over="ignore"):
        vmax = float(np.linalg.norm(state.velocity, axis=1).max())
    if vmax > limit:
        return f"a node moves at {vmax:.3g} m/s (limit {limit:.3g} m/s)"
    return ""


def _divergence(reason: str, state: NetState, dt: float, integrator: str,
                limits: Limits, exact_contact: bool) -> DivergenceError:
    """The typed error of a diverged run, naming the step and the analytical limit (an
    adaptive run, ``dt`` 0, has none) and what to change: on implicit Euler, whose threads
    cannot diverge, a smaller step or, with the ``exact`` contact law (``exact_contact``),
    the implicit one (docs/capture.md, "Contact at practical steps")."""
    if dt <= 0:
        return DivergenceError(f"diverged at t = {state.time:.6g} s: {reason} with the "
                               "adaptive reference engine", state.time)
    if integrator != "implicit_euler":
        advice = "use a smaller --dt or the implicit_euler integrator"
    elif exact_contact:
        advice = ("the exact contact law gives back energy beside implicit-Euler threads: "
                  "use contact.model=implicit (or a smaller --dt)")
    else:
        advice = "use a smaller --dt"
    return DivergenceError(
        f"diverged at t = {state.time:.6g} s: {reason} with step {dt:.3g} s; "
        f"{limits.describe(integrator)}; {advice}",
        state.time, step=dt, limit=limits.for_integrator(integrator))


def preflight(scenario: Scenario, out: str | os.PathLike | None, force: bool = False):
    """Check a run before it starts (existing output, recording size); return its model."""
    if out is not None and Path(out).is_dir():
        raise ScenarioError(f"{out}: is a folder; the output names the recording's file")
    if out is not None and Path(out).exists() and not force:
        raise ScenarioError(f"{out}: exists; pass --force (force=True) to overwrite it")

    def check_size(n: int, p: int) -> None:
        size = recording_bytes(scenario, n, p)
        if out is not None and not force and size > MAX_RECORDING_BYTES:
            raise ScenarioError(
                f"{out}: the recording would take about {size / 1e9:.1f} GB; lower "
                "--record-rate or pass --force")

    if scenario.scene.kind == "net":  # the net's own nodes and threads, before building it
        ns = scenario.net.nodes_per_side
        check_size(ns * ns, 2 * ns * (ns - 1))
    model = build_model(scenario)
    check_size(model.node_count, model.thread_count)
    return model


def warm_up(scenario: Scenario) -> float:
    """Compile the kernels a run of ``scenario`` uses, or load them from numba's cache: one
    record interval, recorded to a temporary file (recording uses kernels of its own).
    Returns its wall time [s]. A run that diverges in it has compiled them all the same."""
    import tempfile

    start = _time.perf_counter()
    short = scenario.with_overrides({"scene.duration": 1.0 / scenario.simulation.record_rate})
    with tempfile.TemporaryDirectory() as tmp:
        try:
            run(short, Path(tmp) / "warm_up.h5")
        except BulletnetError:
            pass
    return _time.perf_counter() - start


def run(scenario: Scenario, out: str | os.PathLike | None = None, *,
        progress: Progress | None = None, force: bool = False,
        profile: Profile | None = None, observers: Sequence[Observer] = ()) -> RunResult:
    """Simulate ``scenario``; record to ``out`` (HDF5) if given; with ``profile``, time the
    run's sections into it (:mod:`bulletnet.sim.profiling`).

    An existing ``out``, or a recording estimated above :data:`MAX_RECORDING_BYTES`, is an
    error unless ``force``. On Ctrl-C the recording is closed with
    status ``interrupted`` and KeyboardInterrupt is re-raised; on divergence with status
    ``diverged`` and :class:`DivergenceError` is re-raised. Every frame so far is kept.
    ``observers`` (:class:`~bulletnet.sim.observers.Observer`) watch the run after the
    built-in ones: each sees every frame and may stop the run there.
    With ``[outcome]`` on, each frame is judged (:mod:`bulletnet.analysis.capture_score`) and the
    recording gets ``outcome`` and ``outcome_time_s``; with ``stop_when_decided`` the run
    ends, ``completed``, at the frame that decides it."""
    import_numba_arrays()  # before the first kernel, which would import them the slow way
    model = preflight(scenario, out, force)
    state = initial_state(scenario, model)
    engine = make_engine(scenario, model)
    helper = compile_ahead(scenario, engine, state)  # a first run with contact: both cores
    times = frame_times(scenario.scene.duration, scenario.simulation.record_rate)
    observers = _observers(scenario, model, engine, state, out, profile) + list(observers)
    view = Run(scenario, model, engine, state)

    def take_frame() -> bool:
        """Show the frame just reached to every observer; True: one stops the run here."""
        view.contacts = engine.contact_loads()
        stops = [observer.frame(view) for observer in observers]
        return any(stops)

    stop = take_frame()
    for observer in observers:
        observer.start(view)
    limit = speed_limit(scenario, state)
    start_position = state.position.copy()
    # the last finite frame's time, positions and cables' rest lengths (with cables only)
    finite_time, finite_position = state.time, start_position.copy()
    finite_rest = engine.cables.rest.copy()
    status, message, error = "running", "", None
    compiling = _Compiling(profile)
    start = _time.perf_counter()
    try:
        with watch_compilation(on_end=compiling.add):
            for t in times[1:]:
                if stop:
                    break
                engine.advance(state, float(t))
                reason = _check(state, limit)
                if reason:
                    limits = analytical_limits(model, start_position, scenario.bending.enabled)
                    if model.cable_count:  # the cables at the last finite frame, as reeled in
                        omega = cable_frequency(model, finite_position, finite_rest)
                        limits = dataclasses.replace(limits, cable_omega=omega,
                                                     cable_time=finite_time)
                    raise _divergence(reason, state, engine.dt, engine.integrator, limits,
                                      scenario.contact.enabled
                                      and scenario.contact.model == "exact")
                if model.cable_count:
                    finite_time, finite_position[:] = state.time, state.position
                    finite_rest[:] = engine.cables.rest
                interrupt.check()  # a stop request the signal's own exception lost
                stop = take_frame()
                if progress is not None:
                    progress(state.time, scenario.scene.duration, _time.perf_counter() - start)
        status = "completed"
    except KeyboardInterrupt as exc:
        interrupt.acted()
        status, message, error = "interrupted", "interrupted by the user", exc
    except DivergenceError as exc:
        status, message, error = "diverged", str(exc), exc
    finally:
        wall = _time.perf_counter() - start
        if status == "running":  # an unexpected error: keep the frames, say so
            status, message = "interrupted", "stopped by an internal error"
        stats = engine.stats()
        attrs = {"message": message, "wall_time_s": wall, "compile_time_s": compiling.seconds,
                 **{f"stats_{k}": v for k, v in stats.items()}}
        with _signals_deferred():  # a second Ctrl-C must not leave the recording half written
            for observer in sorted(observers, key=lambda o: o.finish_order):
                observer.finish(view, status, attrs)
        engine.close()
        stop_helper(helper)
    if error is not None:
        raise error
    recording = next((o for o in observers if isinstance(o, Recording)), None)
    return RunResult(path=None if recording is None else recording.path, status=status,
                     state=state, wall_time_s=wall, compile_time_s=compiling.seconds,
                     stats=stats,
                     frames=0 if recording is None else recording.recorder.frames,
                     **{k: attrs[k] for k in ("outcome", "outcome_time_s", "outcome_reason")
                        if k in attrs})


class _Compiling:
    """The seconds numba spends compiling kernels its cache lacks inside the run loop (a first
    run's step loop, a kernel first called there), kept apart in ``profile`` too."""

    def __init__(self, profile: Profile | None):
        self.seconds, self.profile = 0.0, profile

    def add(self, seconds: float) -> None:
        self.seconds += seconds
        if self.profile is not None:
            self.profile.compiled(seconds)


def _observers(scenario: Scenario, model, engine, state: NetState,
               out: str | os.PathLike | None, profile: Profile | None) -> list[Observer]:
    """The observers of a run, in the order they see each frame: the winch control (its
    wrap trigger acts before the frame is recorded), the recorder, the outcome monitor, the
    thrust control (it starts the burn at the frame that decides the capture) and the tow's
    judge, the reel control (it starts the reel likewise), the profiler."""
    observers: list[Observer] = []
    if scenario.closing.enabled:
        observers.append(WinchControl(scenario))
    samples = None if engine.debris is None else interior_samples(engine.debris)
    if out is not None:
        observers.append(Recording(Recorder(out, model, {
            "scenario": to_toml(scenario),
            "engine": engine.name,
            "integrator": engine.integrator,
            "dt": engine.dt,
            "record_rate": scenario.simulation.record_rate,
            "bending": scenario.bending.enabled,
            "bulletnet_version": _version(),
        }, oriented=state.oriented, debris=engine.debris, interior_samples=samples,
            contact=scenario.contact.enabled, peaks=True,
            reel_threads=0 if engine.arrays.reel is None else engine.arrays.reel.pairs.shape[0])))
    outcome = Outcome(scenario, model, engine, samples) if scenario.outcome.enabled else None
    if outcome is not None:
        observers.append(outcome)
    if scenario.thrust.enabled:
        thrust = ThrustControl(scenario, model, engine,
                               None if outcome is None else outcome.monitor)
        observers.append(thrust)
        if scenario.tow.enabled:
            geometry = (outcome.monitor.geometry if outcome is not None else
                        ScoreGeometry.of(model, samples, engine.debris.center_of_mass))
            observers.append(TowOutcome(scenario, geometry, thrust))
    if scenario.reel.enabled:
        observers.append(ReelControl(scenario, None if outcome is None else outcome.monitor))
    if engine.breakage is not None:
        observers.append(Breakage())
    if profile is not None:
        observers += [Profiling(profile, list(observers)), StepSplit(profile)]
    return observers


def _version() -> str:
    from .. import __version__

    return __version__
