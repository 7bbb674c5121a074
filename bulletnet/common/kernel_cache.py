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
