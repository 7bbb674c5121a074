"""What a replay shows, as arrays: recordings decimated onto one shared timeline, the capture
groups (debris pose and mesh, contacts) when a recording has them, the paper's measures, the
capture score and outcome, the tow and the failed threads from
:mod:`bulletnet.analysis.metrics`, and the colours and line geometry drawn. No viser here: the
live server and the HTML export both draw from a :class:`Replay`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..analysis import metrics
from ..common.errors import RecordingError, ScenarioError
from ..model.net import ElementKind, NodeKind
from ..recording.reader import Recording, open_recording

PALETTE = ((31, 119, 180), (230, 97, 1), (44, 160, 44), (148, 103, 189))
"""Colour of each recording [RGB 0-255], in the order given: blue, orange, green, purple."""
SLACK = (205, 205, 205)
"""Colour of a slack thread (tension 0) [RGB 0-255]."""
CONTACT = (255, 0, 200)
"""Colour of a node touching the debris [RGB 0-255]."""
FAILED = (215, 25, 28)
"""Colour of a failed thread's stubs [RGB 0-255]."""
SATURATION_PERCENTILE = 99.0
"""Thread colours saturate at this percentile of the positive forces of all recordings [%]."""
STUB = 0.25
"""A failed thread is drawn as two stubs from its end nodes, each this fraction of the
distance between them long [-]."""
SCALES = {"net": (ElementKind.NET, ElementKind.CORNER), "tether": (ElementKind.TETHER,
                                                                  ElementKind.BRIDLE),
          "cables": (ElementKind.CABLE,)}
"""Kinds of element whose tension colours share a scale, by name: the net's threads carry
tens of N where a tow loads the tether with hundreds of N to kN and the winches the closing
cables with up to tens of kN."""
CHASER_SIZE = 2.0
"""Edge of the cube drawn for a free chaser [m]: a symbol, seen from tens of metres; in the
model the chaser is a point mass."""
THRUST_LENGTH = 10.0
"""Length of the thrust arrow at the largest thrust of its recording [m]; shorter in
proportion for less."""


@dataclass(frozen=True)
class DebrisTrack:
    """The debris body over time (``/debris/*``)."""

    position: np.ndarray
    """World position of the body-frame origin [m], shape (T, 3)."""
    wxyz: np.ndarray
    """Orientation of the body frame, quaternion w, x, y, z [-], shape (T, 4)."""
    vertices: np.ndarray
    """Visual mesh vertices in the body frame [m], shape (V, 3)."""
    faces: np.ndarray
    """Visual mesh triangles, vertex indices [-], shape (F, 3)."""


@dataclass(frozen=True)
class ContactTrack:
    """Net-debris contacts over time (``/contacts/*``)."""

    count: np.ndarray
    """Nodes touching the debris [-], shape (T,)."""
    normal_force: np.ndarray
    """Total normal contact force [N], shape (T,)."""
    node_force: np.ndarray
    """Normal contact force on each node [N], shape (T, N)."""


@dataclass(frozen=True)
class TowTrack:
    """The tow (:func:`bulletnet.analysis.metrics.tow_series` and ``tow_outcome``) at the
    track's frames; NaN at the frames before the burn's start."""

    thrust: np.ndarray
    """Thrust, the profile's mean over the interval to the next recorded frame [N], shape
    (T,)."""
    tension: np.ndarray
    """The tether's tension at the chaser [N], shape (T,)."""
    distance: np.ndarray
    """Chaser to the debris' centre of mass [m], shape (T,)."""
    enclosed: np.ndarray
    """The debris' enclosed fraction [-], shape (T,)."""
    direction: np.ndarray
    """Unit direction of the thrust in the scene [-], shape (3,)."""
    safe_distance: float | None
    """``tow.safe_distance`` [m]; None without ``[tow]``."""
    slip_fraction: float | None
    """``tow.enclosed_fraction``, below which the debris has slipped out [-]; None without
    ``[tow]``."""
    outcome: str
    """The tow's outcome and when it was decided, as text; "" without ``[tow]``."""


