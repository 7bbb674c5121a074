"""Robust design optimisation: the design variables of a scene (or of a Python function)
chosen by Optuna to maximise (or minimise) a statistic over K uncertain runs per design, under
constraints; each design's runs on the study runner (:func:`bulletnet.studies.runner.fan_out`,
on Dask or serial), one row per run in ``DIR/runs.csv``; resumable (``docs/studies.md`` has
the whole format and when to trust the result).

An optimisation file (TOML)::

    scene = "capture_closing"   # base scene (name or path); or function = "module:name"
    seed = 1                    # the designs asked and the K draws follow from it
    trials = 40                 # designs evaluated, one after another
    draws = 16                  # K: runs per design, the same K draws for every design
    sampler = "tpe"             # "tpe" (default) or "cmaes"
    [design]                    # the variables: bounds in the key's SI unit
    "net.mesh_length" = {low = 0.8, high = 1.2}                  # [m]
    "net.nodes_per_side" = {low = 15, high = 21, int = true}     # [-]
    "net.thread_radius" = {low = 3e-4, high = 1e-3, log = true}  # [m]
    "closing.trigger" = {values = ["contact", "wrap"]}           # a choice
    [set]                       # fixed overrides of every run
    [vary]                      # the uncertainties: a study's distributions
    "debris.position[2]" = {dist = "uniform", low = 7, high = 13}
    [objective]
    measure = "outcome"         # a measure column
    equals = "captured"         # P(measure == equals): its Wilson bound over the K runs;
    confidence = 0.95           #   without `equals`: the mean of a numeric measure
    direction = "maximize"      # or "minimize"
    cost = "net_mass_kg"        # optional: score = objective -+ cost_weight * cost
    cost_weight = 0.0
    [constraints]               # a measure's or a design quantity's bounds, each draw
    net_mass_kg = {max = 60.0}
    min_safety_factor = {min = 1.0}
    [first]                     # optional: a design evaluated first, e.g. today's, so that
    "net.mesh_length" = 1.0     #   it is scored on the same K draws as the others

**Common random numbers**: the K uncertainty draws (seeded numpy uniforms through each
distribution's inverse CDF, :func:`bulletnet.studies.study.draw`) are drawn once, from the
file's seed, and every design runs the same K; two designs differ by their design alone.

**Reproducible**: designs are evaluated one at a time (a design's K runs in parallel), and
trial n's sampler is seeded from (seed, n), so trial n's design is a function of the seed and
of trials 0 .. n-1 alone: the same file gives the same sequence of designs and, the runs
being deterministic, the same table; whether run straight through or stopped and resumed.

**Resumable**: Optuna's journal (``DIR/optuna.journal``) holds the trials; ``DIR/runs.csv``
the runs. Rerunning into the same DIR resumes: a design stopped half-way keeps its finished
runs and runs only the others; ``trials`` may be raised to go on.

Design quantities (scene targets only, of the design with [set], before any run):
``net_mass_kg`` [kg], the net's nodes and its four corner masses (no tether, no chaser).
"""

from __future__ import annotations

import contextlib
import hashlib
import importlib
import importlib.util
import json
import math
import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..common.errors import ScenarioError
from .report import _numeric, wilson
from .runner import dask_client, fan_out, warm_up
from .study import (
    TAIL,
    Distribution,
    RunTable,
    _clock,
    column_names,
    draw,
    parse_distribution,
    read_table,
    resolve_function,
    study_measures,
    study_run,
)
from .sweep import base_scene, build_variants, plan_table, read_plan, set_table

KEYS = ("scene", "function", "measures", "seed", "trials", "draws", "sampler", "design", "set",
        "vary", "objective", "constraints", "first")
"""The keys of an optimisation file."""

SAMPLERS = ("tpe", "cmaes")
OBJECTIVE_KEYS = ("measure", "equals", "confidence", "direction", "cost", "cost_weight")
DESIGN_QUANTITIES = ("net_mass_kg",)
"""What a scene target's design gives before it runs (:func:`design_quantities`)."""

MAX_TRIALS = 100_000
MAX_DRAWS = 100_000


