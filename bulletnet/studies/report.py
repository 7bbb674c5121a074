"""A study's report, from its folder only (``DIR/study.json`` and ``DIR/runs.csv``; it never
runs anything, so it also reads a study still running or stopped half-way).

``DIR/summary.json`` holds:

- ``status``: runs per status; ``wall_s``: their mean and total [s];
- ``measures``: count, mean, std, min and max of each numeric measure over completed runs;
- ``probabilities``: for the outcome columns (:data:`OUTCOMES`, where the recordings keep
  them), each true/false measure (``overloaded``: an element reached its breaking tension)
  and, for each measure some completed run never reached (``first_contact_s``, ``leave_s``,
  ``deployed_90pct_s``: the event "MEASURE reached", True or False), the probability of each
  value with its Wilson score interval (:func:`wilson`), overall and binned by each input
  (quantile bins; one bin per value of a ``choice`` input), over the completed runs that
  are independent draws (:func:`independent`: of a Sobol' design, its A and B samples);
- ``sobol`` (Sobol' designs): first-order ``S1`` and total ``ST`` indices of each numeric
  measure for each input, with the half-widths of their bootstrap confidence intervals
  (SALib's ``analyze.sobol``); a measure missing in a run, or constant, is listed under
  ``sobol_skipped`` with the reason.

Figures (``DIR/figures/``, matplotlib): ``INPUT.png`` each measure against the input (one
panel a measure, :func:`bulletnet.studies.sweep.plot_sweep`), ``probabilities.png`` and
``sobol.png``. :func:`summary_text` gives the summary's headline numbers as a short table.
"""

from __future__ import annotations

import json
import math
import statistics
from pathlib import Path

import numpy as np

from ..common.errors import ScenarioError
from .study import latest, read_table, salib
from .sweep import plot_sweep

OUTCOMES = ("outcome", "tow_outcome")
"""The measure columns that hold an outcome (one of several words: the capture's and the
tow's): the report gives the probability of each word."""


def wilson(successes: int, n: int, conf: float = 0.95) -> tuple[float, float, float]:
    """The proportion ``successes / n`` and its Wilson score interval at confidence ``conf``
    (Wilson 1927): the p solving ``(p_hat - p)^2 = z^2 p (1 - p) / n``. Returns (p_hat, low,
    high) [-]; (nan, 0, 1) for n = 0."""
    if n == 0:
        return math.nan, 0.0, 1.0
    z = statistics.NormalDist().inv_cdf(0.5 + conf / 2)
    p = successes / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z / (1 + z * z / n) * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    # the interval holds p_hat; say so exactly where round-off would put a bound past it
    return p, min(p, max(0.0, centre - half)), max(p, min(1.0, centre + half))


def _numeric(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) \
        and math.isfinite(value)


