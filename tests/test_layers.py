"""The package's layers only point down: each package imports (anywhere in its source,
function-level imports included) only from packages of a lower rank, the heavy libraries
appear only in the packages that need them, and ``import bulletnet`` loads none of them."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import bulletnet

PACKAGE = Path(bulletnet.__file__).resolve().parent


def _module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def import_graph() -> dict[str, set[str]]:
    """Each bulletnet module -> the bulletnet modules it imports anywhere in its source."""
    paths = {_module_name(p): p for p in PACKAGE.rglob("*.py")}
    graph = {}
    for name, path in paths.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        targets = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.level:
                base = package.split(".")[:len(package.split(".")) - node.level + 1]
                module = ".".join(base + ([node.module] if node.module else []))
                targets.update(f"{module}.{a.name}" if f"{module}.{a.name}" in paths else module
                               for a in node.names)
            elif isinstance(node, ast.Import):
                targets.update(a.name for a in node.names)
        # the package's __init__ re-exports everything: importing it is not a dependency
        graph[name] = {t for t in targets if t in paths and t not in (name, "bulletnet")}
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str]:
    """One import cycle of ``graph`` as [a, b, ..., a], or [] if it has none."""
    state: dict[str, int] = {}  # 1 on the current path, 2 done
    path: list[str] = []

    def visit(node: str) -> list[str]:
        state[node] = 1
        path.append(node)
        for nxt in sorted(graph[node]):
            if state.get(nxt) == 1:
                return path[path.index(nxt):] + [nxt]
            if nxt not in state and (cycle := visit(nxt)):
                return cycle
        state[node] = 2
        path.pop()
        return []

    for node in sorted(graph):
        if node not in state and (cycle := visit(node)):
            return cycle
    return []


def test_cycle_finder_finds_a_planted_cycle():
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": set(), "c": {"a", "b"}}) == []


def test_no_import_cycles():
    graph = import_graph()
    assert "bulletnet.analysis.stability" in graph["bulletnet.sim.loop"]  # real imports seen
    assert "bulletnet.sim.loop" in graph["bulletnet.studies.bench"]      # lazy ones included
    assert find_cycle(graph) == []


RANKS = {
    "common": 0,     # errors, package data, numba's cache folder, stop requests
    "kernels": 1,    # compiled leaves: thread, bending, cable forces, contact laws, geometry
    "model": 2,      # scene file -> topology, net model, state, debris, meshes, materials
    "solver": 3,     # one step and the compiled loop, the contact stage
    "recording": 3,  # the HDF5 writer and reader
    "engines": 4,    # fast, bullet, reference; PyBullet
    "analysis": 5,   # capture score, metrics, stability limits, plots
    "sim": 6,        # the run loop and what watches it
    "studies": 7,    # sweeps, studies, benchmarks, reports
    "viewer": 7,     # the browser replay
    "cli": 8,        # the command line
}
"""Each package of bulletnet and its layer: a module may import only from its own package
and from packages of a lower rank (so packages of equal rank never import each other)."""

HEAVY = {  # third-party module -> the packages that may import it
    "pybullet": {"engines"}, "pybullet_utils": {"engines"},
    "dask": {"studies"}, "distributed": {"studies"}, "SALib": {"studies"},
    "optuna": {"studies"},
    "matplotlib": {"analysis", "studies"},
    "viser": {"viewer"},
    "h5py": {"recording"},
    "numba": {"common", "kernels", "solver", "engines", "analysis", "sim"},
    "trimesh": {"model", "viewer"},
}


def _package(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 2 or (len(parts) == 2 and parts[1] in RANKS) else ""


def test_every_package_has_a_rank_and_imports_only_below_it():
    graph = import_graph()
    packages = {_package(m) for m in graph} - {""}
    assert packages == set(RANKS), "a package without a rank, or a rank without a package"
    assert {m for m in graph if not _package(m)} == {"bulletnet"}  # no loose modules
    wrong = sorted(f"{m} -> {t}" for m, targets in graph.items() if _package(m)
                   for t in targets
                   if _package(t) != _package(m) and RANKS[_package(t)] >= RANKS[_package(m)])
    assert wrong == []


def test_the_rank_check_finds_an_upward_import(tmp_path):
    # the check itself, on a planted upward import: a kernel importing the run loop
    graph = {"bulletnet.kernels.axial": {"bulletnet.sim.loop"}, "bulletnet.sim.loop": set()}
    wrong = [(m, t) for m, ts in graph.items() for t in ts
             if RANKS[_package(t)] >= RANKS[_package(m)]]
    assert wrong == [("bulletnet.kernels.axial", "bulletnet.sim.loop")]


def third_party_imports(path: Path) -> set[str]:
    """The top-level names of the modules ``path`` imports (statements anywhere, and
    ``importlib.import_module("name")`` calls with a literal name)."""
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names.update(a.name.split(".")[0] for a in node.names)
        elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
            names.add(node.module.split(".")[0])
        elif (isinstance(node, ast.Call) and getattr(node.func, "attr", getattr(
                node.func, "id", None)) == "import_module" and node.args
              and isinstance(node.args[0], ast.Constant) and isinstance(node.args[0].value, str)
              and not node.args[0].value.startswith(".")):
            names.add(node.args[0].value.split(".")[0])
    return names


def test_heavy_libraries_only_where_they_belong():
    found = {}
    for path in PACKAGE.rglob("*.py"):
        package = _package(_module_name(path))
        for name in third_party_imports(path) & set(HEAVY):
            found.setdefault(name, set()).add(package)
            assert package in HEAVY[name], f"{path.relative_to(PACKAGE)} imports {name}"
    assert {"pybullet", "numba", "h5py", "viser", "dask", "optuna"} <= set(found)  # all seen


def test_importing_the_package_loads_no_heavy_library():
    # the Python API and the command line start without numba, PyBullet, h5py, ...: each is
    # imported when a run, a recording or a plot first needs it
    code = ("import sys, bulletnet, bulletnet.cli.main; "
            f"print(sorted(m for m in {sorted(HEAVY | {'scipy': 0})!r} if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert out.strip() == "[]"
