"""The capture score and the outcome of a capture, from one frame's arrays: one implementation
for the run loop (the live state, :mod:`bulletnet.sim.loop`) and for recordings
(:mod:`bulletnet.analysis.metrics`), so a recording's outcome recomputes exactly.

The net's nodes here are the Ns^2 net nodes and the four corner masses, indices
0 .. Ns^2 + 3 of a frame's positions (N, 3) [m]; nodes a model appends after them (a tether's)
are ignored. Per frame (docs/capture.md, "Capture score and outcome"):

- **enclosed fraction** E [-]: the share of :data:`SAMPLE_COUNT` points, drawn uniformly inside
  the debris (in its body frame, once, seeded: :func:`interior_samples`), that lie inside the
  convex hull of the net's nodes (scipy.spatial's Qhull). A flat net (a hull without volume)
  encloses nothing. Binomial sampling error: sqrt(E (1 - E) / SAMPLE_COUNT) <= 0.011;
- **mouth opening** M [-]: the largest distance between two perimeter nodes over the deployed
  net's diagonal sqrt(2) L, L = (Ns - 1) l_mesh. 1: the deployed square; 0: the perimeter
  cinched to a point; the folded start 0.25. A perimeter that merely folds over the debris
  (the paper's wrap) stays open by this measure; only gathering it all in (what a closing
  cable does) closes it;
- **capture quality** Q = E (1 - min(M, 1)) [-]: 1 for the debris wholly inside a net whose
  mouth is shut; 0 if nothing is enclosed or the mouth is fully open;
- **wrap** [-] (:func:`wrap_fraction`): the fraction of directions from the debris' centre of
  mass along which a ray meets the net's surface.

:class:`OutcomeMonitor` turns the frames into an outcome with the scene's
:class:`~bulletnet.model.scenario.OutcomeRules`: ``captured``, ``escaped``, ``missed`` or
``undecided``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numba as nb
import numpy as np

from ..kernels.geometry import debris_distance
from ..model.debris import Debris, rotation_matrix
from ..model.scenario import OutcomeRules
from ..model.topology import perimeter

SAMPLE_COUNT = 2000
"""Points sampled inside the debris for the enclosed fraction [-]."""
SAMPLE_SEED = 2016
"""Seed of the sample (the same debris always gets the same points)."""
TIME_TOLERANCE = 1e-9
"""Slack on the hold, quiet and miss times, against the round-off of frame times [s]."""


@nb.njit(cache=True)
def _inside(points, parts, mesh):
    """Whether each body-frame point (M, 3) [m] lies inside the debris' ``parts`` (rows of
    :func:`bulletnet.solver.contact_stage.debris_geometry`): a negative signed distance [-], shape
    (M,)."""
    out = np.empty(points.shape[0], dtype=np.bool_)
    normal, origin, rot = np.empty(3), np.zeros(3), np.eye(3)
    for i in range(points.shape[0]):
        out[i] = debris_distance(points[i], origin, rot, parts, mesh, normal, 0.0) < 0.0
    return out


def interior_samples(debris: Debris, count: int = SAMPLE_COUNT,
                     seed: int = SAMPLE_SEED) -> np.ndarray:
    """``count`` points uniformly distributed inside the debris, body frame [m], shape
    (count, 3): uniform points in the cube about its centre of mass that holds every part,
    kept where the debris' own signed distance (its parts united) is negative. Parts without
    a volume (a mesh given for contact only) are left out; a debris with none has an empty
    sample (0, 3), and encloses nothing."""
    from ..solver.contact_stage import debris_geometry

    solids = tuple(p for p in debris.parts if p.closed)
    if not solids:
        return np.zeros((0, 3))
    rows, mesh = debris_geometry(solids)
    centre = np.asarray(debris.center_of_mass, dtype=float)
    reach = max(p.reach(centre) for p in solids)
    rng = np.random.default_rng(seed)
    kept, found = [], 0
    while found < count:
        points = centre + rng.uniform(-reach, reach, size=(4 * count, 3))
        points = points[_inside(points, rows, mesh)]
        kept.append(points)
        found += len(points)
    return np.vstack(kept)[:count]


@dataclass(frozen=True)
class ScoreGeometry:
    """What the score needs besides a frame: the net's size and masses and the debris'
    sample and centre of mass."""

    nodes_per_side: int
    """Ns [-]."""
    side: float
    """Side L of the deployed net, (Ns - 1) l_mesh [m]."""
    mass: np.ndarray
    """Masses of the net's nodes (net nodes, then corner masses) [kg], shape (Ns^2 + 4,)."""
    samples: np.ndarray
    """Points inside the debris, body frame [m], shape (M, 3) (:func:`interior_samples`)."""
    center_of_mass: np.ndarray
    """The debris' centre of mass, body frame [m], shape (3,)."""

    @classmethod
    def of(cls, net, samples: np.ndarray, center_of_mass) -> ScoreGeometry:
        """The geometry of ``net``, a :class:`~bulletnet.model.net.NetModel` or a
        :class:`~bulletnet.recording.reader.Recording` (its Ns, thread rest lengths [m] (thread 0 an
        inner thread) and node masses [kg]), with the debris' ``samples`` (M, 3) and
        ``center_of_mass`` (3,), body frame [m]."""
        ns = net.nodes_per_side
        return cls(nodes_per_side=ns, side=(ns - 1) * float(net.rest_length[0]),
                   mass=np.asarray(net.mass[:ns * ns + 4], dtype=float),
                   samples=np.asarray(samples, dtype=float),
                   center_of_mass=np.asarray(center_of_mass, dtype=float))

    @property
    def net_nodes(self) -> int:
        """Count of the net's nodes, Ns^2 + 4 [-]."""
        return self.nodes_per_side ** 2 + 4


