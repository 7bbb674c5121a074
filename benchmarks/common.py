"""What the benchmarks share: timing runs (:func:`bulletnet.studies.bench.timed`), the two
yardsticks every speed figure is a ratio to (:class:`Yardsticks`) and the Eq. 14 error
summary."""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import time
from pathlib import Path

import yardstick

import bulletnet as bn
from bulletnet.sim.observers import Observer
from bulletnet.studies.bench import ERROR_KEYS, rmse_measure, timed

__all__ = ["ERROR_KEYS", "At", "Yardsticks", "best_us", "errors", "machine", "output_dir",
           "parser", "timed", "triad_bandwidth", "user_env"]

DEPLOYMENT_THREADS = 2 * 11 * 10 + 4
"""Threads of the paper's Ns = 11 net (the yardstick's) [-]."""


def machine() -> dict:
    """What a speed figure was measured on: the CPU as the compiler sees it (its LLVM name and
    widest vector extension: the kernels' code depends on both), its clock as the kernel
    reports it [MHz], the cores and the load average over the last minute [-]. Sessions run on
    different hosts (docs/speed.md), so every benchmark's JSON names its CPU."""
    from llvmlite import binding

    features = binding.get_host_cpu_features()
    vector = next((v for v in ("avx512f", "avx2", "avx", "sse2") if features.get(v)), "none")
    mhz = None
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("cpu MHz"):
                mhz = float(line.split(":")[1])
                break
    except OSError:
        pass
    return {"arch": platform.machine(), "cpu": binding.get_host_cpu_name(), "vector": vector,
            "mhz": mhz, "cpus": os.cpu_count(), "load_average_1min": os.getloadavg()[0]}


