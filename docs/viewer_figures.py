"""Screenshots of the browser replay for the README: docs/figures/viewer_deployment.png and
docs/figures/viewer_capture.png, taken with headless Chromium (as the browser tests).

    bulletnet run deployment --out plain.h5
    bulletnet run deployment --bending --out bending.h5
    bulletnet run capture --integrator implicit_euler --dt 5e-4 --duration 6 --out net.h5
    python docs/viewer_figures.py plain.h5 bending.h5 net.h5

The capture scene does not record its debris yet, so this script copies the capture net's run
and adds a synthetic debris in the capture recording layout: the Apollo CSM mesh fixed 7 m
above the launch point, spinning at 5 deg/s about z, with the nodes within 6 m of its centre
marked in contact (an illustration of the layout, not a capture).
"""

from __future__ import annotations

import shutil
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bulletnet.debris import load_debris, part_mesh  # noqa: E402
from bulletnet.viewer import load_replay, viser_server  # noqa: E402
from bulletnet.viewer.server import LiveViewer  # noqa: E402
from tests.test_viewer import add_capture_groups  # noqa: E402
from tests.test_viewer_browser import ARGS, CHROMIUM  # noqa: E402

OUT = ROOT / "docs" / "figures"


def screenshot(paths: list, at: float, out: Path, snapshots: list[float]) -> None:
    """The live viewer of ``paths`` paused at time ``at`` [s], 1400 x 1100 px, to ``out``."""
    from playwright.sync_api import sync_playwright

    replay = load_replay(paths)
    with viser_server() as server, sync_playwright() as p:
        viewer = LiveViewer(server, replay, snapshots)
        viewer.goto(replay.frame_at(at))
        browser = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        page = browser.new_page(viewport={"width": 1400, "height": 1100})
        page.goto(f"http://127.0.0.1:{server.get_port()}")
        page.wait_for_selector("#bulletnet-mouth")
        page.add_style_tag(content=".mantine-Notifications-root { display: none; }")
        time.sleep(8.0)  # software rendering: let the frame settle
        page.screenshot(path=str(out))
        browser.close()
    print(out)


def main(plain: str, bending: str, net: str) -> None:
    screenshot([plain, bending], 1.5, OUT / "viewer_deployment.png", [0.5, 1.0, 2.0, 3.0])
    capture = Path(net).with_name("capture_synthetic.h5")
    shutil.copy(net, capture)
    import trimesh

    csm = trimesh.util.concatenate([part_mesh(p) for p in load_debris("apollo_csm").parts])
    add_capture_groups(capture, mesh=csm, at=(0.0, 0.0, 7.0), reach=6.0,
                       spin=np.radians(5.0))
    screenshot([capture], 6.0, OUT / "viewer_capture.png", [2.0, 4.0, 6.0])


if __name__ == "__main__":
    main(*sys.argv[1:4])
