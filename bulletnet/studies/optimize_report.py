"""An optimisation's report, from its folder (``DIR/optimize.json``, ``DIR/optuna.journal``,
``DIR/runs.csv``); with ``confirm`` > 0 it also runs the best design on that many fresh draws
(:func:`bulletnet.studies.optimize.confirm`), which the optimisation never saw.

``DIR/summary.json`` holds every design (its variables, objective, cost, score, constraint
violations, feasibility), the ``best`` feasible one, its ``confirmation`` (the fresh draws'
objective; for a probability, its Wilson interval) and each variable's ``importance`` for the
score (Optuna's fANOVA evaluator where scikit-learn is installed, else its PED-ANOVA one,
which needs nothing more; ``importance_method`` says which).

Figures (``DIR/figures/``): ``front.png`` the objective against the cost of every design,
the feasible non-dominated ones joined (the trade-off front; against the design number
without a cost), ``history.png`` each design's score and the best so far, and
``importance.png``.
"""

from __future__ import annotations

import importlib.util
import json
import math
from pathlib import Path

from ..common.errors import ScenarioError
from .optimize import asked, best_trial, confirm, load_folder, optuna_module
from .report import _save


def trial_rows(study, opt) -> list[dict]:
    """Every trial: ``design`` (its number), ``state``, its variables (by table column) and
    what :func:`bulletnet.studies.optimize.assess` gave it."""
    columns = opt.columns
    return [{"design": t.number, "state": t.state.name.lower(),
             "variables": {columns[k]: v for k, v in t.params.items()}, **t.user_attrs}
            for t in asked(study)]


def importances(study) -> tuple[dict, str]:
    """Each design variable's importance for the score [-] (sums to 1) and the evaluator's
    name; ({}, why) where there is none."""
    optuna = optuna_module()
    from optuna.trial import TrialState

    if len(study.get_trials(deepcopy=False, states=(TrialState.COMPLETE,))) < 2:
        return {}, "fewer than 2 completed designs"
    if importlib.util.find_spec("sklearn") is not None:
        evaluator, name = optuna.importance.FanovaImportanceEvaluator(seed=0), "fanova"
    else:
        evaluator, name = optuna.importance.PedAnovaImportanceEvaluator(), "ped-anova"
    try:
        return dict(optuna.importance.get_param_importances(study, evaluator=evaluator)), name
    except (ValueError, RuntimeError) as exc:
        return {}, f"{name}: {exc}"


def front(points: list[tuple[float, float, int]], maximize: bool) -> list[int]:
    """The designs no other beats on both objective and cost (lower cost, better objective):
    the numbers of ``points`` (objective, cost, design), by cost."""
    sign = 1.0 if maximize else -1.0
    best = -math.inf
    kept = []
    for objective, _cost, number in sorted(points, key=lambda p: (p[1], -sign * p[0])):
        if sign * objective > best:
            best = sign * objective
            kept.append(number)
    return kept


def report_optimisation(out: Path, confirm_runs: int = 0, scheduler: str | None = None,
                        workers: int = 2, serial: bool = False, plots: bool = True) -> list[Path]:
    """Write ``out/summary.json`` (and with ``plots`` the figures); with ``confirm_runs``,
    run the best design's confirmation first, and the ``[first]`` design's on the same fresh
    draws (a paired comparison) if it is not the best. The paths written."""
    opt, study, _rows = load_folder(out)
    trials = trial_rows(study, opt)
    best = best_trial(study)
    confirmation = confirmation_first = None
    if confirm_runs > 0:
        if best is None:
            raise ScenarioError(f"{out}: no feasible completed design to confirm")
        confirmation = confirm(opt, out, best.number, dict(best.params), confirm_runs,
                               scheduler, workers, serial)
        if opt.first is not None and best.number != 0:
            confirmation_first = confirm(opt, out, 0, dict(opt.first), confirm_runs,
                                         scheduler, workers, serial)
    weights, method = importances(study)
    weights = {opt.columns.get(k, k): v for k, v in weights.items()}
    ob = opt.objective
    summary = {
        "optimisation": {"source": str(opt.path), "scene": opt.scene, "function": opt.function,
                         "seed": opt.seed, "trials": opt.trials, "draws": len(opt.draws),
                         "sampler": opt.sampler},
        "objective": {"measure": ob.measure, "equals": ob.equals, "confidence": ob.confidence,
                      "direction": ob.direction, "cost": ob.cost,
                      "cost_weight": ob.cost_weight},
        "constraints": opt.constraints,
        "units": {opt.columns[k]: u for k, u in opt.units.items()},
        "designs": trials,
        "best": None if best is None else trials[best.number],
        "confirmation": confirmation,
        "confirmation_first": confirmation_first,
        "importance": weights, "importance_method": method,
    }
    path = out / "summary.json"
    path.write_text(json.dumps(summary, indent=2) + "\n", encoding="utf-8")
    paths = [path]
    done = [t for t in trials if t["state"] == "complete"]
    if plots and done:
        paths += plot_front(done, summary, out), plot_history(done, summary, out)
        if weights:
            paths.append(plot_importance(weights, method, out))
    return paths


