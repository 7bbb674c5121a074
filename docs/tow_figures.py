"""The tow studies' snaps in one figure, docs/figures/tow_snaps.png, from their tables in
benchmarks/results (docs/tow.md, "The tow study" and "The slack study"):

    python docs/tow_figures.py

Left: each run's largest snap at the chaser [N] against sqrt(F E) [sqrt(N Pa)], the law the
tow study found (a line of stiffness k ~ E catching a chaser sped up by the thrust F), the
tow study on symplectic Euler and on the fast tow, the slack study on the fast tow. Right:
the slack study's snaps scaled to 200 N and 70 GPa against the pretension's impulse
F_p t_p [N s], coloured by the chaser's distance [m] (the slack).
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "benchmarks" / "results"
STUDIES = {"tow study, symplectic Euler 8e-6 s": "tow_study_runs.csv",
           "tow study, exponential Euler 1e-4 s": "tow_study_exponential_runs.csv",
           "slack study, exponential Euler 1e-4 s": "tow_slack_study_runs.csv"}


def column(rows: list[dict], name: str) -> np.ndarray:
    """A table's column as floats, shape (runs,)."""
    return np.array([float(r[name]) for r in rows])


def main() -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    tables = {label: [row for row in csv.DictReader((RESULTS / name).open())
                      if row["status"] == "completed"]  # (a diverged run has no measures)
              for label, name in STUDIES.items()}
    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4.4))
    for k, ((label, rows), marker) in enumerate(zip(tables.items(), ("o", "x", "s"),
                                                    strict=True)):
        law = np.sqrt(column(rows, "thrust.force_N") * column(rows, "tether.young_modulus_Pa"))
        left.scatter(law, column(rows, "tow_snap_peak_N"), marker=marker, label=label,
                     **({"color": f"C{k}"} if marker == "x" else
                        {"facecolors": "none", "edgecolors": f"C{k}"}))
    left.set_xlabel("sqrt(thrust x tether modulus) [sqrt(N Pa)]")
    left.set_ylabel("largest snap at the chaser [N]")
    left.set_title("the snap grows as sqrt(F E)")
    left.legend(fontsize=8)
    rows = tables["slack study, exponential Euler 1e-4 s"]
    force, modulus = column(rows, "thrust.force_N"), column(rows, "tether.young_modulus_Pa")
    scaled = column(rows, "tow_snap_peak_N") * np.sqrt(200.0 * 70e9 / (force * modulus))
    impulse = column(rows, "thrust.pretension_N") * column(rows, "thrust.pretension_time_s")
    dots = right.scatter(impulse, scaled, c=column(rows, "tether.chaser_distance_m"),
                         cmap="viridis")
    fig.colorbar(dots, ax=right, label="chaser distance [m] (more: less slack)")
    right.set_xlabel("pretension impulse F_p t_p [N s]")
    right.set_ylabel("snap scaled to 200 N, 70 GPa [N]")
    right.set_title("slack study: pretension and slack")
    for ax in (left, right):
        ax.grid(alpha=0.3)
    fig.tight_layout()
    out = ROOT / "docs" / "figures" / "tow_snaps.png"
    fig.savefig(out, dpi=110)
    print(out)


if __name__ == "__main__":
    main()