@dataclass(frozen=True)
class Variable:
    """One design variable: bounds ``low`` < ``high`` in the key's unit (``integer``: whole
    numbers; ``log``: sampled on a log scale), or a list of ``values`` to choose from."""

    low: float | None = None
    high: float | None = None
    integer: bool = False
    log: bool = False
    values: tuple | None = None

    def distribution(self):
        """The Optuna distribution of this variable."""
        from optuna.distributions import (
            CategoricalDistribution,
            FloatDistribution,
            IntDistribution,
        )

        if self.values is not None:
            return CategoricalDistribution(list(self.values))
        if self.integer:
            return IntDistribution(int(self.low), int(self.high), log=self.log)
        return FloatDistribution(self.low, self.high, log=self.log)

    def corners(self) -> tuple:
        """The values a design may take at its extremes (what validation builds)."""
        return (self.values[0], self.values[-1]) if self.values is not None \
            else ((int(self.low), int(self.high)) if self.integer else (self.low, self.high))


def parse_variable(spec, where: str) -> Variable:
    """A [design] entry ``{low, high[, int][, log]}`` or ``{values = [...]}``, validated."""
    if not isinstance(spec, dict):
        raise ScenarioError(f"{where}: expected {{low = ..., high = ...}} or {{values = "
                            f"[...]}}, got {spec!r}")
    unknown = sorted(set(spec) - {"low", "high", "int", "log", "values"})
    if unknown:
        raise ScenarioError(f"{where}: unknown key '{unknown[0]}' (expected low, high, int, "
                            "log; or values)")
    if "values" in spec:
        if set(spec) != {"values"} or not isinstance(spec["values"], list) \
                or not spec["values"]:
            raise ScenarioError(f"{where}: values: expected a non-empty list, alone")
        return Variable(values=tuple(spec["values"]))
    for name in ("int", "log"):
        if not isinstance(spec.get(name, False), bool):
            raise ScenarioError(f"{where}: {name}: expected true or false")
    integer, log = spec.get("int", False), spec.get("log", False)
    low, high = spec.get("low"), spec.get("high")
    for name, value in (("low", low), ("high", high)):
        if isinstance(value, bool) or not isinstance(value, (int, float)) \
                or not math.isfinite(value):
            raise ScenarioError(f"{where}: {name}: expected a finite number, got {value!r}")
        if integer and value != int(value):
            raise ScenarioError(f"{where}: {name}: an integer variable takes whole bounds, got "
                                f"{value}")
    if not low < high:
        raise ScenarioError(f"{where}: expected low < high, got low = {low}, high = {high}")
    if log and low <= 0:
        raise ScenarioError(f"{where}: a log-scale variable needs low > 0, got {low}")
    return Variable(float(low), float(high), integer, log)


@dataclass(frozen=True)
class Objective:
    """What a design scores: the Wilson bound of P(``measure`` == ``equals``) over its K runs
    (lower bound to maximise, upper to minimise; a run that did not complete counts as not
    equal), or without ``equals`` the mean of a numeric measure over its completed runs;
    then ``cost_weight`` times ``cost`` (a measure's mean, or a design quantity) taken off
    (maximise) or added (minimise)."""

    measure: str
    equals: object = None
    confidence: float = 0.95
    direction: str = "maximize"
    cost: str | None = None
    cost_weight: float = 0.0

    @property
    def probability(self) -> bool:
        return self.equals is not None


def parse_objective(spec, names: set[str], where: str) -> Objective:
    """The [objective] table, validated against the measure and quantity ``names``."""
    if not isinstance(spec, dict) or "measure" not in spec:
        raise ScenarioError(f"{where}: an optimisation needs an [objective] with a measure, "
                            "e.g. measure = \"outcome\", equals = \"captured\"")
    unknown = sorted(set(spec) - set(OBJECTIVE_KEYS))
    if unknown:
        raise ScenarioError(f"{where}: unknown key '{unknown[0]}' (expected "
                            f"{', '.join(OBJECTIVE_KEYS)})")
    objective = Objective(**spec)
    for name in ("measure", "cost"):
        value = getattr(objective, name)
        if (value is not None or name == "measure") and value not in names:
            raise ScenarioError(f"{where}: {name}: expected one of {', '.join(sorted(names))}, "
                                f"got {value!r}")
    if not isinstance(objective.confidence, float) or not 0 < objective.confidence < 1:
        raise ScenarioError(f"{where}: confidence: expected a number in (0, 1), got "
                            f"{objective.confidence!r}")
    if objective.direction not in ("maximize", "minimize"):
        raise ScenarioError(f"{where}: direction: expected maximize or minimize, got "
                            f"{objective.direction!r}")
    weight = objective.cost_weight
    if isinstance(weight, bool) or not isinstance(weight, (int, float)) \
            or not math.isfinite(weight) or weight < 0:
        raise ScenarioError(f"{where}: cost_weight: expected a number >= 0, got {weight!r}")
    return objective


