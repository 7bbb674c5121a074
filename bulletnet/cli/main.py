"""The ``bulletnet`` command line: run, scenes, scene, warmup, params, compare, metrics, plot,
view, bench, stability, sweep, study, optimize.

Errors are one line on stderr: exit code 2 for bad input, 3 for a diverged run, 130 for an
interrupted one."""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import sys
import threading
import time

from ..common import interrupt
from ..common.errors import BulletnetError, ScenarioError

SI_HELP = "all quantities in SI units, angles in degrees; see `bulletnet params SCENE`"


def kernel_group(scene) -> str:
    """The compiled kernels a scene needs, in words (what a first run compiles: each feature
    adds its own kernels, docs/development.md)."""
    parts = [f"{scene.simulation.engine} engine", scene.simulation.integrator.replace("_", " ")]
    parts += [name for name, on in (("bending", scene.bending.enabled),
                                    ("contact", scene.contact.enabled),
                                    ("closing cables", scene.closing.enabled)) if on]
    return ", ".join(parts)


def default_text(action: argparse.Action) -> list[str]:
    """The default an argument's help shows, as texts (none for None, False, [] or a flag)."""
    value = action.default
    if value is None or value is False or value == [] or value is argparse.SUPPRESS \
            or action.nargs == 0:
        return []
    values = value if isinstance(value, list | tuple) else [value]
    return [f"{v:g}" if isinstance(v, float) else str(v) for v in values]


class _Help(argparse.HelpFormatter):
    """Each argument's help with its default, unless the help already names it."""

    def _get_help_string(self, action):
        text, shown = action.help or "", default_text(action)
        if shown and "default" not in text:
            text += " (default: " + " ".join(shown).replace("%", "%%") + ")"
        return text


class _Parser(argparse.ArgumentParser):
    def __init__(self, *args, **kwargs):
        kwargs.setdefault("formatter_class", _Help)
        super().__init__(*args, **kwargs)

    def error(self, message):  # one line, exit code 2, no usage dump
        sys.stderr.write(f"bulletnet: error: {message} (see {self.prog} --help)\n")
        sys.exit(2)


def _positive(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(value) or value <= 0:
        raise argparse.ArgumentTypeError(f"expected a positive finite number, got {text!r}")
    return value


def _add_scene(parser: argparse.ArgumentParser, bending: str = "bending on/off") -> None:
    """The arguments every command that builds a scene takes: the scene, --bending, --set."""
    from ..model.scenario import scene_names

    parser.add_argument("scene", help=f"scene name ({', '.join(scene_names())}) or path to a "
                        ".toml")
    parser.add_argument("--bending", action=argparse.BooleanOptionalAction, default=None,
                        help=f"{bending}; default: the scene's")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="override a scene key, e.g. --set net.nodes_per_side=6 (values in "
                             "SI units, angles in degrees, TOML syntax; repeatable)")


