"""HDF5 recordings, written while the run goes.

Layout (``format_version`` 1; every dataset has a ``units`` attribute):

========================  ============  =====================================================
path                      shape         meaning
========================  ============  =====================================================
/time                     (T,)          sample times [s]
/nodes/position           (T, N, 3)     node positions [m]
/nodes/velocity           (T, N, 3)     node velocities [m/s]
/nodes/mass               (N,)          node masses [kg]
/nodes/radius             (N,)          node sphere radii [m]
/nodes/kind               (N,)          0 inner, 1 edge, 2 corner, 3 corner mass,
                                        4 tether, 5 chaser [-]
/threads/pairs            (P, 2)        end nodes i -> j, 0-based [-]
/threads/rest_length      (P,)          l_0 [m]
/threads/stiffness        (P,)          k_a [N/m]
/threads/damping          (P,)          c_a [N s/m]
/threads/breaking_tension (P,)          tension at which the thread breaks ([strength]) [N]
/threads/tension          (T, P)        axial tension, 0 when slack [N]
/threads/shear            (T, P)        transverse (shear) force magnitude, 0 without bending [N]
/threads/peak_tension     (T, P)        largest tension since the frame before: the frame's
                                        own and every step's in between [N] (the fast and
                                        bullet engines; recordings before it lack it)
/nodes/orientation        (T, N, 4)     unit quaternions x, y, z, w [-] (bending only)
/nodes/angular_velocity   (T, N, 3)     world frame [rad/s] (bending only)
/debris/position          (T, 3)        world position of the body-frame origin (as the
                                        asset defines it) [m] (scenes with debris)
/debris/orientation       (T, 4)        body-frame quaternion x, y, z, w [-]
/debris/velocity          (T, 3)        velocity of the centre of mass [m/s]
/debris/angular_velocity  (T, 3)        world frame [rad/s]
/debris/mesh_vertices     (V, 3)        visual mesh, every part at its pose, body frame [m]
/debris/mesh_faces        (F, 3)        its triangles (vertex indices) [-]
/debris/interior_samples  (M, 3)        points drawn uniformly inside the debris, body
                                        frame [m]: the capture score's sample
                                        (:func:`bulletnet.analysis.capture_score.interior_samples`)
/contacts/count           (T,)          nodes that touched the debris in the interval
                                        ending at the frame [-] (scenes with contact)
/contacts/normal_force    (T,)          total normal force on the debris, mean over
                                        that interval [N]
/contacts/node_force      (T, N)        each node's debris normal force, mean over the
                                        interval [N] (> 0: the node touched)
/contacts/self_count      (T,)          nodes that touched another node in the interval [-]
/cables/nodes             (V,)          closing-cable vertices' nodes, cable after cable [-]
                                        (scenes with a closing mechanism)
/cables/start             (C + 1,)      first vertex of each cable, then V [-]
/cables/rigidity          (C,)          E A [N]
/cables/breaking_tension  (C,)          tension at which the cable breaks [N]
/cables/tension           (T, C)        cable tension, 0 when slack [N]
/cables/peak_tension      (T, C)        largest cable tension since the frame before [N]
/cables/length            (T, C)        length along the cable's polyline [m]
/cables/rest_length       (T, C)        rest length, shortened by the winch [m]
/cables/work              (T, C)        work done by the cable's winch so far [J]
/tether/threads           (S,)          the tether's threads the reel at the chaser reels,
                                        in /threads, the chaser's last [-] (scenes with
                                        [reel])
/tether/length            (T,)          the tether's deployed length at the frame, its
                                        threads' rest lengths summed [m]
/tether/reel_work         (T,)          work done by the reel so far [J] (negative: its
                                        brake took energy out)
/threads/failure_time     (P,)          when the thread failed, -1 if intact [s]
                                        (``strength.breakage`` on; written at the end)
/cables/failure_time      (C,)          when the cable failed, -1 if intact [s]
========================  ============  =====================================================

Contact forces are means over the record interval (impulse / interval): an impact lasts
microseconds and a sample at the frame time would miss it. For the same reason each
element's largest tension over the interval is recorded beside its tension at the frame
(``peak_tension``: the larger of the frame's tension and of the tension of every step
since the frame before, each step's the one it computed its forces from;
:mod:`bulletnet.kernels.peaks`); the first frame's is its own tension.

Root attributes: ``scenario`` (the TOML as run, overrides applied), ``engine``,
``integrator``, ``dt`` [s], ``record_rate`` [Hz] (their units also in the root attribute
``units``), ``bending``, ``status`` (running /
completed / interrupted / diverged), ``message``, ``wall_time_s`` [s] (the run loop's) and
``compile_time_s`` [s] (of it, numba compiling kernels its cache lacked: a first run),
``bulletnet_version``, ``format_version``, ``nodes_per_side``; with contact
``first_contact_s`` and ``first_self_contact_s`` [s] (to the step; -1: none); with
``[outcome]`` on, ``outcome`` (captured, escaped, missed or undecided), ``outcome_time_s``,
when it was decided [s] (-1: undecided), and ``outcome_reason``, why in words
(:data:`bulletnet.analysis.capture_score.REASONS`; recordings before it lack it); with
``[reel]``, ``reel_start_s``, when the reel started [s] (-1: never). ``/debris``
carries
``mass`` [kg], ``inertia`` [kg m^2] (3, 3) about the centre of mass and ``center_of_mass`` [m]
(body frame).

The file is written as ``NAME.part`` in SWMR mode. Frames are kept in memory and written,
one block per dataset, after the first frame and then every ``flush_interval`` seconds of
wall time (a resize and a write per dataset and frame cost ~1 ms a frame), and the file is
renamed to ``NAME`` when the run ends however it ends. After a hard kill the ``.part`` file
still opens (``h5py.File(path, "r", swmr=True)``, or :func:`bulletnet.open_recording`) and
holds every frame up to the last flush, with status ``running``.
"""

