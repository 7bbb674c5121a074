"""Cost of the browser replay on two recordings overlaid: what the live server sends for the
scene and then per frame, the server's time per frame, and the HTML export's time and size
with and without decimation.

    python benchmarks/viewer.py PLAIN.h5 BENDING.h5 [--out benchmarks/results/viewer.json]
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from common import machine  # noqa: E402

from bulletnet.viewer import export_html, load_replay, viser_server  # noqa: E402
from bulletnet.viewer.server import LiveViewer  # noqa: E402


def payload_bytes(message) -> int:
    """Array and string bytes a message carries (what dominates the wire) [B]."""
    total = 0
    stack = [vars(message)]
    while stack:
        item = stack.pop()
        if isinstance(item, np.ndarray):
            total += item.nbytes
        elif isinstance(item, str):
            total += len(item)
        elif isinstance(item, dict):
            stack.extend(item.values())
        elif isinstance(item, (list, tuple)):
            stack.extend(item)
        elif hasattr(item, "__dict__") and not isinstance(item, type):
            stack.append(vars(item))
    return total


def live(paths: list[str]) -> dict:
    replay = load_replay(paths)
    with viser_server() as server:
        sent = []
        queue = server._websock_server.queue_message
        server._websock_server.queue_message = lambda m: (sent.append(payload_bytes(m)),
                                                         queue(m))
        viewer = LiveViewer(server, replay, replay.default_snapshots())
        scene = sum(sent)
        per_frame, wall = [], []
        for k in range(1, replay.time.size):
            sent.clear()
            t = time.perf_counter()
            viewer.goto(k)  # paused stepping: the mouth panel goes with every frame
            wall.append(time.perf_counter() - t)
            per_frame.append(sum(sent))
        panel = len(viewer.panel.svg(0))
        scene_only = [b - panel for b in per_frame]
    return {"frames": int(replay.time.size), "first_scene_and_gui_bytes": scene,
            "per_frame_bytes_median": statistics.median(per_frame),
            "per_frame_scene_bytes_median": statistics.median(scene_only),
            "mouth_panel_bytes": panel,
            "goto_wall_s_median": statistics.median(wall)}


def export(paths: list[str], every: int) -> dict:
    replay = load_replay(paths, every)
    with tempfile.TemporaryDirectory() as d:
        t = time.perf_counter()
        out = export_html(replay, Path(d) / "replay.html", replay.default_snapshots())
        wall = time.perf_counter() - t
        size = out.stat().st_size
    return {"every": every, "frames": int(replay.time.size), "wall_s": wall,
            "bytes": size}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs=2)
    parser.add_argument("--out", default="benchmarks/results/viewer.json")
    args = parser.parse_args()
    doc = {"machine": machine(),
           "recordings": [Path(p).name for p in args.runs], "live": live(args.runs),
           "export": [export(args.runs, every) for every in (1, 5)]}
    Path(args.out).write_text(json.dumps(doc, indent=2))
    print(json.dumps(doc, indent=2))


if __name__ == "__main__":
    main()
