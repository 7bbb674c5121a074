"""Parameter sweeps: variants of a scene fanned out over Dask, gathered into one table.

A sweep file (TOML) names a base scene and how its variants differ::

    scene = "deployment"            # name or path (relative to the sweep file)
    mode = "factorial"              # every combination of [vary]; or "list": [[variant]]
    [set]                           # overrides of every variant (scene keys, SI units)
    "scene.duration" = 0.3
    [vary]                          # factorial: each key a list of values
    "net.nodes_per_side" = [9, 11]
    "bending.enabled" = [false, true]

With ``mode = "list"`` the variants are ``[[variant]]`` tables of overrides instead. Every
variant is validated before anything runs. Each runs with :func:`bulletnet.run` on a Dask
worker (``dask.distributed``, imported lazily: a ``LocalCluster`` of processes by default, or
the scheduler at a given address; recordings go to OUT, which a real cluster's workers must
share) and writes ``OUT/runs/variant_NNN.h5``. A variant that diverges or fails is a row with
its status and message, not a crash. The table (``OUT/sweep.csv``; ``sweep.parquet`` too if
pyarrow is installed) holds the variant's parameters, :data:`SUMMARY_MEASURES` of its
recording, wall time [s], steps and status; ``OUT/figures/`` each measure against each swept
parameter.

The parts a study (:mod:`bulletnet.studies.study`) shares with a sweep live here: reading a plan
file (:func:`read_plan`), building and validating its variants (:func:`build_variants`), running
one scene into summary measures (:func:`run_scene`), and fanning calls out over Dask with a
row for a lost worker (:func:`fan_out`).
"""

from __future__ import annotations

import contextlib
import csv
import itertools
import logging
import os
import signal
import tempfile
import time
import tomllib
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..common.errors import BulletnetError, ScenarioError
from ..recording.reader import Recording


def final_mouth_area(rec: Recording) -> float:
    """Mouth area at the last frame [m^2]."""
    from ..analysis.metrics import mouth_area

    return float(mouth_area(rec)[-1])


def deployed_90(rec: Recording) -> float | None:
    """Time to 90 % deployed [s] (mouth area >= 0.9 L^2), None if not within the run."""
    from ..analysis.metrics import deployed_time

    return deployed_time(rec, 0.9)


def max_corner_tension(rec: Recording) -> float:
    """Largest tension in any corner thread over the recorded frames [N]."""
    from ..model.net import corner_threads

    return float(rec.tension[:, corner_threads(rec.pairs, rec.kind)].max())


def max_wrap(rec: Recording) -> float:
    """Largest wrap of the debris by the net over the recorded frames [-]
    (:func:`bulletnet.analysis.metrics.wrap`)."""
    from ..analysis.metrics import wrap

    return float(wrap(rec).max())


def max_nodes_in_contact(rec: Recording) -> int:
    """Most nodes touching the debris in one frame interval [-]."""
    from ..analysis.metrics import nodes_in_contact

    return int(nodes_in_contact(rec).max())


def outcome(rec: Recording) -> str | None:
    """The capture's outcome, where the recording keeps one (root attribute ``outcome``);
    else None."""
    value = rec.attrs.get("outcome")
    return None if value is None else str(value)


def _first_contact(rec: Recording) -> float | None:
    from ..analysis.metrics import first_contact_time

    return first_contact_time(rec)


def _leave(rec: Recording) -> float | None:
    from ..analysis.metrics import leave_time

    return leave_time(rec)


def min_safety_factor(rec: Recording) -> float | None:
    """The run's least safety factor: breaking tension over the largest tension, min over the
    elements [-] (:func:`bulletnet.analysis.metrics.safety`); None if none was ever taut."""
    from ..analysis.metrics import safety

    return safety(rec)["least_safety_factor"]


def overloaded_elements(rec: Recording) -> int:
    """Elements (threads and closing cables) at or over their breaking tension in some
    frame [-] (:func:`bulletnet.analysis.metrics.safety`)."""
    from ..analysis.metrics import safety

    return safety(rec)["overloaded_elements"]


def overloaded(rec: Recording) -> bool:
    """Whether any element reached its breaking tension (a study's report gives the
    probability of it)."""
    return overloaded_elements(rec) > 0


