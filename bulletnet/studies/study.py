"""Studies: Monte Carlo and Sobol' designs over a scene (or a Python function), run on Dask
(:func:`bulletnet.studies.runner.fan_out`), one row per run appended to ``DIR/runs.csv`` as it
finishes; a study stopped in any way resumes where it stopped.

A study file (TOML; ``docs/studies.md`` has the whole format)::

    scene = "deployment"        # base scene: a name or a path (relative to this file); or
    # function = "module:name"  # a Python callable run for each run (see below)
    design = "sobol"            # "random": seeded Monte Carlo draws; "sobol": Saltelli's
    runs = 64                   # random: the number of runs; sobol: the base sample count N,
    seed = 1                    #   a power of 2, for N (D + 2) runs (D varied keys; first-
    [set]                       #   order and total indices, no second order)
    "scene.duration" = 1.0      # overrides of every run (scene keys, SI units)
    [vary]                      # scene keys (``name[i]``: a vector's component) and their
    "net.mesh_length" = {dist = "uniform", low = 0.4, high = 0.6}     # distributions [SI]

Distributions (:data:`DISTRIBUTIONS`): ``normal`` (mean, std), ``uniform`` (low, high),
``truncnormal`` (mean, std, low, high), ``loguniform`` (low, high > low > 0) and ``choice``
(values: each equally likely). Every design first draws uniforms in (0, 1), shape (runs, D):
``numpy.random.default_rng(seed)`` for ``random`` (so run k's draws are row k, and more runs
keep the first ones), SALib's scrambled Sobol' sequence in Saltelli's scheme for ``sobol``;
each column goes through its distribution's inverse CDF. Run k is therefore reproducible
from the file and k, and its drawn values are stored in its row.

A ``function = "module:name"`` target is called once per run, on a worker, and returns a
dict of ``measures`` (named in the file): with a ``scene``, on the run's
:class:`~bulletnet.model.scenario.Scenario` (the file's scene with [set] and the drawn values;
e.g. :func:`bending_effect` runs it twice); without one, on the dict of [set] and drawn
inputs (e.g. :func:`ishigami`, the standard check of a Sobol' analysis).

``DIR/runs.csv`` has a fixed header: ``run``, one column per varied key (named
``KEY_UNIT``, e.g. ``net.mesh_length_m``), ``status`` (completed, diverged, error, failed:
the worker died), ``message``, ``wall_s`` [s] and the measures; ``DIR/study.json`` the
study's description (what the report reads). Rerunning the same study into the same DIR
skips every run already in the table.
"""

from __future__ import annotations

import csv
import hashlib
import importlib
import json
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..common.errors import BulletnetError, ScenarioError
from .measures import summary_measures
from .runner import estimated_cost, fan_out, kernel_kind, run_scene
from .sweep import base_scene, build_variants, plan_table, read_plan, set_table, write_table

DESIGNS = ("random", "sobol")

DISTRIBUTIONS = {
    "normal": ("mean", "std"),
    "uniform": ("low", "high"),
    "truncnormal": ("mean", "std", "low", "high"),
    "loguniform": ("low", "high"),
    "choice": ("values",),
}
"""Each distribution's parameters, in the unit of the key it draws."""

HEAD = ("run",)
TAIL = ("status", "message", "wall_s")
"""The table's columns before the inputs and between the inputs and the measures."""

MAX_RUNS = 1_000_000
"""Most runs a study may plan [-]."""