from __future__ import annotations

import os
import time as _time
from pathlib import Path

import numpy as np

from ..common.errors import RecordingError
from ..model.net import NetModel
from ..model.state import NetState

FORMAT_VERSION = 1
ROOT_UNITS = "dt: s, record_rate: Hz"
"""The root attribute ``units``: the units of the root attributes whose names do not end in
their unit (the others do: ``wall_time_s``, ``first_contact_s``, ...), as ``/debris``'s."""
FLUSH_INTERVAL_S = 1.0
"""Default wall-clock interval between flushes to disk [s]."""

STATUSES = ("running", "completed", "interrupted", "diverged")


def _reason(exc: OSError) -> str:
    """An OS error in a few words (``No such file or directory``), without HDF5's detail."""
    return os.strerror(exc.errno) if exc.errno else str(exc)


class Recorder:
    """Append frames of a run to an HDF5 file; use as a context manager or call :meth:`close`.
    The file's folder is created if it does not exist. With ``peaks`` every frame also
    carries each element's largest tension since the frame before (:meth:`append`); with
    ``reel_threads`` S > 0, the tether reeled at the chaser (the model's last S threads):
    its deployed length and the reel's work."""

    def __init__(self, path: str | os.PathLike, model: NetModel, attrs: dict,
                 oriented: bool = False, flush_interval: float = FLUSH_INTERVAL_S,
                 debris=None, contact: bool = False,
                 interior_samples: np.ndarray | None = None, peaks: bool = False,
                 reel_threads: int = 0):
        import h5py

        self.path = Path(path)
        self.part_path = self.path.with_name(self.path.name + ".part")
        self.flush_interval = flush_interval
        self.frames = 0
        """Frames appended so far (written or pending) [-]."""
        self._pending: dict[str, list] = {}
        """Frames not yet written, per series."""
        n, p = model.node_count, model.thread_count
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise RecordingError(f"{self.path}: cannot create its folder {self.path.parent}: "
                                 f"{_reason(exc)}") from None
        try:
            f = h5py.File(self.part_path, "w", libver="latest")
        except OSError as exc:
            raise RecordingError(f"{self.path}: cannot write the recording: "
                                 f"{_reason(exc)}") from None
        self._file = f
        for key, value in attrs.items():
            f.attrs[key] = value
        f.attrs["status"] = "running"
        f.attrs["message"] = ""
        f.attrs["units"] = ROOT_UNITS
        f.attrs["format_version"] = FORMAT_VERSION
        f.attrs["nodes_per_side"] = model.nodes_per_side

        def static(name, data, units):
            f.create_dataset(name, data=data).attrs["units"] = units

        def growing(name, shape, units):
            ds = f.create_dataset(name, shape=(0, *shape), maxshape=(None, *shape),
                                  chunks=(16, *shape), dtype="f8")
            ds.attrs["units"] = units
            return ds

        static("nodes/mass", model.mass, "kg")
        static("nodes/radius", model.radius, "m")
        static("nodes/kind", model.kind, "1")
        static("threads/pairs", model.pairs, "1")
        static("threads/rest_length", model.rest_length, "m")
        static("threads/stiffness", model.axial_stiffness, "N/m")
        static("threads/damping", model.axial_damping, "N*s/m")
        static("threads/breaking_tension", model.breaking_tension, "N")
        self._series = {
            "time": growing("time", (), "s"),
            "position": growing("nodes/position", (n, 3), "m"),
            "velocity": growing("nodes/velocity", (n, 3), "m/s"),
            "tension": growing("threads/tension", (p,), "N"),
            "shear": growing("threads/shear", (p,), "N"),
        }
        if peaks:
            self._series["peak_tension"] = growing("threads/peak_tension", (p,), "N")
        if oriented:
            self._series["orientation"] = growing("nodes/orientation", (n, 4), "1")
            self._series["angular_velocity"] = growing("nodes/angular_velocity", (n, 3),
                                                       "rad/s")
        self.debris = debris
        if debris is not None:
            from ..model.debris import visual_mesh

            vertices, faces = visual_mesh(debris)
            static("debris/mesh_vertices", vertices, "m")
            static("debris/mesh_faces", faces, "1")
            if interior_samples is not None:
                static("debris/interior_samples", interior_samples, "m")
            group = f["debris"]
            group.attrs["mass"] = debris.mass
            group.attrs["inertia"] = debris.inertia
            group.attrs["center_of_mass"] = debris.center_of_mass
            group.attrs["units"] = "mass: kg, inertia: kg*m^2, center_of_mass: m"
            group.attrs["name"] = debris.name
            for name, shape, units in (("position", (3,), "m"), ("orientation", (4,), "1"),
                                       ("velocity", (3,), "m/s"),
                                       ("angular_velocity", (3,), "rad/s")):
                self._series["debris_" + name] = growing("debris/" + name, shape, units)
        if model.cable_count:
            static("cables/nodes", model.cable_nodes, "1")
            static("cables/start", model.cable_start, "1")
            static("cables/rigidity", model.cable_rigidity, "N")
            static("cables/breaking_tension", model.cable_breaking_tension, "N")
            for name, units in (("tension", "N"), ("length", "m"), ("rest_length", "m"),
                                ("work", "J")):
                self._series["cable_" + name] = growing("cables/" + name, (model.cable_count,),
                                                        units)
            if peaks:
                self._series["cable_peak_tension"] = growing(
                    "cables/peak_tension", (model.cable_count,), "N")
        if reel_threads:
            static("tether/threads", np.arange(p - reel_threads, p), "1")
            self._series["tether_length"] = growing("tether/length", (), "m")
            self._series["tether_reel_work"] = growing("tether/reel_work", (), "J")
        if contact:
            self._series["contact_count"] = growing("contacts/count", (), "1")
            self._series["contact_force"] = growing("contacts/normal_force", (), "N")
            self._series["contact_node_force"] = growing("contacts/node_force", (n,), "N")
            self._series["contact_self_count"] = growing("contacts/self_count", (), "1")
        f.swmr_mode = True
        self._last_flush = _time.monotonic()

    def append(self, state: NetState, tension: np.ndarray, shear: np.ndarray,
               contacts: dict | None = None, cables: dict | None = None,
               peaks: tuple[np.ndarray, np.ndarray] | None = None,
               reel: dict | None = None) -> None:
        """Add one frame: the state, thread tensions and shear forces (P,) [N], the
        contact forces since the last frame (``node_force``, ``self_force`` (N,) [N], as
        :meth:`bulletnet.engines.base.Engine.contact_loads` gives them), the closing
        cables (as :meth:`~bulletnet.engines.base.Engine.cable_loads` gives them) and, for a
        recorder with peaks, each thread's (P,) and cable's (C,) largest tension in the steps
        since the frame before [N] (as :meth:`~bulletnet.engines.base.Engine.peak_tensions`
        gives them; the larger of them and the frame's own tension is recorded) and the reel
        at the chaser (as :meth:`~bulletnet.engines.base.Engine.reel_loads` gives it)."""
        values = {"time": state.time, "position": state.position, "velocity": state.velocity,
                  "tension": tension, "shear": shear,
                  "orientation": state.orientation, "angular_velocity": state.angular_velocity}
        if self.debris is not None:
            from ..model.debris import OMEGA, QUAT, VELOCITY, body_origin

            values.update(debris_position=body_origin(state.debris, self.debris),
                          debris_orientation=state.debris[QUAT],
                          debris_velocity=state.debris[VELOCITY],
                          debris_angular_velocity=state.debris[OMEGA])
        if contacts is not None:
            values.update(contact_count=np.count_nonzero(contacts["node_force"]),
                          contact_force=contacts["node_force"].sum(),
                          contact_node_force=contacts["node_force"],
                          contact_self_count=np.count_nonzero(contacts["self_force"]))
        if cables is not None:
            values.update({"cable_" + k: v for k, v in cables.items()})
        if reel is not None:
            values.update(tether_length=reel["length"], tether_reel_work=reel["work"])
        if "peak_tension" in self._series:
            thread_peaks, cable_peaks = peaks
            values["peak_tension"] = np.maximum(thread_peaks, tension)
            if cables is not None:
                values["cable_peak_tension"] = np.maximum(cable_peaks, cables["tension"])
        for name in self._series:
            self._pending.setdefault(name, []).append(np.array(values[name], dtype=float))
        self.frames += 1
        if self.frames == 1 or _time.monotonic() - self._last_flush >= self.flush_interval:
            self.flush()

    def flush(self) -> None:
        """Write every frame so far to disk (readable after a hard kill)."""
        for name, ds in self._series.items():
            frames = self._pending.pop(name, [])
            if frames:
                k = ds.shape[0]
                ds.resize(k + len(frames), axis=0)
                ds[k:] = np.stack(frames)
            ds.flush()
        self._last_flush = _time.monotonic()

    def close(self, status: str, message: str = "", datasets: dict | None = None,
              **attrs) -> Path:
        """Flush, mark the run with ``status``, write ``datasets`` (path: (array, units),
        known only at the end: the failure times), close and rename to the final path."""
        import h5py

        assert status in STATUSES
        if self._file is None:
            return self.path
        self.flush()
        self._file.close()
        self._file = None
        with h5py.File(self.part_path, "r+") as f:
            f.attrs["status"] = status
            f.attrs["message"] = message
            for key, value in attrs.items():
                f.attrs[key] = value
            for name, (data, units) in (datasets or {}).items():
                f.create_dataset(name, data=data).attrs["units"] = units
        os.replace(self.part_path, self.path)
        return self.path

    def __enter__(self) -> Recorder:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if self._file is not None:
            self.close("interrupted" if exc_type else "completed",
                       f"{exc_type.__name__}: {exc}" if exc_type else "")
