"""``navsim list``: the shipped aircraft, sensor catalog entries, tracks and scenarios, and the
registered estimators, state presets and measurement types (the installed plug-ins' included)."""

from __future__ import annotations

import shutil
import sys
import textwrap

from navsim.cli.command import Command
from navsim.cli.new import shipped_scenarios
from navsim.experiment.scenario import available_aircraft
from navsim.flight.airframe import load_airframe
from navsim.flight.properties import AIRCRAFT_DIR
from navsim.flight.track import available_tracks, load_track, nominal_duration_s
from navsim.foundations.config import load_yaml
from navsim.foundations.resources import data_folder
from navsim.navigation.estimators import base, measurement_types
from navsim.navigation.estimators.error_model import PRESETS, Layout
from navsim.navigation.estimators.measurements import measurement_class
from navsim.sensors.catalog import entries as catalog_entries


def _first_sentence(text: str) -> str:
    """The first sentence of a text, its whitespace collapsed."""
    para = " ".join((text or "").strip().split("\n\n")[0].split())
    end = para.find(". ")
    return para if end < 0 else para[:end + 1]


def _summary(obj) -> str:
    """The first sentence of a class's docstring, or of its module's where the class's has no
    summary of its own (it starts with its parameters, or sends the reader to the module)."""
    doc = (obj.__doc__ or "").strip()
    if not doc or doc.startswith("Parameters") or "see the module docstring" in _first_sentence(doc):
        doc = sys.modules[obj.__module__].__doc__ or ""
    return _first_sentence(doc)


def _listing(title: str, rows: list) -> str:
    """``title:`` then ``name  tag  text`` per row, the columns aligned and the text wrapped
    to the terminal under itself (never cut)."""
    width = max(60, shutil.get_terminal_size((100, 24)).columns)
    w0, w1 = (max((len(r[k]) for r in rows), default=0) for k in (0, 1))
    indent = 2 + w0 + 2 + (w1 + 2 if w1 else 0)
    out = [f"{title}:"]
    for name, tag, text in rows:
        lines = textwrap.wrap(text, max(width - indent, 30)) or [""]
        head = f"  {name:<{w0}}  " + (f"{tag:<{w1}}  " if w1 else "")
        out += [head + lines[0]] + [" " * indent + ln for ln in lines[1:]]
    return "\n".join(out)


def handle(args) -> int:
    """Print each listing."""
    print(_listing("aircraft", [(a, load_airframe(AIRCRAFT_DIR / a).kind, "") for a in available_aircraft()]))
    print(_listing("sensors (catalog entries)", [(n, k, d) for n, (k, d) in catalog_entries().items()]))
    tracks = [(n, load_track(n)) for n in available_tracks()]
    print(_listing("tracks", [(n, f"{nominal_duration_s(t):.0f} s", _first_sentence(t.description)) for n, t in tracks]))
    print(_listing("scenarios (navsim new scenario NAME --from ...)",
                   [(n, "", _first_sentence((load_yaml(data_folder("scenarios") / f"{n}.yaml") or {}).get("description", "")))
                    for n in shipped_scenarios()]))
    print(_listing("estimators (type:)", [(n, "" if base.get(n).__module__.startswith("navsim.") else "plug-in",
                                           _summary(base.get(n))) for n in base.available()]))
    print(_listing("state presets (states:)", [(n, f"{Layout(b).n} states", ", ".join(b)) for n, b in PRESETS.items()]))
    print(_listing("measurement types (measurements: - type:)",
                   [(n, "", _summary(measurement_class(n))) for n in measurement_types()]))
    return 0


COMMAND = Command(
    "list", "list the aircraft, sensors, tracks, scenarios, estimators, measurements", usage="",
    description="List the shipped aircraft, sensor catalog entries, tracks and scenarios, and the registered "
    "estimators and measurement types (installed plug-ins' included).",
    handler=handle)
