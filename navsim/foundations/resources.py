"""Where navsim's shipped data lies: read through :mod:`importlib.resources`, so that a wheel, an
editable install and a checkout find the same files.

The aircraft (``navsim.data.aircraft``, edited in the repository's ``aircraft/``), the sensor
catalog (``navsim.data.sensors``, edited in ``sensors/``), the shipped scenarios
(``navsim.data.scenarios``, edited in ``scenarios/``), the tracks (``navsim/tracks``) and the
templates of ``navsim new`` (``navsim/cli/templates``) are package data (see pyproject.toml).
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

#: the package of each kind of shipped data, and the folder inside it
DATA = {"aircraft": ("navsim.data.aircraft", ""), "sensors": ("navsim.data.sensors", ""),
        "tracks": ("navsim", "tracks"), "scenarios": ("navsim.data.scenarios", ""),
        "templates": ("navsim.cli", "templates")}


def data_folder(kind: str) -> Path:
    """The folder of one kind of shipped data (a key of :data:`DATA`), as a real folder: JSBSim
    and the catalogs read files by path.

    Raises
    ------
    RuntimeError
        Where the package is not installed as files (a zip import), which navsim does not support.
    """
    package, sub = DATA[kind]
    folder = resources.files(package).joinpath(sub) if sub else resources.files(package)
    if not isinstance(folder, Path):
        raise RuntimeError(f"{package} is not installed as a folder of files ({folder!r}): "
                           "install navsim from its wheel or a checkout")
    return folder
