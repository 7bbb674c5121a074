"""The replay's panels as SVG: time plots of :mod:`bulletnet.analysis.metrics`' measures with a
cursor at the current time and the current values, under a legend of the recordings.

- The mouth panel (Figs. 6 and 11, :class:`Panel`): the mouth shape (x-y projection of the
  perimeter nodes) of every recording at the current time over snapshot outlines at chosen
  times, then mouth area, net height (Eq. 13) and, for captures, the capture score (capture
  quality solid, enclosed fraction dashed, mouth opening dotted;
  :mod:`bulletnet.analysis.capture_score`) against time; the legend gives each capture's
  outcome and, with breakage, the threads failed by the current time.
- The tow panel (:class:`TowPanel`, recordings with a burn or a tow): thrust, the tether's
  tension at the chaser, the chaser's distance to the debris with the safe distance dotted,
  and the enclosed fraction with the slip threshold dotted, from the burn's start; the legend
  gives each tow's outcome.

One renderer for both viewers: :meth:`TimePanel.svg` is the whole figure at a frame (the live
server sends it on each new frame), :meth:`TimePanel.updates` the attributes that change from
frame to frame (the HTML export ships them and ``web/overlay.js`` applies them).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from html import escape

import numpy as np

from .replay import FAILED, Replay, Track

WIDTH = 300
"""Panel width [px]."""
PLOT_HEIGHT = 100
"""Height of each time plot of the mouth panel [px]."""
TOW_PLOT_HEIGHT = 80
"""Height of each time plot of the tow panel [px] (it has four)."""
MARGIN = 34
"""Room for axis labels [px]."""
PLOT_GAP = 26
"""Space between two time plots, for the axis labels [px]."""
ROW = 14
"""Height of a legend row [px]."""
SCORE_CURVES = ((0, "5 3"), (1, "1.5 2.5"))
"""Score columns drawn thin beside the capture quality: (column of ``Track.score``, SVG dash
pattern): the enclosed fraction dashed, the mouth opening dotted."""


def _attrs(attrs: dict) -> str:
    return " ".join(f'{k}="{escape(str(v))}"' for k, v in attrs.items())


def _points(xy: np.ndarray) -> str:
    return " ".join(f"{x:.1f},{y:.1f}" for x, y in xy)


def _number(value: float) -> str:
    """An axis limit: 3 significant digits, whole numbers written out (1316, not 1.32e+03)."""
    text = f"{value:.3g}"
    return f"{value:.0f}" if "e+" in text else text


def _rgb(colour: tuple[int, int, int]) -> str:
    return "rgb({},{},{})".format(*colour)


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
        return [
            f'<rect {_attrs(dict(x=left, y=top, width=w, height=h, fill="none"))} '
            'stroke="#999"/>',
            f'<text x="{left}" y="{top + h + 12}" font-size="10">{_number(self.xlim[0])}</text>',
            f'<text x="{left + w}" y="{top + h + 12}" font-size="10" text-anchor="end">'
            f"{_number(self.xlim[1])}</text>",
            f'<text x="{left + w / 2}" y="{top + h + 12}" font-size="10" '
            f'text-anchor="middle">{escape(xlabel)}</text>',
            f'<text x="{left - 3}" y="{top + 9}" font-size="10" text-anchor="end">'
            f"{_number(self.ylim[1])}</text>",
            f'<text x="{left - 3}" y="{top + h}" font-size="10" text-anchor="end">'
            f"{_number(self.ylim[0])}</text>",
            f'<text transform="translate({left - 24},{top + h / 2}) rotate(-90)" '
            f'font-size="10" text-anchor="middle">{escape(ylabel)}</text>',
        ]


@dataclass(frozen=True)
class Curve:
    """One recording's series in a time plot."""

    track: int
    """Which recording (its colour and frames) [-]."""
    values: np.ndarray
    """The series at the recording's frames, NaN where it has none, shape (T,)."""
    dash: str = ""
    """SVG dash pattern, drawn thin; "" for the solid curve whose value the plot reads
    out."""