Measures = dict[str, Callable[[Recording], float | int | str | bool | None]]
"""Summary measures of a recording: column name (with its unit) -> function of the recording;
None where a run never reaches it."""

STRENGTH_MEASURES: Measures = {
    "min_safety_factor": min_safety_factor,
    "overloaded_elements": overloaded_elements,
    "overloaded": overloaded,
}
"""Summary measures of every recording's safety margins: the least safety factor [-], the
elements that reached their breaking tension [-] and whether any did (true/false)."""

SUMMARY_MEASURES: Measures = {
    "final_mouth_area_m2": final_mouth_area,
    "deployed_90pct_s": deployed_90,
    "max_corner_tension_N": max_corner_tension,
    **STRENGTH_MEASURES,
}
"""Summary measures of a deployment's recording; keys carry the unit."""

CAPTURE_MEASURES: Measures = {
    "first_contact_s": _first_contact,
    "max_wrap": max_wrap,
    "max_nodes_in_contact": max_nodes_in_contact,
    "leave_s": _leave,
    "outcome": outcome,
    **STRENGTH_MEASURES,
}
"""Summary measures of a capture's recording (a scene with debris and contact): first
contact [s], largest wrap [-], most nodes in contact [-], leave time [s] (None: still on the
debris at the end), the outcome (None until the recording keeps one) and
:data:`STRENGTH_MEASURES`."""


def summary_measures(scenario) -> Measures:
    """The measures that fit a scene: :data:`CAPTURE_MEASURES` with debris and contact, else
    :data:`SUMMARY_MEASURES`."""
    return CAPTURE_MEASURES if scenario.debris.asset and scenario.contact.enabled \
        else SUMMARY_MEASURES


@dataclass(frozen=True)
class Sweep:
    """A validated sweep: the base scene and the overrides of each variant."""

    scene: str
    """Base scene: a name or a path to a .toml."""
    swept: tuple[str, ...]
    """Scene keys that differ between variants."""
    variants: tuple[dict, ...]
    """Overrides of each variant (the [set] ones included), in run order."""


def read_plan(path: str | Path, keys: tuple[str, ...]) -> dict:
    """A sweep's or a study's TOML document; one clear error if it cannot be read or has a key
    outside ``keys``."""
    path = Path(path)
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as exc:
        raise ScenarioError(f"{path}: cannot read: {exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{path}: malformed TOML: {exc}") from None
    unknown = sorted(set(doc) - set(keys))
    if unknown:
        raise ScenarioError(f"{path}: unknown key '{unknown[0]}' (expected "
                            f"{', '.join(keys)})")
    return doc


def base_scene(doc: dict, path: Path) -> str:
    """The plan's ``scene``: a name, or a path (relative to the plan file)."""
    scene = doc.get("scene")
    if not isinstance(scene, str):
        raise ScenarioError(f"{path}: scene: expected a scene name or path, got {scene!r}")
    if scene.endswith(".toml") and not Path(scene).is_absolute():
        scene = str(path.parent / scene)
    return scene


def build_variants(scene: str, fixed: dict, variants: list[dict], path: Path,
                   label: str = "variant") -> list:
    """The scene of every variant (``fixed`` overrides, then the variant's), validated: a bad
    key or value is one error naming the variant (``label`` and its index)."""
    from ..model.scenario import load

    base = load(scene)
    built = []
    for k, overrides in enumerate(variants):
        try:
            built.append(base.with_overrides(fixed | overrides))
        except ScenarioError as exc:
            raise ScenarioError(f"{path}: {label} {k}: {exc}") from None
    return built


