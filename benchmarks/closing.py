"""Closing benchmark: the paper's capture (120 s, the spinning Apollo CSM) without and with
the closing mechanism and main tether (scenarios/capture_closing.toml), with and without
bending, on ``fast``.

For each run: the outcome and when it was decided, the smallest enclosed fraction and the
largest mouth opening from the decision to the end (a capture that holds keeps E and M within
the rules), the largest rise of the mechanical energy above its start net of the winches'
work (a sound model has none), the winches' work, the cables' largest tension, and the wall
time, also as a ratio to the frozen yardstick timed in the same run (``yardstick.py``, the
plain loop of the 3 s deployment, REPEATS times before the runs and once after; the machine's
speed drifts between days).
Then the closing capture stopped once decided (``outcome.stop_when_decided``): its wall time.

Writes OUT/closing.json (copy it to benchmarks/results/) and docs/figures/closing.png.
Usage: python benchmarks/closing.py [OUT] [--repeats N]
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
from common import Yardsticks, output_dir, parser

import bulletnet as bn

FIGURE = Path(__file__).resolve().parent.parent / "docs" / "figures" / "closing.png"


def timed_run(scene: str, overrides: dict, path) -> tuple[float, bn.RunResult]:
    start = time.perf_counter()
    result = bn.run(bn.load_scenario(scene, overrides), path, force=True)
    return time.perf_counter() - start, result


def measures(rec: bn.Recording, wall: float, yard: Yardsticks) -> dict:
    scores, judged = bn.metrics.capture_outcome(rec)
    after = rec.time >= judged.time if judged.decided else np.zeros(rec.time.size, bool)
    gain = bn.metrics.energy(rec) - bn.metrics.energy(rec)[0] - bn.metrics.winch_work(rec)
    out = {"outcome": judged.outcome, "outcome_time_s": judged.time,
           "first_contact_s": bn.metrics.first_contact_time(rec),
           "leave_s": bn.metrics.leave_time(rec),
           "max_capture_quality": float(scores[:, 2].max()),
           "max_energy_gain_net_of_winch_work_J": float(gain.max()),
           "wall_s": wall, **yard.ratios(wall)}
    if after.any():
        out.update(min_enclosed_after_decision=float(scores[after, 0].min()),
                   max_mouth_opening_after_decision=float(scores[after, 1].max()),
                   final_enclosed=float(scores[-1, 0]), final_mouth_opening=float(scores[-1, 1]))
    if rec.cables is not None:
        out.update(winch_work_J=float(bn.metrics.winch_work(rec)[-1]),
                   max_cable_tension_N=float(rec.cables["tension"].max()),
                   final_rest_length_m=rec.cables["rest_length"][-1].tolist())
    return out


def plot(recordings: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(14, 4), constrained_layout=True)
    for (closing, bending), rec in recordings.items():
        scores, _ = bn.metrics.capture_outcome(rec)
        label = f"{'closing' if closing else 'open'}, {'bending' if bending else 'no bending'}"
        style = "-" if closing else ":"
        colour = "tab:orange" if bending else "tab:blue"
        axes[0].plot(rec.time, scores[:, 0], style, color=colour, label=label)
        axes[1].plot(rec.time, scores[:, 1], style, color=colour, label=label)
        if closing:
            axes[2].plot(rec.time, rec.cables["rest_length"].mean(axis=1), color=colour,
                         label=f"rest length, {label}")
            axes[2].plot(rec.time, rec.cables["length"].mean(axis=1), "--", color=colour,
                         label=f"length, {label}")
    axes[0].set(xlabel="time [s]", ylabel="enclosed fraction E [-]",
                title="debris inside the net's hull")
    axes[1].axhline(0.25, color="grey", lw=0.8)
    axes[1].set(xlabel="time [s]", ylabel="mouth opening M [-]",
                title="perimeter's largest chord / diagonal")
    axes[2].set(xlabel="time [s]", ylabel="mean over the 4 cables [m]",
                title="closing cables")
    for ax in axes:
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    fig.savefig(path, dpi=110)


def main() -> None:
    args = parser(__doc__).parse_args()
    out = output_dir(args)
    yard = Yardsticks()
    for _ in range(args.repeats):
        yard.time()
    doc = {"bulletnet_version": bn.__version__, "runs": {}}
    recordings = {}
    for closing in (False, True):
        for bending in (False, True):
            name = f"{'closing' if closing else 'capture'}_{'bending' if bending else 'plain'}"
            path = out / f"{name}.h5"
            wall, _ = timed_run("capture_closing" if closing else "capture",
                                {"bending.enabled": bending}, path)
            rec = bn.open_recording(path)
            recordings[(closing, bending)] = rec
            doc["runs"][name] = measures(rec, wall, yard)
            if closing:
                stop_wall, result = timed_run(
                    "capture_closing", {"bending.enabled": bending,
                                        "outcome.stop_when_decided": True}, None)
                doc["runs"][name].update(stopped_wall_s=stop_wall,
                                         stopped_at_s=result.state.time,
                                         stopped_x_yardstick=yard.ratios(stop_wall)[
                                             "x_yardstick"])
            print(name, json.dumps(doc["runs"][name]))
    yard.time()  # after the runs too: the machine's drift over the benchmark
    doc["yardsticks"] = yard.doc()
    (out / "closing.json").write_text(json.dumps(doc, indent=1))
    plot(recordings, FIGURE)
    print(f"yardstick {yard.median:.2f} s; wrote {out / 'closing.json'} and {FIGURE}")


if __name__ == "__main__":
    main()
