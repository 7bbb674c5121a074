"""The paper's aggregate measures (Sec. 4), computed from recordings only.

- mouth: the net's perimeter nodes projected on x-y (Figs. 4a, 6, 11);
- mouth area (shoelace formula) and mouth diagonal (net corner 0 to net corner Ns^2 - 1, in
  the x-y projection) over time (Fig. 7b);
- time to 90 % deployed: the first time the mouth area reaches 90 % of L^2;
- net height (Eq. 13): z of the innermost node (the mean of the four central nodes for even
  Ns) minus the mean z of the four net corners (Figs. 4b, 7a);
- RMSE per node (Eq. 14) and node-averaged RMSE over time (Eq. 15) between two recordings on
  their common sample times (Tables 2-4, Figs. 5, 8).

Capture (Sec. 5), from recordings with debris and contact:

- first-contact time (to the step, from the run), nodes in contact over time;
- wrap: the fraction of all directions from the debris' centre of mass along which a ray
  meets the net's surface (its mesh quads, two triangles each). A flat 20 m net 10 m away
  covers 0.17; a net wrapped all round, 1. Rays: a Fibonacci sphere of ``directions``;
- the capture score (enclosed fraction, mouth opening, capture quality) over time and the
  outcome (captured, escaped, missed, undecided) with the time it was decided: the run
  loop's own :class:`~bulletnet.analysis.capture_score.OutcomeMonitor` on the recorded frames, under
  the recording's ``[outcome]`` rules (docs/capture.md);
- leave time: the end of the last frame interval with debris contact, when no contact follows
  for at least ``LEAVE_QUIET_S`` to the end of the run;
- the debris' spin before and after: angular velocity [deg/s] at the first and last frame;
- the mechanical energy: the nodes' kinetic energy, the threads' and closing cables'
  elastic energy (a reeled tether's at its recorded length) and the debris' kinetic energy.
  What it leaves out (the nodes' rotation, the bending and contact springs) is never negative
  and zero at the start of a scene, and every force of the model is passive: so it never
  rises above its initial value plus the work of the closing mechanism's winches
  (:func:`winch_work`), of the reel at the chaser (:func:`reel_work`) and of the chaser's
  thrust (:func:`thrust_work`) in a sound run.

Strength (every recording; docs/strength.md), over the elements: the threads (net threads,
corner threads, a bridle's lines, the tether's, by their ends' kinds:
:func:`bulletnet.model.net.thread_kinds`), then the closing cables:

- utilisation: tension over breaking tension, per frame and element (:func:`utilisation`),
  from each element's largest tension since the frame before where the recording has it
  (:func:`peak_tension`);
- the least safety factor of the run, breaking tension over the largest tension, with the
  element, its end nodes and their positions, and the time (:func:`safety`), overall and
  for each kind of element; the elements that reached their breaking tension;
- snap loads: each element's slack -> taut events (taut at a frame, slack at the one
  before) and the peak tension of the taut spell each begins (:func:`snap_loads`).
- with ``strength.breakage`` on, what failed: the count, the first failure's time, kind
  and element, and the elastic energy lost at the failures (:func:`breakage`, from the
  recorded failure times, to the step), and which elements have failed by each frame
  (:func:`failed`).

All from the recorded frames. A recording of the fast or bullet engine carries each
element's largest tension in every step since the frame before (``peak_tension``), and the
strength measures read it: they see every step's tension whatever the record rate, and the
time of a peak is the frame that ends the interval it was reached in. In a recording made
before it was recorded (or of the reference engine) they read the frames' own tensions,
and a peak between two frames is missed (a higher record rate resolves it).
"""

from __future__ import annotations

import numpy as np

from ..common.errors import RecordingError
from ..model.debris import rotation_matrix
from ..model.net import ELEMENT_NAMES, ElementKind, thread_kinds
from ..model.topology import center_nodes, net_corners, perimeter
from ..recording.reader import Recording
from .capture_score import (
    TIME_TOLERANCE,
    OutcomeMonitor,
    ScoreGeometry,
    interior_samples,
    score,
    wrap_fraction,
)
from .tow_score import TowMonitor

LEAVE_QUIET_S = 5.0
"""Contact-free time [s] that must follow the last contact for the net to count as gone."""


def mouth(rec: Recording) -> np.ndarray:
    """Mouth polygon: perimeter nodes in order, x-y only [m], shape (T, 4 Ns - 4, 2)."""
    return rec.position[:, perimeter(rec.nodes_per_side), :2]


def mouth_area(rec: Recording) -> np.ndarray:
    """Area enclosed by the mouth polygon in the x-y plane [m^2], shape (T,)."""
    xy = mouth(rec)
    x, y = xy[..., 0], xy[..., 1]
    return 0.5 * np.abs(np.sum(x * np.roll(y, -1, axis=1) - np.roll(x, -1, axis=1) * y, axis=1))


