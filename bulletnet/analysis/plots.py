"""The paper's deployment figures as PNG, from recordings only (matplotlib, imported lazily).

- ``mouth.png``: mouth shapes at chosen times (Figs. 4a, 6), A solid, B dashed;
- ``height.png``: net height, Eq. 13 (Figs. 4b, 7a);
- ``diagonal.png``: mouth diagonal (Fig. 7b); ``area.png``: mouth area;
- ``rmse.png``: node-averaged RMSE over time, Eq. 15, position and velocity (Figs. 5, 8);
  only with two recordings;
- ``corner_thread.png``: tension and shear in a corner thread on a log axis (Fig. 9);
- ``strength.png``: the utilisation (tension over breaking tension) of each kind of element:
  its highest over time, and the distribution of each element's peak, with the least safety
  factor, where and when (:func:`bulletnet.analysis.metrics.safety`);
- with a burn (``[thrust]``): ``tow.png``, the tow from the burn's start: thrust and tether
  tension, chaser-to-debris distance, enclosed fraction, the debris' angular speed;
- with debris: ``mouth.png`` has one panel per time with the debris' long axis (grey, its
  x-y projection through the body origin; Fig. 11), and ``capture.png`` plots nodes in
  contact, the wrap measure and the capture score (enclosed fraction, mouth opening, capture
  quality; :mod:`bulletnet.analysis.capture_score`) over time, with the time each outcome was
  decided.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..common.errors import BulletnetError, RecordingError
from ..model.net import ELEMENT_NAMES, ElementKind, corner_threads
from ..recording.reader import Recording
from . import metrics


def _pyplot():
    try:
        import matplotlib
    except ImportError:
        raise BulletnetError(
            "plotting needs matplotlib: pip install 'bulletnet[plot]'") from None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _label(rec: Recording) -> str:
    bending = "with bending" if bool(rec.attrs.get("bending")) else "no bending"
    return f"{rec.path.stem} ({rec.attrs.get('engine', '?')}, {bending})"


def default_times(rec: Recording, count: int = 7) -> list[float]:
    """``count`` evenly spaced snapshot times over the recording [s]."""
    return list(np.linspace(rec.time[0], rec.time[-1], count))


def plot_recordings(a: Recording, b: Recording | None, out_dir: str | Path,
                    times: list[float] | None = None) -> list[Path]:
    """Write the figures for ``a`` (and ``b`` overlaid) into ``out_dir``; return the paths."""
    recs = [r for r in (a, b) if r is not None]
    for rec in recs:
        rec.require_net("net figures")
    if b is not None and (a.debris is None) != (b.debris is None):
        raise RecordingError(f"{a.path} and {b.path}: one has debris and the other not; "
                             "plot overlays two runs of one kind")
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise RecordingError(f"{out}: exists and is not a folder; --out names the folder of "
                             "the figures")
    plt = _pyplot()
    out.mkdir(parents=True, exist_ok=True)
    styles = ["-", "--"]
    written = []

    def save(fig, name):
        path = out / name
        fig.tight_layout()
        fig.savefig(path, dpi=120)
        plt.close(fig)
        written.append(path)

    times = times or default_times(a)
    if a.debris is not None:
        save(_capture_mouths(plt, recs, styles, times), "mouth.png")
        if a.contacts is not None:
            save(_capture_series(plt, recs, styles), "capture.png")
        if a.attrs.get("thrust_start_s", -1.0) >= 0:
            save(_tow(plt, [r for r in recs if r.attrs.get("thrust_start_s", -1.0) >= 0],
                      styles), "tow.png")
    else:
        save(_mouths(plt, recs, styles, times, b), "mouth.png")

    for name, fn, ylabel in (("height.png", metrics.net_height, "net height [m] (Eq. 13)"),
                             ("diagonal.png", metrics.mouth_diagonal, "mouth diagonal [m]"),
                             ("area.png", metrics.mouth_area, "mouth area [m$^2$]")):
        fig, ax = plt.subplots(figsize=(6.5, 4))
        for rec, style in zip(recs, styles, strict=False):
            ax.plot(rec.time, fn(rec), style, label=_label(rec))
        ax.set_xlabel("time [s]")
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
        save(fig, name)

    if b is not None:
        r = metrics.rmse(a, b)
        fig, axes = plt.subplots(2, 1, figsize=(6.5, 6), sharex=True)
        axes[0].plot(r["time"], r["pos_t"])
        axes[0].set_ylabel("RMSE position [m]")
        axes[1].plot(r["time"], r["vel_t"])
        axes[1].set_ylabel("RMSE velocity [m/s]")
        axes[1].set_xlabel("time [s]")
        axes[0].set_title(f"Node-averaged RMSE (Eq. 15): {a.path.stem} vs {b.path.stem}",
                          fontsize=9)
        for ax in axes:
            ax.grid(alpha=0.3)
        save(fig, "rmse.png")

    corner = corner_threads(a.pairs, a.kind)[0]  # the first corner thread
    fig, ax = plt.subplots(figsize=(6.5, 4))
    for rec, style in zip(recs, styles, strict=False):
        tension = np.where(rec.tension[:, corner] > 0, rec.tension[:, corner], np.nan)
        ax.semilogy(rec.time, tension, style, color="C0", label=f"tension, {rec.path.stem}")
        if rec.shear[:, corner].any():
            ax.semilogy(rec.time, rec.shear[:, corner], style, color="C3",
                        label=f"shear, {rec.path.stem}")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("force [N]")
    ax.set_title(f"Corner thread {corner + 1} (paper numbering); tension not drawn when slack",
                 fontsize=9)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    save(fig, "corner_thread.png")
    save(_strength(plt, recs, styles), "strength.png")
    return written


def _strength(plt, recs, styles):
    """The utilisation of each kind of element (a colour each): the highest over time (top),
    and the distribution of the elements' peaks over the run (bottom), on log axes; the line
    at 1 is the breaking tension."""
    fig, axes = plt.subplots(2, 1, figsize=(6.5, 7))
    titles = []
    utils = [metrics.utilisation(rec) for rec in recs]
    positive = np.concatenate([u.max(axis=0) for u in utils])
    positive = positive[positive > 0]
    bins = (np.geomspace(positive.min(), positive.max() * 1.0001, 30) if positive.size
            else np.geomspace(1e-6, 1.0, 30))  # the same bins for every run
    for rec, style, util in zip(recs, styles, utils, strict=False):
        kinds = metrics.element_kinds(rec)
        peaks = util.max(axis=0)
        for kind in ElementKind:
            columns = kinds == kind
            if not columns.any():
                continue
            colour, name = f"C{int(kind)}", ELEMENT_NAMES[kind]
            history = util[:, columns].max(axis=1)
            axes[0].semilogy(rec.time, np.where(history > 0, history, np.nan), style,
                             color=colour, label=f"{name}s, {rec.path.stem}")
            axes[1].hist(peaks[columns], bins=bins, histtype="step", ls=style, color=colour,
                         label=f"{name}s, {rec.path.stem}")
        margin = metrics.safety(rec)
        titles.append(f"{rec.path.stem}: least safety factor "
                      + (f"{margin['least_safety_factor']:.3g}, {margin['element']['kind']} "
                         f"{margin['element']['index']} at {margin['time_s']:.2f} s"
                         if margin["element"] else "- (never taut)"))
    axes[0].axhline(1.0, color="k", lw=0.8)
    axes[0].set_xlabel("time [s]")
    axes[0].set_ylabel("highest utilisation [-]\n(tension / breaking tension)")
    axes[0].set_title("\n".join(titles), fontsize=8)
    axes[1].set_xscale("log")
    axes[1].set_xlabel("peak utilisation of an element over the run [-]")
    axes[1].set_ylabel("elements [-]")
    for ax in axes:
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7)
    return fig


def _mouths(plt, recs, styles, times, b):
    """Mouth shapes at ``times`` in one panel (Figs. 4a, 6)."""
    a = recs[0]
    fig, ax = plt.subplots(figsize=(6.5, 6))
    colours = plt.cm.viridis(np.linspace(0, 0.9, len(times)))
    for rec, style in zip(recs, styles, strict=False):
        poly = metrics.mouth(rec)
        for t, colour in zip(times, colours, strict=True):
            k = int(np.argmin(np.abs(rec.time - t)))
            xy = np.vstack([poly[k], poly[k][:1]])
            ax.plot(xy[:, 0], xy[:, 1], style, color=colour,
                    label=f"t = {rec.time[k]:.2f} s" if rec is a else None)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title("Mouth shape" + (f"\nsolid: {_label(a)}; dashed: {_label(b)}" if b else ""),
                 fontsize=9)
    ax.legend(fontsize=8)
    return fig


def _capture_mouths(plt, recs, styles, times):
    """One panel per time: each run's mouth and the debris' long axis (Fig. 11)."""
    fig, axes = plt.subplots(1, len(times), figsize=(3.2 * len(times), 3.6), squeeze=False)
    for ax, t in zip(axes[0], times, strict=True):
        for rec, style, colour in zip(recs, styles, ("C0", "C3"), strict=False):
            k = int(np.argmin(np.abs(rec.time - t)))
            xy = metrics.mouth(rec)[k]
            xy = np.vstack([xy, xy[:1]])
            ax.plot(xy[:, 0], xy[:, 1], style, color=colour, lw=1, label=_label(rec))
            centre = rec.debris["position"][k, :2]
            half = 0.5 * np.ptp(rec.debris["mesh_vertices"][:, 1])
            axis = metrics.debris_axis(rec)[k, :2] * half
            ax.plot(*np.stack([centre - axis, centre + axis]).T, "-", color="0.6", lw=5,
                    alpha=0.6, solid_capstyle="butt")
        ax.set_title(f"t = {t:g} s", fontsize=9)
        ax.set_aspect("equal")
        ax.set_xlabel("x [m]")
    axes[0, 0].set_ylabel("y [m]")
    axes[0, 0].legend(fontsize=6, loc="lower left")
    fig.suptitle("Mouth shape and the debris' long axis (grey)", fontsize=10)
    return fig


def _tow(plt, recs, styles):
    """The tow from the burn's start (:func:`~bulletnet.analysis.metrics.tow_series`): thrust
    and tether tension, chaser-to-debris distance with the safe distance, the enclosed
    fraction with its threshold and the debris' angular speed; the outcome where decided."""
    fig, axes = plt.subplots(4, 1, figsize=(6.5, 9), sharex=True)
    for rec, style in zip(recs, styles, strict=False):
        series, rules = metrics.tow_series(rec), metrics.recorded_scene(rec).tow
        t = series["time"]
        axes[0].plot(t, series["tension"], style, color="C0", label=f"tether, {_label(rec)}")
        axes[0].plot(t, series["thrust"], style, color="C3", lw=0.8,
                     label=f"thrust, {_label(rec)}")
        axes[1].plot(t, series["distance"], style, color="C0", label=_label(rec))
        axes[1].axhline(rules.safe_distance, color="C3", lw=0.8, ls=":")
        axes[2].plot(t, series["enclosed"], style, color="C2", label=_label(rec))
        axes[2].axhline(rules.enclosed_fraction, color="C3", lw=0.8, ls=":")
        axes[3].plot(t, np.degrees(series["rate"]), style, color="C1", label=_label(rec))
        outcome, when = rec.attrs.get("tow_outcome"), rec.attrs.get("tow_outcome_time_s", -1)
        if outcome and when >= 0:
            for ax in axes:
                ax.axvline(when, ls=style, lw=0.8, color="0.3")
            axes[1].annotate(f" {outcome} at {when:.1f} s", (when, axes[1].get_ylim()[1]),
                             fontsize=7, va="top")
    _time_axes(axes, ("force [N]", "chaser to debris\ncentre of mass [m]",
                      "enclosed fraction [-]", "debris angular\nspeed [deg/s]"))
    axes[0].legend(fontsize=7)
    return fig


