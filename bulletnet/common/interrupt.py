"""Stop requests (Ctrl-C, SIGTERM) that cannot be lost.

Python delivers a signal by running its handler in the main thread between two bytecodes,
wherever that thread is. A KeyboardInterrupt raised there inside a weakref callback or a
``__del__`` method is printed ("Exception ignored in ...") and dropped, and a run would go on
to its end as if nothing had been asked. The CLI's handler (:func:`install`) therefore also
records the request, and the loops that last (the run loop at every frame, the replay server
at every tick) call :func:`check`, which raises it again if it was lost; the dropped one is
not printed (it is acted upon).
"""

from __future__ import annotations

import signal
import sys

_pending: list[int] = []
"""Signals received and not yet acted upon."""


def _handler(signum, frame):
    _pending.append(signum)
    raise KeyboardInterrupt


def _quiet_if_recorded(previous):
    """An unraisable-exception hook that drops a recorded stop request's KeyboardInterrupt
    (:func:`check` raises it again) and passes anything else to ``previous``."""
    def hook(info):
        if not (_pending and isinstance(info.exc_value, KeyboardInterrupt)):
            previous(info)
    hook.quiets_stop_requests = True
    return hook


def install() -> None:
    """Make SIGINT and SIGTERM raise KeyboardInterrupt and record the request (the CLI's
    handlers; call from the main thread). Installing again (``main`` called twice in one
    process) does not wrap the hook again."""
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, _handler)
    if not getattr(sys.unraisablehook, "quiets_stop_requests", False):
        sys.unraisablehook = _quiet_if_recorded(sys.unraisablehook)


def check() -> None:
    """Raise KeyboardInterrupt if a stop was requested and not yet acted upon."""
    if _pending:
        raise KeyboardInterrupt


def acted() -> None:
    """The request has been acted upon (the run was recorded as interrupted): forget it."""
    _pending.clear()