def build_parser() -> argparse.ArgumentParser:
    from .. import __version__
    from ..model.scenario import ENGINES, INTEGRATORS

    parser = _Parser(prog="bulletnet", description="Tether-net deployment and capture "
                     f"simulation ({SI_HELP}).")
    parser.add_argument("--version", action="version", version=f"bulletnet {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    run = sub.add_parser("run", help="simulate a scene and record it to HDF5")
    _add_scene(run, "oriented nodes with the bending springs of Sec. 3.2 on/off")
    run.add_argument("--engine", choices=ENGINES, help="fast (compiled), bullet (PyBullet "
                     "bodies) or reference (scipy DOP853); default: the scene's")
    run.add_argument("--integrator", choices=INTEGRATORS,
                     help="time integrator of fast/bullet; default: the scene's")
    run.add_argument("--dt", type=_positive, metavar="S",
                     help="time step [s] (implicit Euler: a finer step wants a tighter "
                          "--set simulation.cg_tolerance=..., relative to each step)")
    run.add_argument("--duration", type=_positive, metavar="S", help="simulated time [s]")
    run.add_argument("--record-rate", type=_positive, metavar="HZ",
                     help="frames recorded per simulated second [Hz]")
    run.add_argument("--out", metavar="FILE", help="recording to write [default: SCENE.h5]")
    run.add_argument("--force", action="store_true", help="overwrite an existing --out")
    run.add_argument("--quiet", action="store_true", help="no progress bar")
    run.add_argument("--profile", action="store_true",
                     help="print where the wall time goes (forces, integration, contact, "
                          "recording, I/O) [s]")

    sub.add_parser("scenes", help="list the shipped scenes with their descriptions")
    scene = sub.add_parser("scene", help="print a shipped scene's TOML, to start one's own: "
                           "bulletnet scene capture > mine.toml")
    scene.add_argument("name", help="scene name or path to a .toml")
    scene.add_argument("--full", action="store_true", help="every key with its value, the "
                       "scene's base and the defaults resolved (no comments), instead of the "
                       "file as written")

    warmup = sub.add_parser("warmup", help="compile the kernels of scenes ahead of their runs "
                            "(e.g. on a cluster's login node before a study); a scene whose "
                            "kernels are in the cache takes a second")
    warmup.add_argument("scenes", nargs="*", default=["deployment"], metavar="SCENE",
                        help="scene names or .toml paths [default: deployment]")
    warmup.add_argument("--bending", action=argparse.BooleanOptionalAction, default=None,
                        help="bending on/off in every scene; default: each scene's")

    params = sub.add_parser("params", help="print the derived model (Tables 5-7)")
    _add_scene(params)
    params.add_argument("--json", action="store_true", help="machine-readable output")

    compare = sub.add_parser("compare", help="RMSE between two recordings (Eq. 14, Table 2)")
    compare.add_argument("a", metavar="A.h5", help="a recording")
    compare.add_argument("b", metavar="B.h5", help="the recording to compare it with, on the "
                         "sample times both have")
    compare.add_argument("--json", action="store_true", help="machine-readable output (RMSE in "
                         "m and m/s)")

    metrics = sub.add_parser("metrics", help="mouth area, mouth diagonal, net height (Eq. 13), "
                             "the least safety factor (where and when) and the largest snap "
                             "load; with debris: first contact, nodes in contact, wrap, leave "
                             "time, debris spin, capture score and outcome")
    metrics.add_argument("run", metavar="RUN.h5", help="a recording")
    metrics.add_argument("--json", action="store_true", help="machine-readable output, every "
                         "frame (keys carry their unit: _s, _m, _m2, _N, _J, _deg_s)")
    metrics.add_argument("--every", type=_positive, default=0.1, metavar="S",
                         help="table row interval [s] (text output only)")
    plot = sub.add_parser("plot", help="the paper's deployment and capture figures as PNG")
    plot.add_argument("a", metavar="A.h5", help="a recording")
    plot.add_argument("b", metavar="B.h5", nargs="?", help="a second run to overlay")
    plot.add_argument("--out", required=True, metavar="DIR", help="folder for the PNG files")
    plot.add_argument("--times", type=float, nargs="+", metavar="S",
                      help="mouth snapshot times [s] (default: 7 evenly spaced; Fig. 11: "
                           "9 14 27 44 82)")

    view = sub.add_parser("view", help="replay recordings in a browser: a local viser "
                          "server, or a self-contained HTML file")
    view.add_argument("runs", nargs="+", metavar="RUN.h5",
                      help="recordings to overlay in sync, each in its own colour")
    view.add_argument("--port", type=int, default=8080, metavar="N",
                      help="local server port; the next free one if taken, 0 for any")
    view.add_argument("--html", metavar="OUT.html", help="write a self-contained replay "
                      "instead of serving (index.html beside it lists the folder's replays)")
    view.add_argument("--every", type=int, default=1, metavar="N",
                      help="show every N-th recorded frame (and the last)")
    view.add_argument("--snapshots", type=float, nargs="+", metavar="S",
                      help="mouth snapshot times [s] (default: 7 evenly spaced)")
    view.add_argument("--force", action="store_true", help="overwrite an existing --html")
    _add_bench(sub)
    _add_stability(sub)
    _add_sweep(sub)
    _add_study(sub)
    _add_optimize(sub)
    return parser


DEFAULT_BENCH_DTS = (5e-7, 1e-6, 2e-6, 4e-6, 1e-5, 3e-5, 1e-4)
"""Steps of the bench grid [s] unless --dts is given."""


def _add_bench(sub) -> None:
    bench = sub.add_parser("bench", help="speed against accuracy: a grid of (method, step) "
                           "runs against a converged reference; JSON and a PNG chart")
    _add_scene(bench)
    bench.add_argument("--methods", nargs="+", metavar="ENGINE:INTEGRATOR",
                       default=["fast:symplectic_euler", "fast:implicit_euler"],
                       help="methods to run, e.g. fast:implicit_euler bullet:symplectic_euler "
                            "reference (default: both integrators on fast)")
    bench.add_argument("--dts", nargs="+", type=_positive, metavar="S",
                       default=list(DEFAULT_BENCH_DTS), help="time steps of the grid [s]")
    bench.add_argument("--duration", type=_positive, metavar="S", help="simulated time [s]")
    bench.add_argument("--measures", nargs="+", default=["rmse"], metavar="NAME",
                       help="scores against the reference: rmse (Eq. 14, position [m] and "
                            "velocity [m/s]), mouth_area (mouth-area curve [m^2]); with "
                            "debris: first_contact (time error [s]), wrap (wrap difference)")
    bench.add_argument("--front-by", metavar="KEY",
                       help="score of the Pareto front and the chart's axis, e.g. "
                            "rmse_pos_avg [m], mouth_area_rms [m^2], wrap_rms [-] or "
                            "first_contact_error [s]; default: the first measure's first")
    bench.add_argument("--repeats", type=int, default=1, metavar="N",
                       help="timed repeats of each run (median reported)")
    bench.add_argument("--stability", action="store_true",
                       help="also bisect each method's largest stable step and set it beside "
                            "the analytical limits")
    bench.add_argument("--stability-horizon", type=_positive, metavar="S",
                       help="simulated time of each stability run [s] (default: --duration)")
    bench.add_argument("--out", default="bench", metavar="DIR",
                       help="folder for bench_SCENE[_bending].json/.png and the runs")


def _add_stability(sub) -> None:
    stability = sub.add_parser("stability", help="largest stable step of each method, "
                               "bisected, beside the analytical limits")
    _add_scene(stability)
    stability.add_argument("--methods", nargs="+", metavar="ENGINE:INTEGRATOR",
                           default=["fast:symplectic_euler", "fast:implicit_euler"],
                           help="methods whose largest stable step is bisected")
    stability.add_argument("--horizon", type=_positive, metavar="S",
                           help="simulated time of each trial run [s] (default: the scene's "
                                "duration)")
    stability.add_argument("--json", action="store_true", help="machine-readable output")


def cmd_stability(args) -> int:
    from ..studies.bench import parse_method, stability_table

    methods = [parse_method(m) for m in args.methods]
    scene = _scene(args)
    log = None if args.json else print
    rows = stability_table(scene, methods, args.horizon or scene.scene.duration, log=log)
    if args.json:
        print(json.dumps(rows, indent=2))
    return 0


def _add_dask(parser: argparse.ArgumentParser, what: str) -> None:
    """Where a sweep's or a study's runs go: --scheduler, --workers, --serial."""
    parser.add_argument("--scheduler", metavar="ADDRESS",
                        help="Dask scheduler, e.g. tcp://10.0.0.5:8786 (default: a local "
                             "cluster)")
    parser.add_argument("--workers", type=int, default=2, metavar="N",
                        help="worker processes of the local cluster")
    parser.add_argument("--serial", action="store_true",
                        help=f"no Dask: run {what} one after another in this process")


def _add_set_every_run(parser: argparse.ArgumentParser, runs: str) -> None:
    """--set of a command that runs a file's plan: scene keys on top of the file's [set]."""
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help=f"set a scene key in {runs}, on top of the file's [set], e.g. "
                             "--set simulation.dt=1e-3 (values in SI units, angles in degrees, "
                             "TOML syntax; repeatable; a key the file varies is an error)")


def _set_overrides(args) -> dict:
    """The --set pairs of a plan command, key -> value."""
    from ..model.scenario import parse_override

    return dict(parse_override(item) for item in args.set)