def user_env(**extra: str) -> dict[str, str]:
    """The environment a timed ``bulletnet`` process runs in: this one with ``extra`` set, and
    with Python's bytecode cache as a user has it. A user's interpreter writes each module's
    compiled bytecode on its first import and reads it from then on (a wheel's install writes
    it at once); an environment that sets ``PYTHONDONTWRITEBYTECODE`` (some containers do)
    would make every timed process compile the package's sources anew, about 0.08 s of each
    start that no user pays, so it is dropped here."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    return {**env, **extra}


def sqrt_division_bound(threads: int = DEPLOYMENT_THREADS, repeats: int = 200000) -> float:
    """The machine's throughput bound of a thread's unavoidable arithmetic: one square root
    and one reciprocal per thread, over ``threads`` contiguous values, vectorized as the
    stencils are [ns per thread] (best of 7)."""
    import numba as nb
    import numpy as np

    @nb.njit(error_model="numpy")
    def kernel(x, y, z, out, reps):
        for _ in range(reps):
            for i in range(x.shape[0]):
                length = np.sqrt(x[i] * x[i] + y[i] * y[i] + z[i] * z[i])
                out[i] = 1.0 / length + length

    rng = np.random.default_rng(0)
    x, y, z, out = (rng.random(threads) + 0.5 for _ in range(4))
    kernel(x, y, z, out, 10)
    best = float("inf")
    for _ in range(7):
        start = time.perf_counter()
        kernel(x, y, z, out, repeats)
        best = min(best, (time.perf_counter() - start) / repeats / threads)
    return 1e9 * best


def best_us(call, calls: int = 5000) -> float:
    """Best of 5 timed loops of ``call(calls)``, per call [us] (one untimed warm-up call)."""
    call(2)
    best = float("inf")
    for _ in range(5):
        start = time.perf_counter()
        call(calls)
        best = min(best, (time.perf_counter() - start) / calls)
    return 1e6 * best


def triad_bandwidth(working_set_bytes: int, minimum: int = 1024,
                    calls: int = 2000) -> tuple[float, int]:
    """The memory bandwidth [GB/s] of a triad a = b + s c over three float64 arrays of
    ``working_set_bytes`` in all (each at least ``minimum`` long), best of 5 loops of
    ``calls``; and the arrays' bytes."""
    import numba as nb
    import numpy as np

    @nb.njit(error_model="numpy")
    def triad(a, b, c, reps):
        for _ in range(reps):
            for i in range(a.shape[0]):
                a[i] = b[i] + 1e-300 * c[i]

    n = max(working_set_bytes // 24, minimum)
    a, b, c = (np.random.default_rng(k).random(n) for k in range(3))
    return 24 * n / best_us(lambda k: triad(a, b, c, k), calls) * 1e-3, 24 * n


class Yardsticks:
    """The two yardsticks a speed benchmark times in its own run, so that its figures are
    ratios to what the project's changes cannot move: the frozen plain loop
    (``yardstick.py``: the 3 s deployment over a pair list; its file's SHA-256 recorded),
    timed with :meth:`time` beside the benchmark's own repeats, and the machine's sqrt and
    division bound (:func:`sqrt_division_bound`), the floor of a thread's arithmetic."""

    def __init__(self):
        self.walls: list[float] = []
        """The plain loop's wall times [s], one per :meth:`time`."""
        self.bounds_ns: list[float] = [sqrt_division_bound()]
        """The bound [ns per thread and step], measured at the start and at each
        :meth:`time`: a load on the other core moves it by up to 2x (0.40 against 0.85 ns
        seen on 2026-12-02), so it is timed beside the runs, as the plain loop is."""

    @property
    def bound_ns(self) -> float:
        """Median of the bound's measurements [ns per thread and step]."""
        return statistics.median(self.bounds_ns)

    def time(self) -> float:
        """Time the plain loop once (it compiles on the first call, untimed) and the bound
        [s]."""
        self.walls.append(yardstick.run()[0])
        self.bounds_ns.append(sqrt_division_bound(repeats=20000))
        return self.walls[-1]

    @property
    def median(self) -> float:
        """Median of the plain loop's wall times [s]."""
        return statistics.median(self.walls)

    def bound_s(self, steps: int, threads: int = DEPLOYMENT_THREADS) -> float:
        """The bound's time for ``steps`` steps of ``threads`` threads [s]."""
        return 1e-9 * self.bound_ns * threads * steps

    def ratios(self, wall: float, steps: int | None = None,
               threads: int = DEPLOYMENT_THREADS) -> dict:
        """``wall`` [s] as a ratio to the plain loop's median, and (given the run's steps
        and threads) to the bound's time for the same work."""
        doc = {"x_yardstick": wall / self.median}
        if steps:
            doc["x_bound"] = wall / self.bound_s(steps, threads)
        return doc

    def doc(self) -> dict:
        """What the benchmark's JSON records of the yardsticks."""
        return {"plain_loop": {"file": "benchmarks/yardstick.py",
                               "sha256": yardstick.file_hash(), "walls_s": self.walls,
                               "median_s": self.median,
                               "what": f"{yardstick.DURATION:g} s deployment, symplectic "
                                       f"Euler at {yardstick.DT:g} s, plain pair-list loop"},
                "sqrt_division_bound": {"ns_per_thread": self.bound_ns,
                                        "ns_per_thread_all": self.bounds_ns,
                                        "threads": DEPLOYMENT_THREADS,
                                        "us_per_step": 1e-3 * self.bound_ns
                                        * DEPLOYMENT_THREADS}}


class At(Observer):
    """Acts once on a run, at its first frame at or after ``at`` [s]: keeps what :meth:`act`
    returns in ``taken`` and stops the run."""

    def __init__(self, at: float):
        self.at, self.taken = at, None

    def frame(self, run) -> bool:
        if run.state.time < self.at - 1e-9:
            return False
        self.taken = self.act(run.engine, run.state)
        return True

    def act(self, engine, state):
        """What to take from the run's engine and state at that frame."""
        raise NotImplementedError


def errors(path, reference) -> dict:
    """Eq. 14 RMSE (max and average over nodes) of the recording at ``path`` against a
    recording; keys in :data:`ERROR_KEYS` plus ``samples``."""
    return rmse_measure(bn.open_recording(path), reference)


def parser(doc: str) -> argparse.ArgumentParser:
    """Arguments every benchmark takes: the output folder and the repeat count."""
    p = argparse.ArgumentParser(description=doc)
    p.add_argument("out", nargs="?", default="benchmarks/out", help="output folder")
    p.add_argument("--repeats", type=int, default=3, help="timed repeats (median reported)")
    return p


def output_dir(args) -> Path:
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    return out
