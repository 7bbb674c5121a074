"""numba's cache follows the package's source (bulletnet.kernel_cache)."""

from __future__ import annotations

import os
import shutil

import pytest

from bulletnet import kernel_cache


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
    kernel = copy / "forces" / "contact.py"
    kernel.write_text(kernel.read_text() + "\n# edited\n")
    assert kernel_cache.source_digest(copy) != before
