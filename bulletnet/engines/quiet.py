"""Silencing C libraries that print (PyBullet's build time and argv, its V-HACD progress).

PyBullet prints ``pybullet build time: ...`` on stderr when imported and ``argv[0]=`` on
stdout at every connection: :func:`pybullet` and :func:`bullet_client` are the one way
bulletnet imports and connects it, with both silenced."""

from __future__ import annotations

import contextlib
import os
import sys


@contextlib.contextmanager
def quiet_stdout():
    """Silence file descriptors 1 and 2 (C-level prints) for the duration of the block."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = [os.dup(1), os.dup(2)]
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 1)
    os.dup2(devnull, 2)
    try:
        yield
    finally:
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        for fd in (*saved, devnull):
            os.close(fd)


def pybullet():
    """The ``pybullet`` module, imported without its build-time banner."""
    import importlib

    if "pybullet" not in sys.modules:
        with quiet_stdout():
            importlib.import_module("pybullet")
    return sys.modules["pybullet"]


def bullet_client():
    """A new PyBullet world of its own (a ``BulletClient`` in DIRECT mode), connected without
    PyBullet's ``argv[0]=`` line."""
    pb = pybullet()
    from pybullet_utils.bullet_client import BulletClient

    with quiet_stdout():
        return BulletClient(connection_mode=pb.DIRECT)