@dataclass(frozen=True)
class Distribution:
    """One varied key's distribution: ``dist`` (a key of :data:`DISTRIBUTIONS`) and its
    parameters, in the key's unit."""

    dist: str
    params: dict

    def values(self, u: np.ndarray) -> list:
        """The values at uniforms ``u`` in (0, 1), shape (R,), through the inverse CDF: a list
        of R floats (``choice``: of its values)."""
        p = self.params
        u = np.clip(u, np.nextafter(0.0, 1.0), np.nextafter(1.0, 0.0))
        if self.dist == "choice":
            n = len(p["values"])
            return [p["values"][min(int(x * n), n - 1)] for x in u]
        if self.dist == "uniform":
            x = p["low"] + u * (p["high"] - p["low"])
        elif self.dist == "loguniform":
            x = np.exp(np.log(p["low"]) + u * (np.log(p["high"]) - np.log(p["low"])))
        elif self.dist == "normal":
            from scipy.special import ndtri

            x = p["mean"] + p["std"] * ndtri(u)
        else:
            from scipy.stats import truncnorm

            a, b = ((p["low"] - p["mean"]) / p["std"], (p["high"] - p["mean"]) / p["std"])
            x = truncnorm.ppf(u, a, b, loc=p["mean"], scale=p["std"])
        return [float(v) for v in x]


def parse_distribution(spec, where: str) -> Distribution:
    """A [vary] entry ``{dist = ..., ...}`` validated: known distribution, exactly its
    parameters, finite numbers in a consistent order."""
    if not isinstance(spec, dict) or "dist" not in spec:
        raise ScenarioError(f"{where}: expected a distribution such as {{dist = \"uniform\", "
                            f"low = 0, high = 1}}, got {spec!r}")
    dist = spec["dist"]
    if dist not in DISTRIBUTIONS:
        raise ScenarioError(f"{where}: dist: expected one of {', '.join(DISTRIBUTIONS)}, "
                            f"got {dist!r}")
    params = {k: v for k, v in spec.items() if k != "dist"}
    names = DISTRIBUTIONS[dist]
    if set(params) != set(names):
        raise ScenarioError(f"{where}: a {dist} distribution takes {', '.join(names)}, got "
                            f"{', '.join(sorted(params)) or 'nothing'}")
    if dist == "choice":
        if not isinstance(params["values"], list) or not params["values"]:
            raise ScenarioError(f"{where}: values: expected a non-empty list")
        return Distribution(dist, params)
    for name, value in params.items():
        if isinstance(value, bool) or not isinstance(value, (int, float)) \
                or not math.isfinite(value):
            raise ScenarioError(f"{where}: {name}: expected a finite number, got {value!r}")
    params = {k: float(v) for k, v in params.items()}
    if "std" in params and params["std"] <= 0:
        raise ScenarioError(f"{where}: std: expected a positive number, got {params['std']}")
    if "low" in params and not params["low"] < params["high"]:
        raise ScenarioError(f"{where}: expected low < high, got low = {params['low']}, "
                            f"high = {params['high']}")
    if dist == "loguniform" and params["low"] <= 0:
        raise ScenarioError(f"{where}: low: a loguniform distribution needs low > 0, got "
                            f"{params['low']}")
    return Distribution(dist, params)


@dataclass(frozen=True)
class Study:
    """A validated study: what runs, the design and every run's drawn inputs."""

    path: Path
    """The study file."""
    scene: str | None
    """Base scene (name or path), or None for a function of plain inputs."""
    function: str | None
    """``module:name`` of the callable each run calls, or None to run the scene."""
    design: str
    """``random`` or ``sobol``."""
    runs: int
    """The file's ``runs``: random, the run count; sobol, the base sample count N."""
    seed: int
    fixed: dict
    """[set]: overrides (or inputs) of every run."""
    vary: dict[str, Distribution]
    """Varied key -> its distribution, in the file's order."""
    units: dict[str, str]
    """Varied key -> its SI unit (``-``: none)."""
    measures: tuple[str, ...]
    """The measures each run returns (column names, with their units)."""
    values: tuple[dict, ...]
    """Every run's drawn inputs (varied key -> value), in run order."""
    scene_sha256: str | None = None
    """SHA-256 of the base scene's TOML (with [set]), to tell a changed scene on resume."""

    @property
    def columns(self) -> dict[str, str]:
        """Varied key -> its column in the table: ``KEY_UNIT`` (``net.mesh_length_m``)."""
        return column_names(self.units)

    @property
    def header(self) -> list[str]:
        """The table's columns."""
        return [*HEAD, *self.columns.values(), *TAIL, *self.measures]

    def describe(self) -> dict:
        """The study as JSON-ready data (``DIR/study.json``), for resuming and the report."""
        return {
            "source": str(self.path), "scene": self.scene, "function": self.function,
            "design": self.design, "runs": self.runs, "seed": self.seed,
            "run_count": len(self.values), "set": self.fixed,
            "vary": {k: {"dist": d.dist, **d.params} for k, d in self.vary.items()},
            "units": self.units, "columns": self.columns, "measures": list(self.measures),
            "scene_sha256": self.scene_sha256,
        }