def load_sweep(path: str | Path) -> Sweep:
    """Parse and validate a sweep file; every variant's scene is built, so a bad key or value
    is one clear error before anything runs."""
    from ..model.scenario import to_dict

    path = Path(path)
    doc = read_plan(path, ("scene", "mode", "set", "vary", "variant"))
    scene = base_scene(doc, path)
    mode = doc.get("mode", "factorial")
    fixed = plan_table(doc.get("set", {}), path, "set")
    if mode == "factorial":
        vary = plan_table(doc.get("vary", {}), path, "vary")
        for key, values in vary.items():
            if not isinstance(values, list) or not values:
                raise ScenarioError(f"{path}: vary.{key}: expected a non-empty list of values")
        combos = itertools.product(*vary.values())
        variants = [dict(zip(vary, combo, strict=True)) for combo in combos]
    elif mode == "list":
        variants = doc.get("variant")
        if not isinstance(variants, list) or not variants:
            raise ScenarioError(f"{path}: mode 'list' needs [[variant]] tables of overrides")
        variants = [plan_table(v, path, f"variant[{k}]") for k, v in enumerate(variants)]
    else:
        raise ScenarioError(f"{path}: mode: expected 'factorial' or 'list', got {mode!r}")
    swept = tuple(dict.fromkeys(k for v in variants for k in v))
    built = build_variants(scene, fixed, variants, path)
    # every swept key in every row: the base scene's value where a variant keeps it
    complete = [fixed | {key: lookup(to_dict(b), key) for key in swept} for b in built]
    return Sweep(scene=scene, swept=swept, variants=tuple(complete))


def lookup(doc: dict, key: str):
    """The value of a dotted scene key (``name[i]``: a vector's component) in a nested dict."""
    from ..model.scenario import split_component

    name, component = split_component(key)
    for part in name.split("."):
        doc = doc[part]
    return doc if component is None else doc[component]


def plan_table(value, path: Path, name: str) -> dict:
    """``value`` if it is a table (of scene keys), else one clear error naming it."""
    if not isinstance(value, dict):
        raise ScenarioError(f"{path}: [{name}] must be a table of scene keys, got {value!r}")
    return value


def run_scene(scene: str, overrides: dict, out: str | None = None,
              measures: Measures | None = None) -> dict:
    """Run ``scene`` with ``overrides`` into the recording ``out`` (None: a temporary file,
    deleted once measured) and summarize it: ``status``, ``message``, ``wall_s`` [s],
    ``steps`` and each of ``measures`` (default: :func:`summary_measures` of the scene).
    Never raises for a failing run: its status says what happened (``diverged``, ``error``)."""
    from ..model.scenario import load
    from ..recording.reader import open_recording
    from ..sim.loop import run

    row = {"status": "error", "message": "", "wall_s": None, "steps": None}
    values = {}
    start = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="bulletnet-") as scratch:
        path = out or os.path.join(scratch, "run.h5")
        try:
            scenario = load(scene, overrides)
            measures = summary_measures(scenario) if measures is None else measures
            values = dict.fromkeys(measures)
            result = run(scenario, path, force=True)
            row |= {"status": result.status, "steps": result.stats.get("steps")}
            row["wall_s"] = time.perf_counter() - start
            rec = open_recording(path)
            values = {name: measure(rec) for name, measure in measures.items()}
        except BulletnetError as exc:  # a diverged run keeps its recording (status 'diverged')
            row |= {"status": "diverged" if exc.exit_code == 3 else "error",
                    "message": str(exc)}
        except Exception as exc:  # noqa: BLE001 (one bad variant must not stop the sweep)
            row |= {"status": "error", "message": f"{type(exc).__name__}: {exc}"}
    if row["wall_s"] is None:
        row["wall_s"] = time.perf_counter() - start
    return row | values


def run_variant(index: int, scene: str, overrides: dict, out: str,
                measures: Measures | None = None) -> dict:
    """Run one variant into ``out`` and summarize it (:func:`run_scene`): a row of the sweep
    table."""
    row = run_scene(scene, overrides, out, measures)
    head = {k: row.pop(k) for k in ("status", "message", "wall_s", "steps")}
    return {"variant": index, **overrides, **head, "recording": out, **row}


def kernel_kind(scenario) -> tuple:
    """What decides the compiled kernels a run loads: engine, integrator, kernels (grid or
    pairs), bending, contact, closing cables."""
    return (scenario.simulation.engine, scenario.simulation.integrator,
            scenario.simulation.kernels, scenario.bending.enabled, scenario.contact.enabled,
            scenario.closing.enabled)


