"""Shared helpers: small scenes that run in a second or two."""

from __future__ import annotations

import pytest

import bulletnet as bn


def small_scene(**overrides):
    """The deployment scene shrunk to a 6 x 6 net (Fig. 1's), with dotted-key overrides."""
    base = {"net.nodes_per_side": 6, "scene.duration": 0.4}
    base.update(overrides)
    return bn.load_scenario("deployment", base)


@pytest.fixture
def scene():
    return small_scene()


@pytest.fixture(scope="session")
def viewer_runs(tmp_path_factory):
    """Recordings for the replay tests: a plain run at 100 Hz, a bending run at 50 Hz, and a
    capture-like copy of the plain one (tests/test_viewer.py: add_capture_groups)."""
    from tests.test_viewer import add_capture_groups

    d = tmp_path_factory.mktemp("viewer")
    plain, bending = d / "plain.h5", d / "bending.h5"
    bn.run(small_scene(**{"scene.duration": 0.3}), plain)
    bn.run(small_scene(**{"scene.duration": 0.3, "bending.enabled": True,
                          "simulation.record_rate": 50.0}), bending)
    capture = d / "capture.h5"
    capture.write_bytes(plain.read_bytes())
    add_capture_groups(capture)
    return {"plain": plain, "bending": bending, "capture": capture, "dir": d}