def column_names(units: dict[str, str]) -> dict[str, str]:
    """Key -> its column in a run table: ``KEY_UNIT`` (``net.mesh_length_m``), or the key
    itself where its unit is ``-``."""
    return {key: key if unit == "-" else f"{key}_{unit.replace('/', '_').replace('^', '')}"
            for key, unit in units.items()}


def load_study(path: str | Path, overrides: dict | None = None) -> Study:
    """Parse and validate a study file, draw its design, and build every run's scene: a bad
    key, distribution or drawn value is one clear error before anything runs. ``overrides``
    (scene key -> value; ``bulletnet study --set``) are set in every run on top of the file's
    [set], and are part of the study as [set] is (study.json, the resume check)."""
    path = Path(path)
    doc = read_plan(path, ("scene", "function", "design", "runs", "seed", "measures", "set",
                           "vary"))
    if "scene" not in doc and "function" not in doc:
        raise ScenarioError(f"{path}: a study needs a scene, a function = \"module:name\", "
                            "or both")
    scene = base_scene(doc, path) if "scene" in doc else None
    function = doc.get("function")
    if function is not None:
        resolve_function(function, f"{path}: function")
    design = doc.get("design")
    if design not in DESIGNS:
        raise ScenarioError(f"{path}: design: expected one of {', '.join(DESIGNS)}, got "
                            f"{design!r}")
    runs, seed = doc.get("runs"), doc.get("seed")
    for name, value in (("runs", runs), ("seed", seed)):
        if isinstance(value, bool) or not isinstance(value, int) or value < (
                1 if name == "runs" else 0):
            raise ScenarioError(f"{path}: {name}: expected an integer >= "
                                f"{1 if name == 'runs' else 0}, got {value!r}")
    if design == "sobol" and (runs < 2 or runs & (runs - 1)):
        raise ScenarioError(f"{path}: runs: design 'sobol' takes the base sample count N, a "
                            f"power of 2 >= 2 (N (D + 2) runs in all), got {runs}")
    vary = plan_table(doc.get("vary", {}), path, "vary")
    if not vary:
        raise ScenarioError(f"{path}: [vary]: a study varies at least one key")
    fixed = set_table(doc, path, overrides, vary)
    both = sorted(set(fixed) & set(vary))
    if both:
        raise ScenarioError(f"{path}: '{both[0]}' is both in [set] and in [vary]")
    dists = {k: parse_distribution(v, f"{path}: vary.{k}") for k, v in vary.items()}
    total = runs * (len(dists) + 2) if design == "sobol" else runs
    if total > MAX_RUNS:
        raise ScenarioError(f"{path}: {total} runs planned; at most {MAX_RUNS}")
    measures = study_measures(doc, scene, function, fixed, path)
    values = draw(design, runs, seed, dists)
    units = {k: "-" for k in dists}
    digest = None
    if scene is not None:
        from ..model.scenario import load, to_toml, unit_of

        try:
            units = {k: unit_of(k) for k in dists}
            digest = hashlib.sha256(to_toml(load(scene, fixed)).encode()).hexdigest()
        except ScenarioError as exc:
            raise ScenarioError(f"{path}: {exc}") from None
        build_variants(scene, fixed, list(values), path, label="run")
    return Study(path=path, scene=scene, function=function, design=design, runs=runs,
                 seed=seed, fixed=fixed, vary=dists, units=units, measures=measures,
                 values=tuple(values), scene_sha256=digest)


