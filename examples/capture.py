"""Capture the spinning Apollo CSM (Botta et al. 2016, Sec. 5) and print the capture's
measures.

    python examples/capture.py            # the paper's 120 s capture with bending, ~2 min wall
    python examples/capture.py --quick    # a head-on variant: contact at 1.5 s, ~2 s wall
"""

import sys

import numpy as np

import bulletnet as bn

QUICK = "--quick" in sys.argv
overrides = {"bending.enabled": True}
if QUICK:
    # The debris 5 m above the net, coming at it at 2 m/s: the net touches it at about 1.5 s.
    overrides |= {"debris.position": [0.0, 0.0, 5.0], "debris.velocity": [0.0, 0.0, -2.0],
                  "scene.duration": 2.5, "simulation.record_rate": 20.0}

scene = bn.load_scenario("capture", overrides)
result = bn.run(scene, "capture.h5", force=True)
print(f"{result.status}: {result.frames} frames, {result.wall_time_s:.1f} s wall")

rec = bn.open_recording("capture.h5")
first = bn.metrics.first_contact_time(rec)          # [s], None if the net never touched
touching = bn.metrics.nodes_in_contact(rec)         # nodes touching in each frame, (T,)
wrap = bn.metrics.wrap(rec)                         # share of directions the net covers, (T,)
leave = bn.metrics.leave_time(rec)                  # [s], None if it did not let go
gain = bn.metrics.energy(rec) - bn.metrics.energy(rec)[0]   # [J]: a passive model never gains
spin = bn.metrics.spin(rec)                         # the debris' angular velocity [deg/s]
scores, judged = bn.metrics.capture_outcome(rec)    # capture score (T, 3) [-], the outcome

print(f"first contact: {'never' if first is None else f'{first:.3f} s'}")
print(f"nodes touching at once, at most: {touching.max():.0f}")
print(f"wrap, at most: {wrap.max():.2f} at {rec.time[np.argmax(wrap)]:.1f} s")
print(f"net left the debris: {'not within the run' if leave is None else f'{leave:.1f} s'}")
print(f"largest rise of the mechanical energy above its start: {gain.max():.3g} J")
print(f"debris spin: {np.linalg.norm(spin['initial_deg_s']):.3f} -> "
      f"{np.linalg.norm(spin['final_deg_s']):.3f} deg/s")
print(f"capture quality, at most: {scores[:, 2].max():.2f} (enclosed fraction "
      f"{scores[:, 0].max():.2f}, mouth opening down to {scores[:, 1].min():.2f})")
print(f"outcome: {judged.outcome}"
      + (f", decided at {judged.time:.1f} s" if judged.decided else "")
      + f" (the run judged itself: {result.outcome})")