def mouth_diagonal(rec: Recording) -> np.ndarray:
    """x-y distance between net corner 0 and the opposite corner Ns^2 - 1 [m], shape (T,)."""
    c = net_corners(rec.nodes_per_side)
    return np.linalg.norm(rec.position[:, c[3], :2] - rec.position[:, c[0], :2], axis=1)


def net_height(rec: Recording) -> np.ndarray:
    """Eq. 13: z of the innermost node minus the mean z of the four net corners [m], shape (T,)."""
    ns = rec.nodes_per_side
    z = rec.position[..., 2]
    return z[:, center_nodes(ns)].mean(axis=1) - z[:, net_corners(ns)].mean(axis=1)


def side_length(rec: Recording) -> float:
    """Side L = (Ns - 1) l_mesh of the fully open net [m] (thread 0 is an inner thread)."""
    return (rec.nodes_per_side - 1) * float(rec.rest_length[0])


def deployed_time(rec: Recording, fraction: float = 0.9) -> float | None:
    """First sample time [s] at which the mouth area reaches ``fraction`` of L^2; None if it
    never does."""
    above = np.nonzero(mouth_area(rec) >= fraction * side_length(rec) ** 2)[0]
    return float(rec.time[above[0]]) if above.size else None


def summary(rec: Recording) -> dict:
    """Time series of the aggregate measures, as lists (JSON-ready) with units in the keys
    (of a beam, the cantilever: its tip under ``beam``, :func:`beam_summary`, for the net's);
    the safety margins under ``strength`` (:func:`strength_summary`, and what failed under
    its ``breakage``, :func:`breakage`: None without ``strength.breakage``); with the capture
    measures under ``capture`` for recordings with debris and contact, the burn's and the
    tow's recorded attributes (``thrust_*``, ``tow_*``) under ``tow``, and the reel at the
    chaser under ``reel`` (:func:`reel_summary`) for recordings with one."""
    doc = {"time_s": rec.time.tolist()}
    beam = rec.nodes_per_side == 0  # a beam (the cantilever), not a net: no net measures
    if beam:
        doc["beam"] = beam_summary(rec)
    else:
        doc |= {"mouth_area_m2": mouth_area(rec).tolist(),
                "mouth_diagonal_m": mouth_diagonal(rec).tolist(),
                "net_height_m": net_height(rec).tolist()}
    doc["status"] = rec.status
    doc["strength"] = strength_summary(rec)
    doc["strength"]["breakage"] = breakage(rec)  # what failed; None without breakage
    if beam:
        return doc
    if rec.debris is not None and rec.contacts is not None:
        doc["capture"] = capture_summary(rec)
    tow = {k: v.item() if hasattr(v, "item") else v for k, v in rec.attrs.items()
           if k.startswith(("tow_", "thrust_"))}
    if tow:
        doc["tow"] = tow  # the run's own judgement (docs/recordings.md), units in the keys
    if rec.tether is not None:
        doc["reel"] = reel_summary(rec)
    return doc


def beam_summary(rec: Recording) -> dict:
    """The cantilever's tip (its last node; Fig. 2): ``tip_displacement_m``, its displacement
    from the first frame [m], shape (T, 3); ``euler_bernoulli_m``, the static tip deflection of
    Euler-Bernoulli beam theory under the recorded tip load F and own weight q = rho A g per
    length, F L^3 / (3 E I) + q L^4 / (8 E I) [m], shape (3,) (transverse components: the
    beam lies along x); and ``two_node_model_m``, the two-node model's own, (F + q L / 2)
    L^3 / (3 E I) [m] (half the weight lumped at the tip: docs/model.md)."""
    s = recorded_scene(rec)
    b, material = s.beam, s.materials.net
    area, inertia = np.pi * b.radius**2, np.pi * b.radius**4 / 4.0
    stiffness = material.young_modulus * inertia  # E I [N m^2]
    load = np.array(b.tip_load, dtype=float) * [0.0, 1.0, 1.0]
    weight = material.density * area * np.array(s.scene.gravity) * [0.0, 1.0, 1.0]
    theory = load * b.length**3 / (3 * stiffness) + weight * b.length**4 / (8 * stiffness)
    lumped = (load + weight * b.length / 2) * b.length**3 / (3 * stiffness)
    return {"tip_displacement_m": (rec.position[:, -1] - rec.position[0, -1]).tolist(),
            "euler_bernoulli_m": theory.tolist(), "two_node_model_m": lumped.tolist()}