def study_measures(doc: dict, scene: str | None, function: str | None, fixed: dict,
                   path: Path) -> tuple[str, ...]:
    """The measure columns: a function study's ``measures`` list, a scene's own measures."""
    measures = doc.get("measures")
    if function is None:
        if measures is not None:
            raise ScenarioError(f"{path}: measures: only for a function study (a scene's "
                                "runs give the scene's summary measures)")
        from ..model.scenario import load

        return tuple(summary_measures(load(scene, fixed)))
    if (not isinstance(measures, list) or not measures
            or not all(isinstance(m, str) and m for m in measures)):
        raise ScenarioError(f"{path}: measures: a function study names the measures its "
                            f"function returns, e.g. measures = [\"y\"]; got {measures!r}")
    reserved = sorted(set(measures) & {*HEAD, *TAIL})
    if reserved:
        raise ScenarioError(f"{path}: measures: '{reserved[0]}' is a column of every study")
    return tuple(measures)


MOVED_MODULES = {"bulletnet.study": "bulletnet.studies.study"}
"""Modules that study files written before the package's layering name (old -> new), so that
their folders still resume."""


def resolve_function(name: str, where: str = "function") -> Callable:
    """The callable ``module:name`` names; one clear error if it cannot be imported."""
    module, _, attr = name.partition(":") if isinstance(name, str) else ("", "", "")
    module = MOVED_MODULES.get(module, module)
    if not module or not attr:
        raise ScenarioError(f"{where}: expected \"module:name\", got {name!r}")
    try:
        fn = getattr(importlib.import_module(module), attr)
    except (ImportError, AttributeError) as exc:
        raise ScenarioError(f"{where}: cannot import {name!r}: {exc}") from None
    if not callable(fn):
        raise ScenarioError(f"{where}: {name!r} is not callable")
    return fn


def unit_design(design: str, runs: int, seed: int, dims: int) -> np.ndarray:
    """Uniform draws in [0, 1) of every run, shape (R, dims): seeded numpy (R = runs) for
    ``random``; SALib's scrambled Sobol' sequence in Saltelli's scheme without second order
    (R = runs (dims + 2)) for ``sobol``."""
    if design == "random":
        return np.random.default_rng(seed).random((runs, dims))
    sobol = salib("sample")
    problem = {"num_vars": dims, "names": [f"x{j}" for j in range(dims)],
               "bounds": [[0.0, 1.0]] * dims}
    return sobol.sample(problem, runs, calc_second_order=False, seed=seed)


def salib(part: str):
    """SALib's Sobol' module of ``part`` (``sample`` or ``analyze``), imported lazily."""
    try:
        return importlib.import_module(f"SALib.{part}.sobol")
    except ImportError:
        raise ScenarioError("Sobol' designs need SALib: pip install 'bulletnet[study]'") \
            from None


def draw(design: str, runs: int, seed: int, vary: dict[str, Distribution]) -> list[dict]:
    """Every run's inputs (key -> value), in run order (:func:`unit_design`, then each
    key's inverse CDF)."""
    u = unit_design(design, runs, seed, len(vary))
    columns = {key: dist.values(u[:, j]) for j, (key, dist) in enumerate(vary.items())}
    return [{key: columns[key][k] for key in vary} for k in range(u.shape[0])]


# ---------------------------------------------------------------------------------------------
# one run, on a worker

def study_run(index: int, scene: str | None, function: str | None, fixed: dict, inputs: dict,
              measures: tuple[str, ...], record: str | None) -> dict:
    """Run ``index`` of a study (in a worker; never raises): ``run``, ``status``, ``message``,
    ``wall_s`` [s] and the measures. A scene study runs the scene (recorded to ``record``, or
    to a temporary file) and measures it; a function study calls the function."""
    if function is None:
        row = run_scene(scene, fixed | inputs, record)
        row.pop("steps")
        return {"run": index, **row}
    row = {"run": index, "status": "error", "message": "", "wall_s": None}
    values = dict.fromkeys(measures)
    start = time.perf_counter()
    try:
        fn = resolve_function(function)
        if scene is None:
            result = fn(fixed | inputs)
        else:
            from ..model.scenario import load

            result = fn(load(scene, fixed | inputs))
        if not isinstance(result, dict) or set(result) != set(measures):
            got = sorted(result) if isinstance(result, dict) else type(result).__name__
            raise ScenarioError(f"{function} returned {got}, expected a dict of the study's "
                                f"measures {list(measures)}")
        values = {k: v.item() if isinstance(v, np.generic) else v for k, v in result.items()}
        row["status"] = "completed"
    except BulletnetError as exc:
        row |= {"status": "diverged" if exc.exit_code == 3 else "error", "message": str(exc)}
    except Exception as exc:  # noqa: BLE001 (one bad run must not stop the study)
        row["message"] = f"{type(exc).__name__}: {exc}"
    row["wall_s"] = time.perf_counter() - start
    return row | values