def parse_constraints(spec, names: set[str], where: str) -> dict[str, dict]:
    """The [constraints] table: name -> {min} and/or {max}, in the name's unit."""
    if not isinstance(spec, dict):
        raise ScenarioError(f"{where}: expected a table of bounds")
    out = {}
    for name, bound in spec.items():
        here = f"{where}.{name}"
        if name not in names:
            raise ScenarioError(f"{here}: expected one of {', '.join(sorted(names))}")
        if not isinstance(bound, dict) or not bound or set(bound) - {"min", "max"}:
            raise ScenarioError(f"{here}: expected {{min = ...}}, {{max = ...}} or both, got "
                                f"{bound!r}")
        for key, value in bound.items():
            if isinstance(value, bool) or not isinstance(value, (int, float)) \
                    or not math.isfinite(value):
                raise ScenarioError(f"{here}: {key}: expected a finite number, got {value!r}")
        out[name] = {k: float(v) for k, v in bound.items()}
    return out


@dataclass(frozen=True)
class Optimisation:
    """A validated optimisation: the target, the variables, the common draws, the objective
    and constraints."""

    path: Path
    doc: dict
    """The file's document (scene resolved to a name or an absolute path)."""
    scene: str | None
    function: str | None
    seed: int
    trials: int
    sampler: str
    fixed: dict
    design: dict[str, Variable]
    vary: dict[str, Distribution]
    units: dict[str, str]
    """Design and varied key -> its SI unit (``-``: none)."""
    measures: tuple[str, ...]
    objective: Objective
    constraints: dict[str, dict]
    draws: tuple[dict, ...]
    """The K uncertainty draws every design runs (varied key -> value)."""
    scene_sha256: str | None = None
    """SHA-256 of the base scene's TOML (with [set]), to tell a changed scene on resume."""
    first: dict | None = None
    """A design (key -> value) evaluated as trial 0, or None: the sampler's from the start."""

    @property
    def columns(self) -> dict[str, str]:
        """Design and varied key -> its column in the table (``KEY_UNIT``)."""
        return column_names(self.units)

    @property
    def header(self) -> list[str]:
        return ["run", "design", "draw", *self.columns.values(), *TAIL, *self.measures]

    def describe(self) -> dict:
        """JSON-ready: ``DIR/optimize.json`` (what resuming checks and the report reads)."""
        return {"source": str(self.path), "file": self.doc, "units": self.units,
                "columns": self.columns, "measures": list(self.measures),
                "scene_sha256": self.scene_sha256}

    def distributions(self) -> dict:
        return {key: v.distribution() for key, v in self.design.items()}


def load_optimisation(path: str | Path, overrides: dict | None = None) -> Optimisation:
    """Parse and validate an optimisation file; its scene built at the design's extremes and
    for every draw, so a bad key or value is one error before anything runs. ``overrides``
    (``bulletnet optimize --set``) join the file's [set], and are kept with it."""
    path = Path(path)
    doc = read_plan(path, KEYS)
    if overrides:
        varied = [*plan_table(doc.get("design", {}), path, "design"),
                  *plan_table(doc.get("vary", {}), path, "vary")]
        doc["set"] = set_table(doc, path, overrides, varied)
    if "scene" in doc:
        doc["scene"] = base_scene(doc, path)
        if doc["scene"].endswith(".toml"):
            doc["scene"] = str(Path(doc["scene"]).resolve())
    return parse_optimisation(doc, path)


