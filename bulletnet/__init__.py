"""bulletnet: tether-nets capturing space debris, on PyBullet and compiled kernels.

The Python API mirrors the CLI::

    import bulletnet as bn
    scene = bn.load_scenario("deployment", {"simulation.engine": "fast"})
    result = bn.run(scene, "deployment.h5")
    rec = bn.open_recording("deployment.h5")
    area = bn.metrics.mouth_area(rec)          # [m^2], shape (T,)

The package is layered (docs/development.md): ``common`` < ``kernels`` < ``model`` <
``solver``, ``recording`` < ``engines`` < ``analysis`` < ``sim`` < ``studies``, ``viewer`` <
``cli``. The names below are loaded on first use, so ``import bulletnet`` (and the command
line's start) imports neither numba nor PyBullet.
"""

from __future__ import annotations

import importlib

from .common import kernel_cache  # noqa: F401 (first: it points numba's cache before any kernel)

__version__ = "0.1.0"

_PUBLIC = {  # name -> (module, attribute or None for the module itself)
    "BulletnetError": ("common.errors", "BulletnetError"),
    "DivergenceError": ("common.errors", "DivergenceError"),
    "RecordingError": ("common.errors", "RecordingError"),
    "ScenarioError": ("common.errors", "ScenarioError"),
    "Scenario": ("model.scenario", "Scenario"),
    "load_scenario": ("model.scenario", "load"),
    "loads_scenario": ("model.scenario", "loads"),
    "build_model": ("model.builder", "build_model"),
    "initial_state": ("model.builder", "initial_state"),
    "Debris": ("model.debris", "Debris"),
    "Part": ("model.debris", "Part"),
    "load_debris": ("model.debris", "load_debris"),
    "make_debris": ("model.debris", "make_debris"),
    "contact_table": ("model.materials", "contact_table"),
    "NetModel": ("model.net", "NetModel"),
    "NodeKind": ("model.net", "NodeKind"),
    "NetState": ("model.state", "NetState"),
    "Recording": ("recording.reader", "Recording"),
    "open_recording": ("recording.reader", "open_recording"),
    "metrics": ("analysis.metrics", None),
    "RunResult": ("sim.loop", "RunResult"),
    "run": ("sim.loop", "run"),
}

__all__ = sorted([*_PUBLIC, "__version__"])


def __getattr__(name: str):
    if name not in _PUBLIC:
        raise AttributeError(f"module 'bulletnet' has no attribute {name!r}")
    module, attribute = _PUBLIC[name]
    value = importlib.import_module(f".{module}", __name__)
    if attribute is not None:
        value = getattr(value, attribute)
    globals()[name] = value  # later lookups skip this function
    return value


def __dir__():
    return __all__