# ---------------------------------------------------------------------------------------------
# the table

def _cell(value) -> str:
    """A value as the table writes it: exact float text (repr), '' for None, one line."""
    if value is None:
        return ""
    return " ".join(str(value).split()) if isinstance(value, str) else str(value)


def parse_cell(text: str):
    """A table cell back to its value: '' -> None, True/False, an int, a float (bit for bit
    what was written), else the text."""
    if text == "":
        return None
    if text in ("True", "False"):
        return text == "True"
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


def read_table(path: Path) -> tuple[list[str], list[dict]]:
    """The header and rows of a study table (typed, :func:`parse_cell`); a last line cut off
    by a killed driver is ignored."""
    text = path.read_text(encoding="utf-8")
    lines = text.splitlines(keepends=True)
    if lines and not lines[-1].endswith("\n"):
        lines = lines[:-1]
    reader = csv.reader(lines)
    header = next(reader, [])
    rows = [{k: parse_cell(v) for k, v in zip(header, cells, strict=True)} for cells in reader
            if len(cells) == len(header)]
    return header, rows


def latest(rows: list[dict]) -> dict[int, dict]:
    """Run index -> its last row (a retried run appends a second one)."""
    return {row["run"]: row for row in rows}


class RunTable:
    """``DIR/runs.csv``, opened for appending: each finished run is one line, written and
    flushed as it arrives, so a killed driver loses no finished row. ``study``: a
    :class:`Study`, or anything with its ``header``, ``columns`` and ``values`` (the planned
    inputs of the runs already in the table, which it checks)."""

    def __init__(self, path: Path, study: Study):
        self.path = path
        self.study = study
        self.header = study.header
        self.rows: dict[int, dict] = {}
        header, rows = read_table(path) if path.exists() else ([], [])
        if header:
            if header != self.header:
                raise ScenarioError(f"{path}: its columns are not this study's; use another "
                                    "--out")
            self.rows = latest(rows)
            self._check_inputs()
            # rewrite without a line cut off by a killed driver
            write_table(list(self.rows.values()), path.parent, path.stem, self.header)
        else:
            write_table([], path.parent, path.stem, self.header)
        self.file = path.open("a", newline="", encoding="utf-8")
        self.writer = csv.writer(self.file)

    def _check_inputs(self) -> None:
        columns = self.study.columns
        for k, row in self.rows.items():
            planned = self.study.values[k] if 0 <= k < len(self.study.values) else None
            if planned is None or any(_cell(row[columns[key]]) != _cell(value)
                                      for key, value in planned.items()):
                raise ScenarioError(f"{self.path}: run {k}'s inputs are not this study's; use "
                                    "another --out")

    def append(self, row: dict) -> None:
        self.writer.writerow([_cell(row.get(k)) for k in self.header])
        self.file.flush()
        self.rows[row["run"]] = {k: parse_cell(_cell(row.get(k))) for k in self.header}

    def close(self) -> list[Path]:
        """Close, and rewrite the table in run order, one row per run (and ``runs.parquet``
        if pyarrow is installed); the paths written."""
        self.file.close()
        rows = [self.rows[k] for k in sorted(self.rows)]
        return write_table(rows, self.path.parent, self.path.stem, self.header)


# ---------------------------------------------------------------------------------------------
# running