def warm_up(scene: str, variants: tuple[dict, ...]) -> None:
    """Load the compiled kernels the variants use in this process (a short run of the first
    variant of each :func:`kernel_kind`, :func:`bulletnet.sim.loop.warm_up`), so that no
    variant's wall time includes it."""
    from ..model.scenario import load
    from ..sim.loop import warm_up as warm_up_scene

    seen = set()
    for overrides in variants:
        variant = load(scene, overrides)
        if kernel_kind(variant) not in seen:
            seen.add(kernel_kind(variant))
            warm_up_scene(variant)


def estimated_cost(scene: str, overrides: dict) -> float:
    """Relative cost of a variant [-]: nodes times steps, doubled with bending (its kernels
    take about that much longer); for ordering work, not a prediction of seconds."""
    from ..model.scenario import load

    s = load(scene, overrides)
    steps = s.scene.duration / s.simulation.step if s.simulation.step > 0 else 1.0
    return (s.net.nodes_per_side ** 2 + 4) * steps * (2.0 if s.bending.enabled else 1.0)


def fan_out(fn: Callable[..., dict], jobs: list[tuple], lost: Callable[[tuple, str], dict], *,
            scheduler: str | None = None, workers: int = 2, serial: bool = False,
            warm: tuple[str, tuple[dict, ...]] | None = None,
            costs: list[float] | None = None) -> Iterator[dict]:
    """Call ``fn(*job)`` for every job and yield each result as it finishes: on Dask (a local
    cluster of ``workers`` processes, or ``scheduler``), or one after another in this process
    with ``serial``. ``fn`` must not raise (it reports a failure in its result); a job whose
    worker died or was lost yields ``lost(job, message)`` instead, and the others go on.
    ``warm``: (scene, variants) whose kernels each worker loads first (:func:`warm_up`);
    ``costs``: the jobs' relative costs, handed out longest first, so that no long job is left
    running alone at the end."""
    if serial:
        if warm is not None:
            warm_up(*warm)
        for job in jobs:
            yield fn(*job)
        return
    order = sorted(range(len(jobs)), key=lambda k: -costs[k]) if costs else range(len(jobs))
    with dask_client(scheduler, workers) as client:
        from dask.distributed import as_completed

        if warm is not None:
            client.run(warm_up, *warm)
        futures = {client.submit(fn, *jobs[k], pure=False, priority=len(jobs) - rank): k
                   for rank, k in enumerate(order)}
        for future in as_completed(futures):
            try:
                result = future.result()
            except Exception as exc:  # noqa: BLE001 (a lost worker costs its job, no more)
                result = lost(jobs[futures[future]], f"{type(exc).__name__}: {exc}")
            future.release()
            yield result


def run_sweep(sweep: Sweep, out: Path, scheduler: str | None = None, workers: int = 2,
              serial: bool = False, log=None) -> list[dict]:
    """Run every variant (on Dask, or one after another in this process with ``serial``) and
    return the table's rows in variant order; a variant whose worker died is a row with
    status ``failed``."""
    runs = out / "runs"
    runs.mkdir(parents=True, exist_ok=True)
    jobs = [(k, sweep.scene, v, str(runs / f"variant_{k:03d}.h5"))
            for k, v in enumerate(sweep.variants)]

    def lost(job: tuple, message: str) -> dict:
        k, _, overrides, path = job
        return {"variant": k, **overrides, "status": "failed", "message": message,
                "wall_s": None, "steps": None, "recording": path}

    rows = []
    costs = None if serial else [estimated_cost(sweep.scene, job[2]) for job in jobs]
    for row in fan_out(run_variant, jobs, lost, scheduler=scheduler, workers=workers,
                       serial=serial, warm=(sweep.scene, sweep.variants), costs=costs):
        rows.append(row)
        if log is not None:
            log(_row_text(rows[-1]))
    return sorted(rows, key=lambda r: r["variant"])


