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
"""

from __future__ import annotations

import contextlib
import csv
import itertools
import time
import tomllib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import BulletnetError, ScenarioError
from .recording import Recording


def final_mouth_area(rec: Recording) -> float:
    """Mouth area at the last frame [m^2]."""
    from .metrics import mouth_area

    return float(mouth_area(rec)[-1])


def deployed_90(rec: Recording) -> float | None:
    """Time to 90 % deployed [s] (mouth area >= 0.9 L^2), None if not within the run."""
    from .metrics import deployed_time

    return deployed_time(rec, 0.9)


def max_corner_tension(rec: Recording) -> float:
    """Largest tension in any corner thread over the recorded frames [N]."""
    return float(rec.tension[:, -4:].max())


SUMMARY_MEASURES: dict[str, Callable[[Recording], float | None]] = {
    "final_mouth_area_m2": final_mouth_area,
    "deployed_90pct_s": deployed_90,
    "max_corner_tension_N": max_corner_tension,
}
"""Default summary measures of a variant's recording; keys carry the unit."""


@dataclass(frozen=True)
class Sweep:
    """A validated sweep: the base scene and the overrides of each variant."""

    scene: str
    """Base scene: a name or a path to a .toml."""
    swept: tuple[str, ...]
    """Scene keys that differ between variants."""
    variants: tuple[dict, ...]
    """Overrides of each variant (the [set] ones included), in run order."""


def load_sweep(path: str | Path) -> Sweep:
    """Parse and validate a sweep file; every variant's scene is built, so a bad key or value
    is one clear error before anything runs."""
    from .scenario import load, to_dict

    path = Path(path)
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as exc:
        raise ScenarioError(f"{path}: cannot read: {exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{path}: malformed TOML: {exc}") from None
    unknown = sorted(set(doc) - {"scene", "mode", "set", "vary", "variant"})
    if unknown:
        raise ScenarioError(f"{path}: unknown key '{unknown[0]}' (expected scene, mode, set, "
                            "vary, variant)")
    scene = doc.get("scene")
    if not isinstance(scene, str):
        raise ScenarioError(f"{path}: scene: expected a scene name or path, got {scene!r}")
    if scene.endswith(".toml") and not Path(scene).is_absolute():
        scene = str(path.parent / scene)
    mode = doc.get("mode", "factorial")
    fixed = _table(doc.get("set", {}), path, "set")
    if mode == "factorial":
        vary = _table(doc.get("vary", {}), path, "vary")
        for key, values in vary.items():
            if not isinstance(values, list) or not values:
                raise ScenarioError(f"{path}: vary.{key}: expected a non-empty list of values")
        combos = itertools.product(*vary.values())
        variants = [dict(zip(vary, combo, strict=True)) for combo in combos]
    elif mode == "list":
        variants = doc.get("variant")
        if not isinstance(variants, list) or not variants:
            raise ScenarioError(f"{path}: mode 'list' needs [[variant]] tables of overrides")
        variants = [_table(v, path, f"variant[{k}]") for k, v in enumerate(variants)]
    else:
        raise ScenarioError(f"{path}: mode: expected 'factorial' or 'list', got {mode!r}")
    swept = tuple(dict.fromkeys(k for v in variants for k in v))
    complete = []
    for k, overrides in enumerate(variants):
        try:
            built = to_dict(load(scene, fixed | overrides))
        except ScenarioError as exc:
            raise ScenarioError(f"{path}: variant {k}: {exc}") from None
        # every swept key in every row: the base scene's value where a variant keeps it
        complete.append(fixed | {key: _lookup(built, key) for key in swept})
    return Sweep(scene=scene, swept=swept, variants=tuple(complete))


def _lookup(doc: dict, key: str):
    for part in key.split("."):
        doc = doc[part]
    return doc


def _table(value, path: Path, name: str) -> dict:
    if not isinstance(value, dict):
        raise ScenarioError(f"{path}: [{name}] must be a table of scene keys, got {value!r}")
    return value


def run_variant(index: int, scene: str, overrides: dict, out: str,
                measures: dict[str, Callable] | None = None) -> dict:
    """Run one variant into ``out`` and summarize it: a row of the sweep table. Never raises
    for a failing variant: its status says what happened (``diverged``, ``error``)."""
    from .recording import open_recording
    from .scenario import load
    from .simulate import run

    measures = SUMMARY_MEASURES if measures is None else measures
    row = {"variant": index, **overrides, "status": "error", "message": "", "wall_s": None,
           "steps": None, "recording": out}
    start = time.perf_counter()
    try:
        result = run(load(scene, overrides), out, force=True)
        row |= {"status": result.status, "steps": result.stats.get("steps")}
    except BulletnetError as exc:  # a diverged run keeps its recording (status 'diverged')
        row |= {"status": "diverged" if exc.exit_code == 3 else "error", "message": str(exc)}
    except Exception as exc:  # noqa: BLE001 (one bad variant must not stop the sweep)
        row["message"] = f"{type(exc).__name__}: {exc}"
    row["wall_s"] = time.perf_counter() - start
    for name, measure in measures.items():
        row[name] = None
        if row["status"] == "completed":
            row[name] = measure(open_recording(out))
    return row


