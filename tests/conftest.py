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