class Score(NamedTuple):
    """One frame's capture score."""

    enclosed: float
    """Enclosed fraction E [-]."""
    mouth: float
    """Mouth opening M [-]."""
    quality: float
    """Capture quality Q = E (1 - min(M, 1)) [-]."""


def enclosed_fraction(nodes: np.ndarray, samples: np.ndarray, origin: np.ndarray,
                      rotation: np.ndarray) -> float:
    """Share of ``samples`` (M, 3) (body frame [m]) inside the convex hull of ``nodes``
    (K, 3) [m], with the debris' body frame at ``origin`` (3,) [m] turned by ``rotation``
    (3, 3) [-]; 0 for a hull without volume (a flat net) or an empty sample [-]."""
    from scipy.spatial import ConvexHull, QhullError

    if not samples.size:
        return 0.0
    try:
        hull = ConvexHull(nodes)
    except QhullError:  # coplanar or collinear nodes: a hull without volume
        return 0.0
    # the facets' outward planes n.x + b <= 0, turned into the body frame: x = R s + origin
    planes = np.empty_like(hull.equations)
    planes[:, :3] = hull.equations[:, :3] @ rotation
    planes[:, 3] = hull.equations[:, :3] @ origin + hull.equations[:, 3]
    return _share_inside(samples, planes, 1e-9 * max(1.0, float(np.abs(nodes).max())))


@nb.njit(cache=True)
def _share_inside(points, planes, tolerance):
    """Share of ``points`` (M, 3) [m] below every plane n.x + b of ``planes`` (F, 4) (unit n,
    b [m]), to ``tolerance`` [m] [-]."""
    inside = 0
    for i in range(points.shape[0]):
        x, y, z = points[i, 0], points[i, 1], points[i, 2]
        for f in range(planes.shape[0]):
            if planes[f, 0] * x + planes[f, 1] * y + planes[f, 2] * z + planes[f, 3] > tolerance:
                break
        else:
            inside += 1
    return inside / points.shape[0]