def load(out: Path) -> tuple[dict, list[dict]]:
    """A study folder's description (``study.json``) and its rows, one per run, in run order."""
    try:
        doc = json.loads((out / "study.json").read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise ScenarioError(f"{out}: not a study folder (study.json: {exc})") from None
    table = out / "runs.csv"
    if not table.exists():
        raise ScenarioError(f"{out}: no runs.csv yet")
    rows = latest(read_table(table)[1])
    return doc, [rows[k] for k in sorted(rows)]


def _order(values) -> list:
    """The distinct values, in order: numbers by value, anything else by its text."""
    distinct = set(values)
    numbers = all(isinstance(v, int | float) and not isinstance(v, bool) for v in distinct)
    return sorted(distinct) if numbers else sorted(distinct, key=str)


def _bins(values: list, bins: int, by_value: bool) -> tuple[list, list]:
    """Each value's bin and the bins' labels: one bin per distinct value (``by_value``: a
    ``choice`` input, in :func:`_order`), else ``bins`` quantile bins labelled [lo, hi] (fewer
    if values repeat): a value on an inner edge falls in the bin above it, so each bin holds
    lo <= v < hi but the last, lo <= v <= hi."""
    if by_value:
        distinct = _order(values)
        return [distinct.index(v) for v in values], distinct
    edges = np.unique(np.quantile(np.asarray(values, dtype=float), np.linspace(0, 1, bins + 1)))
    count = max(edges.size - 1, 1)
    index = np.clip(np.searchsorted(edges[1:-1], values, side="right"), 0, count - 1)
    return index.tolist(), [[float(edges[b]), float(edges[min(b + 1, edges.size - 1)])]
                            for b in range(count)]


def _proportions(values: list, categories: list, conf: float) -> dict:
    """Each category's count, proportion and Wilson interval among ``values``."""
    n = len(values)
    out = {}
    for category in categories:
        k = sum(v == category for v in values)
        p, low, high = wilson(k, n, conf)
        out[str(category)] = {"count": k, "n": n, "p": p, "low": low, "high": high}
    return out


def independent(doc: dict, rows: list[dict]) -> list[dict]:
    """The rows that are independent draws of the inputs: all of them, but of a Sobol' design
    only its two base samples, A and B, 2N of its N (D + 2) rows (Saltelli's blocks
    A, AB_1 .. AB_D, B: each AB_i is A with one input of B, so it repeats A's other D - 1
    inputs, and the whole of A where the two drew the same value of a ``choice``)."""
    if doc["design"] != "sobol":
        return rows
    block = len(doc["columns"]) + 2
    return [r for r in rows if r["run"] % block in (0, block - 1)]


def probabilities(doc: dict, rows: list[dict], conf: float = 0.95, bins: int = 4) -> dict:
    """Outcome and event probabilities with Wilson intervals, overall and by input (see the
    module doc), over the completed runs of :func:`independent`'s rows (a Wilson interval
    assumes independent trials); {} if the study has neither."""
    done = [r for r in independent(doc, rows) if r["status"] == "completed"]
    columns = {}  # name -> (runs, the value of a run)
    for name in OUTCOMES:
        if any(r.get(name) is not None for r in done):
            columns[name] = ([r for r in done if r.get(name) is not None],
                             lambda r, name=name: r[name])
    for m in doc["measures"]:
        if done and all(isinstance(r.get(m), bool) for r in done):
            columns[m] = (done, lambda r, m=m: r[m])
        elif m not in OUTCOMES and any(r.get(m) is None for r in done):
            columns[f"{m} reached"] = (done, lambda r, m=m: r[m] is not None)
    result = {}
    for name, (subset, value) in columns.items():
        values = [value(r) for r in subset]
        categories = _order(values) if name in OUTCOMES else [True, False]
        by_input = {}
        for key, column in doc["columns"].items():
            index, labels = _bins([r[column] for r in subset], bins,
                                  doc["vary"][key]["dist"] == "choice")
            by_input[column] = [
                {"bin": label, "values": _proportions(
                    [v for v, b in zip(values, index, strict=True) if b == j], categories, conf)}
                for j, label in enumerate(labels)]
        result[name] = {"overall": _proportions(values, categories, conf),
                        "by_input": by_input}
    return result


def sobol_indices(doc: dict, rows: list[dict], conf: float = 0.95,
                  resamples: int = 1000) -> tuple[dict, dict]:
    """First-order and total Sobol' indices of each numeric measure (SALib ``analyze.sobol``,
    no second order, ``resamples`` bootstrap resamples seeded with the study's seed):
    ``{measure: {input column: {S1, S1_conf, ST, ST_conf}}}``, and ``{measure: reason}`` for
    the measures left out (a run without a value, a constant measure, runs missing)."""
    if doc["design"] != "sobol":
        return {}, {}
    sobol = salib("analyze")
    columns = list(doc["columns"].values())
    problem = {"num_vars": len(columns), "names": columns, "bounds": [[0.0, 1.0]] * len(columns)}
    indices, skipped = {}, {}
    for m in doc["measures"]:
        if len(rows) < doc["run_count"]:
            skipped[m] = f"{doc['run_count'] - len(rows)} of {doc['run_count']} runs not done"
            continue
        y = [r[m] if r["status"] == "completed" else None for r in rows]
        missing = sum(not _numeric(v) for v in y)
        if missing:
            skipped[m] = f"{missing} runs without a numeric value"
            continue
        if np.ptp(y) == 0:
            skipped[m] = "constant over the runs"
            continue
        s = sobol.analyze(problem, np.asarray(y, dtype=float), calc_second_order=False,
                          num_resamples=resamples, conf_level=conf, seed=doc["seed"])
        indices[m] = {c: {key: float(s[key][j]) for key in ("S1", "S1_conf", "ST", "ST_conf")}
                      for j, c in enumerate(columns)}
    return indices, skipped


def _stats(values: list[float]) -> dict:
    a = np.asarray(values, dtype=float)
    return {"count": int(a.size), "mean": float(a.mean()), "std": float(a.std(ddof=1))
            if a.size > 1 else 0.0, "min": float(a.min()), "max": float(a.max())}


def report(out: Path, conf: float = 0.95, bins: int = 4, plots: bool = True) -> list[Path]:
    """Write ``OUT/summary.json`` and (with ``plots``) the figures of the study in ``out``;
    the paths written."""
    if not 0 < conf < 1:
        raise ScenarioError(f"confidence level {conf}: expected a number in (0, 1)")
    doc, rows = load(out)
    done = [r for r in rows if r["status"] == "completed"]
    walls = [r["wall_s"] for r in rows if _numeric(r["wall_s"])]
    measures = {m: _stats(v) for m in doc["measures"]
                if (v := [r[m] for r in done if _numeric(r.get(m))])}
    indices, skipped = sobol_indices(doc, rows, conf)
    summary = {
        "study": {k: doc[k] for k in ("source", "scene", "function", "design", "runs", "seed",
                                      "run_count")},
        "rows": len(rows),
        "status": {s: sum(r["status"] == s for r in rows)
                   for s in dict.fromkeys(r["status"] for r in rows)},
        "wall_s": {"mean": statistics.fmean(walls) if walls else None, "total": sum(walls)},
        "inputs": {c: {"key": k, "unit": doc["units"][k], **doc["vary"][k]}
                   for k, c in doc["columns"].items()},
        "measures": measures,
        "confidence_level": conf,
        "probabilities": probabilities(doc, rows, conf, bins),
        "sobol": indices, "sobol_skipped": skipped,
    }
    path = out / "summary.json"
    path.write_text(json.dumps(summary, indent=2) + "\n", encoding="utf-8")
    paths = [path]
    if plots and done:
        numeric = tuple(m for m in measures) + ("wall_s",)
        paths += plot_sweep(rows, tuple(doc["columns"].values()), out, numeric)
        if summary["probabilities"]:
            paths.append(plot_probabilities(summary["probabilities"], out))
        if indices:
            paths.append(plot_sobol(indices, conf, out))
    return paths


def summary_text(out: Path, leading: int = 2) -> list[str]:
    """``OUT/summary.json`` (:func:`report`) as a short plain-text table: the runs per status,
    each outcome's or event's overall probability with its Wilson interval, and each
    measure's ``leading`` inputs by total Sobol' index with S1 and ST and their intervals."""
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    level = f"{100 * summary['confidence_level']:g} %"
    status = ", ".join(f"{n} {s}" for s, n in summary["status"].items())
    lines = [f"{summary['rows']} runs in the table: {status}"]
    for name, p in summary["probabilities"].items():
        lines.append(f"{name:<28} {'p':>6}  {level + ' interval':>17}  {'runs':>9}")
        lines += [f"  {value:<26} {c['p']:>6.3f}  {c['low']:>8.3f} - {c['high']:.3f}  "
                  f"{c['count']:>4} / {c['n']:<4}" for value, c in p["overall"].items()]
    if summary["sobol"]:
        lines.append(f"Sobol' indices ({level} intervals), the {leading} leading inputs by ST:")
        width = max(len(c) for by_input in summary["sobol"].values() for c in by_input)
        for measure, by_input in summary["sobol"].items():
            ranked = sorted(by_input.items(), key=lambda item: -item[1]["ST"])[:leading]
            lines += [f"  {measure:<26} {column:<{width}}  S1 {v['S1']:6.3f} ± "
                      f"{v['S1_conf']:.3f}  ST {v['ST']:6.3f} ± {v['ST_conf']:.3f}"
                      for column, v in ranked]
    lines += [f"  no indices for {m}: {why}" for m, why in summary["sobol_skipped"].items()]
    return lines


def plot_sobol(indices: dict, conf: float, out: Path) -> Path:
    """``OUT/figures/sobol.png``: a panel per measure, S1 and ST of each input as bars with
    their confidence intervals."""
    from ..analysis.plots import _pyplot

    plt = _pyplot()
    fig, axes = plt.subplots(1, len(indices), figsize=(4.2 * len(indices), 3.6), squeeze=False)
    for ax, (measure, by_input) in zip(axes[0], indices.items(), strict=True):
        names = list(by_input)
        x = np.arange(len(names))
        for shift, key in ((-0.2, "S1"), (0.2, "ST")):
            ax.bar(x + shift, [by_input[n][key] for n in names], 0.4, label=key,
                   yerr=[by_input[n][f"{key}_conf"] for n in names], capsize=3)
        ax.set_xticks(x, names, rotation=30, ha="right", fontsize=8)
        ax.set_title(measure, fontsize=9)
        ax.axhline(0, color="k", lw=0.5)
        ax.grid(True, axis="y", alpha=0.3)
    axes[0][0].set_ylabel(f"Sobol' index [-] ({100 * conf:g} % interval)")
    axes[0][0].legend(fontsize=8)
    return _save(plt, fig, out / "figures" / "sobol.png")


def plot_probabilities(probs: dict, out: Path) -> Path:
    """``OUT/figures/probabilities.png``: a row per outcome or event, its probabilities with
    their Wilson intervals overall (first panel) and against each input's bins (an event's
    probability of happening only)."""
    from ..analysis.plots import _pyplot

    plt = _pyplot()
    inputs = list(next(iter(probs.values()))["by_input"])
    fig, axes = plt.subplots(len(probs), 1 + len(inputs), squeeze=False,
                             figsize=(3.0 * (1 + len(inputs)), 2.8 * len(probs)))
    for row, (name, p) in zip(axes, probs.items(), strict=True):
        # an event's probability of False is 1 - that of True: plot True only
        values = list(p["overall"]) if name in OUTCOMES else ["True"]
        _bars(row[0], [p["overall"][v] for v in values], values)
        row[0].set_title(f"{name}: overall", fontsize=9)
        row[0].set_ylabel("probability [-]")
        for ax, column in zip(row[1:], inputs, strict=True):
            bins = p["by_input"][column]
            labels = [_bin_label(b["bin"]) for b in bins]
            for v in values:
                cells = [b["values"][v] for b in bins]
                x = [j for j, c in enumerate(cells) if c["n"]]
                ax.errorbar(x, [cells[j]["p"] for j in x], fmt="o-", capsize=3, label=v,
                            yerr=[[cells[j]["p"] - cells[j]["low"] for j in x],
                                  [cells[j]["high"] - cells[j]["p"] for j in x]])
            ax.set_xticks(range(len(labels)), labels, fontsize=7, rotation=30, ha="right")
            ax.set_ylim(-0.05, 1.05)
            ax.set_title(column, fontsize=9)
            ax.grid(True, alpha=0.3)
        row[-1].legend(fontsize=7)
    return _save(plt, fig, out / "figures" / "probabilities.png")


def _save(plt, fig, path: Path) -> Path:
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def _bars(ax, cells: list[dict], labels: list[str]) -> None:
    x = np.arange(len(cells))
    ax.bar(x, [c["p"] for c in cells], yerr=[[c["p"] - c["low"] for c in cells],
                                             [c["high"] - c["p"] for c in cells]], capsize=3)
    ax.set_xticks(x, labels, fontsize=8)
    ax.set_ylim(0, 1.05)


def _bin_label(label) -> str:
    if isinstance(label, list):
        return f"{label[0]:.3g} to {label[1]:.3g}"
    return f"{label:.3g}" if isinstance(label, float) else str(label)
