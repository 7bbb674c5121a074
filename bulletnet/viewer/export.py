"""Self-contained HTML replays: the scene recorded frame by frame through viser's scene
serializer into viser's own single-file client, plus the panels (the tow panel for a tow,
then the mouth panel; ``web/overlay.js``, ``web/overlay.css``), and an ``index.html`` beside
them listing every replay in the folder.
"""

from __future__ import annotations

import json
import re
import time
from html import escape, unescape
from pathlib import Path

from ..common.errors import ScenarioError
from ..common.resources import data_dir
from .panel import Panel, TimePanel, TowPanel
from .replay import Replay
from .scene import build_scene, viser_server

WEB = data_dir("web")
"""What the HTML export adds to viser's client: the panel's script and style, the index."""
META = "bulletnet-replay"
"""Name of the ``<meta>`` tag that marks a file as a replay (its content: JSON summary)."""


def scene_html(replay: Replay) -> str:
    """viser's client with the replay's scene embedded; playback time = simulated time."""
    with viser_server() as server:
        layers = build_scene(server, replay)
        serializer = server.get_scene_serializer()
        for k in range(1, replay.time.size):
            serializer.insert_sleep(float(replay.time[k] - replay.time[k - 1]))
            for layer, j in zip(layers, replay.index[:, k], strict=True):
                layer.show(int(j))
        # The last frame is held one interval: viser's playback restarts once it reaches the
        # recording's end, so without this the last frame could not be stepped to.
        if replay.time.size > 1:
            serializer.insert_sleep(float(replay.time[-1] - replay.time[-2]))
        return serializer.as_html()


def panel_data(replay: Replay, panels: dict[str, TimePanel]) -> dict:
    """What ``overlay.js`` needs: times from the start [s], and each panel by title: its SVG
    and its changes by frame."""
    out = []
    for title, panel in panels.items():
        first = panel.updates(0)
        fields = [(ident, attr) for ident, attrs in first.items() for attr in attrs]
        values = []
        for k in range(replay.time.size):
            update = panel.updates(k)
            values.append([update[i][a] for i, a in fields])
        out.append({"title": title, "svg": panel.svg(0), "fields": fields, "values": values})
    return {"time": (replay.time - replay.time[0]).round(9).tolist(), "panels": out}


def export_html(replay: Replay, out: str | Path, snapshots: list[float],
                force: bool = False) -> Path:
    """Write the replay to ``out`` and refresh ``index.html`` beside it; return ``out``."""
    out = Path(out)
    if out.name == "index.html":
        raise ScenarioError(f"{out}: index.html is the folder's list of replays; "
                             "choose another name")
    if out.is_dir():
        raise ScenarioError(f"{out}: is a folder; --html names the replay's file")
    if out.exists() and not force:
        raise ScenarioError(f"{out}: exists; pass --force to overwrite it")
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ScenarioError(f"{out.parent}: cannot create the folder: {exc.strerror}") from None
    summary = {"recordings": [t.label for t in replay.tracks],
               "duration_s": round(float(replay.time[-1] - replay.time[0]), 6),
               "frames": int(replay.time.size), "written": time.strftime("%Y-%m-%d %H:%M")}
    title = " + ".join(t.label for t in replay.tracks)
    head = (f'<meta name="{META}" content="{escape(json.dumps(summary))}">'
            f"<title>bulletnet: {escape(title)}</title>"
            f"<style>{(WEB / 'overlay.css').read_text()}</style>")
    panels = {"Tow": TowPanel(replay)} if replay.has_tow else {}
    panels["Mouth"] = Panel(replay, snapshots)
    data = json.dumps(panel_data(replay, panels), separators=(",", ":"))
    data = data.replace("</", "<\\/")  # no "</script>" inside the script
    body = (f"<script>window.__BULLETNET__={data};</script>"
            f"<script>{(WEB / 'overlay.js').read_text()}</script>")
    page = scene_html(replay).replace("<title>Viser</title>", "", 1)
    page = page.replace("</head>", head + "</head>", 1).replace("</body>", body + "</body>", 1)
    out.write_text(page, encoding="utf-8")
    write_index(out.parent)
    return out


def write_index(folder: Path) -> Path:
    """``folder/index.html``: a table of the replays in ``folder``, newest first."""
    pattern = re.compile(rf'<meta name="{META}" content="([^"]*)">')
    rows = []
    for path in sorted(folder.glob("*.html"), key=lambda p: p.stat().st_mtime, reverse=True):
        if path.name == "index.html":
            continue
        match = pattern.search(path.read_text(encoding="utf-8", errors="replace"))
        if match is None:
            continue
        info = json.loads(unescape(match.group(1)))
        rows.append(f'<tr><td><a href="{escape(path.name)}">{escape(path.stem)}</a></td>'
                    f"<td>{escape(', '.join(info['recordings']))}</td>"
                    f"<td>{info['duration_s']:g}</td><td>{info['frames']}</td>"
                    f"<td>{escape(info['written'])}</td></tr>")
    index = folder / "index.html"
    index.write_text((WEB / "index.html").read_text().replace("<!-- REPLAYS -->",
                                                               "\n".join(rows)))
    return index