def _add_sweep(sub) -> None:
    sweep = sub.add_parser("sweep", help="run variants of a scene over Dask and gather a table "
                           "of summary measures (CSV, Parquet with pyarrow) and plots")
    sweep.add_argument("sweep", metavar="SWEEP.toml", help="sweep file (see "
                       "scenarios/sweep_example.toml)")
    _add_dask(sweep, "the variants")
    _add_set_every_run(sweep, "every variant")
    sweep.add_argument("--out", default="sweep", metavar="DIR",
                       help="folder for sweep.csv, runs/ and figures/")


def cmd_sweep(args) -> int:
    from pathlib import Path

    from ..model.scenario import load
    from ..studies.measures import summary_measures
    from ..studies.sweep import load_sweep, plot_sweep, run_sweep, write_table

    _check_workers(args.workers)
    spec = load_sweep(args.sweep, _set_overrides(args))
    out = Path(args.out)
    print(f"bulletnet: {len(spec.variants)} variants of {spec.scene} -> {out}", file=sys.stderr)
    start = time.perf_counter()
    rows = run_sweep(spec, out, args.scheduler, args.workers, args.serial,
                     log=lambda text: print(text, file=sys.stderr))
    wall = time.perf_counter() - start
    measures = (*summary_measures(load(spec.scene)), "wall_s")
    paths = write_table(rows, out) + plot_sweep(rows, spec.swept, out, measures)
    counts = {s: sum(r["status"] == s for r in rows) for s in dict.fromkeys(
        r["status"] for r in rows)}
    print(f"{len(rows)} variants in {wall:.1f} s wall: "
          + ", ".join(f"{n} {s}" for s, n in counts.items()))
    print("\n".join(str(p) for p in paths))
    return 0


def _add_study(sub) -> None:
    study = sub.add_parser("study", help="Monte Carlo or Sobol' study of a scene on Dask: one "
                           "row per run in DIR/runs.csv, resumable; probabilities and Sobol' "
                           "indices in DIR/summary.json (see docs/studies.md)")
    study.add_argument("study", nargs="?", metavar="STUDY.toml", help="study file (see "
                       "scenarios/study_*.toml); rerun into the same --out to resume")
    study.add_argument("--out", metavar="DIR", help="folder for runs.csv, study.json, "
                       "summary.json, figures/ (and runs/ with --record)")
    study.add_argument("--report", metavar="DIR", help="run nothing: write DIR/summary.json "
                       "and DIR/figures/ from the table of a study (done, running or stopped) "
                       "and print its probabilities and leading Sobol' indices")
    _add_dask(study, "the runs")
    _add_set_every_run(study, "every run")
    study.add_argument("--record", action="store_true", help="keep each run's recording as "
                       "DIR/runs/run_NNNNN.h5 (default: summaries only)")
    study.add_argument("--retry-failed", action="store_true", help="also rerun the runs whose "
                       "worker died (status failed)")
    study.add_argument("--confidence", type=float, default=0.95, metavar="LEVEL",
                       help="confidence level of the report's intervals [-]")
    study.add_argument("--bins", type=int, default=4, metavar="N",
                       help="quantile bins of each input for the report's probabilities")


def cmd_study(args) -> int:
    from pathlib import Path

    from ..studies.report import report, summary_text
    from ..studies.study import load_study, run_study

    if (args.study is None) == (args.report is None):
        raise ScenarioError("give a STUDY.toml to run, or --report DIR" + (
            ", not both" if args.study is not None else ""))
    if args.report is not None and args.set:
        raise ScenarioError("--set applies to a study to run, not to --report")
    if args.bins < 1:
        raise ScenarioError(f"--bins {args.bins}: expected an integer >= 1")
    if not 0 < args.confidence < 1:
        raise ScenarioError(f"--confidence {args.confidence}: expected a number in (0, 1)")
    if args.report is not None:
        paths = report(Path(args.report), args.confidence, args.bins)
        print("\n".join([*summary_text(Path(args.report)), *map(str, paths)]))
        return 0
    if args.out is None:
        raise ScenarioError("--out DIR: the study's folder is required (rerun into it to "
                            "resume)")
    _check_workers(args.workers)
    spec = load_study(args.study, _set_overrides(args))
    out = Path(args.out)
    print(f"bulletnet: study {spec.path.name}: {spec.design} design, {len(spec.values)} runs "
          f"of {spec.function or spec.scene} -> {out}", file=sys.stderr)
    try:
        done = run_study(spec, out, args.scheduler, args.workers, args.serial, args.record,
                         args.retry_failed, log=lambda text: print(text, file=sys.stderr))
    except KeyboardInterrupt:
        print(f"\nbulletnet: study interrupted; {out / 'runs.csv'} keeps every finished run: "
              "rerun the same command to resume", file=sys.stderr)
        return 130
    rate = done["ran"] / done["wall_s"] * 3600 if done["wall_s"] > 0 else math.inf
    print(f"{done['ran']} runs in {done['wall_s']:.1f} s wall ({rate:.4g} runs/h); "
          f"{done['skipped']} were already in the table")
    try:
        paths = done["paths"] + report(out, args.confidence, args.bins)
    except BulletnetError as exc:  # e.g. no matplotlib: the table and summary.json stand
        paths = done["paths"] + [out / "summary.json"]
        print(f"bulletnet: no figures: {exc}", file=sys.stderr)
    print("\n".join(str(p) for p in paths))
    return 0


def _add_optimize(sub) -> None:
    opt = sub.add_parser("optimize", help="robust design optimisation (Optuna): design "
                         "variables chosen to maximise an objective over the same K uncertain "
                         "runs per design, under constraints; resumable (see docs/studies.md)")
    opt.add_argument("file", nargs="?", metavar="FILE.toml", help="optimisation file (see "
                     "scenarios/optimize_*.toml); rerun into the same --out to resume, or "
                     "with more trials to go on")
    opt.add_argument("--out", metavar="DIR", help="folder for optimize.json, optuna.journal, "
                     "runs.csv (one row per run), summary.json and figures/")
    opt.add_argument("--report", metavar="DIR", help="run no design: write DIR/summary.json "
                     "(every design, the best, each variable's importance) and DIR/figures/ "
                     "(the objective-cost front, the history) and print the best design")
    opt.add_argument("--confirm", type=int, default=0, metavar="K",
                     help="with --report: first run the best design on K fresh draws (a seed "
                     "stream apart from the optimisation's) and report its objective and, for "
                     "a probability, its Wilson interval (0: none)")
    _add_dask(opt, "each design's runs")
    _add_set_every_run(opt, "every run of every design")