def common_times(a: Recording, b: Recording, tol: float = 1e-9) -> tuple[np.ndarray, np.ndarray]:
    """Indices (ia, ib) of the sample times the two recordings share (to ``tol`` seconds)."""
    j = np.searchsorted(b.time, a.time)
    j = np.clip(j, 0, b.time.size - 1)
    jm = np.clip(j - 1, 0, b.time.size - 1)
    best = np.where(np.abs(b.time[jm] - a.time) < np.abs(b.time[j] - a.time), jm, j)
    ok = np.abs(b.time[best] - a.time) <= tol
    return np.nonzero(ok)[0], best[ok]


def rmse(a: Recording, b: Recording) -> dict:
    """Eq. 14-15 between two recordings of the same net on their common sample times.

    Returns per-node RMSE arrays ``pos`` [m] and ``vel`` [m/s], shape (N,), their max and
    average over nodes, the node-averaged RMSE over time ``pos_t``/``vel_t`` (Eq. 15), shape
    (T_common,), and the common ``time`` [s]."""
    if a.position.shape[1] != b.position.shape[1]:
        raise RecordingError(
            f"{a.path} has {a.position.shape[1]} nodes, {b.path} has {b.position.shape[1]}: "
            "not the same net")
    ia, ib = common_times(a, b)
    if ia.size < 2:
        raise RecordingError(
            f"{a.path} and {b.path} share " + ("no sample time" if ia.size == 0 else
                                                f"only the sample at {a.time[ia[0]]:g} s")
            + ": nothing to compare (record both at one rate: --record-rate)")
    dx = np.sum((a.position[ia] - b.position[ib]) ** 2, axis=-1)  # (T, N)
    dv = np.sum((a.velocity[ia] - b.velocity[ib]) ** 2, axis=-1)
    pos, vel = np.sqrt(dx.mean(axis=0)), np.sqrt(dv.mean(axis=0))
    return {
        "rmse_pos_max": float(pos.max()), "rmse_pos_avg": float(pos.mean()),
        "rmse_vel_max": float(vel.max()), "rmse_vel_avg": float(vel.mean()),
        "samples": int(ia.size), "time": a.time[ia],
        "pos": pos, "vel": vel,
        "pos_t": np.sqrt(dx.mean(axis=1)), "vel_t": np.sqrt(dv.mean(axis=1)),
    }


def _require(rec: Recording, group: str) -> dict:
    data = getattr(rec, group)
    if data is None:
        raise RecordingError(f"{rec.path}: no /{group} in this recording (a scene without "
                             f"{'debris' if group == 'debris' else 'contact'})")
    return data


def debris_axis(rec: Recording) -> np.ndarray:
    """The debris' long (body y) axis in the world [-], shape (T, 3)."""
    return rotation_matrix(_require(rec, "debris")["orientation"])[..., 1]


def debris_center_of_mass(rec: Recording) -> np.ndarray:
    """World position of the debris' centre of mass [m], shape (T, 3)."""
    d = _require(rec, "debris")
    com = np.asarray(d["attrs"]["center_of_mass"], dtype=float)
    return d["position"] + rotation_matrix(d["orientation"]) @ com


def first_contact_time(rec: Recording) -> float | None:
    """Time of the first node-debris contact [s] (to the step), or None."""
    _require(rec, "contacts")
    t = float(rec.attrs.get("first_contact_s", -1.0))
    if t >= 0:
        return t
    hit = np.nonzero(rec.contacts["count"] > 0)[0]
    return float(rec.time[hit[0]]) if hit.size else None


def nodes_in_contact(rec: Recording) -> np.ndarray:
    """Nodes that touched the debris in each frame's interval [-], shape (T,)."""
    return _require(rec, "contacts")["count"]


def leave_time(rec: Recording) -> float | None:
    """When the net left the debris [s]: the end of the last interval with contact, if at
    least :data:`LEAVE_QUIET_S` without contact follow to the end of the run (to the frame
    times' round-off, as the outcome's quiet time: an escape decided and stopped there has
    left); else None."""
    hit = np.nonzero(nodes_in_contact(rec) > 0)[0]
    if not hit.size or rec.time[-1] - rec.time[hit[-1]] < LEAVE_QUIET_S - TIME_TOLERANCE:
        return None
    return float(rec.time[hit[-1]])


def wrap(rec: Recording, directions: int = 400) -> np.ndarray:
    """Fraction of directions from the debris' centre of mass whose ray meets the net's
    surface [-], shape (T,) (:func:`bulletnet.analysis.capture_score.wrap_fraction`)."""
    origin = debris_center_of_mass(rec)
    return np.array([wrap_fraction(rec.position[k], rec.nodes_per_side, origin[k], directions)
                     for k in range(rec.time.size)])


