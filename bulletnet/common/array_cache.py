"""Arrays too slow to recompute at every start, kept on disk beside the compiled kernels.

A debris' mass properties come from trimesh's solids: trimesh's import and the convex hulls
took 0.1-0.2 s of a capture's 1.1 s start (:func:`bulletnet.model.debris.make_debris`; numba
imports scipy regardless). They are stored under ``$NUMBA_CACHE_DIR/arrays/`` (:mod:`.kernel_cache`)
named by a digest of what they are computed from, of the package's source and of the
versions of the libraries that compute them, and read back bit for bit. A folder that cannot
be written leaves them uncached (computed at every start, as before).
"""

from __future__ import annotations

import functools
import hashlib
import os
import tempfile
from collections.abc import Callable
from importlib import metadata
from pathlib import Path

import numpy as np

from .kernel_cache import package_digest


@functools.cache
def _versions() -> str:
    """The package's source digest and the versions of the libraries the cached arrays come
    from (read from their metadata, without importing them)."""
    versions = []
    for name in ("numpy", "scipy", "trimesh"):
        try:
            versions.append(f"{name} {metadata.version(name)}")
        except metadata.PackageNotFoundError:
            versions.append(f"{name} -")
    return f"{package_digest()} {' '.join(versions)}"


def cached_arrays(what: str, compute: Callable[[], dict[str, np.ndarray]]
                  ) -> dict[str, np.ndarray]:
    """``compute()``'s arrays (by name), from the cache if it holds those of ``what`` (the
    full description of their inputs, e.g. a repr of frozen dataclasses), else computed and
    stored."""
    folder = os.environ.get("NUMBA_CACHE_DIR")  # (set when bulletnet is imported)
    if not folder:
        return compute()
    digest = hashlib.sha256(f"{_versions()}\n{what}".encode()).hexdigest()[:32]
    path = Path(folder) / "arrays" / f"{digest}.npz"
    try:
        with np.load(path) as stored:
            return {name: stored[name] for name in stored.files}
    except (OSError, ValueError):
        pass
    arrays = compute()
    temporary = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=path.parent, suffix=".npz", delete=False) as f:
            temporary = f.name
            np.savez(f, **arrays)
        os.replace(temporary, path)  # whole or not at all, for processes starting together
    except OSError:
        if temporary is not None:
            Path(temporary).unlink(missing_ok=True)
    return arrays
