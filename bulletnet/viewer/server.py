"""The live replay: a viser server on localhost with playback controls, visibility toggles,
the mouth panel and, for a tow, the tow panel. Frames stream: each new frame sends only what
moved (see :mod:`.scene`)."""

from __future__ import annotations

import threading
import time

from ..common import interrupt
from .panel import Panel, TowPanel
from .replay import CHASER_SIZE, FAILED, SLACK, STUB, THRUST_LENGTH, Replay
from .scene import THRUST, build_scene, viser_server

SPEEDS = ("0.1", "0.25", "0.5", "1", "2", "4")
"""Playback speeds offered [simulated s per wall s]."""
TICK = 1.0 / 30.0
"""Playback clock period [s]."""
PANEL_INTERVAL = 0.1
"""Shortest interval between two panels sent while playing [s]."""


class LiveViewer:
    """Scene, controls and playback clock of one replay on a running viser server."""

    def __init__(self, server, replay: Replay, snapshots: list[float]):
        self.server, self.replay = server, replay
        self.layers = build_scene(server, replay)
        self.panel = Panel(replay, snapshots)
        self.tow_panel = TowPanel(replay) if replay.has_tow else None
        self.frame = 0
        self.playing = False
        self.clock = float(replay.time[0])
        self._panel_sent = 0.0
        self._lock = threading.RLock()
        self._build_gui()

    def _build_gui(self) -> None:
        gui, replay = self.server.gui, self.replay
        last = replay.time.size - 1
        with gui.add_folder("Playback"):
            self.slider = gui.add_slider("frame", min=0, max=max(last, 1), step=1,
                                         initial_value=0, disabled=last == 0)
            self.time_text = gui.add_text("time [s]", f"{replay.time[0]:.4f}", disabled=True)
            self.play_button = gui.add_button("Play")
            prev_button, next_button = gui.add_button("Previous frame"), \
                gui.add_button("Next frame")
            self.speed = gui.add_dropdown("speed [x real time]", SPEEDS, initial_value="1")
        self.slider.on_update(lambda _: self.goto(int(self.slider.value)))
        self.play_button.on_click(lambda _: self.toggle_play())
        prev_button.on_click(lambda _: self.step(-1))
        next_button.on_click(lambda _: self.step(+1))
        self.controls = {}
        """Controls that depend on the recordings' groups, by name."""
        with gui.add_folder("Show"):
            parts = ["nodes", "threads", "trails"] + (["chaser"] if replay.has_chaser else []) \
                + (["debris"] if replay.has_debris else [])
            for part in parts:
                box = self.controls[part] = gui.add_checkbox(part, initial_value=True)
                box.on_update(lambda event, part=part: self._show(part, event.target.value))
            colour_by = self.controls["thread colour"] = gui.add_dropdown(
                "thread colour", ("tension", "utilisation")
                + (("shear",) if replay.has_bending else ()), initial_value="tension")
            colour_by.on_update(lambda _: self._colour_by(colour_by.value))
            if replay.has_contacts:
                self.controls["contacts"] = gui.add_text("contacts", "", disabled=True)
        if self.tow_panel is not None:
            with gui.add_folder("Tow"):
                self.tow_html = gui.add_html(self.tow_panel.svg(0))
        with gui.add_folder("Mouth", expand_by_default=self.tow_panel is None):
            self.panel_html = gui.add_html(self.panel.svg(0))
            times = gui.add_text("snapshots [s]", ", ".join(f"{s:g}" for s in
                                                             self.panel.snapshots))
            times.on_update(lambda _: self._set_snapshots(times.value))
            now = gui.add_button("Snapshot at current time")
            now.on_click(lambda _: self._add_snapshot(times))
        gui.add_markdown(self._legend())
        self._update_readouts()

    def _legend(self) -> str:
        replay = self.replay
        lines = [f"**{t.label}**: rgb{t.colour}" for t in replay.tracks]
        scales = ", ".join(f"{scale:.3g} N ({name})" for name, scale in
                           replay.tension_scale.items())
        lines.append(f"Threads: slack rgb{SLACK}; taut light to dark up to {scales} tension"
                     + (f" ({replay.shear_scale:.3g} N shear)" if replay.has_bending else "")
                     + " (utilisation: up to the breaking tension)")
        if replay.has_breakage:
            lines.append(f"Failed threads: two stubs of {STUB:g} of their length, "
                         f"rgb{FAILED}")
        if replay.has_chaser:
            lines.append(f"Chaser: a {CHASER_SIZE:g} m cube (a symbol: a point mass in the "
                         "model)" + (f"; its thrust: an arrow rgb{THRUST}, {THRUST_LENGTH:g} m "
                                     "long at its recording's largest thrust"
                                     if replay.has_tow else ""))
        return "  \n".join(lines)

    def _show(self, part: str, visible: bool) -> None:
        with self._lock:
            for layer in self.layers:
                layer.set_visible(part, visible)

    def _colour_by(self, quantity: str) -> None:
        with self._lock:
            for layer in self.layers:
                layer.set_colour_by(quantity)

    def _set_snapshots(self, text: str) -> None:
        try:
            snapshots = [float(s) for s in text.replace(",", " ").split()]
        except ValueError:
            return  # keep the last valid list while the user types
        with self._lock:
            self.panel = Panel(self.replay, snapshots)
            self.panel_html.content = self.panel.svg(self.frame)

    def _add_snapshot(self, times) -> None:
        t = float(self.replay.time[self.frame])
        times.value = ", ".join(f"{s:g}" for s in sorted(self.panel.snapshots + [t]))
        self._set_snapshots(times.value)

    def _update_readouts(self, throttle: bool = False) -> None:
        now = time.monotonic()
        k = self.frame
        self.time_text.value = f"{self.replay.time[k]:.4f}"
        if "contacts" in self.controls:
            self.controls["contacts"].value = " / ".join(
                f"{int(t.contacts.count[j])} nodes, {t.contacts.normal_force[j]:.3g} N"
                if t.contacts is not None else "-"
                for t, j in zip(self.replay.tracks, self.replay.index[:, k], strict=True))
        if not throttle or now - self._panel_sent >= PANEL_INTERVAL:
            self.panel_html.content = self.panel.svg(k)
            if self.tow_panel is not None:
                self.tow_html.content = self.tow_panel.svg(k)
            self._panel_sent = now

    def goto(self, k: int, playing: bool = False) -> None:
        """Show master frame ``k`` (clamped to the replay); nothing is sent if it is shown.
        While ``playing``, the panels are sent at most every :data:`PANEL_INTERVAL`."""
        with self._lock:
            k = min(max(int(k), 0), self.replay.time.size - 1)
            if k == self.frame:
                return
            self.frame = k
            with self.server.atomic():
                for layer, j in zip(self.layers, self.replay.index[:, k], strict=True):
                    layer.show(int(j))
                self._update_readouts(throttle=playing)
                if int(self.slider.value) != k:
                    self.slider.value = k

    def step(self, delta: int) -> None:
        self.playing = False
        self.play_button.label = "Play"
        self.goto(self.frame + delta)
        self.clock = float(self.replay.time[self.frame])

    def toggle_play(self) -> None:
        self.playing = not self.playing
        self.play_button.label = "Pause" if self.playing else "Play"
        if self.playing:
            self.clock = float(self.replay.time[self.frame])
        else:
            self._update_readouts()  # the panels may lag the frame while playing

    def tick(self, elapsed: float) -> None:
        """Advance the playback clock by ``elapsed`` wall seconds [s] (looping at the end)."""
        if not self.playing:
            return
        t0, t1 = float(self.replay.time[0]), float(self.replay.time[-1])
        self.clock += elapsed * float(self.speed.value)
        if self.clock > t1:
            self.clock = t0
        k = self.replay.frame_at(self.clock)
        if k != self.frame:
            self.goto(k, playing=True)


def serve(replay: Replay, port: int = 8080, snapshots: list[float] | None = None,
          announce=print, stop: threading.Event | None = None) -> None:
    """Serve ``replay`` on localhost until Ctrl-C (or ``stop`` is set); ``announce`` gets the
    URL."""
    with viser_server(port) as server:
        viewer = LiveViewer(server, replay, replay.default_snapshots() if snapshots is None
                            else snapshots)
        announce(f"http://127.0.0.1:{server.get_port()}")
        stop = stop or threading.Event()
        last = time.monotonic()
        while not stop.wait(TICK):
            interrupt.check()  # a stop request the signal's own exception lost
            now = time.monotonic()
            viewer.tick(now - last)
            last = now