def score_geometry(rec: Recording) -> ScoreGeometry:
    """The net and debris data of the capture score (:mod:`bulletnet.analysis.capture_score`): the
    points inside the debris recorded with the run (``/debris/interior_samples``), or, for a
    recording without them, drawn again from the scene's debris asset."""
    d = _require(rec, "debris")
    samples = d.get("interior_samples")
    if samples is None:
        from ..model.builder import scene_debris

        samples = interior_samples(scene_debris(recorded_scene(rec)))
    return ScoreGeometry.of(rec, samples, d["attrs"]["center_of_mass"])


def recorded_scene(rec: Recording):
    """The scene a recording ran (its ``scenario`` attribute)."""
    from ..model.scenario import loads

    return loads(str(rec.attrs["scenario"]), f"{rec.path} (scenario attribute)")


def capture_outcome(rec: Recording) -> tuple[np.ndarray, OutcomeMonitor]:
    """The capture score of every frame, columns enclosed fraction, mouth opening and capture
    quality [-], shape (T, 3), and the outcome monitor after the last frame, judged by the
    recording's own ``[outcome]`` rules: the same monitor, on the same frames, as the run's
    (a run that judged itself recorded the same ``outcome`` and ``outcome_time_s``)."""
    d = _require(rec, "debris")
    count = _require(rec, "contacts")["count"]
    monitor = OutcomeMonitor(recorded_scene(rec).outcome, score_geometry(rec))
    scores = np.array([monitor.observe(float(rec.time[k]), rec.position[k], rec.velocity[k],
                                       d["position"][k], d["orientation"][k],
                                       d["velocity"][k], int(count[k]))
                       for k in range(rec.time.size)])
    monitor.finish(rec.status == "completed")
    return scores, monitor


def thrust_profile(rec: Recording):
    """The recorded run's burn (:class:`~bulletnet.model.thrust.ThrustProfile`), from its
    scene's ``[thrust]``, its start ``thrust_start_s`` [s], the axial mode it recorded and
    when a failed tether cut it short (``thrust_cut_s`` [s], -1: never)."""
    from ..model.thrust import ThrustProfile

    profile = ThrustProfile(recorded_scene(rec).thrust, float(rec.attrs["thrust_start_s"]),
                            float(rec.attrs["thrust_axial_frequency_rad_s"]),
                            float(rec.attrs["thrust_damping_ratio"]))
    cut = float(rec.attrs.get("thrust_cut_s", -1.0))
    if cut >= 0.0:
        profile.end = cut
    return profile


def tow_series(rec: Recording) -> dict:
    """The tow's frames, from the burn's start (``thrust_start_s``) on, as the run's tow judge
    saw them (:class:`~bulletnet.sim.tow.TowOutcome`): ``time`` [s], ``thrust`` [N] (the
    profile's mean over the interval to the next frame; none after a failed tether cut the
    burn), ``tension`` [N] (the tether's at the
    chaser, its last thread), ``distance`` [m] (chaser to the debris' centre of mass),
    ``enclosed`` [-] (the capture score's enclosed fraction) and ``rate`` [rad/s] (the
    debris' angular speed), each shape (F,); empty if the burn never started."""
    d = _require(rec, "debris")
    start = float(rec.attrs.get("thrust_start_s", -1.0))
    if "tow_outcome" not in rec.attrs and start < 0:
        raise RecordingError(f"{rec.path}: no tow in this recording (a scene without "
                             "[thrust] and [tow])")
    frames = np.nonzero(rec.time >= start)[0] if start >= 0 else np.zeros(0, dtype=int)
    geometry = score_geometry(rec)
    chaser = debris_center_of_mass(rec)[frames] - rec.position[frames, -1]
    profile = thrust_profile(rec)
    times = rec.time[frames]
    ends = np.append(times[1:], times[-1] + 1.0) if times.size else times
    return {
        "time": times,
        "thrust": np.array([profile.mean(a, b) for a, b in zip(times, ends, strict=True)]),
        "tension": rec.tension[frames, -1],
        "distance": np.linalg.norm(chaser, axis=1),
        "enclosed": np.array([score(rec.position[k], d["position"][k], d["orientation"][k],
                                    geometry).enclosed for k in frames]),
        "rate": np.linalg.norm(d["angular_velocity"][frames], axis=1),
    }


def tow_outcome(rec: Recording, series: dict | None = None) -> TowMonitor:
    """The tow judged again from the recorded frames by the recording's own ``[tow]`` rules
    (:func:`tow_series`, or ``series`` if it is already at hand): the same judge on the same
    frames as the run's, so a run that judged its tow recorded the same ``tow_*``
    attributes."""
    series = tow_series(rec) if series is None else series
    monitor = TowMonitor(recorded_scene(rec).tow)
    for k in range(series["time"].size):
        monitor.update(*(float(series[key][k]) for key in
                         ("time", "tension", "distance", "enclosed", "rate")))
    monitor.finish(rec.status == "completed", float(rec.time[-1]))
    return monitor