@contextlib.contextmanager
def dask_client(scheduler: str | None, workers: int):
    """A Dask client on ``scheduler``, or on a local cluster of ``workers`` processes (one
    thread each: the compiled kernels hold the GIL), closed on exit. The local scheduler hands
    a worker one job at a time and does not retry a job whose worker died (it would likely
    kill the next one too): a lost worker costs one job. A remote scheduler follows its own
    ``distributed.scheduler.allowed-failures`` (Dask's default retries a job 3 times)."""
    try:
        import dask
        from dask.distributed import Client, LocalCluster
    except ImportError:
        raise ScenarioError(
            "sweeps and studies need dask.distributed: pip install 'bulletnet[sweep]'") from None
    if scheduler is not None:
        try:
            client = Client(scheduler, timeout="10s")
        except OSError as exc:
            raise ScenarioError(f"--scheduler {scheduler}: cannot connect: {exc}") from None
        with client:
            yield client
        return
    config = {"distributed.scheduler.allowed-failures": 0,
              "distributed.scheduler.worker-saturation": 1.0}
    with dask.config.set(config), LocalCluster(
            n_workers=workers, threads_per_worker=1, processes=True,
            dashboard_address=None) as cluster, Client(cluster) as client:
        client.run(_quiet_worker)
        try:
            yield client
        except KeyboardInterrupt:
            # closing the cluster mid-run logs each cancelled job and each worker it has to
            # stop: the caller says it was interrupted, in one line
            logging.getLogger("distributed").setLevel(logging.CRITICAL)
            raise


def _quiet_worker() -> None:
    """Make this local worker process ignore Ctrl-C, which reaches it too (one process group)
    while the driver stops it, and log Dask's errors only (not its warnings about jobs
    cancelled as the cluster closes)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    logging.getLogger("distributed").setLevel(logging.ERROR)


def _row_text(row: dict) -> str:
    wall = "" if row["wall_s"] is None else f"{row['wall_s']:.2f} s"
    return f"variant {row['variant']:3d}: {row['status']:<10} {wall}"


def write_table(rows: list[dict], out: Path, stem: str = "sweep",
                columns: list[str] | None = None) -> list[Path]:
    """``OUT/STEM.csv``, and ``OUT/STEM.parquet`` if pyarrow is installed, each replaced
    whole (written beside, then renamed: a reader never sees half a table); their paths.
    ``columns``: their order (default: as the rows first name them)."""
    columns = columns or list(dict.fromkeys(k for r in rows for k in r))
    written = [out / f"{stem}.csv"]
    partial = written[0].with_suffix(".csv.partial")
    with partial.open("w", newline="") as f:
        writer = csv.DictWriter(f, columns)
        writer.writeheader()
        writer.writerows({k: ("" if r.get(k) is None else r.get(k)) for k in columns}
                         for r in rows)
    os.replace(partial, written[0])
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        return written
    written.append(out / f"{stem}.parquet")
    partial = written[1].with_suffix(".parquet.partial")
    pq.write_table(pa.Table.from_pylist([{k: r.get(k) for k in columns} for r in rows]),
                   partial)
    os.replace(partial, written[1])
    return written


def plot_sweep(rows: list[dict], swept: tuple[str, ...], out: Path,
               measures: tuple[str, ...] = (*SUMMARY_MEASURES, "wall_s")) -> list[Path]:
    """One PNG per swept parameter, ``OUT/figures/PARAM.png``: each measure (a panel) against
    the parameter's values, completed variants only (numeric and true/false parameters and
    measures). Returns the paths."""
    from ..analysis.plots import _pyplot

    plt = _pyplot()
    folder = out / "figures"
    folder.mkdir(parents=True, exist_ok=True)
    done = [r for r in rows if r["status"] == "completed"]
    paths = []
    numeric = [k for k in swept if all(isinstance(r[k], (int, float)) for r in done)]
    for key in numeric:
        fig, axes = plt.subplots(1, len(measures), figsize=(3.2 * len(measures), 3.2))
        for ax, name in zip(np.atleast_1d(axes), measures, strict=True):
            points = [(float(r[key]), r[name]) for r in done
                      if isinstance(r.get(name), (int, float))]
            if points:
                x, y = zip(*points, strict=True)
                ax.plot(x, y, "o", alpha=0.7)
            else:
                ax.text(0.5, 0.5, "no value in any run\n(not reached)", ha="center",
                        va="center", transform=ax.transAxes, fontsize=8)
            ax.set_xlabel(key)
            ax.set_title(name, fontsize=9)
            ax.grid(True, alpha=0.3)
        fig.tight_layout()
        paths.append(folder / f"{key}.png")
        fig.savefig(paths[-1], dpi=100)
        plt.close(fig)
    return paths