def cmd_optimize(args) -> int:
    from pathlib import Path

    from ..studies.optimize import load_optimisation, run_optimisation
    from ..studies.optimize_report import report_optimisation, summary_text

    if (args.file is None) == (args.report is None):
        raise ScenarioError("give a FILE.toml to run, or --report DIR" + (
            ", not both" if args.file is not None else ""))
    if args.confirm < 0 or (args.confirm and args.report is None):
        raise ScenarioError(f"--confirm {args.confirm}: an integer >= 0, with --report DIR")
    if args.report is not None and args.set:
        raise ScenarioError("--set applies to an optimisation to run, not to --report")
    _check_workers(args.workers)
    if args.report is not None:
        out = Path(args.report)
        paths = report_optimisation(out, args.confirm, args.scheduler, args.workers,
                                    args.serial)
        print("\n".join([*summary_text(out), *map(str, paths)]))
        return 0
    if args.out is None:
        raise ScenarioError("--out DIR: the optimisation's folder is required (rerun into it "
                            "to resume)")
    spec = load_optimisation(args.file, _set_overrides(args))
    out = Path(args.out)
    print(f"bulletnet: optimize {spec.path.name}: {spec.trials} designs ({spec.sampler}) of "
          f"{len(spec.draws)} runs of {spec.function or spec.scene} -> {out}", file=sys.stderr)
    try:
        done = run_optimisation(spec, out, args.scheduler, args.workers, args.serial,
                                log=lambda text: print(text, file=sys.stderr))
    except KeyboardInterrupt:
        print(f"\nbulletnet: optimisation interrupted; {out} keeps every finished run and "
              "design: rerun the same command to resume", file=sys.stderr)
        return 130
    print(f"{done['trials']} designs in {done['wall_s']:.1f} s wall; {done['skipped']} were "
          "already done")
    try:
        paths = report_optimisation(out)
    except BulletnetError as exc:  # e.g. no matplotlib: the table and summary.json stand
        paths = [out / "summary.json"]
        print(f"bulletnet: no figures: {exc}", file=sys.stderr)
    print("\n".join([*summary_text(out), str(done["table"]), *map(str, paths)]))
    return 0


def _check_workers(workers: int) -> None:
    if workers < 1:
        raise ScenarioError(f"--workers {workers}: expected an integer >= 1")


def cmd_bench(args) -> int:
    from pathlib import Path

    from ..common.errors import ScenarioError
    from ..studies.bench import MEASURES, bench, parse_method

    if args.repeats < 1:
        raise ScenarioError(f"--repeats {args.repeats}: expected an integer >= 1")
    unknown = [m for m in args.measures if m not in MEASURES]
    if unknown:
        raise ScenarioError(f"--measures {unknown[0]}: expected one of {', '.join(MEASURES)}")
    keys = [k for m in args.measures for k in MEASURES[m][1]]
    front_by = args.front_by or keys[0]
    if front_by not in keys:
        raise ScenarioError(f"--front-by {front_by}: expected a key of the measures "
                            f"chosen: {', '.join(keys)}")
    methods = [parse_method(m) for m in args.methods]
    scene = _scene(args, {"scene.duration": args.duration})
    with_debris = [m for m in args.measures if m in ("first_contact", "wrap")]
    if with_debris and not scene.debris.asset:
        raise ScenarioError(f"--measures {with_debris[0]}: needs debris; "
                            f"{scene.scene.name} has none")
    horizon = args.stability_horizon or scene.scene.duration if args.stability else None
    doc = bench(scene, methods, sorted(args.dts), Path(args.out),
                [MEASURES[m][0] for m in args.measures], repeats=args.repeats,
                stability_horizon=horizon, error_key=front_by)
    stem = Path(args.out) / (f"bench_{doc['scene']}" + ("_bending" if doc["bending"] else ""))
    print(f"Pareto front ({len(doc['pareto_front'])} runs): " + ", ".join(
        f"{r['method']} dt {r['dt_s']:.3g} s" if r["dt_s"] else r["method"]
        for r in doc["pareto_front"]))
    print(f"-> {stem}.json, {stem}.png")
    return 0


def _scene(args, flags: dict | None = None):
    """The scene of ``args`` with its --set overrides, then --bending and the command's other
    ``flags`` (dotted scene keys; None: not given)."""
    from ..model.scenario import load

    overrides = _set_overrides(args)
    flags = {"bending.enabled": args.bending, **(flags or {})}
    overrides.update({k: v for k, v in flags.items() if v is not None})
    return load(args.scene, overrides)


def cmd_run(args) -> int:
    from pathlib import Path

    from ..common.kernel_cache import watch_compilation
    from ..sim.loop import preflight, run

    flags = {"simulation.engine": args.engine, "simulation.integrator": args.integrator,
             "simulation.dt": args.dt, "scene.duration": args.duration,
             "simulation.record_rate": args.record_rate}
    scene = _scene(args, flags)
    if scene.simulation.engine == "reference" and args.integrator:
        raise ScenarioError("--integrator: the reference engine integrates with scipy's "
                            "DOP853 (to its tolerances); the integrators are the fast and "
                            "bullet engines'")
    out = Path(args.out or f"{scene.scene.name}.h5")
    preflight(scene, out, args.force)
    progress = None if args.quiet else ProgressBar(kernel_group(scene))
    print(f"bulletnet: {scene.scene.name}: engine {scene.simulation.engine}, bending "
          f"{'on' if scene.bending.enabled else 'off'}, "
          f"{scene.scene.duration:g} s simulated -> {out}", file=sys.stderr)
    profile = None
    if args.profile:
        from ..sim.profiling import Profile

        profile = Profile()
    with contextlib.ExitStack() as stack:
        if progress:
            stack.enter_context(watch_compilation(progress.compile_started,
                                                  progress.compile_ended))
        result = run(scene, out, progress=progress, force=args.force, profile=profile)
    if progress:
        progress.done()
    steps = result.stats.get("steps", 0)
    in_loop = (f", {result.compile_time_s:.1f} s of it compiling" if result.compile_time_s
               else "")
    compiling = (f" (first run: {progress.compile_s:.1f} s compiling kernels)"
                 if progress and progress.compile_s else "")
    stepping = result.wall_time_s - result.compile_time_s  # the loop's own time [s]
    print(f"{result.status}: {result.frames} frames, {steps} steps, "
          f"{result.wall_time_s:.2f} s wall{in_loop}{compiling}, real-time factor "
          f"{result.state.time / max(stepping, 1e-9):.3g} -> {result.path}")
    if result.outcome:
        print("outcome: " + _outcome_text(result.outcome, result.outcome_time_s,
                                          result.outcome_reason))
    if profile is not None:
        from ..sim.profiling import report

        print("\n".join(report(profile, result.wall_time_s, scene.contact.enabled)))
    return 0


