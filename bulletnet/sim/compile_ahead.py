"""A first run's compilation on both cores.

The first run of a scene compiles groups of kernels that do not depend on each other: the
threads' step (the implicit solver), the bending springs, the contact stage (the Verlet
list, the debris' signed distance, the contact laws). numba compiles in the process that
calls, holding the interpreter, so one process compiles them one after the other.
:func:`compile_ahead` has a second process compile the contact stage, if numba's cache lacks
it, or else the other groups it lacks besides the step and the frame's (the thread loads
each recorded frame computes), into the same folder (:mod:`bulletnet.common.kernel_cache`),
while this one compiles the rest; the compiled loop then loads them all. (The split roughly
balances the two processes: the capture with bending's step and frame kernels took 11.6 and
2.1 s, its bending springs and contact stage 4.8 and 13.4 s; the closing capture's contact
stage with its coupled solve 29 s, its bending springs 5.8 s; docs/development.md.) If the
cache holds those groups,
or the second process fails, nothing changes but the time: each process compiles exactly
what a run would (the same kernels for the same argument types), so the results are the
same.

A scene whose tow goes on with another integrator (``thrust.integrator``: the removal's
implicit capture, then its symplectic tow) needs that integrator's loop only at the burn,
tens of seconds into the run; a second process compiles it meanwhile, on the other core, and
the run loads it at the switch (or, if it is not ready, compiles it itself as before).

    python -m bulletnet.sim.compile_ahead SCENE.toml GROUP ...   # the second process
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
from pathlib import Path

from ..common.direct_call import signature

HELPER_TIMEOUT_S = 600.0
"""Longest wait for the second process [s]; past it this process compiles on its own."""


def is_cached(dispatcher, args: tuple) -> bool:
    """Whether the dispatcher's compiled code for ``args`` is loaded or in numba's cache."""
    sig = signature(args)
    if sig in dispatcher.overloads:
        return True
    # what Dispatcher.compile tries first (numba has no public call for it)
    return dispatcher._cache.load_overload(sig, dispatcher.targetctx) is not None


def compile_group(calls: list[tuple]) -> None:
    """Compile (or load) each (dispatcher, args) of a group for its arguments' types."""
    for dispatcher, args in calls:
        dispatcher.compile(signature(args))


def _helper(scenario, groups: list[str]) -> subprocess.Popen:
    """A second process compiling the named groups of ``scenario`` (its TOML in a file the
    process reads before it compiles; the file is removed when the process ends)."""
    from ..model.scenario import to_toml

    with tempfile.NamedTemporaryFile("w", suffix=".toml", delete=False,
                                     encoding="utf-8") as f:
        f.write(to_toml(scenario))
    return subprocess.Popen([sys.executable, "-m", "bulletnet.sim.compile_ahead", f.name,
                             *groups], stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)


def stop_helper(helper: subprocess.Popen | None) -> None:
    """End ``helper`` if it still runs (the run is over: what it has not compiled is not
    needed)."""
    if helper is not None and helper.poll() is None:
        helper.kill()
        helper.wait()
        Path(helper.args[3]).unlink(missing_ok=True)  # its scene, if it had not read it yet


def compile_ahead(scenario, engine, state) -> subprocess.Popen | None:
    """Compile the engine's kernel groups for ``state`` on two cores when numba's cache lacks
    any group besides the step and the frame's: the contact stage there if it is among them,
    else those groups, and the rest here (see the module doc); otherwise do nothing (the
    run compiles or loads as usual). The tow's loop (group ``tow``, a scene whose burn switches
    integrator) is left compiling in a second process while the run goes on, to be loaded
    at the switch: the process is returned, for :func:`stop_helper` at the run's end (None:
    none)."""
    groups = engine.kernel_groups(state)
    missing = [name for name, calls in groups.items() if name not in ("step", "frame", "tow")
               and not all(is_cached(d, a) for d, a in calls)]
    if missing:
        there = ["contact"] if "contact" in missing else missing  # the largest: module doc
        helper = _helper(scenario, there)
        try:
            for name in groups:
                if name not in (*there, "tow"):
                    compile_group(groups[name])
            helper.wait(timeout=HELPER_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            pass  # this process compiles what is left, as the run goes
        finally:
            stop_helper(helper)  # timed out, or this process was interrupted
    if "tow" in groups and not all(is_cached(d, a) for d, a in groups["tow"]):
        return _helper(scenario, ["tow"])
    return None


def main(argv: list[str]) -> int:
    """The second process: build the scene's engine (``argv[0]``: its TOML) and compile the
    named kernel groups (``argv[1:]``)."""
    from ..common.kernel_cache import import_numba_arrays
    from ..engines import make_engine
    from ..model.builder import build_model, initial_state
    from ..model.scenario import load

    import_numba_arrays()
    try:
        scenario = load(argv[0])
    finally:
        Path(argv[0]).unlink(missing_ok=True)
    model = build_model(scenario)
    state = initial_state(scenario, model)
    engine = make_engine(scenario, model)
    try:
        groups = engine.kernel_groups(state)
        for name in argv[1:]:
            compile_group(groups.get(name, []))
    finally:
        engine.close()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