@nb.njit(cache=True, error_model="numpy")
def largest_distance(positions, nodes):
    """Largest distance [m] between two of the nodes ``nodes`` (M,) of ``positions`` (N, 3)
    [m]; NaN if a distance is (a NaN position), inf if one is infinite. Each distance as
    scipy's ``pdist`` computes it, sqrt(dx^2 + dy^2 + dz^2) summed in that order, and sqrt
    is monotonic: the same bits as ``pdist(positions[nodes]).max()``, without its import
    (about 0.1 s) or its call."""
    largest, defined = 0.0, True
    for a in range(nodes.shape[0]):
        i = nodes[a]
        x, y, z = positions[i, 0], positions[i, 1], positions[i, 2]
        for b in range(a + 1, nodes.shape[0]):
            j = nodes[b]
            dx, dy, dz = x - positions[j, 0], y - positions[j, 1], z - positions[j, 2]
            s = dx * dx + dy * dy + dz * dz
            defined &= s == s  # (NaN is not equal to itself)
            largest = s if s > largest else largest
    return math.sqrt(largest) if defined else math.nan


def mouth_opening(positions: np.ndarray, nodes_per_side: int, side: float) -> float:
    """Largest distance between two perimeter nodes of ``positions`` (N, 3) [m] over the
    deployed diagonal sqrt(2) ``side`` [m] [-]."""
    return largest_distance(np.ascontiguousarray(positions, dtype=float),
                            perimeter(nodes_per_side)) / (math.sqrt(2.0) * side)


def capture_quality(enclosed: float, mouth: float) -> float:
    """Capture quality Q = E (1 - min(M, 1)) of an enclosed fraction and a mouth opening [-]."""
    return enclosed * (1.0 - min(mouth, 1.0))


def score(positions: np.ndarray, origin: np.ndarray, quaternion: np.ndarray,
          geometry: ScoreGeometry, enclosed_up_to: float = math.inf) -> Score:
    """The capture score of one frame: node positions (N, 3) [m] and the debris' body frame
    at ``origin`` (3,) [m] with orientation ``quaternion`` (x, y, z, w) [-]. The enclosed
    fraction (the net's convex hull, most of a score's cost) only where the mouth opening is
    at most ``enclosed_up_to`` [-], 0.0 elsewhere (for a judge that needs it only there)."""
    mouth = mouth_opening(positions, geometry.nodes_per_side, geometry.side)
    enclosed = 0.0
    if mouth <= enclosed_up_to:
        enclosed = enclosed_fraction(positions[:geometry.net_nodes], geometry.samples,
                                     np.asarray(origin, dtype=float),
                                     rotation_matrix(quaternion))
    return Score(enclosed, mouth, capture_quality(enclosed, mouth))


def receding(position: np.ndarray, velocity: np.ndarray, mass: np.ndarray,
             debris_center: np.ndarray, debris_velocity: np.ndarray) -> bool:
    """Whether the net's centre of mass moves away from the debris' (relative velocity along
    their separation > 0): the net's nodes' positions (K, 3) [m], velocities (K, 3) [m/s] and
    masses (K,) [kg], the debris' centre of mass (3,) [m] and its velocity (3,) [m/s]."""
    total = mass.sum()
    separation = mass @ position / total - debris_center
    return float(separation @ (mass @ velocity / total - debris_velocity)) > 0.0


def all_receding(position: np.ndarray, velocity: np.ndarray, debris_center: np.ndarray,
                 debris_velocity: np.ndarray) -> bool:
    """Whether every node moves away from the debris' centre of mass (each one's relative
    velocity along its own separation > 0): the nodes' positions (K, 3) [m] and velocities
    (K, 3) [m/s], the debris' centre of mass (3,) [m] and its velocity (3,) [m/s]. The test of
    a miss: the centre of mass of a net in flight runs ahead of the bag that first meets the
    debris (the corner masses lead), so it passes the debris' centre while nodes still
    approach it."""
    radial = np.einsum("ij,ij->i", position - debris_center, velocity - debris_velocity)
    return bool((radial > 0.0).all())