def parse_optimisation(doc: dict, path: Path) -> Optimisation:
    """An optimisation from its document (a file's, or the one ``optimize.json`` keeps)."""
    if "scene" not in doc and "function" not in doc:
        raise ScenarioError(f"{path}: an optimisation needs a scene, a function = "
                            "\"module:name\", or both")
    scene, function = doc.get("scene"), doc.get("function")
    if function is not None:
        resolve_function(function, f"{path}: function")
    seed, trials, draws = doc.get("seed"), doc.get("trials"), doc.get("draws")
    for name, value, least, most in (("seed", seed, 0, None), ("trials", trials, 1, MAX_TRIALS),
                                     ("draws", draws, 1, MAX_DRAWS)):
        if isinstance(value, bool) or not isinstance(value, int) or value < least \
                or (most is not None and value > most):
            raise ScenarioError(f"{path}: {name}: expected an integer >= {least}"
                                + (f" and <= {most}" if most else "") + f", got {value!r}")
    sampler = doc.get("sampler", "tpe")
    if sampler not in SAMPLERS:
        raise ScenarioError(f"{path}: sampler: expected one of {', '.join(SAMPLERS)}, got "
                            f"{sampler!r}")
    fixed = plan_table(doc.get("set", {}), path, "set")
    design = {k: parse_variable(v, f"{path}: design.{k}")
              for k, v in plan_table(doc.get("design", {}), path, "design").items()}
    if not design:
        raise ScenarioError(f"{path}: [design]: an optimisation has at least one variable")
    vary = {k: parse_distribution(v, f"{path}: vary.{k}")
            for k, v in plan_table(doc.get("vary", {}), path, "vary").items()}
    keys = [*fixed, *design, *vary]
    twice = sorted({k for k in keys if keys.count(k) > 1})
    if twice:
        raise ScenarioError(f"{path}: '{twice[0]}' is in more than one of [set], [design], "
                            "[vary]")
    measures = study_measures(doc, scene, function, fixed, path)
    names = set(measures) | (set(DESIGN_QUANTITIES) if scene is not None else set())
    objective = parse_objective(doc.get("objective"), names, f"{path}: objective")
    constraints = parse_constraints(doc.get("constraints", {}), names, f"{path}: constraints")
    if constraints and sampler == "cmaes":
        raise ScenarioError(f"{path}: constraints: Optuna's CMA-ES sampler takes none; use "
                            "sampler = \"tpe\"")
    first = parse_first(doc.get("first"), design, f"{path}: first")
    drawn = draw("random", draws, seed, vary) if vary else [{} for _ in range(draws)]
    units = dict.fromkeys([*design, *vary], "-")
    digest = None
    if scene is not None:
        from ..model.scenario import load, to_toml, unit_of

        try:
            units = {k: unit_of(k) for k in units}
            digest = hashlib.sha256(to_toml(load(scene, fixed)).encode()).hexdigest()
        except ScenarioError as exc:
            raise ScenarioError(f"{path}: {exc}") from None
        corners = [{k: v.corners()[j] for k, v in design.items()} for j in (0, 1)]
        build_variants(scene, fixed, [c | drawn[0] for c in corners]
                       + [corners[0] | d for d in drawn], path, label="design/draw")
    return Optimisation(path=path, doc=doc, scene=scene, function=function, seed=seed,
                        trials=trials, sampler=sampler, fixed=fixed, design=design, vary=vary,
                        units=units, measures=measures, objective=objective,
                        constraints=constraints, draws=tuple(drawn), scene_sha256=digest,
                        first=first)


def parse_first(spec, design: dict[str, Variable], where: str) -> dict | None:
    """The ``[first]`` design: a value for every design variable, in its domain."""
    if spec is None:
        return None
    if not isinstance(spec, dict) or set(spec) != set(design):
        raise ScenarioError(f"{where}: expected a value for each design variable "
                            f"({', '.join(design)}), got {spec!r}")
    for key, value in spec.items():
        v = design[key]
        inside = value in v.values if v.values is not None else (
            isinstance(value, int | float) and not isinstance(value, bool)
            and v.low <= value <= v.high and (not v.integer or value == int(value)))
        if not inside:
            raise ScenarioError(f"{where}.{key}: {value!r} is outside the variable's domain")
    return dict(spec)


def design_quantities(opt: Optimisation, params: dict) -> dict:
    """What a scene target's design gives before it runs: ``net_mass_kg`` [kg], the net's
    nodes and its corner masses; {} for a function target."""
    if opt.scene is None:
        return {}
    from ..model.builder import build_model
    from ..model.net import NodeKind
    from ..model.scenario import load

    model = build_model(load(opt.scene, opt.fixed | params))
    net = np.isin(model.kind, [NodeKind.INNER, NodeKind.EDGE, NodeKind.CORNER,
                               NodeKind.CORNER_MASS])
    return {"net_mass_kg": float(model.mass[net].sum())}


# ---------------------------------------------------------------------------------------------
# scoring a design