@dataclass(frozen=True)
class Track:
    """One recording, decimated: the frames a replay draws."""

    label: str
    """File stem and bending on/off, for legends."""
    colour: tuple[int, int, int]
    """This recording's colour [RGB 0-255]."""
    time: np.ndarray
    """Sample times [s], shape (T,)."""
    position: np.ndarray
    """Node positions [m], shape (T, N, 3)."""
    tension: np.ndarray
    """Thread (and cable span) tensions, 0 when slack [N], shape (T, P)."""
    shear: np.ndarray | None
    """Thread shear force magnitudes [N], shape (T, P); None without bending."""
    utilisation: np.ndarray
    """Thread (and cable span) tensions over their breaking tensions [-], shape (T, P)."""
    radius: np.ndarray
    """Node radii [m], shape (N,)."""
    kind: np.ndarray
    """Node kinds (:class:`bulletnet.model.net.NodeKind`) [-], shape (N,)."""
    pairs: np.ndarray
    """End nodes of the threads, then of the closing cables' spans [-], shape (P, 2)."""
    mouth: np.ndarray
    """Mouth polygon, x-y of the perimeter nodes [m], shape (T, 4 Ns - 4, 2)."""
    area: np.ndarray
    """Mouth area [m^2], shape (T,)."""
    height: np.ndarray
    """Net height, Eq. 13 [m], shape (T,)."""
    debris: DebrisTrack | None
    contacts: ContactTrack | None
    score: np.ndarray | None = None
    """Capture score: enclosed fraction, mouth opening, capture quality [-], shape (T, 3);
    None without debris and contacts (:func:`bulletnet.analysis.metrics.capture_outcome`)."""
    outcome: str = ""
    """The capture's outcome and when it was decided, as text; "" without a score."""
    element: np.ndarray | None = None
    """:class:`~bulletnet.model.net.ElementKind` of each segment's element [-], shape (P,)."""
    chaser: bool = False
    """Whether the last node is a free chaser (``tether.chaser_mass`` > 0), drawn as a cube
    of :data:`CHASER_SIZE`."""
    tow: TowTrack | None = None
    """The tow, for a recording whose burn or tow was on; else None."""
    failed: np.ndarray | None = None
    """Whether each segment's element has failed by each frame
    (:func:`bulletnet.analysis.metrics.failed`) [-], bool, shape (T, P); None without
    breakage."""
    failures: np.ndarray | None = None
    """Threads and closing cables failed by each frame [-], shape (T, 2); None without
    breakage."""

    @property
    def quality(self) -> np.ndarray | None:
        """Capture quality [-], shape (T,); None without a score."""
        return None if self.score is None else self.score[:, 2]

    @property
    def corner_masses(self) -> np.ndarray:
        """Indices of the corner masses [-], shape (4,)."""
        return np.nonzero(self.kind == NodeKind.CORNER_MASS)[0]

    @property
    def net_nodes(self) -> np.ndarray:
        """Indices of every node drawn as a sphere: all but the corner masses and a free
        chaser [-]."""
        drawn = self.kind != NodeKind.CORNER_MASS
        drawn[-1] &= not self.chaser
        return np.nonzero(drawn)[0]

    @property
    def breakable(self) -> np.ndarray:
        """Segments whose element fails by the last frame [-], shape (B,)."""
        if self.failed is None:
            return np.zeros(0, dtype=int)
        return np.flatnonzero(self.failed[-1])


