"""Browser replay of recordings: a live viser server (:func:`serve`) and self-contained HTML
replays (:func:`export_html`). viser is imported only when a viewer starts."""

import contextlib
import io

from ..errors import BulletnetError
from .replay import Replay, load_replay

__all__ = ["Replay", "export_html", "load_replay", "serve"]


@contextlib.contextmanager
def viser_server(port: int = 0):
    """A viser server on localhost ``port`` (the next free one if taken, any if 0), stopped on
    exit; viser is imported here, on first use, and its banners are kept off stdout."""
    try:
        import viser
    except ImportError:
        raise BulletnetError(
            "the browser replay needs viser: pip install 'bulletnet[view]'") from None
    with contextlib.redirect_stdout(io.StringIO()):
        server = viser.ViserServer(host="127.0.0.1", port=port, verbose=False)
    try:
        yield server
    finally:
        with contextlib.redirect_stdout(io.StringIO()):
            server.stop()


def export_html(*args, **kwargs):
    """See :func:`bulletnet.viewer.export.export_html`."""
    from .export import export_html as _export

    return _export(*args, **kwargs)


def serve(*args, **kwargs):
    """See :func:`bulletnet.viewer.server.serve`."""
    from .server import serve as _serve

    return _serve(*args, **kwargs)