@dataclass(frozen=True)
class TimePlot:
    """A plot against time: its curves, the current values read out, dotted levels."""

    name: str
    """Names its cursor's and readout's elements (``cursor-NAME``, ``value-NAME``)."""
    label: str
    """Y axis label, the unit last in brackets."""
    curves: list[Curve]
    fmt: str = "{:.3g}"
    """Format of the values read out."""
    levels: list[tuple[float, str]] = field(default_factory=list)
    """Dotted horizontal lines: (value, what it is)."""
    title: str = ""
    """What is plotted, in words, written in the plot's top left corner."""

    def limits(self) -> tuple[float, float]:
        """Y range: every curve's finite values and the levels, padded by 5 %; from 0 if none
        is negative."""
        values = [c.values[np.isfinite(c.values)] for c in self.curves]
        values = np.concatenate(values + [np.array([v for v, _ in self.levels])])
        if values.size == 0:
            return 0.0, 1.0
        lo, hi = float(values.min()), float(values.max())
        pad = 0.05 * (hi - lo) or 1.0
        return (lo - pad if lo < 0 else 0.0), hi + pad

    def reading(self, r: int, j: int) -> str:
        """Recording ``r``'s value at its frame ``j``, "-" where it has none."""
        for curve in self.curves:
            if curve.track == r and not curve.dash and np.isfinite(curve.values[j]):
                return self.fmt.format(curve.values[j])
        return "-"


class TimePanel:
    """Time plots of a replay stacked from ``top`` [px] down, over ``tlim`` [s], under a
    legend of the recordings (one row each, :meth:`legend`)."""

    svg_id = "bulletnet-panel"
    """The ``<svg>`` element's id."""
    time_id = "time-label"
    """Id of the current time's text."""
    plot_height = PLOT_HEIGHT
    """Height of each time plot [px]."""

    def __init__(self, replay: Replay, plots: list[TimePlot], top: float,
                 tlim: tuple[float, float]):
        self.replay = replay
        size = WIDTH - MARGIN - 6
        if tlim[1] <= tlim[0]:
            tlim = (tlim[0], tlim[0] + 1.0)
        h = self.plot_height
        self.time_axes = [(plot, _Axes((MARGIN, top + i * (h + PLOT_GAP), size, h), tlim,
                                       plot.limits())) for i, plot in enumerate(plots)]
        self.height = top + len(plots) * (h + PLOT_GAP) + 18 - PLOT_GAP
        self._still = "".join(self._static())

    def legend(self, track: Track) -> str:
        """A recording's row of the legend."""
        return track.label

    def _static(self) -> list[str]:
        """Everything that does not move: legend, axes, levels, curves against time."""
        tracks = self.replay.tracks
        out = [f'<text x="4" y="{12 + ROW * r}" font-size="11" fill="{_rgb(track.colour)}">'
               f"{escape(self.legend(track))}</text>" for r, track in enumerate(tracks)]
        for plot, axes in self.time_axes:
            out += axes.frame("t [s]", plot.label)
            left, top, w, _ = axes.box
            if plot.title:
                out.append(f'<text x="{left + 3}" y="{top + 11}" font-size="9" fill="#555">'
                           f"{escape(plot.title)}</text>")
            for value, what in plot.levels:
                y = float(axes(axes.xlim[0], value)[1])
                out += [f'<line x1="{left}" x2="{left + w}" y1="{y:.1f}" y2="{y:.1f}" '
                        'stroke="#555" stroke-dasharray="1.5 2.5"/>',
                        f'<text x="{left + 3}" y="{y - 2:.1f}" font-size="9" fill="#555">'
                        f"{escape(what)}</text>"]
            for curve in plot.curves:
                track = tracks[curve.track]
                finite = np.isfinite(curve.values)
                xy = axes(track.time[finite], curve.values[finite])
                style = (f'stroke-width="1" stroke-dasharray="{curve.dash}"' if curve.dash
                         else 'stroke-width="1.5"')
                out.append(f'<polyline points="{_points(xy)}" fill="none" {style} '
                           f'stroke="{_rgb(track.colour)}"/>')
        return out

    def _dynamic(self) -> list[tuple[str, str, dict]]:
        """(tag, id, fixed attributes) of the elements :meth:`updates` moves."""
        out = [("text", self.time_id, {"x": WIDTH - 4, "y": 12, "font-size": 11,
                                       "text-anchor": "end"})]
        for plot, axes in self.time_axes:
            out.append(("line", f"cursor-{plot.name}", {
                "y1": axes.box[1], "y2": axes.box[1] + axes.box[3], "stroke": "#d00"}))
            out.append(("text", f"value-{plot.name}", {
                "x": axes.box[0] + axes.box[2] - 3, "y": axes.box[1] + 11, "font-size": 10,
                "text-anchor": "end"}))
        return out

    def updates(self, k: int) -> dict[str, dict]:
        """Attributes of the moving elements at master frame ``k``, by element id; the key
        ``text`` is the element's text. A cursor outside its plot's time range is hidden."""
        replay = self.replay
        t = float(replay.time[k])
        out = {self.time_id: {"text": f"t = {t:.3f} s"}}
        for plot, axes in self.time_axes:
            x = float(axes(t, 0.0)[0])
            inside = axes.xlim[0] <= t <= axes.xlim[1]
            out[f"cursor-{plot.name}"] = {"x1": f"{x:.1f}", "x2": f"{x:.1f}",
                                          "visibility": "visible" if inside else "hidden"}
            values = " / ".join(plot.reading(r, int(replay.index[r, k]))
                                for r in range(len(replay.tracks)))
            out[f"value-{plot.name}"] = {"text": f"{values} {plot.label.split()[-1]}"}
        return out

    def svg(self, k: int) -> str:
        """The whole panel at master frame ``k``, as one ``<svg>`` element."""
        state = self.updates(k)
        moving = []
        for tag, ident, fixed in self._dynamic():
            attrs = dict(fixed, **state[ident])
            text = escape(attrs.pop("text", ""))
            moving.append(f'<{tag} id="{ident}" {_attrs(attrs)}>{text}</{tag}>')
        return (f'<svg id="{self.svg_id}" xmlns="http://www.w3.org/2000/svg" '
                f'width="{WIDTH}" height="{self.height}" viewBox="0 0 {WIDTH} {self.height}" '
                'font-family="sans-serif">' + self._still + "".join(moving) + "</svg>")


