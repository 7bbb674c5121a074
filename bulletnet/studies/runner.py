"""Running scenes for sweeps, studies and benchmarks: one scene, its divergence caught and its
recording summarized (:func:`run_scene`), and many fanned out over Dask (:func:`fan_out`,
a local cluster or a scheduler's address; Dask is imported lazily), each worker warmed up
first (:func:`warm_up`: the compiled kernels the runs use, loaded once)."""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import tempfile
import time
from collections.abc import Callable, Iterator

from ..common.errors import BulletnetError, ScenarioError
from .measures import Measures, summary_measures


def run_scene(scene, overrides: dict | None = None, out: str | os.PathLike | None = None,
              measures: Measures | None = None) -> dict:
    """Run ``scene`` (a name, a path or a :class:`~bulletnet.model.scenario.Scenario`) with
    ``overrides`` into the recording ``out`` (None: a temporary file, deleted once measured)
    and summarize it: ``status``, ``message``, ``wall_s`` (the run's wall time, from loading
    the scene to its recording closed) [s], ``steps`` and each of ``measures`` (default:
    :func:`~bulletnet.studies.measures.summary_measures` of the scene). Never raises for a
    failing run: its status says what happened (``diverged``, ``error``); a diverged run
    keeps its recording."""
    from ..model.scenario import Scenario, load
    from ..recording.reader import open_recording
    from ..sim.loop import run

    row = {"status": "error", "message": "", "wall_s": None, "steps": None}
    values = {}
    start = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="bulletnet-") as scratch:
        path = out or os.path.join(scratch, "run.h5")
        try:
            scenario = (scene.with_overrides(overrides) if overrides else scene) \
                if isinstance(scene, Scenario) else load(scene, overrides or {})
            measures = summary_measures(scenario) if measures is None else measures
            values = dict.fromkeys(measures)
            result = run(scenario, path, force=True)
            row |= {"status": result.status, "steps": result.stats.get("steps")}
            row["wall_s"] = time.perf_counter() - start
            rec = open_recording(path)
            values = {name: measure(rec) for name, measure in measures.items()}
        except BulletnetError as exc:
            row |= {"status": "diverged" if exc.exit_code == 3 else "error",
                    "message": str(exc)}
        except Exception as exc:  # noqa: BLE001 (one bad run must not stop the others)
            row |= {"status": "error", "message": f"{type(exc).__name__}: {exc}"}
    if row["wall_s"] is None:
        row["wall_s"] = time.perf_counter() - start
    return row | values


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
            costs: list[float] | None = None, client=None) -> Iterator[dict]:
    """Call ``fn(*job)`` for every job and yield each result as it finishes: on Dask (a local
    cluster of ``workers`` processes, or ``scheduler``), or one after another in this process
    with ``serial``. ``fn`` must not raise (it reports a failure in its result); a job whose
    worker died or was lost yields ``lost(job, message)`` instead, and the others go on.
    ``warm``: (scene, variants) whose kernels each worker loads first (:func:`warm_up`);
    ``costs``: the jobs' relative costs, handed out longest first, so that no long job is left
    running alone at the end. ``client``: a Dask client already open (:func:`dask_client`)
    to run on instead of opening one (``scheduler`` and ``workers`` are then unused)."""
    if serial:
        if warm is not None:
            warm_up(*warm)
        for job in jobs:
            yield fn(*job)
        return
    order = sorted(range(len(jobs)), key=lambda k: -costs[k]) if costs else range(len(jobs))
    opened = contextlib.nullcontext(client) if client is not None \
        else dask_client(scheduler, workers)
    with opened as client:
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
            dashboard_address=":0") as cluster, Client(cluster) as client:
        # (":0": a free port; None still takes 8787 and warns if another cluster has it)
        client.run(_quiet_worker)
        try:
            yield client
        except KeyboardInterrupt:
            # closing the cluster mid-run logs each cancelled job and each worker it has to
            # stop: the caller says it was interrupted, in one line
            logging.getLogger("distributed").setLevel(logging.CRITICAL)
            raise
        client.run(_closing_worker)


def _closing_worker() -> None:
    """Once the work is done: closing a local cluster stops its scheduler and workers in an
    order in which a worker's heartbeat can find the scheduler gone, which Dask logs as an
    error with a traceback; with nothing left to run it is none, so the worker says
    nothing more."""
    logging.getLogger("distributed").setLevel(logging.CRITICAL)


def _quiet_worker() -> None:
    """Make this local worker process ignore Ctrl-C, which reaches it too (one process group)
    while the driver stops it, and log Dask's errors only (not its warnings about jobs
    cancelled as the cluster closes)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    logging.getLogger("distributed").setLevel(logging.ERROR)