@dataclass(frozen=True)
class Replay:
    """Recordings on one timeline: master time k shows frame ``index[r, k]`` of track r."""

    tracks: tuple[Track, ...]
    time: np.ndarray
    """Master sample times, the union of the tracks' [s], shape (K,)."""
    index: np.ndarray
    """Frame of each track at each master time: its last frame at or before it [-],
    shape (R, K)."""
    tension_scale: dict[str, float]
    """Tension at which line colours saturate [N], by kind of line (:data:`SCALES`; those
    some track has)."""
    shear_scale: float | None = None
    """Shear force at which thread colours saturate [N]; None when no track has bending."""

    @property
    def has_debris(self) -> bool:
        return any(t.debris is not None for t in self.tracks)

    @property
    def has_contacts(self) -> bool:
        return any(t.contacts is not None for t in self.tracks)

    @property
    def has_score(self) -> bool:
        return any(t.score is not None for t in self.tracks)

    @property
    def has_bending(self) -> bool:
        return self.shear_scale is not None

    @property
    def has_chaser(self) -> bool:
        return any(t.chaser for t in self.tracks)

    @property
    def has_tow(self) -> bool:
        return any(t.tow is not None for t in self.tracks)

    @property
    def has_breakage(self) -> bool:
        return any(t.failed is not None for t in self.tracks)

    def view_box(self) -> tuple[np.ndarray, np.ndarray]:
        """Lowest and highest corners of what the initial camera frames [m], shape (3,) each:
        the nodes of every recording over its frames up to its last one in contact with the
        debris (all its frames if it has no contact), and the debris' bounding sphere (about
        its body-frame origin) at every recorded pose. After the last contact, a net that did
        not hold the debris drifts off (tens of metres in the 120 s capture): framing that too
        would shrink the debris to a few pixels."""
        points = []
        for t in self.tracks:
            frames = t.time.size
            if t.contacts is not None and np.any(t.contacts.count > 0):
                frames = int(np.nonzero(t.contacts.count > 0)[0][-1]) + 1
            points.append(t.position[:frames].reshape(-1, 3))
            if t.debris is not None:
                reach = float(np.linalg.norm(t.debris.vertices.astype(np.float64),
                                               axis=1).max())
                points += [t.debris.position - reach, t.debris.position + reach]
        return (np.min([p.min(axis=0) for p in points], axis=0),
                np.max([p.max(axis=0) for p in points], axis=0))

    def default_snapshots(self, count: int = 7) -> list[float]:
        """``count`` evenly spaced snapshot times over the replay, as ``bulletnet plot``'s
        [s]."""
        return np.linspace(self.time[0], self.time[-1], count).tolist()

    def frame_at(self, t: float) -> int:
        """Master frame shown at time ``t`` [s]: the last at or before it [-]."""
        k = int(np.searchsorted(self.time, t + 1e-9, side="right")) - 1
        return min(max(k, 0), self.time.size - 1)


def read_capture(rec: Recording, frames: np.ndarray) -> tuple[DebrisTrack | None,
                                                              ContactTrack | None]:
    """The capture groups of ``rec`` at the given frame indices; None where absent."""
    debris = contacts = None
    t = rec.time.size
    if rec.debris is not None:
        d = rec.debris
        try:
            pos, xyzw = d["position"], d["orientation"]
            vertices, faces = d["mesh_vertices"], d["mesh_faces"]
        except KeyError as exc:
            raise RecordingError(f"{rec.path}: damaged capture groups ({exc})") from None
        if pos.shape != (t, 3) or xyzw.shape != (t, 4):
            raise RecordingError(f"{rec.path}: /debris pose has shapes {pos.shape}, "
                                 f"{xyzw.shape}; expected ({t}, 3), ({t}, 4)")
        if vertices.ndim != 2 or vertices.shape[1] != 3 or faces.ndim != 2 \
                or faces.shape[1] != 3 or faces.size == 0 \
                or faces.min() < 0 or faces.max() >= vertices.shape[0]:
            raise RecordingError(f"{rec.path}: /debris mesh is not a triangle mesh "
                                 f"(vertices {vertices.shape}, faces {faces.shape})")
        debris = DebrisTrack(position=pos[frames], wxyz=np.roll(xyzw[frames], 1, axis=1),
                             vertices=vertices.astype(np.float32),
                             faces=faces.astype(np.uint32))
    if rec.contacts is not None:
        c = rec.contacts
        try:
            contacts = ContactTrack(count=c["count"][frames],
                                    normal_force=c["normal_force"][frames],
                                    node_force=c["node_force"][frames])
        except (KeyError, IndexError) as exc:
            raise RecordingError(f"{rec.path}: damaged capture groups ({exc})") from None
    return debris, contacts


def segments(rec: Recording) -> tuple[np.ndarray, np.ndarray]:
    """What a replay draws as line segments: the threads, then the closing cables' spans
    (each with its cable's tension). Their end nodes [-], shape (S, 2), and the element of
    :func:`bulletnet.analysis.metrics.element_tension` (threads, then cables) each belongs
    to [-], shape (S,); the threads alone without cables."""
    threads = rec.pairs.shape[0]
    if rec.cables is None:
        return rec.pairs, np.arange(threads)
    nodes, start = rec.cables["nodes"], rec.cables["start"]
    cable = np.concatenate([np.full(b - a - 1, c) for c, (a, b) in
                            enumerate(zip(start[:-1], start[1:], strict=True))])
    first = np.concatenate([np.arange(a, b - 1) for a, b in zip(start[:-1], start[1:],
                                                                 strict=True)])
    spans = np.stack([nodes[first], nodes[first + 1]], axis=1)
    return (np.concatenate([rec.pairs, spans]),
            np.concatenate([np.arange(threads), threads + cable]))