def warm_up(scene: str, variants: tuple[dict, ...]) -> None:
    """Load the compiled kernels the variants use in this process (one record interval of the
    first variant of each integrator and bending setting), so that no variant's wall time
    includes it."""
    from .scenario import load
    from .simulate import run

    seen = set()
    for overrides in variants:
        variant = load(scene, overrides)
        kind = (variant.simulation.engine, variant.simulation.integrator,
                variant.bending.enabled)
        if kind not in seen:
            seen.add(kind)
            try:
                run(variant.with_overrides(
                    {"scene.duration": 1.0 / variant.simulation.record_rate}))
            except BulletnetError:
                pass


def estimated_cost(scene: str, overrides: dict) -> float:
    """Relative cost of a variant [-]: nodes times steps, doubled with bending (its kernels
    take about that much longer); for ordering work, not a prediction of seconds."""
    from .scenario import load

    s = load(scene, overrides)
    steps = s.scene.duration / s.simulation.step if s.simulation.step > 0 else 1.0
    return (s.net.nodes_per_side ** 2 + 4) * steps * (2.0 if s.bending.enabled else 1.0)


def run_sweep(sweep: Sweep, out: Path, scheduler: str | None = None, workers: int = 2,
              serial: bool = False, log=None) -> list[dict]:
    """Run every variant (on Dask, or one after another in this process with ``serial``) and
    return the table's rows in variant order."""
    runs = out / "runs"
    runs.mkdir(parents=True, exist_ok=True)
    jobs = [(k, sweep.scene, v, str(runs / f"variant_{k:03d}.h5"))
            for k, v in enumerate(sweep.variants)]
    if serial:
        warm_up(sweep.scene, sweep.variants)
        rows = []
        for job in jobs:
            rows.append(run_variant(*job))
            if log is not None:
                log(_row_text(rows[-1]))
        return rows
    with dask_client(scheduler, workers) as client:
        client.run(warm_up, sweep.scene, sweep.variants)
        # longest first, so that no long variant is left running alone at the end
        jobs.sort(key=lambda job: -estimated_cost(sweep.scene, job[2]))
        futures = [client.submit(run_variant, *job, pure=False, priority=len(jobs) - k)
                   for k, job in enumerate(jobs)]
        rows = []
        from dask.distributed import as_completed

        for future in as_completed(futures):
            rows.append(future.result())
            if log is not None:
                log(_row_text(rows[-1]))
    return sorted(rows, key=lambda r: r["variant"])


@contextlib.contextmanager
def dask_client(scheduler: str | None, workers: int):
    """A Dask client on ``scheduler``, or on a local cluster of ``workers`` processes (one
    thread each: the compiled kernels hold the GIL), closed on exit."""
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError:
        raise ScenarioError(
            "sweeps need dask.distributed: pip install 'bulletnet[sweep]'") from None
    if scheduler is not None:
        try:
            client = Client(scheduler, timeout="10s")
        except OSError as exc:
            raise ScenarioError(f"--scheduler {scheduler}: cannot connect: {exc}") from None
        with client:
            yield client
        return
    with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster, Client(cluster) as client:
        yield client


def _row_text(row: dict) -> str:
    wall = "" if row["wall_s"] is None else f"{row['wall_s']:.2f} s"
    return f"variant {row['variant']:3d}: {row['status']:<10} {wall}"


def write_table(rows: list[dict], out: Path) -> list[Path]:
    """``OUT/sweep.csv``, and ``OUT/sweep.parquet`` if pyarrow is installed; their paths."""
    columns = list(dict.fromkeys(k for r in rows for k in r))
    written = [out / "sweep.csv"]
    with written[0].open("w", newline="") as f:
        writer = csv.DictWriter(f, columns)
        writer.writeheader()
        writer.writerows({k: ("" if r.get(k) is None else r.get(k)) for k in columns}
                         for r in rows)
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        return written
    written.append(out / "sweep.parquet")
    pq.write_table(pa.Table.from_pylist([{k: r.get(k) for k in columns} for r in rows]),
                   written[1])
    return written


def plot_sweep(rows: list[dict], swept: tuple[str, ...], out: Path,
               measures: tuple[str, ...] = (*SUMMARY_MEASURES, "wall_s")) -> list[Path]:
    """One PNG per swept parameter, ``OUT/figures/PARAM.png``: each measure (a panel) against
    the parameter's values, completed variants only (numeric and true/false parameters).
    Returns the paths."""
    from .plots import _pyplot

    plt = _pyplot()
    folder = out / "figures"
    folder.mkdir(parents=True, exist_ok=True)
    done = [r for r in rows if r["status"] == "completed"]
    paths = []
    numeric = [k for k in swept if all(isinstance(r[k], (int, float)) for r in done)]
    for key in numeric:
        fig, axes = plt.subplots(1, len(measures), figsize=(3.2 * len(measures), 3.2))
        for ax, name in zip(np.atleast_1d(axes), measures, strict=True):
            points = [(float(r[key]), r[name]) for r in done if r.get(name) is not None]
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
