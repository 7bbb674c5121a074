"""Engines: ``fast`` (compiled kernels), ``bullet`` (PyBullet bodies), ``reference`` (scipy)."""

from __future__ import annotations

from ..model.net import NetModel
from ..model.scenario import Scenario
from .base import Engine


def make_engine(scenario: Scenario, model: NetModel) -> Engine:
    """The engine named by ``scenario.simulation.engine``; heavy imports happen here."""
    name = scenario.simulation.engine
    if name == "fast":
        from .fast import FastEngine as cls
    elif name == "bullet":
        from .bullet import BulletEngine as cls
    else:
        from .reference import ReferenceEngine as cls
    return cls(scenario, model)
