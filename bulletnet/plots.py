"""The paper's deployment figures as PNG, from recordings only (matplotlib, imported lazily).

- ``mouth.png``: mouth shapes at chosen times (Figs. 4a, 6), A solid, B dashed;
- ``height.png``: net height, Eq. 13 (Figs. 4b, 7a);
- ``diagonal.png``: mouth diagonal (Fig. 7b); ``area.png``: mouth area;
- ``rmse.png``: node-averaged RMSE over time, Eq. 15, position and velocity (Figs. 5, 8);
  only with two recordings;
- ``corner_thread.png``: tension and shear in a corner thread on a log axis (Fig. 9).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from . import metrics
from .errors import BulletnetError
from .recording import Recording


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
    plt = _pyplot()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    recs = [r for r in (a, b) if r is not None]
    styles = ["-", "--"]
    written = []

    def save(fig, name):
        path = out / name
        fig.tight_layout()
        fig.savefig(path, dpi=120)
        plt.close(fig)
        written.append(path)

    # mouth shapes
    times = times or default_times(a)
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
    save(fig, "mouth.png")

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

    corner = a.pairs.shape[0] - 4  # the first corner thread
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
    return written
