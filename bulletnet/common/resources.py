"""Where the shipped data are: the scenes, the debris assets and the viewer's web files.

In the repository (and so in an editable install) they are the top-level folders
``scenarios/``, ``assets/`` and ``web/``; a wheel (``pip install .``, ``pip install git+...``)
carries them inside the package as ``bulletnet/scenarios`` and so on (``pyproject.toml`` maps
them). :func:`data_dir` returns whichever this installation has.
"""

from __future__ import annotations

from pathlib import Path

PACKAGE = Path(__file__).resolve().parent.parent
"""The package's folder."""
FOLDERS = ("scenarios", "assets", "web")
"""The data folders a wheel carries inside the package."""


def data_dir(name: str) -> Path:
    """The folder of shipped data ``name`` (one of :data:`FOLDERS`): inside the installed
    package, or beside it in a source tree."""
    if name not in FOLDERS:
        raise ValueError(f"{name}: not a data folder of bulletnet ({', '.join(FOLDERS)})")
    installed = PACKAGE / name
    return installed if installed.is_dir() else PACKAGE.parent / name
