"""What the benchmarks share: timing runs and the Eq. 14 error summary."""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import bulletnet as bn

ERROR_KEYS = ("rmse_pos_max", "rmse_pos_avg", "rmse_vel_max", "rmse_vel_avg")


def timed(scene, path, repeats: int = 1):
    """Run ``scene`` into ``path`` ``repeats`` times: (median wall [s], all walls, last result)."""
    walls = []
    for _ in range(repeats):
        start = time.perf_counter()
        result = bn.run(scene, path, force=True)
        walls.append(time.perf_counter() - start)
    return statistics.median(walls), walls, result


def errors(path, reference) -> dict:
    """Eq. 14 RMSE (max and average over nodes) of the recording at ``path`` against a
    recording; keys in :data:`ERROR_KEYS` plus ``samples``."""
    r = bn.metrics.rmse(bn.open_recording(path), reference)
    return {k: r[k] for k in (*ERROR_KEYS, "samples")}


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
