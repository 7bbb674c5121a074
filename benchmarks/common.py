"""What the benchmarks share: timing runs (:func:`bulletnet.studies.bench.timed`) and the Eq. 14
error summary."""

from __future__ import annotations

import argparse
from pathlib import Path

import bulletnet as bn
from bulletnet.studies.bench import ERROR_KEYS, rmse_measure, timed

__all__ = ["ERROR_KEYS", "errors", "output_dir", "parser", "timed"]


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