def _timeline(replay: Replay) -> tuple[float, float]:
    return float(replay.time[0]), float(replay.time[-1])


class Panel(TimePanel):
    """The mouth panel of a replay, with mouth snapshots at ``snapshots`` [s]."""

    svg_id = "bulletnet-mouth"

    def __init__(self, replay: Replay, snapshots: list[float]):
        self.replay = replay
        self.snapshots = sorted(snapshots)
        tracks = replay.tracks
        bound = 1.05 * max(float(np.abs(t.mouth).max()) for t in tracks)
        size = WIDTH - MARGIN - 6
        legend = ROW * (len(tracks) + replay.has_breakage) + 6
        self.mouth_axes = _Axes((MARGIN, legend, size, size), (-bound, bound), (-bound, bound))
        plots = [TimePlot("area", "mouth area [m^2]",
                          [Curve(r, t.area) for r, t in enumerate(tracks)]),
                 TimePlot("height", "net height [m]",
                          [Curve(r, t.height) for r, t in enumerate(tracks)])]
        if replay.has_score:
            plots.append(TimePlot("quality", "capture score [-]", [
                Curve(r, t.score[:, column], dash)
                for r, t in enumerate(tracks) if t.score is not None
                for column, dash in ((2, ""), *SCORE_CURVES)]))
        super().__init__(replay, plots, legend + size + 24, _timeline(replay))

    def legend(self, track: Track) -> str:
        return track.label + (f": {track.outcome}" if track.outcome else "")

    def _static(self) -> list[str]:
        out = self.mouth_axes.frame("x [m]", "y [m]")
        for r, track in enumerate(self.replay.tracks):
            for s in self.snapshots:
                k = int(np.argmin(np.abs(track.time - s)))
                xy = self.mouth_axes(*track.mouth[k].T)
                out.append(f'<polygon class="snapshot" points="{_points(xy)}" fill="none" '
                           f'stroke="{_rgb(track.colour)}" stroke-opacity="0.45" '
                           'stroke-dasharray="4 3"/>')
                if r == 0:
                    out.append(f'<text x="{xy[0, 0]:.1f}" y="{xy[0, 1] + 11:.1f}" '
                               f'font-size="9" fill="#555">{track.time[k]:.2f} s</text>')
        return out + super()._static()

    def _dynamic(self) -> list[tuple[str, str, dict]]:
        out = super()._dynamic()
        for r, track in enumerate(self.replay.tracks):
            out.append(("polygon", f"mouth-{r}", {
                "fill": _rgb(track.colour), "fill-opacity": 0.12, "stroke": _rgb(track.colour),
                "stroke-width": 2}))
        if self.replay.has_breakage:
            out.append(("text", "failed-count", {
                "x": 4, "y": 12 + ROW * len(self.replay.tracks), "font-size": 11,
                "fill": _rgb(FAILED)}))
        return out

    def updates(self, k: int) -> dict[str, dict]:
        replay = self.replay
        out = super().updates(k)
        for r, track in enumerate(replay.tracks):
            out[f"mouth-{r}"] = {"points": _points(self.mouth_axes(*track.mouth[
                replay.index[r, k]].T))}
        if replay.has_breakage:
            counts = []
            for track, j in zip(replay.tracks, replay.index[:, k], strict=True):
                if track.failures is None:
                    counts.append("-")
                    continue
                threads, cables = track.failures[j]
                counts.append(f"{threads}" + (f" + {cables} cables" if cables else ""))
            out["failed-count"] = {"text": "failed threads: " + " / ".join(counts)}
        return out