def energy(rec: Recording) -> np.ndarray:
    """Mechanical energy [J], shape (T,): the nodes' translational kinetic energy, the
    threads' and closing cables' elastic energy (Eq. 3 springs) and, with debris, its kinetic
    energy (translation of its centre of mass and rotation about it). Leaves out the nodes'
    rotation and the bending and contact springs (see the module doc), and the elements
    that have failed (``strength.breakage``; their energy at the failure, lost, is the
    recording's ``broken_energy_J``)."""
    from ..kernels.axial import axial_energy

    total = 0.5 * np.einsum("n,tna,tna->t", rec.mass, rec.velocity, rec.velocity)
    rest, stiffness = thread_rest_lengths(rec)
    if rec.failure_time is not None:  # a failed thread holds nothing from its failure on
        stiffness = np.where(_failed(rec.time, rec.failure_time), 0.0, stiffness)
    total += axial_energy(rec.position, rec.pairs, rest, stiffness)
    if rec.cables is not None:
        from ..kernels.cable import cable_energy

        c = rec.cables
        rigidity = c["rigidity"]
        if "failure_time" in c:
            rigidity = np.where(_failed(rec.time, c["failure_time"]), 0.0, rigidity)
        total += cable_energy(c["length"], c["rest_length"], rigidity).sum(axis=1)
    if rec.debris is not None:
        d = rec.debris
        rot = rotation_matrix(d["orientation"])
        inertia = rot @ np.asarray(d["attrs"]["inertia"], dtype=float) @ np.swapaxes(rot, 1, 2)
        w = d["angular_velocity"]
        total += 0.5 * float(d["attrs"]["mass"]) * np.einsum("ta,ta->t", d["velocity"],
                                                              d["velocity"])
        total += 0.5 * np.einsum("ta,tab,tb->t", w, inertia, w)
    return total


def failure_times(rec: Recording) -> np.ndarray | None:
    """When each element (the threads, then the closing cables) failed [s], -1 if intact,
    shape (P + C,); None for a recording without breakage."""
    if rec.failure_time is None:
        return None
    cables = np.zeros(0) if rec.cables is None else rec.cables["failure_time"]
    return np.concatenate([rec.failure_time, cables])


def failed(rec: Recording) -> np.ndarray | None:
    """Whether each element (the threads, then the closing cables) has failed by each frame
    [-], bool, shape (T, P + C): after the step it failed in (:func:`failure_times`); None
    for a recording without breakage."""
    times = failure_times(rec)
    return None if times is None else _failed(rec.time, times)


def _failed(time: np.ndarray, failure_time: np.ndarray) -> np.ndarray:
    """Whether each element has failed by each frame [-], shape (T, E), from the frame
    times (T,) and the failure times (E,) [s] (-1: intact): after the step it failed in."""
    return (failure_time >= 0) & (time[:, None] > failure_time)


def winch_work(rec: Recording) -> np.ndarray:
    """Work done by all the closing mechanism's winches so far [J], shape (T,); zero without
    one. The mechanical energy (:func:`energy`) may rise by this much and no more."""
    if rec.cables is None:
        return np.zeros(rec.time.size)
    return rec.cables["work"].sum(axis=1)


def thrust_work(rec: Recording) -> np.ndarray:
    """Work done by the chaser's thrust so far [J], shape (T,); zero without a burn. From the
    frames: over each frame interval the profile's mean force (:func:`tow_series`' thrust)
    times the chaser's displacement along the burn's direction, exact where the force is
    constant over the interval (the steps of a shaped rise are smeared over the interval
    they fall in). The mechanical energy may rise by this, the winches' and the reel's work
    and no more (the HCW forces of ``[orbit]`` are left out: in the removal scene their
    potential changes by about 1 J)."""
    work = np.zeros(rec.time.size)
    start = float(rec.attrs.get("thrust_start_s", -1.0))
    if start < 0:
        return work
    profile = thrust_profile(rec)
    direction = np.asarray(recorded_scene(rec).thrust.direction, dtype=float)
    moved = np.diff(rec.position[:, -1], axis=0) @ (direction / np.linalg.norm(direction))
    force = np.array([profile.mean(a, b)
                      for a, b in zip(rec.time[:-1], rec.time[1:], strict=True)])
    work[1:] = np.cumsum(force * moved)
    return work


