"""What a run does at its start and between its chunks, kept out of its way without changing
its results: the debris' solids kept on disk (bulletnet.common.array_cache) and the fast
engine's loop called without numba's dispatch (bulletnet.common.direct_call)."""

from __future__ import annotations

import numba as nb
import numpy as np

from bulletnet.common import array_cache
from bulletnet.common.direct_call import DirectCall
from bulletnet.model import debris as debris_module


def test_debris_solid_from_the_disk_is_the_computed_one_bit_for_bit(tmp_path, monkeypatch):
    # Reference: trimesh's mass properties computed afresh; the copy read back from the cache
    # must be the same floats, and a second start must not compute them again.
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    parts = debris_module.load_debris("apollo_csm").parts
    computed = debris_module._solid_properties(parts)
    first = debris_module.make_debris("csm", parts)  # computes and stores
    calls = []
    monkeypatch.setattr(debris_module, "_solid_properties",
                        lambda p: calls.append(p) or computed)
    second = debris_module.make_debris("csm", parts)  # reads
    assert not calls
    assert list((tmp_path / "arrays").glob("*.npz"))
    for d in (first, second):
        assert d.mass == float(computed["mass"])
        for name in ("center_of_mass", "inertia", "extents"):
            assert np.array_equal(getattr(d, name), computed[name])
    vertices, faces = debris_module.visual_mesh(second)
    fresh = debris_module._surface(parts, 48)
    assert np.array_equal(vertices, fresh["vertices"]) and np.array_equal(faces, fresh["faces"])


def test_array_cache_recomputes_what_it_cannot_read_or_write(tmp_path, monkeypatch):
    # Reference: the definition: a damaged file is computed again (and replaced); a folder
    # that cannot be written leaves the result uncached but still returned.
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    value = {"a": np.arange(3.0)}
    array_cache.cached_arrays("x", lambda: value)
    (stored,) = (tmp_path / "arrays").glob("*.npz")
    stored.write_bytes(b"not a zip file")
    assert np.array_equal(array_cache.cached_arrays("x", lambda: value)["a"], value["a"])
    assert np.array_equal(np.load(stored)["a"], value["a"])
    blocked = tmp_path / "file"
    blocked.write_text("")
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(blocked))  # (arrays/ cannot be made in a file)
    assert array_cache.cached_arrays("y", lambda: value) is value


@nb.njit(cache=False)
def _scaled_sum(scale, x, pair):
    return scale * (x.sum() + pair[0].sum() + pair[1].sum())


def test_direct_call_is_the_dispatchers_call_and_follows_the_arguments_kinds():
    # Reference: the dispatcher's own call with the same arguments; a change of kind (a float
    # array for an int one, another tuple) is resolved again, a new value of the same kind not.
    call = DirectCall(_scaled_sum)
    x, pair = np.arange(4.0), (np.ones(2), np.ones(3))
    entry = call.resolve((2.0, x, pair))
    assert entry(2.0, x, pair) == _scaled_sum(2.0, x, pair) == 2.0 * 11.0
    assert call.resolve((3.0, x * 2.0, pair)) is entry
    other = call.resolve((2.0, np.arange(4), pair))
    assert other is not entry and other(2.0, np.arange(4), pair) == 22.0
    again = (np.ones(2), np.ones(3))
    call.resolve((2.0, x, again))
    assert call._kinds[2].value is again