def _outcome_text(outcome: str, time: float) -> str:
    """An outcome and when it was decided [s] (negative: undecided), for legends."""
    return f"{outcome} at {time:.1f} s" if time >= 0 else outcome


def read_tow(rec: Recording, frames: np.ndarray, scene) -> TowTrack | None:
    """The tow of ``rec`` (its ``scene``) at the given frame indices; None for a recording
    without a burn or a tow."""
    if "tow_outcome" not in rec.attrs and rec.attrs.get("thrust_start_s", -1.0) < 0:
        return None
    series = metrics.tow_series(rec)
    at = np.searchsorted(rec.time, series["time"])  # the recording's frames of the series
    full = {}
    for key in ("thrust", "tension", "distance", "enclosed"):
        full[key] = np.full(rec.time.size, np.nan)
        full[key][at] = series[key]
    safe = slip = None
    outcome = ""
    if scene.tow.enabled:
        judged = metrics.tow_outcome(rec, series)
        safe, slip = judged.rules.safe_distance, judged.rules.enclosed_fraction
        outcome = _outcome_text(judged.outcome, judged.time)
    direction = np.asarray(scene.thrust.direction, dtype=np.float64)
    return TowTrack(**{key: value[frames] for key, value in full.items()},
                    direction=direction / np.linalg.norm(direction), safe_distance=safe,
                    slip_fraction=slip, outcome=outcome)


def make_track(rec: Recording, colour: tuple[int, int, int], every: int) -> Track:
    """``rec`` decimated to every ``every``-th frame (its last frame always kept)."""
    rec.require_net("net replay")
    frames = np.unique(np.append(np.arange(0, rec.time.size, every), rec.time.size - 1))
    bending = rec.orientation is not None
    scene = metrics.recorded_scene(rec)
    debris, contacts = read_capture(rec, frames)
    score, outcome = None, ""
    if debris is not None and contacts is not None:
        scores, judged = metrics.capture_outcome(rec)
        score = scores[frames]
        outcome = _outcome_text(judged.outcome, judged.time if judged.decided else -1.0)
    pairs, element = segments(rec)
    failed = metrics.failed(rec)
    failures = None
    if failed is not None:
        failed = failed[frames]
        threads = rec.pairs.shape[0]
        failures = np.stack([failed[:, :threads].sum(axis=1), failed[:, threads:].sum(axis=1)],
                            axis=1)
        failed = failed[:, element]
    tension = metrics.element_tension(rec)[frames][:, element]
    shear = np.zeros_like(tension)  # cables carry no shear
    shear[:, :rec.shear.shape[1]] = rec.shear[frames]
    return Track(
        label=f"{rec.path.stem} ({'with' if bending else 'no'} bending)",
        colour=colour, time=rec.time[frames], position=rec.position[frames],
        tension=tension, shear=shear if bending else None,
        utilisation=tension / metrics.breaking_tension(rec)[element],
        radius=rec.radius, kind=rec.kind, pairs=pairs,
        mouth=metrics.mouth(rec)[frames], area=metrics.mouth_area(rec)[frames],
        height=metrics.net_height(rec)[frames], debris=debris, contacts=contacts,
        score=score, outcome=outcome,
        element=metrics.element_kinds(rec)[element],
        chaser=bool(rec.kind[-1] == NodeKind.CHASER and scene.tether.chaser_mass > 0),
        tow=read_tow(rec, frames, scene) if debris is not None else None,
        failed=failed, failures=failures)


def _scale(values: list[np.ndarray]) -> float:
    positive = np.concatenate([v[v > 0] for v in values])
    return float(np.percentile(positive, SATURATION_PERCENTILE)) if positive.size else 1.0


def load_replay(paths: list, every: int = 1) -> Replay:
    """Open the recordings (:func:`bulletnet.recording.reader.open_recording`) and put every
    ``every``-th frame of each on one timeline."""
    if not 1 <= len(paths) <= len(PALETTE):
        raise ScenarioError(f"a replay shows 1 to {len(PALETTE)} recordings, got {len(paths)}")
    if every < 1:
        raise ScenarioError(f"--every must be a whole number >= 1, got {every}")
    tracks = tuple(make_track(open_recording(p), c, every)
                   for p, c in zip(paths, PALETTE, strict=False))
    time = np.unique(np.concatenate([t.time for t in tracks]))
    index = np.array([np.clip(np.searchsorted(t.time, time + 1e-9, side="right") - 1,
                              0, t.time.size - 1) for t in tracks])
    shears = [t.shear for t in tracks if t.shear is not None]
    lines = {name: [t.tension[:, np.isin(t.element, kinds)] for t in tracks]
             for name, kinds in SCALES.items()}
    return Replay(tracks=tracks, time=time, index=index,
                  tension_scale={name: _scale(tensions) for name, tensions in lines.items()
                                 if any(v.shape[1] for v in tensions)},
                  shear_scale=_scale(shears) if shears else None)