def thread_rest_lengths(rec: Recording) -> tuple[np.ndarray, np.ndarray]:
    """Each thread's rest length [m] and axial stiffness [N/m]: the recorded ones, shape
    (P,) each; with a tether reeled at the chaser (``/tether``), at each frame, shape (T, P)
    each, its S threads sharing the deployed length, L / S each, at the stiffness
    E A / (L / S) of their rigidity E A (their recorded k l_0) (:mod:`bulletnet.kernels.reel`)."""
    if rec.tether is None:
        return rec.rest_length, rec.stiffness
    shape = (rec.time.size, rec.pairs.shape[0])
    rest = np.broadcast_to(rec.rest_length, shape).copy()
    stiffness = np.broadcast_to(rec.stiffness, shape).copy()
    threads = rec.tether["threads"]
    rigidity = rec.stiffness[threads] * rec.rest_length[threads]
    rest[:, threads] = rec.tether["length"][:, None] / threads.size
    stiffness[:, threads] = rigidity / rest[:, threads]
    return rest, stiffness


def reel_work(rec: Recording) -> np.ndarray:
    """Work done by the reel at the chaser so far [J], shape (T,) (negative while its brake
    pays out: it takes energy out); zero without one. With :func:`winch_work`, what the
    mechanical energy (:func:`energy`) may rise by."""
    if rec.tether is None:
        return np.zeros(rec.time.size)
    return rec.tether["reel_work"].copy()


def reel_summary(rec: Recording) -> dict:
    """The reel at the chaser (JSON-ready, units in the keys): when it started
    (``start_s``, -1: never), the tether's deployed length at the first and last frames and
    its least and largest, and the reel's work at the end [J]."""
    length = rec.tether["length"]
    return {"start_s": float(rec.attrs.get("reel_start_s", -1.0)),
            "initial_length_m": float(length[0]), "final_length_m": float(length[-1]),
            "least_length_m": float(length.min()), "largest_length_m": float(length.max()),
            "work_J": float(rec.tether["reel_work"][-1])}


def spin(rec: Recording) -> dict:
    """The debris' angular velocity [deg/s] at the first and last frame, (3,) each, and the
    change of its magnitude [deg/s]."""
    w = np.degrees(_require(rec, "debris")["angular_velocity"])
    return {"initial_deg_s": w[0].tolist(), "final_deg_s": w[-1].tolist(),
            "magnitude_change_deg_s": float(np.linalg.norm(w[-1]) - np.linalg.norm(w[0]))}


def energy_gain(rec: Recording) -> float:
    """The largest rise of the mechanical energy above its start and the winches', the
    reel's and the thrust's work over the recorded frames [J] (:func:`energy`,
    :func:`winch_work`, :func:`reel_work`, :func:`thrust_work`); a sound run has none."""
    total = energy(rec)
    return float(np.max(total - total[0] - winch_work(rec) - reel_work(rec)
                        - thrust_work(rec)))


def capture_summary(rec: Recording) -> dict:
    """Capture measures (JSON-ready, units in the keys): first-contact and leave times,
    peak nodes in contact and wrap, the debris' spin change, the largest rise of the
    mechanical energy above its start plus the work done (:func:`energy_gain`; a sound run
    has none), the outcome (:func:`capture_outcome`: ``outcome``, ``outcome_time_s`` when
    decided and
    ``outcome_since_s`` when its condition began, -1 while undecided, and
    ``outcome_reason``), the highest capture quality, and the time series."""
    count = nodes_in_contact(rec)
    wrapped = wrap(rec)
    k = int(np.argmax(wrapped))
    scores, judged = capture_outcome(rec)
    best = int(np.argmax(scores[:, 2]))
    return {
        "first_contact_s": first_contact_time(rec),
        "first_self_contact_s": (float(rec.attrs["first_self_contact_s"])
                                 if rec.attrs.get("first_self_contact_s", -1) >= 0 else None),
        "leave_s": leave_time(rec),
        "max_nodes_in_contact": int(count.max()),
        "max_wrap": float(wrapped[k]), "max_wrap_time_s": float(rec.time[k]),
        "spin": spin(rec),
        "max_energy_gain_J": energy_gain(rec),
        "outcome": judged.outcome, "outcome_time_s": judged.time,
        "outcome_since_s": judged.since, "outcome_reason": judged.reason,
        "max_capture_quality": float(scores[best, 2]),
        "max_capture_quality_time_s": float(rec.time[best]),
        "nodes_in_contact": count.astype(int).tolist(),
        "normal_force_N": rec.contacts["normal_force"].tolist(),
        "wrap": wrapped.tolist(),
        "enclosed_fraction": scores[:, 0].tolist(),
        "mouth_opening": scores[:, 1].tolist(),
        "capture_quality": scores[:, 2].tolist(),
    }


