"""The 3D scene of a replay on a viser server: per recording, its nodes as spheres at their
radius, its corner masses, its threads as line segments coloured by tension (on a scale per
kind of line: net, tether, closing cables; or shear, or utilisation: tension over breaking
tension, dark at the breaking tension), failed threads as red stubs, the corner masses'
trails, a free chaser as a cube with its thrust as an arrow while the burn is on, and the
debris mesh. Geometry that does not change (sphere mesh, radii, debris mesh) is sent once; a
new frame sends only what moved, and node colours only when the set of nodes in contact
changes.
"""

from __future__ import annotations

import contextlib
import io

import numpy as np

from ..common.errors import BulletnetError
from .replay import (
    CHASER_SIZE,
    Replay,
    Track,
    node_colours,
    segment_colours,
    segment_points,
    tension_scales,
    thrust_arrow,
)

TRAIL_FRAMES = 60
"""Length of the corner masses' trails, in frames of the replay [-]."""
THREAD_WIDTH = 2.0
"""Thread line width on screen [px]."""
THRUST = (230, 145, 0)
"""Colour of the thrust arrow [RGB 0-255]."""



@contextlib.contextmanager
def viser_server(port: int = 0):
    """A viser server on localhost ``port`` (the next free one if taken, any if 0), stopped on
    exit; viser is imported here, on first use, and its banners are kept off stdout."""
    try:
        import viser
    except ImportError:
        raise BulletnetError(
            "the browser replay needs viser: pip install 'bulletnet[view]'") from None
    with contextlib.redirect_stdout(io.StringIO()):
        server = viser.ViserServer(host="127.0.0.1", port=port, verbose=False)
    try:
        yield server
    finally:
        with contextlib.redirect_stdout(io.StringIO()):
            server.stop()


def _sphere():
    import trimesh

    return trimesh.creation.icosphere(subdivisions=2, radius=1.0)