class ProgressBar:
    """Simulated time, real-time factor and ETA on stderr, at most 4 updates a second (one
    every 10 s when stderr is not a terminal).

    While numba compiles kernels its cache lacks (the first run after an install or a change
    of the source), it says so, naming the ``group`` of kernels (:func:`kernel_group`), with
    the time spent so far (on a terminal, updated every second), instead of an ETA; the rate
    and the ETA count from the first frame after the compilation, once stepping has
    started."""

    def __init__(self, group: str, stream=None):
        self.stream = stream or sys.stderr
        self.group = group
        self.last = 0.0
        self.tty = self.stream.isatty()
        self.interval = 0.25 if self.tty else 10.0
        self.origin: tuple[float, float] | None = None
        """(simulated time [s], clock [s]) the rate counts from; None until a frame is seen."""
        self.compiling = False
        self.compile_s = 0.0
        """Wall time spent compiling so far [s]."""
        self._ticker: tuple[threading.Event, threading.Thread] | None = None
        """(stop, thread) of the running-time display while compiling on a terminal."""
        self._compile_start = 0.0
        self._reported = True
        """Whether the compile time so far has been reported (once stepping resumed)."""

    def _notice(self, seconds: float | None) -> str:
        spent = f": {seconds:.0f} s" if seconds is not None else " ..."
        return f"bulletnet: compiling the kernels ({self.group}), once after an install{spent}"

    def compile_started(self) -> None:
        if not self.compiling:
            if not self.compile_s:  # said once a run
                self._write(self._notice(0.0 if self.tty else None), final=not self.tty)
            self._compile_start = time.perf_counter()
            if self.tty:  # the running time, while numba holds the main thread
                stop = threading.Event()
                thread = threading.Thread(target=self._tick, args=(stop,), daemon=True)
                thread.start()
                self._ticker = (stop, thread)
        self.compiling = True

    def _tick(self, stop: threading.Event) -> None:
        while not stop.wait(1.0):
            self._write(self._notice(self.compile_s + time.perf_counter()
                                     - self._compile_start))

    def compile_ended(self, seconds: float) -> None:
        self.compiling = False
        self.compile_s += seconds
        self.origin = None  # the rate restarts at the next frame
        self._reported = False
        if self._ticker is not None:
            stop, thread = self._ticker
            stop.set()
            thread.join()
            self._ticker = None

    def __call__(self, t: float, duration: float, wall: float) -> None:
        if not self._reported:
            self._write(f"bulletnet: compiled in {self.compile_s:.1f} s; later runs start at "
                        "once", final=True)
            self._reported = True
        now = time.perf_counter()
        if self.origin is None:
            # without a compilation, stepping started with the run (wall [s] ago) at t = 0
            self.origin = (t, now) if self.compile_s else (0.0, now - wall)
        if now - self.last < self.interval and t < duration:
            return
        self.last = now
        frac = t / duration
        t0, clock0 = self.origin
        if t > t0 and now > clock0:
            rate = (t - t0) / (now - clock0)
            speed = f"real-time x{rate:8.3g}  ETA {(duration - t) / rate:6.1f} s"
        else:
            speed = "real-time x       -  ETA      - s"
        self._write(f"[{'#' * int(30 * frac):<30}] t = {t:8.3f} / {duration:g} s  {speed}")

    def _write(self, line: str, final: bool = False) -> None:
        if self.tty:
            line = "\r\033[K" + line + ("\n" if final else "")
        else:
            line += "\n"
        self.stream.write(line)
        self.stream.flush()

    def done(self) -> None:
        if self.tty:
            self.stream.write("\n")


def cmd_scenes(args) -> int:
    from ..model.scenario import load, scene_names

    names = scene_names()
    width = max(map(len, names))
    for name in names:
        print(f"{name:<{width}}  {load(name).scene.description}")
    print("\n(print one with `bulletnet scene NAME`; run it with `bulletnet run NAME`)")
    return 0


def cmd_scene(args) -> int:
    from ..model.scenario import load, resolve_path, to_toml

    if args.full:
        sys.stdout.write(to_toml(load(args.name)))
    else:
        path = resolve_path(args.name)
        load(args.name)  # a valid scene, not a study or sweep file
        sys.stdout.write(path.read_text(encoding="utf-8"))
    return 0


def cmd_warmup(args) -> int:
    from ..model.scenario import load
    from ..sim.loop import warm_up

    overrides = {} if args.bending is None else {"bending.enabled": args.bending}
    scenes = [load(name, overrides) for name in args.scenes]  # every name checked first
    for name, scene in zip(args.scenes, scenes, strict=True):
        print(f"{name}: {warm_up(scene):.1f} s ({kernel_group(scene)})", flush=True)
    return 0