def tension_scales(track: Track, scales: dict[str, float]) -> np.ndarray:
    """The tension at which each of ``track``'s segments saturates (``scales``:
    :attr:`Replay.tension_scale`) [N], shape (P,)."""
    out = np.empty(track.element.size)
    for name, kinds in SCALES.items():
        lines = np.isin(track.element, kinds)
        if lines.any():
            out[lines] = scales[name]
    return out


def thread_colours(force: np.ndarray, scale, colour: tuple[int, int, int]) -> np.ndarray:
    """Per-vertex colours of threads carrying ``force`` [N], shape (P,): from a light tint of
    ``colour`` at small force to its dark shade at ``scale`` [N] (one for all, or each
    thread's, shape (P,)) and above, by the square root of force / scale (tensions span
    decades); slack (0) grey. uint8 RGB, shape (P, 2, 3)."""
    base = np.asarray(colour, dtype=np.float64)
    light, dark = 0.8 * base + 0.2 * 255.0, 0.45 * base
    ratio = np.sqrt(np.clip(force / scale, 0.0, 1.0))[:, None]
    rgb = light + ratio * (dark - light)
    rgb[force <= 0] = SLACK
    return np.repeat(np.rint(rgb).astype(np.uint8)[:, None, :], 2, axis=1)


def segment_points(track: Track, j: int) -> np.ndarray:
    """The line segments drawn at frame ``j`` [m], shape (P + B, 2, 3): every thread and
    cable span from end node to end node, except the B that fail during the recording
    (:attr:`Track.breakable`), drawn as two segments from their end nodes: intact, the two
    halves; failed, two stubs of :data:`STUB` of the distance between the nodes. The first
    stays in the segment's place, the second is appended."""
    points = track.position[j][track.pairs]
    if track.failed is None:
        return points
    b = track.breakable
    first, second = points[b, 0], points[b, 1]
    length = np.where(track.failed[j, b], STUB, 0.5)[:, None]
    points[b, 1] = first + length * (second - first)
    ends = np.stack([second, second + length * (first - second)], axis=1)
    return np.concatenate([points, ends])


def segment_colours(track: Track, j: int, force: np.ndarray, scale) -> np.ndarray:
    """Per-vertex colours of :func:`segment_points` at frame ``j``: by ``force`` [N], shape
    (P,), on ``scale`` [N] (:func:`thread_colours`), failed ones :data:`FAILED`. uint8 RGB,
    shape (P + B, 2, 3)."""
    rgb = thread_colours(force, scale, track.colour)
    if track.failed is not None:
        rgb[track.failed[j]] = FAILED
    return np.concatenate([rgb, rgb[track.breakable]])


def thrust_arrow(track: Track, j: int) -> np.ndarray | None:
    """The thrust at frame ``j`` as an arrow [m], shape (1, 2, 3): from the face of the
    chaser's cube along the thrust direction, :data:`THRUST_LENGTH` at the recording's
    largest thrust and in proportion below; None while the burn is off."""
    tow = track.tow
    if tow is None or not tow.thrust[j] > 0:
        return None
    start = track.position[j, -1] + 0.5 * CHASER_SIZE * tow.direction
    length = THRUST_LENGTH * tow.thrust[j] / np.nanmax(tow.thrust)
    return np.stack([start, start + length * tow.direction])[None]


def node_colours(track: Track, frame: int, nodes: np.ndarray) -> np.ndarray:
    """Colours of ``nodes`` at ``frame``: the track's colour, :data:`CONTACT` where the node
    touches the debris. uint8 RGB, shape (len(nodes), 3)."""
    rgb = np.tile(np.asarray(track.colour, dtype=np.uint8), (nodes.size, 1))
    if track.contacts is not None:
        rgb[track.contacts.node_force[frame, nodes] > 0] = CONTACT
    return rgb
