"""numba's cache follows the package's source (bulletnet.common.kernel_cache)."""

from __future__ import annotations

import io
import os
import shutil
import subprocess
import sys
import time

import pytest

from bulletnet.common import kernel_cache


def test_numba_caches_in_the_folder_of_this_source():
    # Reference: the definition: importing bulletnet points numba at .../DIGEST of its source.
    folder = os.environ.get("NUMBA_CACHE_DIR", "")
    if not folder.endswith(kernel_cache.source_digest()):
        pytest.skip("NUMBA_CACHE_DIR was set before bulletnet was imported (the user's wins)")
    from numba.core import config

    assert config.CACHE_DIR == folder


def test_cache_folder_is_keyed_on_every_source_file(tmp_path):
    # Reference: the definition: editing any module (here a kernel that another module's
    # kernels inline) gives another digest, hence another cache folder.
    copy = tmp_path / "bulletnet"
    shutil.copytree(kernel_cache.PACKAGE, copy, ignore=shutil.ignore_patterns("__pycache__"))
    before = kernel_cache.source_digest(copy)
    assert before == kernel_cache.source_digest()
    kernel = copy / "kernels" / "contact.py"
    kernel.write_text(kernel.read_text() + "\n# edited\n")
    assert kernel_cache.source_digest(copy) != before


def test_compilation_is_watched_and_cache_hits_are_not():
    # Reference: numba's own event: compiling a new kernel (one that calls another, itself
    # compiled in turn) is one outer compilation; calling it again compiles nothing.
    import numba

    @numba.njit
    def inner(x):
        return 2.0 * x

    @numba.njit
    def outer(x):
        return inner(x) + 1.0

    events = []
    with kernel_cache.watch_compilation(lambda: events.append("start"), events.append):
        assert outer(1.0) == 3.0
        assert outer(2.0) == 5.0
    assert events[0] == "start" and len(events) == 2 and events[1] > 0


class _Stream(io.StringIO):
    def isatty(self):
        return False


def test_progress_says_compiling_instead_of_an_eta():
    # Reference: the definition: while kernels compile the display names the compilation and
    # the kernel group; once stepping resumes it says how long it took; the rate and ETA
    # count only frames stepped after it.
    from bulletnet.cli.main import ProgressBar

    stream = _Stream()
    bar = ProgressBar("fast engine, symplectic euler", stream)
    bar.interval = 0.0
    bar.compile_started()
    bar.compile_started()  # a second kernel of the same compilation: said once
    bar.compile_ended(20.0)
    bar(0.1, 1.0, 20.0)  # the frame that included the compilation: no rate yet
    time.sleep(0.05)
    bar(0.2, 1.0, 20.05)
    lines = stream.getvalue().splitlines()
    assert lines[0] == ("bulletnet: compiling the kernels (fast engine, symplectic euler), "
                        "once after an install ...")
    assert lines[1] == "bulletnet: compiled in 20.0 s; later runs start at once"
    assert len(lines) == 4 and "ETA      - s" in lines[2]
    eta = float(lines[3].split("ETA")[1].split()[0])
    assert eta < 8  # 0.8 s to go at 0.1 s per ~0.05 s; counted from the start, 80 s


def test_progress_without_compilation_counts_from_the_start():
    from bulletnet.cli.main import ProgressBar

    stream = _Stream()
    bar = ProgressBar("fast engine, symplectic euler", stream)
    bar(0.5, 1.0, 2.0)
    assert "compiling" not in stream.getvalue()
    assert "real-time x    0.25  ETA    2.0 s" in stream.getvalue()


def test_bulletnet_run_reports_a_compilation(tmp_path, monkeypatch, capsys):
    # Reference: numba's compile event. A kernel compiled during `bulletnet run` (a fresh one,
    # so that the test does not have to empty the real cache) shows the notice on stderr.
    import numba

    import bulletnet.sim.loop
    from bulletnet.cli.main import main

    real_run = bulletnet.sim.loop.run

    def run_compiling(*args, **kwargs):
        numba.njit(lambda x: x + 1.0)(1.0)
        return real_run(*args, **kwargs)

    monkeypatch.setattr(bulletnet.sim.loop, "run", run_compiling)
    out = tmp_path / "run.h5"
    assert main(["run", "deployment", "--set", "net.nodes_per_side=4", "--duration", "0.01",
                 "--out", str(out)]) == 0
    captured = capsys.readouterr()
    notice = "compiling the kernels (fast engine, symplectic euler), once after an install"
    assert captured.err.count(notice) == 1 and "bulletnet: compiled in" in captured.err
    assert "s compiling kernels)" in captured.out


_CLOSURE_KEYS = """
import hashlib
from numba.core.serialize import dumps
from bulletnet.solver import grid, integrators
loops = [integrators.advance(g, i) for g in (False, True) for i in (False, True)]
loops += [grid.free_steps(i) for i in (False, True)]
for loop in loops:
    cells = tuple(c.cell_contents for c in loop.py_func.__closure__ or ())
    print(loop.py_func.__qualname__, hashlib.sha256(dumps(cells)).hexdigest())
"""


def test_compiled_loops_have_the_same_cache_key_in_every_process():
    # Reference: numba's cache index (numba.core.caching.Cache._index_key) hashes a closure's
    # captured values as pickled; a captured dispatcher pickles differently in every process,
    # so a loop capturing one would compile anew in every run. Two processes, the same keys.
    keys = [subprocess.run([sys.executable, "-c", _CLOSURE_KEYS], capture_output=True,
                           text=True, check=True).stdout for _ in range(2)]
    assert keys[0].count("\n") == 6 and keys[0] == keys[1]


def test_numba_finds_its_blas_without_scipy_linalg_init():
    # Reference: numba's own check and numpy: after import_numba_arrays, in a fresh
    # interpreter, scipy.linalg's __init__ has not run, a kernel calling np.dot (which numba
    # compiles only with a BLAS) equals numpy's product, and scipy.linalg then imports whole.
    code = """if True:
        import sys
        import numpy as np
        from bulletnet.common.kernel_cache import import_numba_arrays
        import_numba_arrays()
        assert "scipy.linalg" not in sys.modules and "scipy.linalg.cython_blas" in sys.modules
        import numba
        x = np.arange(9.0).reshape(3, 3)
        assert np.array_equal(numba.njit(lambda a, b: np.dot(a, b))(x, x), x @ x)
        import scipy.linalg
        a = x + 10.0 * np.eye(3)
        assert np.allclose(a @ scipy.linalg.solve(a, np.ones(3)), 1.0, rtol=0, atol=1e-12)
        print("ok")
    """
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.stdout.strip() == "ok", out.stderr[-2000:]