def cmd_params(args) -> int:
    import numpy as np

    from ..model.builder import build_model, scene_debris
    from ..model.materials import contact_table
    from ..model.net import ELEMENT_NAMES, ElementKind, NodeKind, corner_threads, thread_kinds

    scene = _scene(args)
    model = build_model(scene)
    beam = scene.scene.kind == "cantilever"  # one element: no corner threads, no contact
    kinds = {}
    for kind in NodeKind:
        nodes = (model.kind == kind).nonzero()[0]
        if nodes.size:
            kinds[kind.name.lower()] = {"count": int(nodes.size),
                                        "mass_kg": float(model.mass[nodes[0]]),
                                        "radius_m": float(model.radius[nodes[0]])}
    threads = {}
    corner = corner_threads(model.pairs, model.kind)
    columns = [("inner", 0)] + ([] if beam else [("corner", corner[-1] if corner.size else 0)])
    for label, index in columns:
        threads[label] = {
            "rest_length_m": float(model.rest_length[index]),
            "radius_m": float(model.thread_radius[index]),
            "k_a_N_per_m": float(model.axial_stiffness[index]),
            "c_a_Ns_per_m": float(model.axial_damping[index]),
            "k_t_N_per_m": float(model.transverse_stiffness[index]),
            "c_t_Ns_per_m": float(model.transverse_damping[index]),
            "k_b_Nm_per_rad": float(model.bending_stiffness[index]),
            "c_b_Nms_per_rad": float(model.bending_damping[index]),
            "breaking_tension_N": float(model.breaking_tension[index]),
        }
    element_kinds = thread_kinds(model.pairs, model.kind)
    strength = {ELEMENT_NAMES[ElementKind(kind)]: float(model.breaking_tension[
        element_kinds == kind][0]) for kind in np.unique(element_kinds)}
    if model.cable_count:
        strength[ELEMENT_NAMES[ElementKind.CABLE]] = float(model.cable_breaking_tension[0])
    contact = {} if beam else {f"{a}/{b}": {"k_c_N_per_m": k, "c_c_Ns_per_m": c}
                               for (a, b), (k, c) in contact_table(scene, model).items()}
    pybullet_fit = {}
    if scene.contact.enabled:
        from ..engines.bullet_materials import fit

        mat = fit(scene, model, bool(scene.debris.asset))
        pybullet_fit = {pair: {"k_c_rel_error": e[0], "c_c_rel_error": e[1],
                               "mu_k_rel_error": e[2]} for pair, e in mat.errors.items()}
    shape = ({"beam_length_m": scene.beam.length} if beam else
             {"nodes_per_side": model.nodes_per_side,
              "side_length_m": (model.nodes_per_side - 1) * scene.net.mesh_length})
    doc = {
        "scene": scene.scene.name,
        **shape,
        "node_count": model.node_count,
        "thread_count": model.thread_count,
        "total_mass_kg": float(model.mass.sum()),
        "nodes": kinds, "threads": threads, "breaking_tension_N": strength,
        "contact": contact,
        "bullet_engine_contact_fit": pybullet_fit,
    }
    debris = scene_debris(scene)
    if debris is not None:
        doc["debris"] = {
            "name": debris.name, "parts": len(debris.parts), "mass_kg": debris.mass,
            "center_of_mass_m": debris.center_of_mass.tolist(),
            "inertia_kg_m2": debris.inertia.tolist(),
            "principal_moments_kg_m2": debris.principal_moments.tolist(),
            "principal_axes": debris.principal_axes.T.tolist(),
            "extents_m": debris.extents.tolist()}
    if args.json:
        print(json.dumps(doc, indent=2))
        return 0
    size = (f"a beam {doc['beam_length_m']:g} m long" if beam else
            f"Ns = {model.nodes_per_side}, side {doc['side_length_m']:g} m")
    print(f"scene {doc['scene']}: {size}, {model.node_count} masses, {model.thread_count} "
          f"threads, total mass {doc['total_mass_kg']:.6g} kg")
    print("\nnodes        count    mass [kg]   radius [m]")
    for name, v in kinds.items():
        print(f"{name:<12}{v['count']:>6} {v['mass_kg']:>12.6g} {v['radius_m']:>12.6g}")
    print("\nthreads (Table 7)" + "".join(f"{label:>13}" for label in threads))
    rows = [("l_0 [m]", "rest_length_m"), ("r [m]", "radius_m"),
            ("k_a [N/m]", "k_a_N_per_m"), ("c_a [N s/m]", "c_a_Ns_per_m"),
            ("k_t [N/m]", "k_t_N_per_m"), ("c_t [N s/m]", "c_t_Ns_per_m"),
            ("k_b [N m/rad]", "k_b_Nm_per_rad"), ("c_b [N m s/rad]", "c_b_Nms_per_rad"),
            ("T_break [N]", "breaking_tension_N")]
    for label, key in rows:
        print(f"{label:<17}" + "".join(f"{t[key]:>13.6g}" for t in threads.values()))
    print("\nbreaking tension ([strength]; a knot efficiency on net and corner threads): "
          + ", ".join(f"{name} {value:.6g} N" for name, value in strength.items()))
    if contact:
        print("\ncontact pair (Tables 5-6)        k_c [1e9 N/m]   c_c [N s/m]")
    for pair, v in contact.items():
        print(f"{pair:<33}{v['k_c_N_per_m'] / 1e9:>13.4f} {v['c_c_Ns_per_m']:>13.2f}")
    if pybullet_fit:
        print("\nbullet engine: PyBullet's per-body values combine per pair (1/k in series, c "
              "summed, mu multiplied);\nrelative error of the fitted pairs   k_c       c_c"
              "      mu_k")
        for pair, v in pybullet_fit.items():
            print(f"{pair:<33}{v['k_c_rel_error']:>+9.1%} {v['c_c_rel_error']:>+9.1%} "
                  f"{v['mu_k_rel_error']:>+9.1%}")
    if debris is not None:
        d = doc["debris"]
        print(f"\ndebris {d['name']}: {d['parts']} parts, mass {d['mass_kg']:.6g} kg, "
              f"extents {_vec(d['extents_m'])} m (body frame)")
        print(f"centre of mass {_vec(d['center_of_mass_m'])} m (body frame)")
        print("inertia about it [kg m^2]: " + ", ".join(_vec(r) for r in d['inertia_kg_m2']))
        print("principal moments [kg m^2] " + _vec(d["principal_moments_kg_m2"]) + " about "
              + ", ".join(_vec(a, ".4f") for a in d["principal_axes"]))
    return 0


def _vec(values, fmt: str = ".6g") -> str:
    """A vector as text: (1, 2.5, 3)."""
    return "(" + ", ".join(f"{v:{fmt}}" for v in values) + ")"


