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


BOWL_CALLS = {"left": None}
"""Calls of :func:`bowl` left before it raises KeyboardInterrupt (None: never), as a killed
driver would stop a serial optimisation half-way through a design."""


def bowl(inputs: dict) -> dict:
    """A noisy bowl with its maximum at (x, y) = (0.3, 0.7):
    ``f = -(x - 0.3)^2 - (y - 0.7)^2 + 0.05 u`` of the design (x, y) and the drawn
    uncertainty u; also returns u itself (``u_seen``) and the event ``high`` (f > -0.05).
    Raises ValueError where u > ``fail_above`` (if given), as a failing run would."""
    if inputs["u"] > inputs.get("fail_above", float("inf")):
        raise ValueError(f"u = {inputs['u']} > fail_above")
    left = BOWL_CALLS["left"]
    if left is not None:
        if left <= 0:
            raise KeyboardInterrupt
        BOWL_CALLS["left"] = left - 1
    f = -(inputs["x"] - 0.3) ** 2 - (inputs["y"] - 0.7) ** 2 + 0.05 * inputs["u"]
    return {"f": f, "u_seen": inputs["u"], "high": f > -0.05}