def breaking_tension(rec: Recording) -> np.ndarray:
    """Tension at which each element breaks [N], shape (E,) = (P + C,): the threads', then
    the closing cables', as recorded (``/threads/breaking_tension``,
    ``/cables/breaking_tension``); for a recording made before they were, from its scene
    (the ``scenario`` attribute, with ``[strength]``'s defaults) built again."""
    if rec.breaking_tension is not None:
        cables = [] if rec.cables is None else [rec.cables["breaking_tension"]]
        return np.concatenate([rec.breaking_tension, *cables])
    from ..model.builder import build_model

    model = build_model(recorded_scene(rec))
    if not np.array_equal(model.pairs, rec.pairs):
        raise RecordingError(f"{rec.path}: its scene builds other threads than it recorded; "
                             "cannot tell their strength")
    return np.concatenate([model.breaking_tension, model.cable_breaking_tension])


def element_kinds(rec: Recording) -> np.ndarray:
    """:class:`~bulletnet.model.net.ElementKind` of each element [-], shape (P + C,)."""
    cables = 0 if rec.cables is None else rec.cables["tension"].shape[1]
    return np.concatenate([thread_kinds(rec.pairs, rec.kind),
                           np.full(cables, ElementKind.CABLE, dtype=np.int8)])


def element_tension(rec: Recording) -> np.ndarray:
    """Tension of each element, 0 when slack [N], shape (T, P + C): the threads', then the
    closing cables'."""
    return rec.tension if rec.cables is None else np.hstack([rec.tension,
                                                             rec.cables["tension"]])


def has_peaks(rec: Recording) -> bool:
    """Whether the recording carries each element's largest tension between frames
    (``/threads/peak_tension``, and ``/cables/peak_tension`` with cables)."""
    return rec.peak_tension is not None and (rec.cables is None
                                             or "peak_tension" in rec.cables)


def peak_tension(rec: Recording) -> np.ndarray:
    """Each element's largest tension over the interval ending at each frame [N], shape
    (T, P + C): the threads', then the closing cables' (the larger of the frame's tension
    and every step's since the frame before; the first frame's own). A recording without
    it (:func:`has_peaks`): the frames' tensions (:func:`element_tension`)."""
    if not has_peaks(rec):
        return element_tension(rec)
    return (rec.peak_tension if rec.cables is None
            else np.hstack([rec.peak_tension, rec.cables["peak_tension"]]))


def utilisation(rec: Recording) -> np.ndarray:
    """Largest tension over breaking tension of each element in the interval ending at each
    frame (:func:`peak_tension`; a recording without peaks: at each frame) [-], shape
    (T, P + C) (1: the element is at its strength)."""
    return peak_tension(rec) / breaking_tension(rec)


def element(rec: Recording, index: int, frame: int | None = None) -> dict:
    """Element ``index`` (of the P + C) described, JSON-ready: its ``kind`` in words, its
    ``index`` in ``/threads`` or ``/cables``, its end ``nodes`` (a cable's first and last
    vertex) and, at ``frame``, their ``positions_m`` [m]."""
    kinds = element_kinds(rec)
    threads = rec.pairs.shape[0]
    if index < threads:
        nodes = rec.pairs[index]
    else:
        vertices, start = rec.cables["nodes"], rec.cables["start"]
        cable = index - threads
        nodes = vertices[[start[cable], start[cable + 1] - 1]]
    out = {"kind": ELEMENT_NAMES[ElementKind(kinds[index])],
           "index": int(index if index < threads else index - threads),
           "nodes": [int(n) for n in nodes]}
    if frame is not None:
        out["positions_m"] = rec.position[frame, nodes].tolist()
    return out