def cmd_compare(args) -> int:
    from ..analysis.metrics import rmse
    from ..recording.reader import open_recording

    a, b = open_recording(args.a), open_recording(args.b)
    r = rmse(a, b)
    keys = ("rmse_pos_max", "rmse_pos_avg", "rmse_vel_max", "rmse_vel_avg", "samples")
    if args.json:
        print(json.dumps({k: r[k] for k in keys} | {"units": {
            "rmse_pos_max": "m", "rmse_pos_avg": "m", "rmse_vel_max": "m/s",
            "rmse_vel_avg": "m/s"}}, indent=2))
        return 0
    print(f"RMSE over {r['samples']} common sample times (Eq. 14)   maximum      average")
    print(f"position [m]                                  {r['rmse_pos_max']:10.4g}   "
          f"{r['rmse_pos_avg']:10.4g}")
    print(f"velocity [m/s]                                {r['rmse_vel_max']:10.4g}   "
          f"{r['rmse_vel_avg']:10.4g}")
    for rec in (a, b):
        if rec.status != "completed":
            print(f"note: {rec.path} is {rec.status}", file=sys.stderr)
    return 0


def cmd_metrics(args) -> int:
    from ..analysis.metrics import summary
    from ..recording.reader import open_recording

    rec = open_recording(args.run)
    doc = summary(rec)
    if args.json:
        print(json.dumps(doc))
        return 0
    print(f"{rec.path}: {rec.status}, {rec.time.size} frames")
    print("\n".join(strength_text(doc["strength"])))
    if "beam" in doc:
        _print_beam(doc, args.every)
        return 0
    capture = doc.get("capture")
    if capture:
        def when(t):
            return "never" if t is None else f"{t:.3f} s"
        spin = capture["spin"]
        print(f"first contact with the debris: {when(capture['first_contact_s'])}; "
              f"first net self-contact: {when(capture['first_self_contact_s'])}")
        print(f"net left the debris: {when(capture['leave_s'])}; at most "
              f"{capture['max_nodes_in_contact']} nodes in contact; wrap at most "
              f"{capture['max_wrap']:.3f} (at {capture['max_wrap_time_s']:.1f} s)")
        print("debris angular velocity [deg/s]: "
              f"{' '.join(f'{w:.4f}' for w in spin['initial_deg_s'])} -> "
              f"{' '.join(f'{w:.4f}' for w in spin['final_deg_s'])}")
        print(f"largest rise of the mechanical energy above its start and the work done on "
              f"it (winches, thrust): {capture['max_energy_gain_J']:.3g} J (a sound run has "
              "none)")
        print(f"capture quality at most {capture['max_capture_quality']:.3f} (at "
              f"{capture['max_capture_quality_time_s']:.1f} s); at the end: enclosed "
              f"{capture['enclosed_fraction'][-1]:.3f}, mouth opening "
              f"{capture['mouth_opening'][-1]:.3f}")
        print("outcome: " + _outcome_text(capture["outcome"], capture["outcome_time_s"],
                                          capture["outcome_reason"]))
    tow = doc.get("tow")
    if tow:
        _print_tow(tow)
    if "reel" in doc:
        print(_reel_text(doc["reel"]))
    print("   time [s]  mouth area [m^2]  mouth diagonal [m]  net height [m]"
          + ("  contacts [-]  wrap [-]  enclosed [-]  mouth [-]  quality [-]"
             if capture else ""))
    for k in _rows(doc["time_s"], args.every):
        extra = (f" {capture['nodes_in_contact'][k]:13d} {capture['wrap'][k]:9.3f}"
                 f" {capture['enclosed_fraction'][k]:13.3f}"
                 f" {capture['mouth_opening'][k]:10.3f}"
                 f" {capture['capture_quality'][k]:12.3f}" if capture else "")
        print(f"{doc['time_s'][k]:11.3f} {doc['mouth_area_m2'][k]:17.5g} "
              f"{doc['mouth_diagonal_m'][k]:19.5g} {doc['net_height_m'][k]:15.5g}{extra}")
    return 0


def _rows(times: list[float], every: float):
    """The frames a text table prints: the first, then the first at least ``every`` [s]
    after the last printed, and the last frame."""
    next_t = 0.0
    for k, t in enumerate(times):
        if t + 1e-9 >= next_t or k == len(times) - 1:
            yield k
            next_t = t + every


def _print_beam(doc: dict, every: float) -> None:
    """The cantilever's tip deflection against beam theory, then over time."""
    beam = doc["beam"]
    tip, theory, lumped = beam["tip_displacement_m"], beam["euler_bernoulli_m"], \
        beam["two_node_model_m"]

    def mm(v):
        return " ".join(f"{1e3 * c:.4f}" for c in v)
    print(f"tip displacement at the end [mm]: {mm(tip[-1])}; static, Euler-Bernoulli: "
          f"{mm(theory)}; the two-node model's: {mm(lumped)}")
    print("   time [s]  tip x [mm]  tip y [mm]  tip z [mm]")
    for k in _rows(doc["time_s"], every):
        print(f"{doc['time_s'][k]:11.3f}" + "".join(f" {1e3 * c:11.4f}" for c in tip[k]))


def _where(margin: dict) -> str:
    """An element at a time, as text: ``corner thread 220 (nodes 0-36) at 0.52 s``."""
    e = margin["element"]
    return (f"{e['kind']} {e['index']} (nodes {e['nodes'][0]}-{e['nodes'][1]}) at "
            f"{margin['time_s']:.3f} s")


def strength_text(doc: dict) -> list[str]:
    """The safety margins of :func:`bulletnet.analysis.metrics.strength_summary` as lines:
    the least safety factor, where (the element, its ends' positions) and when, the least
    of each kind, the elements over their strength and the largest snap load; with
    breakage, what failed (:func:`breakage_text`)."""
    if doc["least_safety_factor"] is None:
        return ["least safety factor: no element was ever taut", *breakage_text(doc)]
    ends = " and ".join(_vec(p, ".3f") for p in doc["element"]["positions_m"])
    lines = [f"least safety factor (breaking tension / largest tension): "
             f"{doc['least_safety_factor']:.4g}, {_where(doc)}: {doc['tension_N']:.4g} N "
             f"of {doc['breaking_tension_N']:.4g} N; its ends at {ends} m"]
    lines += [f"  {kind + 's':<15} ({m['elements']:>4}): "
              + (f"{m['least_safety_factor']:.4g}, {_where(m)}" if m["element"] else "never taut")
              for kind, m in doc["by_kind"].items()]
    over = doc["overloaded_elements"]
    lines.append(f"elements at or over their breaking tension: {over}"
                 + (f" (the first at {doc['first_overload_s']:.3f} s)" if over else ""))
    snap = doc["largest_snap"]
    if snap:
        lines.append(f"largest snap load: {snap['tension_N']:.4g} N (utilisation "
                     f"{snap['utilisation']:.3g}) in {_where(snap)}; "
                     f"{doc['snap_events']} slack -> taut events in all")
    lines.append("tensions: the largest of every step between frames" if doc["between_frames"]
                 else "tensions: the frames' own (a recording without peak tensions: a peak "
                 "between frames is missed)")
    return lines + breakage_text(doc)


