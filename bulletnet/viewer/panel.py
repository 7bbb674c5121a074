"""The mouth panel as SVG (Figs. 6 and 11): the mouth shape (x-y projection of the perimeter
nodes) of every recording at the current time over snapshot outlines at chosen times, then
mouth area, net height (Eq. 13) and, for captures, the capture score (capture quality solid,
enclosed fraction dashed, mouth opening dotted; :mod:`bulletnet.analysis.capture_score`) against
time with a cursor; the legend gives each capture's outcome.

One renderer for both viewers: :meth:`Panel.svg` is the whole figure at a frame (the live
server sends it on each new frame), :meth:`Panel.updates` the attributes that change from
frame to frame (the HTML export ships them and ``web/overlay.js`` applies them).
"""

from __future__ import annotations

from html import escape

import numpy as np

from .replay import Replay

WIDTH = 300
"""Panel width [px]."""
PLOT_HEIGHT = 100
"""Height of each time plot [px]."""
MARGIN = 34
"""Room for axis labels [px]."""
PLOT_GAP = 26
"""Space between two time plots, for the axis labels [px]."""
SCORE_CURVES = ((0, "5 3"), (1, "1.5 2.5"))
"""Score columns drawn thin beside the capture quality: (column of ``Track.score``, SVG dash
pattern): the enclosed fraction dashed, the mouth opening dotted."""


def _attrs(attrs: dict) -> str:
    return " ".join(f'{k}="{escape(str(v))}"' for k, v in attrs.items())


def _points(xy: np.ndarray) -> str:
    return " ".join(f"{x:.1f},{y:.1f}" for x, y in xy)


class _Axes:
    """Linear map from data (x, y) to a pixel box (left, top, width, height)."""

    def __init__(self, box: tuple[float, float, float, float], xlim, ylim):
        self.box, self.xlim, self.ylim = box, xlim, ylim

    def __call__(self, x, y) -> np.ndarray:
        left, top, w, h = self.box
        px = left + (np.asarray(x) - self.xlim[0]) / (self.xlim[1] - self.xlim[0]) * w
        py = top + h - (np.asarray(y) - self.ylim[0]) / (self.ylim[1] - self.ylim[0]) * h
        return np.stack([px, py], axis=-1)

    def frame(self, xlabel: str, ylabel: str) -> list[str]:
        left, top, w, h = self.box
        fmt = "{:.3g}".format
        return [
            f'<rect {_attrs(dict(x=left, y=top, width=w, height=h, fill="none"))} '
            'stroke="#999"/>',
            f'<text x="{left}" y="{top + h + 12}" font-size="10">{fmt(self.xlim[0])}</text>',
            f'<text x="{left + w}" y="{top + h + 12}" font-size="10" text-anchor="end">'
            f"{fmt(self.xlim[1])}</text>",
            f'<text x="{left + w / 2}" y="{top + h + 12}" font-size="10" '
            f'text-anchor="middle">{escape(xlabel)}</text>',
            f'<text x="{left - 3}" y="{top + 9}" font-size="10" text-anchor="end">'
            f"{fmt(self.ylim[1])}</text>",
            f'<text x="{left - 3}" y="{top + h}" font-size="10" text-anchor="end">'
            f"{fmt(self.ylim[0])}</text>",
            f'<text transform="translate({left - 24},{top + h / 2}) rotate(-90)" '
            f'font-size="10" text-anchor="middle">{escape(ylabel)}</text>',
        ]


def _limits(values: list[np.ndarray]) -> tuple[float, float]:
    lo = min(float(v.min()) for v in values)
    hi = max(float(v.max()) for v in values)
    pad = 0.05 * (hi - lo) or 1.0
    return lo - pad, hi + pad