def assess(opt: Optimisation, rows: list[dict], quantities: dict) -> dict:
    """A design's scores from its runs' rows and its design quantities: ``objective`` (None
    if no run gives it), the success count and Wilson interval (``p``, ``low``, ``high``) of
    a probability objective, ``cost``, ``score``, each constraint's violation (<= 0:
    satisfied; the worst draw's) and ``feasible``. A run that did not complete counts
    against a probability objective's design (not a success of a maximised probability, an
    event of a minimised one); a mean objective and the constraints are taken over the
    completed runs (a failure that a draw causes in every design must not leave the
    optimisation without a score: ``completed`` says how many runs count)."""
    ob = opt.objective
    done = [r for r in rows if r["status"] == "completed"]
    incomplete = len(rows) - len(done)
    result = {"runs": len(rows), "completed": len(done), **quantities}

    def values(name: str) -> list[float]:
        if name in quantities:
            return [quantities[name]]
        return [float(r[name]) for r in done if _numeric(r.get(name))]

    if ob.probability:
        hits = sum(r.get(ob.measure) == ob.equals for r in done)
        counted = hits if ob.direction == "maximize" else hits + incomplete
        p, low, high = wilson(counted, len(rows), ob.confidence)
        result |= {"successes": hits, "p": p, "low": low, "high": high,
                   "objective": low if ob.direction == "maximize" else high}
    else:
        found = values(ob.measure)
        result["objective"] = statistics.fmean(found) if found else None
    cost = 0.0
    if ob.cost is not None:
        found = values(ob.cost)
        cost = statistics.fmean(found) if found else math.nan
        result["cost"] = cost
    sign = -1.0 if ob.direction == "maximize" else 1.0
    penalty = ob.cost_weight * cost if ob.cost_weight else 0.0  # a cost for the front only
    score = None if result["objective"] is None else result["objective"] + sign * penalty
    result["score"] = score if score is None or math.isfinite(score) else None
    violations = {}
    for name, bound in opt.constraints.items():
        found = values(name)
        worst = [bound["min"] - v for v in found] if "min" in bound else []
        worst += [v - bound["max"] for v in found] if "max" in bound else []
        violations[name] = max(worst, default=0.0)
    result["constraints"] = violations
    result["feasible"] = all(v <= 0 for v in violations.values())
    return result


# ---------------------------------------------------------------------------------------------
# running

def optuna_module():
    """Optuna, imported lazily, quiet."""
    try:
        optuna = importlib.import_module("optuna")
    except ImportError:
        raise ScenarioError("optimisation needs Optuna: pip install 'bulletnet[study]'") \
            from None
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    return optuna


def make_sampler(opt: Optimisation, number: int):
    """Trial ``number``'s sampler, seeded from (seed, number): its design depends on the
    seed and the trials before it only (resuming asks what a straight run asks)."""
    optuna = optuna_module()
    seed = int(np.random.SeedSequence([opt.seed, number]).generate_state(1)[0])
    if opt.sampler == "cmaes":
        if importlib.util.find_spec("cmaes") is None:
            raise ScenarioError("sampler = \"cmaes\" needs the cmaes package: pip install "
                                "cmaes")
        return optuna.samplers.CmaEsSampler(seed=seed)
    return optuna.samplers.TPESampler(seed=seed)


def open_study(opt: Optimisation, out: Path, create: bool = True):
    """The Optuna study kept in ``out/optuna.journal``."""
    optuna = optuna_module()
    from optuna.storages.journal import JournalFileBackend, JournalStorage

    journal = out / "optuna.journal"
    if not create and not journal.exists():
        raise ScenarioError(f"{out}: no optuna.journal: not an optimisation folder")
    storage = JournalStorage(JournalFileBackend(str(journal)))
    return optuna.create_study(study_name="optimize", storage=storage, load_if_exists=True,
                               direction=opt.objective.direction,
                               sampler=make_sampler(opt, 0))


@dataclass(frozen=True)
class _Planned:
    """What a :class:`RunTable` checks: the header, columns and the planned inputs."""

    header: list
    columns: dict
    values: list


