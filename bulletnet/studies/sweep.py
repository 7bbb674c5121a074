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

A study (:mod:`bulletnet.studies.study`) shares with a sweep the reading of a plan file
(:func:`read_plan`) and the building and validating of its variants (:func:`build_variants`);
both run scenes with :mod:`bulletnet.studies.runner` and summarize them with
:mod:`bulletnet.studies.measures`.
"""

from __future__ import annotations

import csv
import itertools
import os
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..common.errors import ScenarioError
from .measures import SUMMARY_MEASURES, Measures
from .runner import estimated_cost, fan_out, run_scene


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


def load_sweep(path: str | Path, overrides: dict | None = None) -> Sweep:
    """Parse and validate a sweep file; every variant's scene is built, so a bad key or value
    is one clear error before anything runs. ``overrides`` (``bulletnet sweep --set``) are set
    in every variant on top of the file's [set]."""
    from ..model.scenario import to_dict

    path = Path(path)
    doc = read_plan(path, ("scene", "mode", "set", "vary", "variant"))
    scene = base_scene(doc, path)
    mode = doc.get("mode", "factorial")
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
    fixed = set_table(doc, path, overrides, swept)
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


def set_table(doc: dict, path: Path, overrides: dict | None, varied) -> dict:
    """The keys every run sets: the plan's [set] with ``overrides`` (``--set``, key ->
    value) on top; an override of a key the plan varies (``varied``) is one clear error."""
    overrides = overrides or {}
    both = sorted(set(overrides) & set(varied))
    if both:
        raise ScenarioError(f"--set {both[0]}: {path} varies it")
    return {**plan_table(doc.get("set", {}), path, "set"), **overrides}


def run_variant(index: int, scene: str, overrides: dict, out: str,
                measures: Measures | None = None) -> dict:
    """Run one variant into ``out`` and summarize it (:func:`run_scene`): a row of the sweep
    table."""
    row = run_scene(scene, overrides, out, measures)
    head = {k: row.pop(k) for k in ("status", "message", "wall_s", "steps")}
    return {"variant": index, **overrides, **head, "recording": out, **row}


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