class TowPanel(TimePanel):
    """The tow panel of a replay with a burn or a tow (:attr:`Replay.has_tow`), over the time
    from the earliest burn's start to the end (the whole replay if no burn started)."""

    svg_id = "bulletnet-tow"
    time_id = "tow-time-label"
    plot_height = TOW_PLOT_HEIGHT

    def __init__(self, replay: Replay):
        tows = [(r, t.tow) for r, t in enumerate(replay.tracks) if t.tow is not None]
        starts = [float(replay.tracks[r].time[np.isfinite(tow.thrust)][0])
                  for r, tow in tows if np.isfinite(tow.thrust).any()]
        tlim = (min(starts), float(replay.time[-1])) if starts else _timeline(replay)

        def curves(key: str) -> list[Curve]:
            return [Curve(r, getattr(tow, key)) for r, tow in tows]

        def levels(key: str, what: str) -> list[tuple[float, str]]:
            values = sorted({getattr(tow, key) for _, tow in tows} - {None})
            return [(v, what.format(v)) for v in values]

        plots = [TimePlot("thrust", "thrust [N]", curves("thrust"), "{:.0f}",
                          title="the chaser's burn"),
                 TimePlot("tension", "tension [N]", curves("tension"), "{:.0f}",
                          title="the tether's, at the chaser"),
                 TimePlot("distance", "distance [m]", curves("distance"), "{:.1f}",
                          levels("safe_distance", "safe distance {:g} m"),
                          "chaser to the debris' centre of mass"),
                 TimePlot("enclosed", "enclosed [-]", curves("enclosed"), "{:.3f}",
                          levels("slip_fraction", "slips below {:g}"),
                          "the debris' enclosed fraction")]
        super().__init__(replay, plots, ROW * len(replay.tracks) + 16, tlim)

    def legend(self, track: Track) -> str:
        if track.tow is None:
            return f"{track.label}: no tow"
        return track.label + (f": tow {track.tow.outcome}" if track.tow.outcome else "")
