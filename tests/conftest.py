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


def small_capture(**overrides):
    """The capture scene shrunk to a 6 x 6 net, 1 m mesh, with the debris 3 m above it coming
    down at 2 m/s: the net touches it between 0.4 and 0.6 s; 1 s at 20 Hz (0.2 s of wall
    time once the kernels are compiled); with dotted-key overrides."""
    return bn.load_scenario("capture", {
        "net.nodes_per_side": 6, "net.mesh_length": 1.0, "debris.position": [0.0, 0.0, 3.0],
        "debris.velocity": [0.0, 0.0, -2.0], "scene.duration": 1.0,
        "simulation.record_rate": 20.0, **overrides})


@pytest.fixture(scope="session")
def viewer_runs(tmp_path_factory):
    """Recordings for the replay tests: a plain deployment at 100 Hz, a bending deployment at
    50 Hz, and a real capture (:func:`small_capture`) whose net touches the debris."""
    d = tmp_path_factory.mktemp("viewer")
    plain, bending, capture = d / "plain.h5", d / "bending.h5", d / "capture.h5"
    bn.run(small_scene(**{"scene.duration": 0.3}), plain)
    bn.run(small_scene(**{"scene.duration": 0.3, "bending.enabled": True,
                          "simulation.record_rate": 50.0}), bending)
    bn.run(small_capture(), capture)
    assert bn.open_recording(capture).contacts["count"].max() > 0, "no contact in the capture"
    return {"plain": plain, "bending": bending, "capture": capture, "dir": d}