class OutcomeMonitor:
    """Judges a capture frame by frame (as a termination condition would), from what a
    frame holds: node positions and velocities, the debris' pose and velocity, and the count
    of nodes that touched the debris since the last frame. Rules (``rules``, times [s]):

    - ``captured``: E >= ``enclosed_fraction`` and M <= ``mouth_opening`` on every frame
      over ``hold_time``;
    - ``escaped``: after a contact, no contact for ``quiet_time`` with the net's centre of
      mass moving away from the debris', the debris not enclosed in a closed net (the
      captured conditions do not hold on that frame);
    - ``missed``: no contact by ``miss_time``; with ``miss_time`` 0, by the end of a
      completed run whose every net node moves away from the debris at its last frame
      (:func:`all_receding`; a run that ends while any node still approaches it, before
      contact was possible, stays undecided);
    - ``undecided``: none of these by the end.

    The first outcome decided is final; :attr:`time` is when it was decided (the frame that
    completed the hold or the quiet time) and :attr:`since` when its condition began (the
    hold's first frame, the last contact); :attr:`reason` says why, in words, once decided or
    finished (:data:`REASONS`)."""

    def __init__(self, rules: OutcomeRules, geometry: ScoreGeometry):
        self.rules = rules
        self.geometry = geometry
        self.outcome = "undecided"
        """``captured``, ``escaped``, ``missed`` or ``undecided``."""
        self.time = -1.0
        """When the outcome was decided [s]; -1 while undecided."""
        self.since = -1.0
        """When the decided outcome's condition began [s]; -1 while undecided."""
        self.reason = ""
        """Why the outcome is what it is (:data:`REASONS`); "" while undecided and running."""
        self._held_from: float | None = None
        self._last_contact: float | None = None
        self._last_time = 0.0
        self._last_past = False

    @property
    def decided(self) -> bool:
        return self.outcome != "undecided"

    def _decide(self, outcome: str, t: float, since: float, reason: str) -> None:
        self.outcome, self.time, self.since = outcome, t, since
        self.reason = REASONS[reason].format(since=since, end=t, miss=self.rules.miss_time)

    def observe(self, t: float, positions: np.ndarray, velocities: np.ndarray,
                origin: np.ndarray, quaternion: np.ndarray, debris_velocity: np.ndarray,
                contacts: int, *, judge_only: bool = False) -> Score | None:
        """Take the frame at time ``t`` [s]: node positions and velocities (N, 3) [m, m/s],
        the debris' body-frame origin (3,) [m], orientation (x, y, z, w) [-] and centre-of-mass
        velocity (3,) [m/s], and the nodes that touched it since the last frame [-]; return
        the frame's :class:`Score`. With ``judge_only`` (a run judging as it goes), compute
        only what the judgement needs and return None: nothing once decided, and the enclosed
        fraction only where the mouth is closed enough for a capture (the same outcome)."""
        g = self.geometry
        if judge_only and self.decided:
            return None
        s = score(positions, origin, quaternion, g,
                  self.rules.mouth_opening if judge_only else math.inf)
        centre = origin + rotation_matrix(quaternion) @ g.center_of_mass
        net = slice(0, g.net_nodes)
        away = receding(positions[net], velocities[net], g.mass, centre, debris_velocity)
        past = (self.rules.miss_time == 0 and self._last_contact is None and contacts == 0
                and all_receding(positions[net], velocities[net], centre, debris_velocity))
        self.update(t, s, contacts, away, past)
        return None if judge_only else s

    def update(self, t: float, s: Score, contacts: int, away: bool, past: bool) -> None:
        """Judge the frame at time ``t`` [s] from its score, the nodes that touched the debris
        since the last frame [-], whether the net's centre of mass moves away from the debris'
        (:func:`receding`: an escape) and whether every one of its nodes does
        (:func:`all_receding`: a miss by the end; needed only while nothing has touched and
        with ``miss_time`` 0, and computed only then)."""
        r = self.rules
        self._last_time, self._last_past = t, past
        if self.decided:
            return
        if contacts > 0:
            self._last_contact = t
        if s.enclosed >= r.enclosed_fraction and s.mouth <= r.mouth_opening:
            if self._held_from is None:
                self._held_from = t
            if t - self._held_from >= r.hold_time - TIME_TOLERANCE:
                self._decide("captured", t, self._held_from, "captured")
                return
        else:
            self._held_from = None
        if self._last_contact is not None:
            # not while enclosed and closed: a debris floating free inside a closed bag has
            # not escaped (the hold goes on, and decides it captured if it lasts)
            if (self._held_from is None and away
                    and t - self._last_contact >= r.quiet_time - TIME_TOLERANCE):
                self._decide("escaped", t, self._last_contact, "escaped")
        elif 0 < r.miss_time <= t + TIME_TOLERANCE:
            self._decide("missed", t, t, "missed by miss_time")

    def finish(self, completed: bool) -> None:
        """The run ended (``completed``: it reached its end, or stopped once decided): a
        completed run that never touched the debris missed it if its rules judge misses by
        the end (``miss_time`` 0) and every net node was moving away from the debris; otherwise an
        undecided outcome gets its :attr:`reason`."""
        if self.decided:
            return
        t, miss = self._last_time, self.rules.miss_time
        if not completed:
            key = "stopped"
        elif self._last_contact is not None:
            key = "touched"
        elif miss > 0:
            key = "before miss_time"
        elif not self._last_past:
            key = "approaching"
        else:
            self._decide("missed", t, t, "missed by the end")
            return
        self.reason = REASONS[key].format(end=t, miss=miss)