class TrackLayer:
    """One recording's scene nodes under ``/run{r}``, drawn at any of its frames."""

    def __init__(self, scene, replay: Replay, r: int):
        self.track: Track = replay.tracks[r]
        self.force_scale = {"tension": tension_scales(self.track, replay.tension_scale),
                            "shear": replay.shear_scale, "utilisation": 1.0}
        self.colour_by = "tension"
        self.frame = -1
        self._contact_key = None
        track, name = self.track, f"/run{r}"
        sphere = _sphere()
        self.groups = {}
        dark = tuple(int(0.6 * c) for c in track.colour)
        for group, nodes, colour in (("nodes", track.net_nodes, track.colour),
                                     ("corner_masses", track.corner_masses, dark)):
            self.groups[group] = (nodes, colour, scene.add_batched_meshes_simple(
                f"{name}/{group}", sphere.vertices, sphere.faces,
                batched_wxyzs=np.tile([1.0, 0.0, 0.0, 0.0], (nodes.size, 1)),
                batched_positions=track.position[0, nodes],
                batched_scales=track.radius[nodes], batched_colors=colour,
                lod="off", cast_shadow=False, receive_shadow=False))
        self.threads = scene.add_line_segments(
            f"{name}/threads", self._thread_points(0), self._thread_colours(0),
            thickness=THREAD_WIDTH, thickness_units="screen")
        self.trails = scene.add_line_segments(
            f"{name}/trails", self._trail_points(0), dark, thickness=1.5,
            thickness_units="screen")
        self.chaser = self.thrust = None
        if track.chaser:
            self.chaser = scene.add_box(
                f"{name}/chaser", color=dark, dimensions=(CHASER_SIZE,) * 3,
                position=track.position[0, -1], cast_shadow=False, receive_shadow=False)
            if track.tow is not None:
                self.thrust = scene.add_arrows(
                    f"{name}/thrust", np.zeros((1, 2, 3)), THRUST,
                    shaft_radius=CHASER_SIZE / 8, head_radius=CHASER_SIZE / 3,
                    head_length=CHASER_SIZE, visible=False)
        self.debris = None
        if track.debris is not None:
            d = track.debris
            self.debris = scene.add_mesh_simple(
                f"{name}/debris", d.vertices, d.faces, color=(120, 120, 135), opacity=0.85,
                flat_shading=True, wxyz=d.wxyz[0], position=d.position[0])

    def _thread_points(self, j: int) -> np.ndarray:
        return segment_points(self.track, j)

    def _thread_colours(self, j: int) -> np.ndarray:
        force = getattr(self.track, self.colour_by)
        return segment_colours(self.track, j, force[j], self.force_scale[self.colour_by])

    def _trail_points(self, j: int) -> np.ndarray:
        path = self.track.position[max(0, j - TRAIL_FRAMES):j + 1, self.track.corner_masses]
        if path.shape[0] < 2:
            path = np.concatenate([path, path])
        return np.stack([path[:-1], path[1:]], axis=2).reshape(-1, 2, 3)

    def show(self, j: int) -> None:
        """Draw frame ``j`` of this recording: nothing is sent if it is already shown, nor for
        hidden parts (they are brought up to date when shown again)."""
        if j == self.frame:
            return
        self.frame = j
        track = self.track
        if self.groups["nodes"][2].visible:
            if track.contacts is not None:
                touching = tuple(np.nonzero(track.contacts.node_force[j] > 0)[0])
                if touching != self._contact_key:
                    self._contact_key = touching
                    for nodes, _, handle in self.groups.values():
                        handle.batched_colors = node_colours(track, j, nodes)
            for nodes, _, handle in self.groups.values():
                handle.batched_positions = track.position[j, nodes]
        if self.threads.visible:
            self.threads.points = self._thread_points(j)
            self.threads.colors = self._thread_colours(j)
        if self.trails.visible:
            self.trails.points = self._trail_points(j)
        if self.chaser is not None and self.chaser.visible:
            self.chaser.position = track.position[j, -1]
            if self.thrust is not None:
                arrow = thrust_arrow(track, j)
                if arrow is not None:
                    self.thrust.points = arrow
                self.thrust.visible = arrow is not None
        if self.debris is not None and self.debris.visible:
            self.debris.position = track.debris.position[j]
            self.debris.wxyz = track.debris.wxyz[j]

    def set_colour_by(self, quantity: str) -> None:
        """Colour threads by ``tension``, ``utilisation`` or ``shear`` (bending recordings
        only)."""
        if getattr(self.track, quantity) is None or quantity == self.colour_by:
            return
        self.colour_by = quantity
        self.threads.colors = self._thread_colours(self.frame)

    def set_visible(self, part: str, visible: bool) -> None:
        """Show or hide ``nodes`` (with the corner masses), ``threads``, ``trails``,
        ``chaser`` (with the thrust arrow) or ``debris``."""
        handles = {"nodes": [h for _, _, h in self.groups.values()],
                   "threads": [self.threads], "trails": [self.trails],
                   "chaser": [h for h in (self.chaser, self.thrust) if h is not None],
                   "debris": [self.debris] if self.debris is not None else []}[part]
        for handle in handles:
            handle.visible = visible
        if visible:
            frame, self.frame = self.frame, -1
            self.show(frame)


def build_scene(server, replay: Replay) -> list[TrackLayer]:
    """Ground grid, camera on :meth:`Replay.view_box`, and one layer per recording at frame 0."""
    scene = server.scene
    scene.set_up_direction("+z")
    # no shadows (of 2 px threads) and no environment map: both cost much and show little,
    # and a software-rendered browser draws the scene 3x faster without them
    scene.configure_default_lights(cast_shadow=False)
    scene.configure_environment_map(hdri=None)
    scene.add_light_ambient("/ambient", intensity=1.5)
    lo, hi = replay.view_box()
    centre, size = 0.5 * (lo + hi), float(np.max(hi - lo)) or 1.0
    scene.add_grid("/grid", width=2 * size, height=2 * size, cell_size=size / 10,
                   section_size=size / 2, position=(centre[0], centre[1], lo[2]))
    server.initial_camera.look_at = tuple(centre)
    server.initial_camera.position = tuple(centre + size * np.array([0.8, -0.8, 0.6]))
    layers = [TrackLayer(scene, replay, r) for r in range(len(replay.tracks))]
    for layer in layers:
        layer.show(0)
    return layers