class Progress:
    """Runs done, failed (any status but completed) and the ETA, one line at most every
    ``interval`` seconds and at the end."""

    def __init__(self, total: int, done: int, failed: int, log: Callable[[str], None],
                 interval: float = 10.0):
        self.total, self.done, self.failed = total, done, failed
        self.log, self.interval = log, interval
        self.first = done
        self.start = self.last = time.perf_counter()

    def update(self, row: dict) -> None:
        self.done += 1
        self.failed += row["status"] != "completed"
        now = time.perf_counter()
        if now - self.last >= self.interval or self.done == self.total:
            self.last = now
            self.log(self.line(now))

    def line(self, now: float) -> str:
        rate = (self.done - self.first) / max(now - self.start, 1e-9)
        eta = (self.total - self.done) / rate if rate > 0 else math.inf
        return (f"study: {self.done}/{self.total} done, {self.failed} failed, "
                f"{3600 * rate:.3g} runs/h, ETA {_clock(eta)}")


def _clock(seconds: float) -> str:
    if not math.isfinite(seconds):
        return "-"
    m, s = divmod(round(seconds), 60)
    h, m = divmod(m, 60)
    return f"{h}:{m:02d}:{s:02d}"


def run_study(study: Study, out: Path, scheduler: str | None = None, workers: int = 2,
              serial: bool = False, record: bool = False, retry_failed: bool = False,
              log: Callable[[str], None] | None = None) -> dict:
    """Run the study's runs not yet in ``out/runs.csv`` (with ``retry_failed``, those whose
    worker died too) on Dask, or one after another with ``serial``; append each row as it
    finishes. Returns counts: ``planned``, ``skipped`` (already in the table), ``ran``,
    ``wall_s`` [s] and the ``paths`` written. On Ctrl-C the rows so far are kept and
    KeyboardInterrupt is re-raised."""
    if record and study.function is not None:
        raise ScenarioError("--record: only for scene studies (a function records what it "
                            "chooses)")
    out.mkdir(parents=True, exist_ok=True)
    described = out / "study.json"
    doc = study.describe()
    if described.exists():
        old = json.loads(described.read_text(encoding="utf-8"))
        if {k: v for k, v in old.items() if k != "source"} != \
                {k: v for k, v in doc.items() if k != "source"}:
            raise ScenarioError(f"{out}: holds the table of another study (or of this one "
                                "before a change); use another --out")
    else:
        described.write_text(json.dumps(doc, indent=2) + "\n", encoding="utf-8")
    table = RunTable(out / "runs.csv", study)
    redo = {"failed"} if retry_failed else set()
    todo = [k for k in range(len(study.values))
            if k not in table.rows or table.rows[k]["status"] in redo]
    if record:
        (out / "runs").mkdir(exist_ok=True)
    jobs = [(k, study.scene, study.function, study.fixed, study.values[k], study.measures,
             str(out / "runs" / f"run_{k:05d}.h5") if record else None) for k in todo]
    costs = None
    warm = None
    if study.scene is not None and not serial:
        costs = [estimated_cost(study.scene, study.fixed | study.values[k]) for k in todo]
    if study.scene is not None and todo:
        warm = (study.scene, _one_per_kernel(study, todo))
    kept = {k: r for k, r in table.rows.items() if k not in todo}
    progress = Progress(len(study.values), len(kept),
                        sum(r["status"] != "completed" for r in kept.values()),
                        log or (lambda _: None))
    if log is not None:
        log(f"study: {len(study.values)} runs planned, {len(kept)} in the table, "
            f"{len(todo)} to run")

    def lost(job: tuple, message: str) -> dict:
        return {"run": job[0], "status": "failed", "message": message, "wall_s": None}

    start = time.perf_counter()
    try:
        for result in fan_out(study_run, jobs, lost, scheduler=scheduler, workers=workers,
                              serial=serial, warm=warm, costs=costs):
            k = result["run"]
            table.append({**dict(zip(study.columns.values(), study.values[k].values(),
                                     strict=True)), **result})
            progress.update(result)
    finally:
        paths = table.close()
    return {"planned": len(study.values), "skipped": len(kept), "ran": len(todo),
            "wall_s": time.perf_counter() - start, "paths": paths}