REASONS = {
    "captured": "enclosed and closed since {since:.2f} s",
    "escaped": "no contact since {since:.2f} s",
    "missed by miss_time": "no contact by outcome.miss_time, {miss:g} s",
    "missed by the end": "no contact by the end, every net node moving away from the debris",
    "stopped": "the run stopped at {end:.2f} s, before its end",
    "touched": "touched, but neither captured nor escaped by the end, {end:.2f} s",
    "before miss_time": "no contact yet: the run ended at {end:.2f} s, before "
                        "outcome.miss_time, {miss:g} s",
    "approaching": "no contact yet: the run ended at {end:.2f} s with net nodes still "
                   "approaching the debris",
}
"""The reasons an :class:`OutcomeMonitor` gives (its :attr:`~OutcomeMonitor.reason`), by
case; ``{since}`` is when the outcome's condition began, ``{end}`` the last frame's time [s],
``{miss}`` the rules' ``miss_time`` [s]."""


def fibonacci_sphere(count: int) -> np.ndarray:
    """``count`` near-uniform unit vectors, shape (count, 3)."""
    k = np.arange(count) + 0.5
    z = 1.0 - 2.0 * k / count
    phi = np.pi * (1.0 + 5.0**0.5) * k
    r = np.sqrt(1.0 - z * z)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def net_triangles(ns: int) -> np.ndarray:
    """The net surface as triangles of node indices, two per mesh quad, shape (2 (Ns-1)^2, 3)."""
    r, c = np.divmod(np.arange((ns - 1) ** 2), ns - 1)
    a = r * ns + c
    quads = np.stack([a, a + 1, a + ns + 1, a + ns], axis=1)
    return np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])


def wrap_fraction(positions: np.ndarray, ns: int, origin: np.ndarray,
                  directions: int = 400) -> float:
    """Fraction of ``directions`` (a Fibonacci sphere) from ``origin`` (3,) [m] whose ray
    meets the surface of the net of ``positions`` (N, 3) [m] (its mesh quads, two triangles
    each) [-]. A flat 20 m net 10 m away covers 0.17; a net wrapped all round, 1."""
    return _covered(positions - origin, net_triangles(ns), fibonacci_sphere(directions))


CONE_MARGIN = 1e-9
"""Slack [-] of :func:`_cones`' bound on the cosine: far above the round-off of the
intersection test (~1e-15), so that no ray the test would count is skipped."""


