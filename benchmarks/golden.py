"""Golden check: hashes of every dataset of short runs covering each path of the solver.

A change that must leave results bit for bit the same (a restructure, a kernel split, a
different argument layout) is checked by writing the hashes before it and comparing after:

    python benchmarks/golden.py --write benchmarks/results/golden.json    # before
    python benchmarks/golden.py --check benchmarks/results/golden.json    # after (exit 1: differs)

A dataset the hashes do not hold (one a change adds, such as ``threads/breaking_tension``) is
listed as new, not as a difference: the check is of the datasets that existed before. A
dataset that is gone differs.

The runs cover the grid and pair-list kernels, both integrators, bending, contact with the
debris and self-contact (primitives, boxes and a mesh), the closing cables with their winches
and the tether, the clamped cantilever and the ``bullet`` engine. Each is short (the whole
check takes about a minute once compiled). The hashes are of the datasets' bytes, so they
hold for one machine kind and one build of the libraries (a different CPU, or another numpy,
may round differently: the file records the versions, and a check under others says so); the
check is a tool for changes, not a test of physics: write the hashes at the commit before the
change, in the environment of the check.
"""

from __future__ import annotations

import argparse
import hashlib
import importlib.metadata
import json
import platform
import sys
import tempfile
from pathlib import Path

import h5py

import bulletnet as bn

DEPLOY_BENDING = {"bending.enabled": True}
IMPLICIT = {"simulation.integrator": "implicit_euler", "simulation.dt": 4e-5}
PAIRS = {"simulation.kernels": "pairs"}
CASES: dict[str, tuple[str, dict]] = {
    "deployment_symplectic_grid": ("deployment", {"scene.duration": 0.1}),
    "deployment_symplectic_pairs": ("deployment", {"scene.duration": 0.1, **PAIRS}),
    "deployment_implicit_grid": ("deployment", {"scene.duration": 0.5, **IMPLICIT}),
    "deployment_implicit_pairs": ("deployment", {"scene.duration": 0.5, **IMPLICIT, **PAIRS}),
    "deployment_bending_symplectic_grid": ("deployment", {"scene.duration": 0.1,
                                                          **DEPLOY_BENDING}),
    "deployment_bending_symplectic_pairs": ("deployment", {"scene.duration": 0.1,
                                                           **DEPLOY_BENDING, **PAIRS}),
    "deployment_bending_implicit_grid": ("deployment", {"scene.duration": 0.5, **IMPLICIT,
                                                        **DEPLOY_BENDING}),
    "deployment_bending_implicit_pairs": ("deployment", {"scene.duration": 0.5, **IMPLICIT,
                                                         **DEPLOY_BENDING, **PAIRS}),
    "capture_bending_grid": ("capture", {"scene.duration": 10.0, "bending.enabled": True}),
    "capture_pairs": ("capture", {"scene.duration": 10.0, **PAIRS}),
    "capture_symplectic_grid": ("capture", {"scene.duration": 0.2,
                                            "simulation.integrator": "symplectic_euler",
                                            "simulation.dt": 2e-6}),
    "closing_tether_bending": ("capture_closing", {"scene.duration": 10.0,
                                                   "bending.enabled": True}),
    "closing_tether_pairs_timed": ("capture_closing", {"scene.duration": 2.0, **PAIRS,
                                                       "closing.trigger": "time",
                                                       "closing.trigger_time": 0.5}),
    "envisat": ("capture_envisat", {"scene.duration": 1.0}),
    "capture_mesh": ("capture", {"scene.duration": 1.0, "debris.asset": "apollo_csm_mesh"}),
    "cantilever": ("cantilever", {"scene.duration": 0.2}),
    "bullet_engine": ("deployment", {"scene.duration": 0.02, "net.nodes_per_side": 5,
                                     "simulation.engine": "bullet"}),
}
"""Case name -> (scene, overrides)."""


def dataset_hashes(path: Path) -> dict[str, str]:
    """SHA-256 (first 16 hex digits) of every dataset's bytes, by its path in the file."""
    out = {}
    with h5py.File(path, "r") as f:
        def visit(name, obj):
            if isinstance(obj, h5py.Dataset):
                out[name] = hashlib.sha256(obj[()].tobytes()).hexdigest()[:16]
        f.visititems(visit)
    return out


LIBRARIES = "_libraries"
"""The key of the file's record of the versions the hashes were written with."""


def libraries() -> dict[str, str]:
    """The versions of the libraries the results depend on, and the machine's CPU kind."""
    return {"machine": platform.machine(), "python": platform.python_version(),
            **{name: importlib.metadata.version(name)
               for name in ("numpy", "numba", "llvmlite", "scipy", "pybullet", "h5py")}}


def run_cases(names: list[str]) -> dict[str, dict[str, str]]:
    """Run each named case into a temporary file; its dataset hashes, by case."""
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name in names:
            scene, overrides = CASES[name]
            path = Path(tmp) / f"{name}.h5"
            bn.run(bn.load_scenario(scene, overrides), path, force=True)
            out[name] = dataset_hashes(path)
            print(f"golden: {name}: {len(out[name])} datasets", file=sys.stderr)
    return out


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    mode = p.add_mutually_exclusive_group(required=True)
    mode.add_argument("--write", metavar="FILE", help="write the hashes to FILE (JSON)")
    mode.add_argument("--check", metavar="FILE", help="compare with FILE; exit 1 on a difference")
    p.add_argument("--only", nargs="*", choices=sorted(CASES), help="these cases only")
    args = p.parse_args()
    names = args.only or list(CASES)
    hashes = run_cases(names)
    if args.write:
        Path(args.write).parent.mkdir(parents=True, exist_ok=True)
        Path(args.write).write_text(json.dumps({LIBRARIES: libraries(), **hashes}, indent=1,
                                               sort_keys=True) + "\n")
        return 0
    expected = json.loads(Path(args.check).read_text())
    written, now = expected.get(LIBRARIES, {}), libraries()
    for name in sorted(set(written) | set(now)):
        if written.get(name) != now.get(name):
            print(f"golden: written with {name} {written.get(name, '(not recorded)')}, "
                  f"this environment has {now.get(name)}: differences may be the build's")
    differ = [f"{case}/{key}" for case in names for key in sorted(expected.get(case, {}))
              if hashes[case].get(key) != expected[case][key]]
    new = [f"{case}/{key}" for case in names
           for key in sorted(set(hashes[case]) - set(expected.get(case, {})))]
    for item in differ:
        print(f"golden: differs: {item}")
    for item in new:
        print(f"golden: new: {item}")
    print(f"golden: {len(names)} cases, {len(differ)} datasets differ, {len(new)} new "
          "(datasets the hashes do not hold yet: not a difference)")
    return 1 if differ else 0


if __name__ == "__main__":
    sys.exit(main())
