"""The run loop hands every frame to its observers (bulletnet.sim.observers): a user's observer
sees each recorded frame once, is started before the first step and finished with the run's
status, can stop the run, and what it adds at the end lands in the recording."""

from __future__ import annotations

import numpy as np

import bulletnet as bn
from bulletnet.sim.loop import frame_times
from bulletnet.sim.observers import Observer


class Log(Observer):
    """Writes down what the loop shows it; stops at ``stop_at`` [s] if given."""

    def __init__(self, stop_at: float | None = None):
        self.events, self.stop_at = [], stop_at

    def frame(self, run):
        self.events.append(("frame", run.state.time))
        return self.stop_at is not None and run.state.time >= self.stop_at - 1e-12

    def start(self, run):
        self.events.append(("start", run.state.time, run.engine.steps))

    def finish(self, run, status, attrs):
        self.events.append(("finish", status))
        attrs["frames_seen"] = sum(e[0] == "frame" for e in self.events)


def _scene(duration):
    return bn.load_scenario("deployment", {"net.nodes_per_side": 5, "scene.duration": duration})


def test_an_observer_sees_every_frame_once_between_start_and_finish(tmp_path):
    # reference: the frame schedule (frame_times) and the recording written beside it
    log = Log()
    scene = _scene(0.05)
    result = bn.run(scene, tmp_path / "r.h5", observers=[log])
    times = frame_times(0.05, scene.simulation.record_rate)
    assert log.events[0] == ("frame", 0.0)
    assert log.events[1] == ("start", 0.0, 0)        # after the initial frame, before any step
    assert [e[1] for e in log.events if e[0] == "frame"] == list(times)
    assert log.events[-1] == ("finish", "completed")
    rec = bn.open_recording(tmp_path / "r.h5")
    np.testing.assert_array_equal(rec.time, times)
    assert rec.attrs["frames_seen"] == len(times) == result.frames
    # the run's own attributes are there beside it: the engine's counters (recordings.md)
    assert rec.attrs["stats_steps"] == result.stats["steps"] > 0


def test_an_observer_stops_the_run_at_its_frame(tmp_path):
    # reference: the stopping frame: the run ends there, completed, with every frame so far
    log = Log(stop_at=0.03)
    bn.run(_scene(0.1), tmp_path / "r.h5", observers=[log])
    rec = bn.open_recording(tmp_path / "r.h5")
    assert rec.status == "completed"
    assert np.isclose(rec.time[-1], 0.03) and rec.time.size == 4
    assert log.events[-1] == ("finish", "completed")