@nb.njit(cache=True)
def _cones(points, tri):
    """Each triangle's cone of directions from the origin: (axis (F, 3), least cosine (F,)).
    A direction d through the triangle is a positive combination of its corners' unit
    directions u_k, so with the axis c = sum u_k / |sum u_k| it has c . d >= min_k c . u_k
    where that minimum is >= 0 (|sum a_k u_k| <= sum a_k). Where it is not (a triangle seen
    across more than a right angle), or a corner sits at the origin, the least cosine is -inf:
    every ray is tested."""
    axis = np.zeros((tri.shape[0], 3))
    least = np.full(tri.shape[0], -np.inf)
    unit = np.empty((points.shape[0], 3))  # each point's direction, zero at the origin
    for i in range(points.shape[0]):
        norm = np.sqrt(points[i, 0] ** 2 + points[i, 1] ** 2 + points[i, 2] ** 2)
        for a in range(3):
            unit[i, a] = points[i, a] / norm if norm > 0.0 else 0.0
    for f in range(tri.shape[0]):
        i, j, k = tri[f, 0], tri[f, 1], tri[f, 2]
        sx, sy, sz = (unit[i, 0] + unit[j, 0] + unit[k, 0], unit[i, 1] + unit[j, 1]
                      + unit[k, 1], unit[i, 2] + unit[j, 2] + unit[k, 2])
        norm = np.sqrt(sx * sx + sy * sy + sz * sz)
        if norm == 0.0:
            continue
        cx, cy, cz = sx / norm, sy / norm, sz / norm
        low = np.inf
        for c in (i, j, k):
            if unit[c, 0] == 0.0 and unit[c, 1] == 0.0 and unit[c, 2] == 0.0:
                low = -np.inf  # a corner at the origin: no cone
            low = min(low, cx * unit[c, 0] + cy * unit[c, 1] + cz * unit[c, 2])
        axis[f, 0], axis[f, 1], axis[f, 2] = cx, cy, cz
        if low >= 0.0:
            least[f] = low - CONE_MARGIN
    return axis, least


@nb.njit(cache=True)
def _covered(points, tri, rays):
    """Fraction of ``rays`` (R, 3) from the origin that cross a triangle ``tri`` (F, 3) of
    ``points`` (N, 3) (Moller-Trumbore), each ray tested only against the triangles whose
    cone of directions (:func:`_cones`) may hold it: the same count as testing all."""
    axis, least = _cones(points, tri)
    hits = 0
    for r in range(rays.shape[0]):
        dx, dy, dz = rays[r, 0], rays[r, 1], rays[r, 2]
        for f in range(tri.shape[0]):
            if dx * axis[f, 0] + dy * axis[f, 1] + dz * axis[f, 2] < least[f]:
                continue
            i, j, k = tri[f, 0], tri[f, 1], tri[f, 2]
            ax, ay, az = points[i, 0], points[i, 1], points[i, 2]
            e1x, e1y, e1z = points[j, 0] - ax, points[j, 1] - ay, points[j, 2] - az
            e2x, e2y, e2z = points[k, 0] - ax, points[k, 1] - ay, points[k, 2] - az
            px, py, pz = dy * e2z - dz * e2y, dz * e2x - dx * e2z, dx * e2y - dy * e2x
            det = px * e1x + py * e1y + pz * e1z
            if abs(det) < 1e-15:
                continue
            u = -(ax * px + ay * py + az * pz) / det
            if u < 0.0 or u > 1.0:
                continue
            qx, qy, qz = -(ay * e1z - az * e1y), -(az * e1x - ax * e1z), -(ax * e1y - ay * e1x)
            v = (dx * qx + dy * qy + dz * qz) / det
            if v < 0.0 or u + v > 1.0:
                continue
            if (e2x * qx + e2y * qy + e2z * qz) / det > 0.0:
                hits += 1
                break
    return hits / rays.shape[0]