def summary_text(out: Path) -> list[str]:
    """``out/summary.json`` in a few lines: designs per state, the best design, its
    confirmation and the variables' importance."""
    s = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    states = {}
    for t in s["designs"]:
        states[t["state"]] = states.get(t["state"], 0) + 1
    lines = [f"{len(s['designs'])} designs: " + ", ".join(f"{n} {k}" for k, n in states.items())]
    best, ob = s["best"], s["objective"]
    if best is None:
        return [*lines, "no feasible completed design yet"]
    lines.append(f"best: design {best['design']}, score {best['score']:.4g}, objective "
                 f"{best['objective']:.4g}" + (f" (P = {best['p']:.3f}, {best['successes']}"
                                                f"/{best['runs']})" if "p" in best else "")
                 + (f", {ob['cost']} {best['cost']:.4g}" if ob["cost"] else ""))
    lines += [f"  {k} = {v}" for k, v in best["variables"].items()]
    level = f"{100 * ob['confidence']:g} %"
    for key, what in (("confirmation", "confirmation on"),
                      ("confirmation_first", "the first design (0) on the same")):
        c = s.get(key)
        if c is not None:
            lines.append(f"{what} {c['draws']} fresh draws: objective "
                         + ("none" if c["objective"] is None else f"{c['objective']:.4g}")
                         + (f", P = {c['p']:.3f} ({level} interval {c['low']:.3f} - "
                            f"{c['high']:.3f}, {c['successes']}/{c['runs']})" if "p" in c
                            else "")
                         + ("" if c["feasible"] else ", infeasible"))
    if s["importance"]:
        lines.append(f"importance ({s['importance_method']}): " + ", ".join(
            f"{k} {v:.2f}" for k, v in s["importance"].items()))
    return lines


def plot_front(done: list[dict], summary: dict, out: Path) -> Path:
    """``out/figures/front.png``: objective against cost (or design number), feasible and
    infeasible designs, the front joined, the best circled."""
    from ..analysis.plots import _pyplot

    plt = _pyplot()
    ob = summary["objective"]
    cost = ob["cost"]
    fig, ax = plt.subplots(figsize=(5.5, 4.0))
    x = [t["cost"] if cost else t["design"] for t in done]
    for feasible, style in ((True, "o"), (False, "x")):
        picked = [j for j, t in enumerate(done) if t["feasible"] == feasible]
        ax.plot([x[j] for j in picked], [done[j]["objective"] for j in picked], style,
                label="feasible" if feasible else "infeasible", alpha=0.7)
    if cost:
        ok = [(t["objective"], t["cost"], t["design"]) for t in done
              if t["feasible"] and t["objective"] is not None and math.isfinite(t["cost"])]
        kept = front(ok, ob["direction"] == "maximize")
        by = {t["design"]: t for t in done}
        ax.plot([by[n]["cost"] for n in kept], [by[n]["objective"] for n in kept], "k-",
                lw=1, label="front")
    if summary["best"] is not None:
        b = summary["best"]
        ax.plot([b["cost"] if cost else b["design"]], [b["objective"]], "o", ms=14, mfc="none",
                mec="r", label="best score")
    ax.set_xlabel(cost or "design [-]")
    what = f"P({ob['measure']} = {ob['equals']}), Wilson bound" if ob["equals"] is not None \
        else f"mean {ob['measure']}"
    ax.set_ylabel(what)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    return _save(plt, fig, out / "figures" / "front.png")


def plot_history(done: list[dict], summary: dict, out: Path) -> Path:
    """``out/figures/history.png``: each design's score and the best feasible so far."""
    from ..analysis.plots import _pyplot

    plt = _pyplot()
    sign = 1.0 if summary["objective"]["direction"] == "maximize" else -1.0
    fig, ax = plt.subplots(figsize=(5.5, 3.5))
    ax.plot([t["design"] for t in done], [t["score"] for t in done], "o", alpha=0.6,
            label="design")
    best, xs, ys = -math.inf, [], []
    for t in sorted(done, key=lambda t: t["design"]):
        if t["feasible"] and sign * t["score"] > best:
            best = sign * t["score"]
        if math.isfinite(best):
            xs.append(t["design"])
            ys.append(sign * best)
    ax.step(xs, ys, "k-", where="post", label="best feasible so far")
    ax.set_xlabel("design [-]")
    ax.set_ylabel("score")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    return _save(plt, fig, out / "figures" / "history.png")


def plot_importance(weights: dict, method: str, out: Path) -> Path:
    """``out/figures/importance.png``: each design variable's importance."""
    from ..analysis.plots import _pyplot

    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(5.5, 0.5 + 0.4 * len(weights)))
    names = list(weights)[::-1]
    ax.barh(names, [weights[n] for n in names])
    ax.set_xlabel(f"importance for the score [-] ({method})")
    ax.grid(True, axis="x", alpha=0.3)
    return _save(plt, fig, out / "figures" / "importance.png")