def breakage_text(doc: dict) -> list[str]:
    """What failed (``strength.breakage`` on; the ``breakage`` of
    :func:`bulletnet.analysis.metrics.summary`'s strength) as lines; none without."""
    b = doc.get("breakage")
    if b is None:
        return []
    text = (f"failed (breakage on): {b['broken_threads']} threads, {b['broken_cables']} "
            "closing cables")
    if b["first_break_s"] >= 0:
        where = "/cables" if b["first_break_kind"] == "closing cable" else "/threads"
        text += (f"; the first at {b['first_break_s']:.6f} s, {b['first_break_kind']} "
                 f"{b['first_break_index']} (in {where}); elastic energy lost at the failures "
                 f"{b['broken_energy_J']:.4g} J")
    return [text]


def _print_tow(tow: dict) -> None:
    """The burn and the tow's outcome and measures, from a recording's attributes."""
    burn = ("never started" if tow["thrust_start_s"] < 0 else
            f"from {tow['thrust_start_s']:.2f} s, impulse {tow['thrust_impulse_Ns']:.6g} N s"
            + (f" (cut at {tow['thrust_cut_s']:.2f} s: the tether failed)"
               if tow.get("thrust_cut_s", -1.0) >= 0 else ""))
    print(f"burn: {burn}; tether axial mode {tow['thrust_axial_frequency_rad_s']:.4g} rad/s "
          f"(damping ratio {tow['thrust_damping_ratio']:.3g}, towed mass "
          f"{tow['thrust_towed_mass_kg']:.6g} kg)")
    if tow.get("thrust_integrator"):
        print(f"from the burn on: {tow['thrust_integrator']} at steps of "
              f"{tow['thrust_dt_s']:.3g} s")
    if "tow_outcome" in tow:
        print("tow: " + _outcome_text(tow["tow_outcome"], tow["tow_outcome_time_s"],
                                      tow["tow_outcome_reason"]))
        if tow["tow_start_s"] < 0:  # no frame judged: no measures
            return
        print(f"tether tension at the chaser: peak {tow['tow_peak_tension_N']:.4g} N, mean "
              f"{tow['tow_mean_tension_N']:.4g} N; {tow['tow_snaps']} snaps (slack to taut), "
              f"largest {tow['tow_snap_peak_N']:.4g} N; least chaser-debris distance "
              f"{tow['tow_least_distance_m']:.3f} m; debris rate at most "
              f"{tow['tow_largest_debris_rate_deg_s']:.3f} deg/s")


def _reel_text(reel: dict) -> str:
    """The reel at the chaser (:func:`bulletnet.analysis.metrics.reel_summary`) as a line."""
    start = ("never started" if reel["start_s"] < 0 else f"from {reel['start_s']:.2f} s")
    return (f"reel at the chaser: {start}; tether deployed {reel['initial_length_m']:.3f} m -> "
            f"{reel['final_length_m']:.3f} m (least {reel['least_length_m']:.3f} m, largest "
            f"{reel['largest_length_m']:.3f} m); its work {reel['work_J']:.4g} J (negative: "
            "its brake took energy out)")


def _outcome_text(outcome: str, decided: float, reason: str) -> str:
    """An outcome, when it was decided [s] and why, as a line: ``escaped, decided at 50.60 s
    (no contact since 45.60 s)``, ``undecided (no contact yet: ...)``."""
    when = f", decided at {decided:.2f} s" if outcome != "undecided" else ""
    return f"{outcome}{when} ({reason})"


def cmd_plot(args) -> int:
    from ..analysis.plots import plot_recordings
    from ..recording.reader import open_recording

    a = open_recording(args.a)
    b = open_recording(args.b) if args.b else None
    _within("--times", args.times, a.time[0], a.time[-1])
    for path in plot_recordings(a, b, args.out, args.times):
        print(path)
    return 0


def _within(option: str, times: list[float] | None, start: float, end: float) -> None:
    """A clear error for a time [s] outside the recorded [start, end]."""
    for t in times or []:
        if not start - 1e-9 <= t <= end + 1e-9:
            raise ScenarioError(f"{option} {t:g}: outside the recording, {start:g} to {end:g} s")


def cmd_view(args) -> int:
    from ..viewer import export_html, load_replay, serve

    if not 0 <= args.port <= 65535:
        raise ScenarioError(f"--port must be 0 to 65535, got {args.port}")
    replay = load_replay(args.runs, args.every)
    _within("--snapshots", args.snapshots, replay.time[0], replay.time[-1])
    snapshots = args.snapshots or replay.default_snapshots()
    if args.html:
        print(export_html(replay, args.html, snapshots, force=args.force))
        return 0
    try:
        serve(replay, args.port, snapshots, announce=lambda url: print(
            f"bulletnet: replay at {url} (Ctrl-C to stop)", flush=True))
    except KeyboardInterrupt:
        print("bulletnet: viewer stopped", file=sys.stderr)
    return 0


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    handler = {"run": cmd_run, "scenes": cmd_scenes, "scene": cmd_scene, "warmup": cmd_warmup,
               "params": cmd_params, "compare": cmd_compare, "metrics": cmd_metrics,
               "plot": cmd_plot, "view": cmd_view,
               "bench": cmd_bench, "stability": cmd_stability,
               "sweep": cmd_sweep, "study": cmd_study, "optimize": cmd_optimize}[args.command]
    interrupt.install()  # Ctrl-C and SIGTERM: the run keeps its frames, marked interrupted
    try:
        return handler(args)
    except BulletnetError as exc:
        print(f"bulletnet: error: {exc}", file=sys.stderr)
        return exc.exit_code
    except BrokenPipeError:  # e.g. piped into `head`
        sys.stderr.close()
        return 0
    except KeyboardInterrupt:
        kept = ("; the recording keeps every frame so far (status 'interrupted')"
                if args.command == "run" else "")
        print(f"\nbulletnet: interrupted{kept}", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