def _one_per_kernel(study: Study, todo: list[int]) -> tuple[dict, ...]:
    """The overrides of the first run to do of each kernel kind (what workers warm up)."""
    from ..model.scenario import load

    base, seen, picked = load(study.scene), set(), []
    for k in todo:
        overrides = study.fixed | study.values[k]
        kind = kernel_kind(base.with_overrides(overrides))
        if kind not in seen:
            seen.add(kind)
            picked.append(overrides)
    return tuple(picked)


# ---------------------------------------------------------------------------------------------
# run functions

ISHIGAMI_S1 = (0.3139, 0.4424, 0.0)
ISHIGAMI_ST = (0.5576, 0.4424, 0.2437)
"""Sobol' indices of :func:`ishigami` with a = 7, b = 0.1, x_i uniform on [-pi, pi]
(Ishigami & Homma 1990; Saltelli et al. 2008, Global Sensitivity Analysis, p. 179)."""


def ishigami(inputs: dict) -> dict:
    """The Ishigami function, the standard check of a Sobol' analysis:
    ``y = sin x1 + a sin^2 x2 + b x3^4 sin x1`` of inputs ``x1``, ``x2``, ``x3`` [-] (and
    ``a``, ``b``, default 7 and 0.1); returns ``{"y": y}``."""
    x1, x2, x3 = inputs["x1"], inputs["x2"], inputs["x3"]
    a, b = inputs.get("a", 7.0), inputs.get("b", 0.1)
    return {"y": math.sin(x1) + a * math.sin(x2) ** 2 + b * x3 ** 4 * math.sin(x1)}


MOUTH_AREA_TIME_S = 1.5
"""When :func:`bending_effect` compares the mouth areas [s] (Sec. 4.2: 2.5 times larger with
bending at 1.5 s)."""


def bending_effect(scenario) -> dict:
    """How much bending changes a deployment (Sec. 4.2, Table 4), at one design point: the
    scene run without and with bending, all else equal (temporary recordings), measured
    against each other. Returns Eq. 14's position RMSE between the two runs, maximum and
    average over the nodes (``rmse_pos_max_m``, ``rmse_pos_avg_m`` [m]) and the average
    velocity RMSE (``rmse_vel_avg_m_s`` [m/s]); each run's time to 90 % deployed
    (``deployed_90pct_plain_s``, ``deployed_90pct_bending_s`` [s], None if not within the
    run); the mouth area at :data:`MOUTH_AREA_TIME_S` with over without bending
    (``mouth_area_ratio_1_5s`` [-]) and the side length L = (Ns - 1) l_mesh (``side_m``)."""
    import tempfile

    from ..analysis.metrics import deployed_time, mouth_area, rmse
    from ..recording.reader import open_recording
    from ..sim.loop import run

    if scenario.scene.duration < MOUTH_AREA_TIME_S:
        raise ScenarioError(f"bending_effect: scene.duration {scenario.scene.duration} s is "
                            f"shorter than the {MOUTH_AREA_TIME_S} s of the mouth-area ratio")
    recs = {}
    with tempfile.TemporaryDirectory(prefix="bulletnet-") as scratch:
        for name, bending in (("plain", False), ("bending", True)):
            path = Path(scratch) / f"{name}.h5"
            run(scenario.with_overrides({"bending.enabled": bending}), path)
            recs[name] = open_recording(path)
    r = rmse(recs["plain"], recs["bending"])
    area = {name: float(np.interp(MOUTH_AREA_TIME_S, rec.time, mouth_area(rec)))
            for name, rec in recs.items()}
    return {"rmse_pos_max_m": r["rmse_pos_max"], "rmse_pos_avg_m": r["rmse_pos_avg"],
            "rmse_vel_avg_m_s": r["rmse_vel_avg"],
            "deployed_90pct_plain_s": deployed_time(recs["plain"], 0.9),
            "deployed_90pct_bending_s": deployed_time(recs["bending"], 0.9),
            "mouth_area_ratio_1_5s": area["bending"] / area["plain"],
            "side_m": (scenario.net.nodes_per_side - 1) * scenario.net.mesh_length}
