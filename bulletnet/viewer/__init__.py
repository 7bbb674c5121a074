"""Browser replay of recordings: a live viser server (:func:`serve`) and self-contained HTML
replays (:func:`export_html`). viser is imported only when a viewer starts."""

from .export import export_html
from .replay import Replay, load_replay
from .scene import viser_server
from .server import serve

__all__ = ["Replay", "export_html", "load_replay", "serve", "viser_server"]