class Runner:
    """Where a design's runs go: serial in this process, or one Dask client for the whole
    optimisation; opened, and each worker warmed up with the base scene's kernels, once there
    is a run to do."""

    def __init__(self, opt: Optimisation, scheduler: str | None, workers: int, serial: bool):
        self.opt, self.serial = opt, serial
        self.scheduler, self.workers = scheduler, workers
        self.stack = contextlib.ExitStack()
        self.client = None
        self.ready = False

    def _start(self) -> None:
        warm = (self.opt.scene, (self.opt.fixed,)) if self.opt.scene is not None else None
        if not self.serial:
            self.client = self.stack.enter_context(dask_client(self.scheduler, self.workers))
            if warm is not None:
                self.client.run(warm_up, *warm)
        elif warm is not None:
            warm_up(*warm)
        self.ready = True

    def __enter__(self) -> Runner:
        return self

    def __exit__(self, *exc) -> None:
        self.stack.__exit__(*exc)

    def evaluate(self, number: int, params: dict, draws: tuple[dict, ...], table: RunTable,
                 first: int) -> list[dict]:
        """Run the draws of design ``number`` (runs ``first`` + k) not yet in ``table``, and
        return the design's rows, in draw order."""
        opt = self.opt
        jobs = [(first + k, opt.scene, opt.function, opt.fixed | params, d, opt.measures, None)
                for k, d in enumerate(draws) if first + k not in table.rows]

        def lost(job: tuple, message: str) -> dict:
            return {"run": job[0], "status": "failed", "message": message, "wall_s": None}

        if jobs and not self.ready:
            self._start()
        columns = opt.columns
        for result in fan_out(study_run, jobs, lost, serial=self.serial, client=self.client):
            k = result["run"] - first
            inputs = params | draws[k]
            table.append({"design": number, "draw": k,
                          **{columns[key]: inputs[key] for key in columns}, **result})
        return [table.rows[first + k] for k in range(len(draws))]


