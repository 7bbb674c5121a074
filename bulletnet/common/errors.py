"""Typed errors. The CLI turns each into a one-line message and an exit code."""


class BulletnetError(Exception):
    """Base class of every error bulletnet reports to a user."""

    exit_code = 2


class ScenarioError(BulletnetError):
    """A scene file, a ``--set`` override or a CLI flag is invalid (exit code 2)."""


class RecordingError(BulletnetError):
    """A recording is missing, truncated, not a bulletnet file, or of an unknown layout."""


class DivergenceError(BulletnetError):
    """The integration blew up: NaN, infinity or runaway velocity (exit code 3)."""

    exit_code = 3

    def __init__(self, message: str, time: float, step: float | None = None,
                 limit: float | None = None):
        super().__init__(message)
        self.time = time
        """Simulated time [s] of the last good state."""
        self.step = step
        """The step the run took [s]."""
        self.limit = limit
        """The integrator's analytical stability limit on this net [s] (inf if none)."""
