"""Screenshots of the browser replay for the README, taken with headless Chromium (as the
browser tests): docs/figures/viewer_deployment.png from the two 3 s deployment recordings,

    bulletnet run deployment --out plain.h5
    bulletnet run deployment --bending --out bending.h5
    python docs/viewer_figures.py deployment plain.h5 bending.h5

and docs/figures/viewer_capture.png from the two 120 s capture recordings,

    bulletnet run capture --out capture_plain.h5
    bulletnet run capture --bending --out capture_bending.h5
    python docs/viewer_figures.py capture capture_plain.h5 capture_bending.h5

and docs/figures/viewer_closing.png from the two 120 s closing captures at 60 s, the debris
held in the cinched nets (the cables drawn with the threads),

    bulletnet run capture_closing --out closing_plain.h5
    bulletnet run capture_closing --bending --out closing_bending.h5
    python docs/viewer_figures.py closing closing_plain.h5 closing_bending.h5

and docs/figures/viewer_removal.png from the removal run at the largest tension of the
tether at the chaser during the tow (:func:`bulletnet.analysis.metrics.tow_series`; the script
prints its time), with the tow panel,

    bulletnet run removal --out removal.h5
    python docs/viewer_figures.py removal removal.h5

and docs/figures/viewer_breaking.png from the deployment with breakage at 2.1 s, its failed
threads drawn as red stubs,

    bulletnet run deployment_breaking --out breaking.h5
    python docs/viewer_figures.py breaking breaking.h5

The capture picture is taken at the frame of 20-30 s where the net wraps the debris best: the
largest, over those frames, of the smaller of the two recordings' wrap fractions
(:func:`bulletnet.analysis.metrics.wrap`); the script prints the time and both fractions. Its camera
looks at the debris from the viewer's default direction, 1.8 times closer than the default
camera (which frames the whole capture up to the last contact).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import bulletnet as bn  # noqa: E402
from bulletnet.viewer import load_replay, viser_server  # noqa: E402
from bulletnet.viewer.server import LiveViewer  # noqa: E402
from tests.test_viewer_browser import ARGS, CHROMIUM  # noqa: E402

OUT = ROOT / "docs" / "figures"
WRAP_WINDOW = (20.0, 30.0)
"""Times among which the capture picture is taken [s]."""


def debris(replay, k: int) -> np.ndarray:
    """The first recording's debris at master frame ``k`` [m]."""
    return replay.tracks[0].debris.position[replay.index[0, k]]


def tow(replay, k: int) -> np.ndarray:
    """Halfway from the first recording's debris to its chaser at master frame ``k`` [m]."""
    return 0.5 * (debris(replay, k) + replay.tracks[0].position[replay.index[0, k], -1])


def screenshot(paths: list, at: float, out: Path, snapshots: list[float],
               zoom: float = 1.0, focus=debris) -> None:
    """The live viewer of ``paths`` paused at time ``at`` [s], 1400 x 1100 px, to ``out``;
    with ``zoom`` > 1 the camera looks at ``focus(replay, k)`` [m] (k the master frame), from
    the default camera's direction, ``zoom`` times closer than the default camera's
    distance."""
    from playwright.sync_api import sync_playwright

    replay = load_replay(paths)
    with viser_server() as server, sync_playwright() as p:
        viewer = LiveViewer(server, replay, snapshots)
        k = replay.frame_at(at)
        viewer.goto(k)
        if zoom != 1.0:
            camera = server.initial_camera
            target = focus(replay, k)
            camera.position = target + (camera.position - camera.look_at) / zoom
            camera.look_at = target
        browser = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        page = browser.new_page(viewport={"width": 1400, "height": 1100})
        page.goto(f"http://127.0.0.1:{server.get_port()}")
        page.wait_for_selector("#bulletnet-mouth", state="attached")
        page.add_style_tag(content=".mantine-Notifications-root { display: none; }")
        time.sleep(8.0)  # software rendering: let the frame settle
        page.screenshot(path=str(out))
        browser.close()
    print(out)


def best_wrap_time(paths: list) -> float:
    """The time in :data:`WRAP_WINDOW` at which the smallest wrap fraction of the recordings
    is largest [s] (recordings at one record rate)."""
    recs = [bn.open_recording(p) for p in paths]
    t = recs[0].time
    for rec in recs[1:]:
        if not np.array_equal(rec.time, t):
            raise SystemExit("the capture recordings must share their frame times")
    window = (t >= WRAP_WINDOW[0]) & (t <= WRAP_WINDOW[1])
    wraps = np.array([bn.metrics.wrap(rec) for rec in recs])
    k = int(np.flatnonzero(window)[np.argmax(wraps[:, window].min(axis=0))])
    print(f"t = {t[k]:g} s, wrap " + " / ".join(f"{w:.3f}" for w in wraps[:, k]))
    return float(t[k])


def peak_tension_time(path) -> float:
    """The time of the tow's largest tension at the chaser [s]."""
    series = bn.metrics.tow_series(bn.open_recording(path))
    k = int(np.argmax(series["tension"]))
    print(f"t = {series['time'][k]:g} s, tension at the chaser {series['tension'][k]:.0f} N")
    return float(series["time"][k])


def main(which: str, *paths: str) -> None:
    if which == "deployment":
        screenshot(list(paths), 1.5, OUT / "viewer_deployment.png", [0.5, 1.0, 2.0, 3.0])
    elif which == "capture":
        at = best_wrap_time(list(paths))
        screenshot(list(paths), at, OUT / "viewer_capture.png", [10.0, at], zoom=1.8)
    elif which == "closing":
        screenshot(list(paths), 60.0, OUT / "viewer_closing.png", [10.0, 30.0, 60.0], zoom=1.8)
    elif which == "removal":
        at = peak_tension_time(paths[0])
        screenshot(list(paths), at, OUT / "viewer_removal.png", [30.0, at], zoom=1.6,
                   focus=tow)
    elif which == "breaking":
        screenshot(list(paths), 2.1, OUT / "viewer_breaking.png", [1.0, 2.1])
    else:
        raise SystemExit(__doc__)


if __name__ == "__main__":
    main(*sys.argv[1:])