class Panel:
    """The mouth panel of a replay, with mouth snapshots at ``snapshots`` [s]."""

    def __init__(self, replay: Replay, snapshots: list[float]):
        self.replay = replay
        self.snapshots = sorted(snapshots)
        tracks = replay.tracks
        bound = 1.05 * max(float(np.abs(t.mouth).max()) for t in tracks)
        size = WIDTH - MARGIN - 6
        legend = 14 * len(tracks) + 6
        self.mouth_axes = _Axes((MARGIN, legend, size, size), (-bound, bound), (-bound, bound))
        t0, t1 = float(replay.time[0]), float(replay.time[-1])
        tlim = (t0, t1 if t1 > t0 else t0 + 1.0)
        top = legend + size + 24
        plots = [("area", "mouth area [m^2]"), ("height", "net height [m]")]
        if replay.has_score:
            plots.append(("quality", "capture score [-]"))
        self.time_axes = [
            (name, unit, _Axes((MARGIN, top + i * (PLOT_HEIGHT + PLOT_GAP), size, PLOT_HEIGHT),
                               tlim, _limits(self._values(name))))
            for i, (name, unit) in enumerate(plots)]
        self.height = top + len(plots) * (PLOT_HEIGHT + PLOT_GAP) + 18 - PLOT_GAP
        self._still = "".join(self._static())

    def _values(self, name: str) -> list[np.ndarray]:
        """Every value a time plot draws: the tracks' ``name`` series (for the score, all
        its columns)."""
        if name == "quality":
            return [t.score for t in self.replay.tracks if t.score is not None]
        return [getattr(t, name) for t in self.replay.tracks]

    def _static(self) -> list[str]:
        """Everything that does not move: axes, curves against time, snapshots, legend."""
        out = self.mouth_axes.frame("x [m]", "y [m]")
        for r, track in enumerate(self.replay.tracks):
            colour = "rgb({},{},{})".format(*track.colour)
            for s in self.snapshots:
                k = int(np.argmin(np.abs(track.time - s)))
                xy = self.mouth_axes(*track.mouth[k].T)
                out.append(f'<polygon class="snapshot" points="{_points(xy)}" fill="none" '
                           f'stroke="{colour}" stroke-opacity="0.45" stroke-dasharray="4 3"/>')
                if r == 0:
                    out.append(f'<text x="{xy[0, 0]:.1f}" y="{xy[0, 1] + 11:.1f}" '
                               f'font-size="9" fill="#555">{track.time[k]:.2f} s</text>')
            label = track.label + (f": {track.outcome}" if track.outcome else "")
            out.append(f'<text x="4" y="{12 + 14 * r}" font-size="11" '
                       f'fill="{colour}">{escape(label)}</text>')
        for name, unit, axes in self.time_axes:
            out += axes.frame("t [s]", unit)
            for track in self.replay.tracks:
                if getattr(track, name) is None:
                    continue
                colour = "rgb({},{},{})".format(*track.colour)
                out.append(f'<polyline points="{_points(axes(track.time, getattr(track, name)))}"'
                           f' fill="none" stroke-width="1.5" stroke="{colour}"/>')
                if name == "quality":
                    out += [f'<polyline points="{_points(axes(track.time, track.score[:, c]))}" '
                            f'fill="none" stroke-width="1" stroke="{colour}" '
                            f'stroke-dasharray="{dash}"/>' for c, dash in SCORE_CURVES]
        return out

    def _dynamic(self) -> list[tuple[str, str, dict]]:
        """(tag, id, fixed attributes) of the elements :meth:`updates` moves."""
        out = [("text", "time-label", {"x": WIDTH - 4, "y": 12, "font-size": 11,
                                       "text-anchor": "end"})]
        for r, track in enumerate(self.replay.tracks):
            out.append(("polygon", f"mouth-{r}", {
                "fill": "rgb({},{},{})".format(*track.colour), "fill-opacity": 0.12,
                "stroke": "rgb({},{},{})".format(*track.colour), "stroke-width": 2}))
        for name, _, axes in self.time_axes:
            out.append(("line", f"cursor-{name}", {
                "y1": axes.box[1], "y2": axes.box[1] + axes.box[3], "stroke": "#d00"}))
            out.append(("text", f"value-{name}", {
                "x": axes.box[0] + axes.box[2] - 3, "y": axes.box[1] + 11, "font-size": 10,
                "text-anchor": "end"}))
        return out

    def updates(self, k: int) -> dict[str, dict]:
        """Attributes of the moving elements at master frame ``k``, by element id; the key
        ``text`` is the element's text."""
        replay = self.replay
        t = float(replay.time[k])
        out = {"time-label": {"text": f"t = {t:.3f} s"}}
        for r, track in enumerate(replay.tracks):
            out[f"mouth-{r}"] = {"points": _points(self.mouth_axes(*track.mouth[
                replay.index[r, k]].T))}
        for name, unit, axes in self.time_axes:
            x = float(axes(t, 0.0)[0])
            out[f"cursor-{name}"] = {"x1": f"{x:.1f}", "x2": f"{x:.1f}"}
            values = " / ".join("-" if getattr(tr, name) is None
                                else f"{getattr(tr, name)[replay.index[r, k]]:.3g}"
                                for r, tr in enumerate(replay.tracks))
            out[f"value-{name}"] = {"text": f"{values} {unit.split()[-1]}"}
        return out

    def svg(self, k: int) -> str:
        """The whole panel at master frame ``k``, as one ``<svg>`` element."""
        state = self.updates(k)
        moving = []
        for tag, ident, fixed in self._dynamic():
            attrs = dict(fixed, **state[ident])
            text = escape(attrs.pop("text", ""))
            moving.append(f'<{tag} id="{ident}" {_attrs(attrs)}>{text}</{tag}>')
        return (f'<svg id="bulletnet-mouth" xmlns="http://www.w3.org/2000/svg" '
                f'width="{WIDTH}" height="{self.height}" viewBox="0 0 {WIDTH} {self.height}" '
                'font-family="sans-serif">' + self._still + "".join(moving) + "</svg>")