def _time_axes(axes, ylabels) -> None:
    """Label stacked panels sharing a time axis [s] and grid them."""
    for ax, label in zip(axes, ylabels, strict=True):
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("time [s]")


def _capture_series(plt, recs, styles):
    """Nodes in contact with the debris, the wrap measure and the capture score over time;
    a grey line (in the run's style) where each run's outcome was decided."""
    fig, axes = plt.subplots(3, 1, figsize=(6.5, 8), sharex=True)
    for row, (rec, style) in enumerate(zip(recs, styles, strict=False)):
        axes[0].plot(rec.time, metrics.nodes_in_contact(rec), style, label=_label(rec))
        axes[1].plot(rec.time, metrics.wrap(rec), style, label=_label(rec))
        scores, judged = metrics.capture_outcome(rec)
        for column, (name, colour) in enumerate((("enclosed fraction", "C2"),
                                                 ("mouth opening", "C1"),
                                                 ("capture quality", "C0"))):
            axes[2].plot(rec.time, scores[:, column], style, color=colour,
                         label=f"{name}, {rec.path.stem}")
        if judged.decided:
            axes[2].axvline(judged.time, ls=style, lw=0.8, color="0.3")
            axes[2].annotate(f" {judged.outcome} at {judged.time:.1f} s",
                             (judged.time, 0.98 - 0.1 * row), fontsize=7, va="top")
    _time_axes(axes, ("nodes touching the debris [-]",
                      "wrap [-]\n(fraction of directions\ncovered by the net)",
                      "capture score [-]"))
    axes[0].legend(fontsize=8)
    axes[2].legend(fontsize=7, loc="center right")
    return fig
