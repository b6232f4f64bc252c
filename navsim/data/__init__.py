"""navsim's shipped data, installed as packages: ``navsim.data.aircraft`` (the JSBSim aircraft,
edited in the repository's top-level ``aircraft/``), ``navsim.data.sensors`` (the sensor catalog,
edited in ``sensors/``) and ``navsim.data.scenarios`` (the shipped scenarios, edited in
``scenarios/``); pyproject.toml maps the three folders here. Read them with
:func:`navsim.foundations.resources.data_folder`.

In a checkout imported without installing (``PYTHONPATH``), the three folders are found beside
the ``navsim`` package."""

from pathlib import Path

_CHECKOUT = Path(__file__).resolve().parents[2]
if (_CHECKOUT / "pyproject.toml").is_file() and (_CHECKOUT / "aircraft" / "__init__.py").is_file():
    __path__.append(str(_CHECKOUT))       # noqa: F821 (a package's __path__)