def _check_folder(opt: Optimisation, out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    described = out / "optimize.json"
    doc = json.loads(json.dumps(opt.describe()))
    if described.exists():
        old = json.loads(described.read_text(encoding="utf-8"))
        same = {k: v for k, v in old.items() if k != "source"}
        new = {k: v for k, v in doc.items() if k != "source"}
        # more trials go on from where the folder stopped
        same["file"] = {k: v for k, v in same["file"].items() if k != "trials"}
        new["file"] = {k: v for k, v in new["file"].items() if k != "trials"}
        if same != new:
            raise ScenarioError(f"{out}: holds another optimisation (or this one before a "
                                "change); use another --out")
    described.write_text(json.dumps(doc, indent=2) + "\n", encoding="utf-8")


def _table(opt: Optimisation, path: Path, designs: list[tuple[int, dict]],
           draws: tuple[dict, ...]) -> RunTable:
    """The run table at ``path``: run n K + k is design n's draw k."""
    values = [{}] * ((max((n for n, _ in designs), default=-1) + 1) * len(draws))
    for n, params in designs:
        for k, d in enumerate(draws):
            values[n * len(draws) + k] = params | d
    return RunTable(path, _Planned(opt.header, opt.columns, values))


def run_optimisation(opt: Optimisation, out: Path, scheduler: str | None = None,
                     workers: int = 2, serial: bool = False,
                     log: Callable[[str], None] | None = None) -> dict:
    """Evaluate designs until ``opt.trials`` are done (resuming what ``out`` holds): Optuna
    asks a design, its K runs go to the runner, their rows to ``out/runs.csv``, its score to
    Optuna. Returns ``trials`` (done now), ``skipped`` (done before), ``wall_s`` [s] and
    ``best`` (:func:`best_trial`). On Ctrl-C the runs and trials so far are kept and
    KeyboardInterrupt is re-raised."""
    optuna_module()  # installed, and quiet
    from optuna.trial import Trial, TrialState

    log = log or (lambda _: None)
    _check_folder(opt, out)
    study = open_study(opt, out)
    if opt.first is not None and not study.get_trials(deepcopy=False):
        study.enqueue_trial(opt.first)  # trial 0: the next ask gives these values
    trials = asked(study)
    K = len(opt.draws)
    table = _table(opt, out / "runs.csv", [(t.number, t.params) for t in trials], opt.draws)
    finished = [t for t in trials if t.state.is_finished()]
    skipped = len(finished)
    log(f"optimize: {opt.trials} designs of {K} runs planned, {skipped} done, "
        f"{max(opt.trials - skipped, 0)} to run")
    start = time.perf_counter()
    ran = 0
    try:
        with Runner(opt, scheduler, workers, serial) as runner:
            while True:
                trials = asked(study)
                running = [t for t in trials if t.state == TrialState.RUNNING]
                if not running and len(trials) >= opt.trials:
                    break
                number = running[0].number if running else len(trials)
                study.sampler = make_sampler(opt, number)
                trial = Trial(study, running[0]._trial_id) if running \
                    else study.ask(opt.distributions())
                params = dict(trial.params)
                if not running:
                    table.study.values.extend(params | d for d in opt.draws)
                rows = runner.evaluate(number, params, opt.draws, table, number * K)
                scores = assess(opt, rows, design_quantities(opt, params))
                for key, value in scores.items():
                    trial.set_user_attr(key, value)
                for name, violation in scores["constraints"].items():
                    trial.set_constraint(name, violation)  # what a constrained TPE reads
                if scores["score"] is None:
                    study.tell(trial, state=TrialState.FAIL)
                else:
                    study.tell(trial, scores["score"])
                ran += 1
                log(_progress(study, opt, number, scores, ran, skipped,
                              time.perf_counter() - start))
    finally:
        table.close()
    return {"trials": ran, "skipped": skipped, "wall_s": time.perf_counter() - start,
            "best": best_trial(study), "table": out / "runs.csv"}


def asked(study) -> list:
    """The study's trials asked so far (not one enqueued and waiting to be asked)."""
    from optuna.trial import TrialState

    return [t for t in study.get_trials(deepcopy=False) if t.state != TrialState.WAITING]


def best_trial(study):
    """The feasible completed trial of the best score, or None; of equal scores (K runs give
    few distinct Wilson bounds) the one of least cost, then the first."""
    from optuna.trial import TrialState

    done = [t for t in study.get_trials(deepcopy=False, states=(TrialState.COMPLETE,))
            if t.user_attrs.get("feasible", True)]
    if not done:
        return None
    sign = 1.0 if study.direction.name == "MAXIMIZE" else -1.0

    def cost(t) -> float:
        c = t.user_attrs.get("cost")
        return c if isinstance(c, int | float) and math.isfinite(c) else math.inf

    return max(done, key=lambda t: (sign * t.value, -cost(t), -t.number))


def _progress(study, opt: Optimisation, number: int, scores: dict, ran: int, skipped: int,
              wall: float) -> str:
    best = best_trial(study)
    left = max(opt.trials - skipped - ran, 0)
    eta = wall / ran * left
    score = "failed" if scores["score"] is None else f"{scores['score']:.4g}" + (
        "" if scores["feasible"] else " infeasible")
    where = "none feasible yet" if best is None else \
        f"best {best.value:.4g} (design {best.number})"
    return (f"optimize: design {number + 1}/{opt.trials}: score {score}, {scores['completed']}"
            f"/{scores['runs']} runs completed; {where}; ETA {_clock(eta)}")


def confirm_seed(seed: int) -> int:
    """The seed of the confirmation draws: a stream apart from the optimisation's."""
    return int(np.random.SeedSequence([seed, 0xC0F1]).generate_state(1)[0])


def confirm(opt: Optimisation, out: Path, number: int, params: dict, runs: int,
            scheduler: str | None = None, workers: int = 2, serial: bool = False) -> dict:
    """Run design ``number`` on ``runs`` fresh draws (:func:`confirm_seed`) into
    ``out/confirm_NNNN.csv`` (resumable) and score it as the optimisation did
    (:func:`assess`)."""
    draws = tuple(draw("random", runs, confirm_seed(opt.seed), opt.vary)) if opt.vary \
        else tuple({} for _ in range(runs))
    table = _table(opt, out / f"confirm_{number:04d}.csv", [(0, params)], draws)
    try:
        with Runner(opt, scheduler, workers, serial) as runner:
            rows = runner.evaluate(number, params, draws, table, 0)
    finally:
        table.close()
    return {"design": number, "draws": runs, "seed": confirm_seed(opt.seed),
            **assess(opt, rows, design_quantities(opt, params))}


def load_folder(out: Path) -> tuple[Optimisation, object, list[dict]]:
    """An optimisation folder's description, its Optuna study and its run rows."""
    try:
        doc = json.loads((out / "optimize.json").read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise ScenarioError(f"{out}: not an optimisation folder (optimize.json: {exc})") \
            from None
    opt = parse_optimisation(doc["file"], out / "optimize.json")
    rows = read_table(out / "runs.csv")[1] if (out / "runs.csv").exists() else []
    return opt, open_study(opt, out, create=False), rows
