"""The paper's aggregate measures (Sec. 4), computed from recordings only.

- mouth: the net's perimeter nodes projected on x-y (Figs. 4a, 6, 11);
- mouth area (shoelace formula) and mouth diagonal (net corner 0 to net corner Ns^2 - 1, in
  the x-y projection) over time (Fig. 7b);
- time to 90 % deployed: the first time the mouth area reaches 90 % of L^2;
- net height (Eq. 13): z of the innermost node (the mean of the four central nodes for even
  Ns) minus the mean z of the four net corners (Figs. 4b, 7a);
- RMSE per node (Eq. 14) and node-averaged RMSE over time (Eq. 15) between two recordings on
  their common sample times (Tables 2-4, Figs. 5, 8).
"""

from __future__ import annotations

import numpy as np

from .errors import RecordingError
from .recording import Recording
from .topology import center_nodes, net_corners, perimeter


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
    """Time series of the aggregate measures, as lists (JSON-ready) with units in the keys."""
    return {
        "time_s": rec.time.tolist(),
        "mouth_area_m2": mouth_area(rec).tolist(),
        "mouth_diagonal_m": mouth_diagonal(rec).tolist(),
        "net_height_m": net_height(rec).tolist(),
        "status": rec.status,
    }


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
    if ia.size == 0:
        raise RecordingError(f"{a.path} and {b.path} share no sample time")
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
