"""Run functions of the study tests (imported by name on Dask workers and in subprocesses)."""

from __future__ import annotations

import os
import time


def slow(inputs: dict) -> dict:
    """Sleeps ``pause`` [s], then returns y = x^2 and the outcome ``hit`` if x < 0.3, else
    ``miss``: a run slow enough to be stopped half-way through a study."""
    time.sleep(inputs.get("pause", 0.0))
    x = inputs["x"]
    return {"y": x * x, "outcome": "hit" if x < 0.3 else "miss"}


def crash(inputs: dict) -> dict:
    """Kills its own process (a worker dying mid-run) when x > ``above``; else y = x."""
    if inputs["x"] > inputs["above"]:
        os._exit(1)
    return {"y": inputs["x"]}
