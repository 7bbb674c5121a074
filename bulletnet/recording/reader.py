"""Read bulletnet recordings (the layout is documented in :mod:`bulletnet.recording.writer`)."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..common.errors import RecordingError
from .writer import FORMAT_VERSION


@dataclass(frozen=True)
class Recording:
    path: Path
    attrs: dict
    """Root attributes (scenario TOML, engine, integrator, dt [s], status, ...)."""
    time: np.ndarray
    """Sample times [s], shape (T,)."""
    position: np.ndarray
    """Node positions [m], shape (T, N, 3)."""
    velocity: np.ndarray
    """Node velocities [m/s], shape (T, N, 3)."""
    tension: np.ndarray
    """Thread tensions [N], shape (T, P)."""
    shear: np.ndarray
    """Thread shear force magnitudes [N], shape (T, P)."""
    orientation: np.ndarray | None
    """Node orientations, quaternions x, y, z, w [-], shape (T, N, 4); None without bending."""
    mass: np.ndarray
    """Node masses [kg], shape (N,)."""
    radius: np.ndarray
    """Node radii [m], shape (N,)."""
    kind: np.ndarray
    """Node kinds [-], shape (N,)."""
    pairs: np.ndarray
    """Thread end nodes [-], shape (P, 2)."""
    rest_length: np.ndarray
    """Thread rest lengths [m], shape (P,)."""
    stiffness: np.ndarray
    """Thread axial stiffnesses k_a [N/m], shape (P,)."""
    breaking_tension: np.ndarray | None = None
    """Tension at which each thread breaks [N], shape (P,); None in a recording made before
    it was recorded (:func:`bulletnet.analysis.metrics.breaking_tension` then derives it from
    the recording's scene)."""
    peak_tension: np.ndarray | None = None
    """Each thread's largest tension since the frame before [N], shape (T, P): the larger of
    its tension at the frame and of every step's in between; None in a recording made
    before it was recorded."""
    failure_time: np.ndarray | None = None
    """When each thread failed [s], -1 if intact, shape (P,); None without
    ``strength.breakage``."""
    debris: dict | None = None
    """Scenes with debris: ``position`` (T, 3) of the body-frame origin [m], ``orientation``
    (T, 4) quaternions x, y, z, w, ``velocity`` (T, 3) [m/s], ``angular_velocity`` (T, 3)
    [rad/s], ``mesh_vertices`` (V, 3) [m] and ``mesh_faces`` (F, 3) in the body frame, and
    ``attrs`` (mass [kg], inertia [kg m^2], center_of_mass [m], name); else None."""
    contacts: dict | None = None
    """Scenes with contact: ``count`` (T,), ``normal_force`` (T,) [N], ``node_force``
    (T, N) [N], ``self_count`` (T,) (see :mod:`bulletnet.recording.writer`); else None."""
    cables: dict | None = None
    """Scenes with a closing mechanism: ``nodes`` (V,) and ``start`` (C + 1,) (each cable's
    polyline of nodes), ``rigidity`` (C,) E A [N], and per frame ``tension`` (T, C) [N],
    ``length`` (T, C) [m], ``rest_length`` (T, C) [m] and the winches' ``work`` (T, C) [J],
    and ``breaking_tension`` (C,) [N] and ``peak_tension`` (T, C) [N] where recorded,
    ``failure_time`` (C,) [s] with
    breakage (see :mod:`bulletnet.recording.writer`); else None."""
    tether: dict | None = None
    """Scenes with a reel at the chaser: ``threads`` (S,) (the reeled threads in
    ``/threads``, the chaser's last) and per frame the deployed ``length`` (T,) [m] and the
    reel's ``work`` so far, ``reel_work`` (T,) [J] (see :mod:`bulletnet.recording.writer`);
    else None."""

    @property
    def nodes_per_side(self) -> int:
        """Ns [-]."""
        return int(self.attrs["nodes_per_side"])

    @property
    def status(self) -> str:
        return str(self.attrs.get("status", "unknown"))

    def require_net(self, what: str) -> None:
        """A clear :class:`RecordingError` if this is a beam's (the cantilever: Ns = 0), for
        ``what`` needs a net."""
        if self.nodes_per_side == 0:
            raise RecordingError(f"{self.path}: a beam (the cantilever), not a net: no {what}; "
                                 "`bulletnet metrics` gives its tip deflection against beam "
                                 "theory")


def open_recording(path: str | os.PathLike) -> Recording:
    """Load a recording fully into memory; a clear :class:`RecordingError` if it is not one."""
    import h5py

    p = Path(path)
    if not p.is_file():
        raise RecordingError(f"{p}: " + ("a folder, not a recording" if p.is_dir() else
                                         "no such recording"))
    try:
        f = h5py.File(p, "r")
    except OSError as exc:
        # a run killed while writing leaves its SWMR file marked open for write; SWMR readers
        # may open it (only then: SWMR reads of a damaged file retry for a long time)
        if "already open for write" not in str(exc):
            raise RecordingError(f"{p}: not a readable HDF5 file ({exc})") from None
        try:
            f = h5py.File(p, "r", swmr=True)
        except OSError as exc2:
            raise RecordingError(f"{p}: not a readable HDF5 file ({exc2})") from None
    with f:
        if "format_version" not in f.attrs or "nodes/position" not in f:
            raise RecordingError(f"{p}: not a bulletnet recording")
        version = int(f.attrs["format_version"])
        if version > FORMAT_VERSION:
            raise RecordingError(
                f"{p}: recording format {version} is newer than this bulletnet reads "
                f"({FORMAT_VERSION}); upgrade bulletnet")
        try:
            frames = min(f["time"].shape[0], f["nodes/position"].shape[0],
                         f["nodes/velocity"].shape[0], f["threads/tension"].shape[0])
            rec = Recording(
                path=p,
                attrs={k: (v.decode() if isinstance(v, bytes) else v) for k, v in f.attrs.items()},
                time=f["time"][:frames],
                position=f["nodes/position"][:frames],
                velocity=f["nodes/velocity"][:frames],
                tension=f["threads/tension"][:frames],
                shear=f["threads/shear"][:frames],
                orientation=(f["nodes/orientation"][:frames] if "nodes/orientation" in f
                             else None),
                mass=f["nodes/mass"][()],
                radius=f["nodes/radius"][()],
                kind=f["nodes/kind"][()],
                pairs=f["threads/pairs"][()],
                rest_length=f["threads/rest_length"][()],
                stiffness=f["threads/stiffness"][()],
                breaking_tension=(f["threads/breaking_tension"][()]
                                  if "threads/breaking_tension" in f else None),
                peak_tension=(f["threads/peak_tension"][:frames]
                              if "threads/peak_tension" in f else None),
                failure_time=(f["threads/failure_time"][()]
                              if "threads/failure_time" in f else None),
                debris=_group(f, "debris", frames),
                contacts=_group(f, "contacts", frames),
                cables=_group(f, "cables", frames),
                tether=_group(f, "tether", frames),
            )
        except (KeyError, OSError) as exc:
            raise RecordingError(f"{p}: damaged recording ({exc})") from None
    if rec.time.shape[0] == 0:
        raise RecordingError(f"{p}: recording holds no frames")
    return rec


def _group(f, name: str, frames: int) -> dict | None:
    """A group's datasets (time series cut to ``frames``) and its attributes, or None."""
    if name not in f:
        return None
    out = {"attrs": dict(f[name].attrs)}
    for key, ds in f[name].items():
        out[key] = ds[:frames] if ds.maxshape[0] is None else ds[()]
    return out