def safety(rec: Recording) -> dict:
    """The run's safety margins (JSON-ready): the least safety factor (breaking tension over
    the largest tension, min over the elements) with the element (:func:`element`), the
    ``time_s`` [s], its ``tension_N`` then [N] and its ``breaking_tension_N`` [N] (all None,
    the tension 0, if no element was ever taut); the same for each kind of element
    (``by_kind``, with its ``elements`` count); the ``overloaded_elements`` (at or over
    their breaking tension in some frame), the ``first_overload_s`` [s] (None: none was)
    and the highest utilisation at each frame (``max_utilisation``, (T,)). The tensions are
    the largest since the frame before where the recording has them (:func:`peak_tension`;
    ``between_frames`` True), and a time is then the frame that ends the interval; else the
    frames' own."""
    tension, strength, kinds = peak_tension(rec), breaking_tension(rec), element_kinds(rec)
    util = tension / strength

    def least(columns: np.ndarray) -> dict:
        frame, column = np.unravel_index(np.argmax(util[:, columns]),
                                         (util.shape[0], columns.size))
        index, peak = int(columns[column]), float(util[frame, columns[column]])
        if peak <= 0:
            return {"least_safety_factor": None, "time_s": None, "element": None,
                    "tension_N": 0.0, "breaking_tension_N": None}
        return {"least_safety_factor": 1.0 / peak, "time_s": float(rec.time[frame]),
                "element": element(rec, index, frame),
                "tension_N": float(tension[frame, index]),
                "breaking_tension_N": float(strength[index])}

    over = util >= 1.0
    by_kind = {ELEMENT_NAMES[kind]: {"elements": int(columns.size), **least(columns)}
               for kind in ElementKind if (columns := np.flatnonzero(kinds == kind)).size}
    return {**least(np.arange(kinds.size)), "between_frames": has_peaks(rec),
            "by_kind": by_kind,
            "overloaded_elements": int(over.any(axis=0).sum()),
            "first_overload_s": float(rec.time[np.argmax(over.any(axis=1))])
            if over.any() else None,
            "max_utilisation": util.max(axis=1).tolist()}


def snap_loads(rec: Recording) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Slack -> taut events of each element (taut at a frame, slack at the frame before; an
    element taut at the first frame has had none yet) [-], shape (P + C,); the peak tension
    of each element over the taut spells such events begin [N], shape (P + C,) (0 without
    one); and the frame of that peak [-], shape (P + C,). From the largest tensions between
    frames where the recording has them (:func:`peak_tension`): an element is then taut in
    an interval if it was in any step of it, and an event is an interval with tension after
    one slack throughout."""
    tension = peak_tension(rec)
    taut = tension > 0
    start = taut & ~np.vstack([taut[:1], taut[:-1]])
    in_spell = taut & (np.cumsum(start, axis=0) > 0)
    spell_tension = np.where(in_spell, tension, 0.0)
    return start.sum(axis=0), spell_tension.max(axis=0), spell_tension.argmax(axis=0)


def strength_summary(rec: Recording) -> dict:
    """:func:`safety` with the largest snap load (:func:`snap_loads`; JSON-ready):
    ``snap_events`` in all, and ``largest_snap`` with its ``tension_N`` [N], ``time_s`` [s],
    ``utilisation`` [-], the element and its own ``events``; None without any event."""
    events, peaks, frames = snap_loads(rec)
    doc = safety(rec)
    doc["snap_events"] = int(events.sum())
    doc["largest_snap"] = None
    if events.any():
        index = int(np.argmax(peaks))
        frame = int(frames[index])
        doc["largest_snap"] = {
            "tension_N": float(peaks[index]), "time_s": float(rec.time[frame]),
            "utilisation": float(peaks[index] / breaking_tension(rec)[index]),
            "events": int(events[index]), "element": element(rec, index, frame)}
    return doc


def failures(thread_time: np.ndarray, cable_time: np.ndarray, kinds: np.ndarray,
             energy_J: float) -> dict:
    """What failed (JSON-ready), from each thread's failure time (P,) and each cable's (C,)
    [s] (-1: intact) and the threads' :class:`~bulletnet.model.net.ElementKind` (P,):
    ``broken_threads`` and ``broken_cables`` [-], ``first_break_s`` [s] (-1: none), its
    ``first_break_kind`` (in words; "" if none) and ``first_break_index`` (in ``/threads``
    or ``/cables``; -1 if none), and ``broken_energy_J``, the elastic energy the failed
    elements held when they failed [J]."""
    times = np.concatenate([thread_time, cable_time])
    broken = times >= 0
    out = {"broken_threads": int(np.count_nonzero(thread_time >= 0)),
           "broken_cables": int(np.count_nonzero(cable_time >= 0)),
           "first_break_s": -1.0, "first_break_kind": "", "first_break_index": -1,
           "broken_energy_J": float(energy_J)}
    if broken.any():
        first = int(np.flatnonzero(broken)[np.argmin(times[broken])])
        cable = first >= thread_time.size
        kind = ElementKind.CABLE if cable else ElementKind(int(kinds[first]))
        out.update(first_break_s=float(times[first]), first_break_kind=ELEMENT_NAMES[kind],
                   first_break_index=first - thread_time.size if cable else first)
    return out


def breakage(rec: Recording) -> dict | None:
    """What failed in a run with ``strength.breakage`` on (:func:`failures`, from its
    recorded failure times and attributes); None for a recording without breakage."""
    times = failure_times(rec)
    if times is None:
        return None
    threads = rec.pairs.shape[0]
    return failures(times[:threads], times[threads:], thread_kinds(rec.pairs, rec.kind),
                    float(rec.attrs.get("broken_energy_J", 0.0)))
