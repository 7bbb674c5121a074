"""Where numba caches the compiled kernels: one folder per version of the package's source.

numba keys a cached function on its own file only, so a kernel that calls (and inlines) a
kernel from another module keeps running the old code after that module changes (a ``git
pull`` into an editable install, say) -- silently. Caching under a digest of every source
file of the package makes any change compile afresh. The folder is
``$XDG_CACHE_HOME/bulletnet/numba/DIGEST`` (``~/.cache`` by default); a ``NUMBA_CACHE_DIR``
set by the user wins. Importing this module configures it (``bulletnet`` imports it before
any kernel).
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import os
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent.parent
"""The installed package's folder."""


def source_digest(root: Path = PACKAGE) -> str:
    """SHA-256 (first 16 hex digits) of the Python sources below ``root``, paths and
    contents."""
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        digest.update(path.relative_to(root).as_posix().encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


@functools.cache
def package_digest() -> str:
    """:func:`source_digest` of the installed package, computed once a process."""
    return source_digest()


def configure() -> None:
    """Point numba's cache at this source's folder, unless the user chose one."""
    if "NUMBA_CACHE_DIR" in os.environ:
        return
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    os.environ["NUMBA_CACHE_DIR"] = str(base / "bulletnet" / "numba" / package_digest())
    if "numba" in sys.modules:  # imported before us: make it read the variable again
        from numba.core import config

        config.reload_config()


def import_numba_arrays() -> None:
    """Import numba's array functions (``numba.np.arraymath``) with scipy.linalg's BLAS
    extension module alone, not that package's ``__init__``.

    numba's first compile or cache load in a process imports ``numba.np.arraymath``, which
    checks for a BLAS by importing ``scipy.linalg.cython_blas``; that runs scipy.linalg's
    ``__init__``, which imports most of scipy's and numpy's submodules (0.16 s of a
    process's 1.1 s here, docs/speed.md) for no kernel of this package. With a stand-in for
    the package, pointing at its folder, in ``sys.modules`` while the check runs, the import
    loads the extension module alone; the stand-in is removed after, so a later ``import
    scipy.linalg`` runs the real ``__init__`` (and finds the extension loaded). Does nothing
    once numba's array functions or scipy.linalg are imported, or without scipy."""
    if "numba.np.arraymath" in sys.modules or "scipy.linalg" in sys.modules:
        return
    import importlib.util
    import types

    try:
        spec = importlib.util.find_spec("scipy.linalg")
    except ImportError:
        spec = None
    if spec is None or not spec.submodule_search_locations:
        import numba.np.arraymath  # noqa: F401
        return
    stand_in = types.ModuleType("scipy.linalg")
    stand_in.__path__ = list(spec.submodule_search_locations)
    sys.modules["scipy.linalg"] = stand_in
    try:
        import numba.np.arraymath  # noqa: F401
    finally:
        del sys.modules["scipy.linalg"]


@contextlib.contextmanager
def watch_compilation(on_start: Callable[[], None] | None = None,
                      on_end: Callable[[float], None] | None = None) -> Iterator[None]:
    """Inside the block, call ``on_start()`` when numba starts compiling a kernel its cache
    lacks and ``on_end(seconds)`` when that compilation (with the kernels it compiles in
    turn) ends, with its wall time [s] (None: no call). Kernels loaded from the cache call
    neither."""
    from numba.core import event

    class _Listener(event.Listener):
        depth = 0
        start = 0.0

        def on_start(self, ev):
            self.depth += 1
            if self.depth == 1:
                self.start = time.perf_counter()
                if on_start is not None:
                    on_start()

        def on_end(self, ev):
            self.depth -= 1
            if self.depth == 0 and on_end is not None:
                on_end(time.perf_counter() - self.start)

    with event.install_listener("numba:compile", _Listener()):
        yield


configure()
