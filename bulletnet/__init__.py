"""bulletnet: tether-nets capturing space debris, on PyBullet and compiled kernels.

The Python API mirrors the CLI::

    import bulletnet as bn
    scene = bn.load_scenario("deployment", {"simulation.engine": "fast"})
    result = bn.run(scene, "deployment.h5")
    rec = bn.open_recording("deployment.h5")
    area = bn.metrics.mouth_area(rec)          # [m^2], shape (T,)
"""

from __future__ import annotations

__version__ = "0.1.0"

from . import kernel_cache, metrics  # noqa: F401 (kernel_cache first: it points numba's cache)
from .builder import build_model, initial_state
from .debris import Debris, Part, load_debris, make_debris
from .errors import BulletnetError, DivergenceError, RecordingError, ScenarioError
from .hertz import contact_table
from .model import NetModel, NodeKind
from .recording import Recording, open_recording
from .scenario import Scenario
from .scenario import load as load_scenario
from .scenario import loads as loads_scenario
from .simulate import RunResult, run
from .state import NetState

__all__ = [
    "BulletnetError", "Debris", "DivergenceError", "NetModel", "NetState", "NodeKind", "Part",
    "Recording", "RecordingError", "RunResult", "Scenario", "ScenarioError", "__version__",
    "build_model", "contact_table", "initial_state", "load_debris", "load_scenario",
    "loads_scenario", "make_debris", "metrics", "open_recording", "run",
]
