"""Aircraft folders (issue 52, items 2 and 3): ``aircraft:`` names a shipped folder or a folder
beside the scenario holding ``<name>.xml`` and ``navsim.yaml`` (or ``navsim.yaml`` naming a model
of the jsbsim package); the airframe's class and envelope
are read from ``navsim.yaml`` and checked; each segment type names the classes that fly it.

A copy of survey10 beside a scenario under another name flies survey10's flight bit for bit; each
refusal exits 2 naming the file, the key and what was expected, without a traceback.
"""

from __future__ import annotations

import dataclasses
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml

from navsim.cli import main
from navsim.experiment.runner import flight_key
from navsim.experiment.scenario import load_scenario
from navsim.flight.airframe import CLASSES, FIXED_WING, MULTIROTOR, load_airframe
from navsim.flight.properties import AIRCRAFT_DIR
from navsim.flight.simulator import fly
from navsim.flight.track import SEGMENT_CLASSES, SEGMENT_KEYS, check_segments, parse_track
from navsim.foundations.errors import ScenarioError

TRACK = {"start": {"lat_deg": 37.0, "lon_deg": 118.0, "alt_m": 250, "speed_mps": 14, "heading_deg": 45},
         "segments": [{"type": "straight", "time_s": 20, "label": "leg"},
                      {"type": "turn", "by_deg": 45, "bank_deg": 20}]}
#: every segment a fixed wing flies
FIXED_WING_SEGMENTS = [{"type": "straight", "time_s": 10}, {"type": "speed", "to_mps": 16},
                       {"type": "turn", "by_deg": 90, "bank_deg": 20},
                       {"type": "circle", "radius_m": 150, "laps": 1},
                       {"type": "climb", "to_m": 280, "rate_mps": 2},
                       {"type": "descend", "to_m": 250, "rate_mps": 2},
                       {"type": "goto", "north_m": 500, "east_m": 500}]
#: a multirotor's envelope as aircraft/README.md declares it (a quadrotor in X)
MULTIROTOR_YAML = {
    "class": "multirotor", "mass_kg": 1.5, "max_tilt_deg": 30.0, "max_climb_mps": 3.0,
    "max_descent_mps": 2.0, "max_speed_mps": 12.0, "hover_throttle": 0.5,
    "rotors": [{"position_m": [0.16 * sx, 0.16 * sy, 0.0], "spin": spin, "tilt_deg": 0.0,
                "thrust_coefficient": 1.2e-5, "torque_coefficient": 2.0e-7}
               for sx, sy, spin in ((1, 1, 1), (-1, 1, -1), (-1, -1, 1), (1, -1, -1))]}


def first_rotor(**change) -> list:
    """The multirotor's rotors, the first changed by ``change``."""
    rotors = MULTIROTOR_YAML["rotors"]
    return [dict(rotors[0], **change)] + rotors[1:]


def plane(folder: Path, name: str = "my_plane") -> Path:
    """survey10's folder copied to ``folder/<name>`` as ``<name>.xml`` (named so inside)."""
    dest = folder / name
    dest.mkdir(parents=True)
    xml = (AIRCRAFT_DIR / "survey10" / "survey10.xml").read_text()
    (dest / f"{name}.xml").write_text(xml.replace('<fdm_config name="survey10"', f'<fdm_config name="{name}"'))
    shutil.copy(AIRCRAFT_DIR / "survey10" / "navsim.yaml", dest / "navsim.yaml")
    return dest


def write_scenario(folder: Path, aircraft: str | None, segments=None, start=None) -> Path:
    track = dict(TRACK, segments=segments or TRACK["segments"], start=start or TRACK["start"])
    data = {"name": "folder_test", "track": track}
    if aircraft is not None:
        data["aircraft"] = aircraft
    path = folder / "s.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def refused(capsys, argv, code: int = 2) -> str:
    """The message of a command that must exit with ``code`` and no traceback."""
    assert main(argv) == code
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return err


def test_a_folder_beside_the_scenario_flies_survey10s_flight(tmp_path):
    plane(tmp_path / "case")
    mine = load_scenario(write_scenario(tmp_path / "case", "./my_plane"))
    shipped = load_scenario(write_scenario(tmp_path, None))
    assert (mine.flight.aircraft, Path(mine.flight.aircraft_dir)) == ("my_plane", (tmp_path / "case").resolve())
    assert (shipped.flight.aircraft, shipped.flight.aircraft_dir) == ("survey10", None)
    a, b = fly(mine.flight), fly(shipped.flight)
    assert a.meta["aircraft"] == "my_plane" and len(a.t_s) > 2000
    arrays = [f.name for f in dataclasses.fields(a) if isinstance(getattr(a, f.name), np.ndarray)]
    assert len(arrays) >= 20 and "f_b_mps2" in arrays and "segment" in arrays
    for name in arrays:
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert a.segment_labels == b.segment_labels


def test_the_flight_key_follows_the_models_files_not_its_path(tmp_path):
    one, two = tmp_path / "one", tmp_path / "two"
    plane(one), plane(two)
    k1 = flight_key(load_scenario(write_scenario(one, "./my_plane")).flight)
    assert k1 == flight_key(load_scenario(write_scenario(two, "./my_plane")).flight)   # same model, same flight
    xml = two / "my_plane" / "my_plane.xml"
    xml.write_text(xml.read_text().replace("</fdm_config>", "<!-- edited --></fdm_config>"))
    assert flight_key(load_scenario(write_scenario(two, "./my_plane")).flight) != k1     # edited: flown again
    sub = two / "my_plane" / "Engines"
    sub.mkdir()
    (sub / "motor.xml").write_text("<x/>")                                              # a model's sub-folder
    k2 = flight_key(load_scenario(write_scenario(two, "./my_plane")).flight)
    (sub / "motor.xml").write_text("<y/>")
    assert flight_key(load_scenario(write_scenario(two, "./my_plane")).flight) != k2


def test_a_folder_below_the_scenario_and_a_fixed_wing_segment_list_are_accepted(tmp_path, capsys):
    plane(tmp_path / "planes")
    path = write_scenario(tmp_path, "planes/my_plane", segments=FIXED_WING_SEGMENTS)
    assert main(["validate", str(path)]) == 0, capsys.readouterr().err
    write_scenario(tmp_path, "survey10", segments=FIXED_WING_SEGMENTS)
    assert main(["validate", str(path)]) == 0, capsys.readouterr().err


@pytest.mark.parametrize("aircraft, words", [
    ("../my_plane", ["s.yaml: aircraft", "'../my_plane' leaves the scenario's folder"]),
    ("/tmp/my_plane", ["s.yaml: aircraft", "not allowed", "relative path"]),
    ("./nowhere", ["s.yaml: aircraft", "'./nowhere' is not a folder beside the scenario"]),
    ("my_plane", ["s.yaml: aircraft", "not a shipped aircraft", "./my_plane"]),
    ("./", ["s.yaml: aircraft", "not allowed"]),
])
def test_a_folder_that_escapes_or_is_missing_is_refused(tmp_path, capsys, aircraft, words):
    plane(tmp_path), plane(tmp_path / "case")
    err = refused(capsys, ["validate", str(write_scenario(tmp_path / "case", aircraft))])
    for w in words:
        assert w in err, (w, err)


@pytest.mark.parametrize("remove, words", [
    ("navsim.yaml", ["my_plane", "has no navsim.yaml", "class and envelope"]),
    ("my_plane.xml", ["my_plane", "has no my_plane.xml", "JSBSim model"]),
])
def test_a_folder_without_its_files_is_refused(tmp_path, capsys, remove, words):
    (plane(tmp_path) / remove).unlink()
    err = refused(capsys, ["validate", str(write_scenario(tmp_path, "./my_plane"))])
    assert "s.yaml: aircraft" in err
    for w in words:
        assert w in err, (w, err)


@pytest.mark.parametrize("change, words", [
    ({"max_bank": 30}, ["my_plane/navsim.yaml: max_bank", "not a known key", "max_bank_deg"]),
    ({"stall_speed_mps": -3}, ["my_plane/navsim.yaml: stall_speed_mps", "> 0"]),
    ({"max_speed_mps": "fast"}, ["my_plane/navsim.yaml: max_speed_mps", "a number"]),
    ({"class": "helicopter"}, ["my_plane/navsim.yaml: class", "fixed_wing, multirotor"]),
    ({"trim_alpha_deg": None}, ["my_plane/navsim.yaml: trim_alpha_deg", "is missing"]),
])
def test_a_bad_envelope_is_refused_naming_the_file_and_key(tmp_path, capsys, change, words):
    folder = plane(tmp_path)
    data = yaml.safe_load((folder / "navsim.yaml").read_text())
    data.update(change)
    (folder / "navsim.yaml").write_text(yaml.safe_dump({k: v for k, v in data.items() if v is not None}))
    err = refused(capsys, ["validate", str(write_scenario(tmp_path, "./my_plane"))])
    for w in words:
        assert w in err, (w, err)


def test_a_model_jsbsim_cannot_load_is_refused_with_jsbsims_reason(tmp_path, capsys):
    xml = plane(tmp_path) / "my_plane.xml"
    xml.write_text(xml.read_text().replace("<mass_balance>", "<mass_balanc>"))
    err = refused(capsys, ["fly", str(write_scenario(tmp_path, "./my_plane")), "--out", str(tmp_path / "out")])
    assert "my_plane.xml" in err and "JSBSim cannot load the model" in err and "mismatched tag" in err, err


def test_survey10_is_a_fixed_wing_and_a_file_without_class_is_one(tmp_path):
    assert load_airframe(AIRCRAFT_DIR / "survey10").kind == FIXED_WING
    folder = plane(tmp_path)
    text = (folder / "navsim.yaml").read_text()
    assert "class:" not in text                   # survey10's file (its flight key unchanged)
    (folder / "navsim.yaml").write_text("class: fixed_wing\n" + text)
    airframe = load_airframe(folder)
    assert airframe.kind == FIXED_WING and airframe == load_airframe(AIRCRAFT_DIR / "survey10")


#: a multirotor's start and segments
HOVER_START = {"type": "hover", "lat_deg": 37.0, "lon_deg": 118.0, "alt_m": 20, "heading_deg": 45}
MULTIROTOR_SEGMENTS = [{"type": "hover", "time_s": 10}, {"type": "goto", "north_m": 20, "east_m": 0, "yaw": "course"},
                       {"type": "circle", "radius_m": 10, "laps": 1, "yaw": "center"}]


def test_a_multirotor_is_read_and_validates_with_a_multirotors_track(tmp_path, capsys):
    folder = plane(tmp_path)
    (folder / "navsim.yaml").write_text(yaml.safe_dump(MULTIROTOR_YAML))
    airframe = load_airframe(folder)
    assert airframe.kind == MULTIROTOR and len(airframe.rotors) == 4
    assert airframe.rotors[1].position_m == (-0.16, 0.16, 0.0) and airframe.rotors[1].spin == -1
    assert main(["validate", str(write_scenario(tmp_path, "./my_plane", MULTIROTOR_SEGMENTS, HOVER_START))]) == 0
    err = refused(capsys, ["validate", str(write_scenario(tmp_path, "./my_plane"))])
    assert "s.yaml: track.start.type" in err and "'air' start is not a multirotor's" in err and "hover" in err, err


@pytest.mark.parametrize("change, words", [
    ({"rotors": []}, ["navsim.yaml: rotors", "at least"]),
    ({"rotors": first_rotor(spin=2)}, ["navsim.yaml: rotors[0].spin", "one of 1, -1"]),
    ({"rotors": first_rotor(position_m=[1, 2])}, ["navsim.yaml: rotors[0].position_m"]),
    ({"rotors": first_rotor(arm=1)}, ["navsim.yaml: rotors[0].arm", "not a known key"]),
    ({"max_tilt_deg": 95}, ["navsim.yaml: max_tilt_deg", "<= 89"]),
    ({"stall_speed_mps": 9.6}, ["navsim.yaml: stall_speed_mps", "not a known key"]),
])
def test_a_bad_multirotor_envelope_is_refused(tmp_path, change, words):
    folder = plane(tmp_path)
    (folder / "navsim.yaml").write_text(yaml.safe_dump(dict(MULTIROTOR_YAML, **change)))
    with pytest.raises(ScenarioError) as info:
        load_airframe(folder)
    for w in words:
        assert w in str(info.value), (w, str(info.value))


def test_a_segment_the_class_cannot_fly_is_named():
    track = parse_track(dict(TRACK, segments=FIXED_WING_SEGMENTS))
    assert set(SEGMENT_CLASSES) == set(SEGMENT_KEYS) and SEGMENT_CLASSES["hold"] == CLASSES
    check_segments(track, FIXED_WING, "s.yaml")                  # every one of them a fixed wing's
    with pytest.raises(ScenarioError) as info:
        check_segments(dict_track(FIXED_WING_SEGMENTS, HOVER_START), MULTIROTOR, "s.yaml")
    text = str(info.value)
    assert "s.yaml: track.segments[0]" in text and "'straight'" in text and "multirotor" in text, text
    check_segments(dict_track(MULTIROTOR_SEGMENTS, HOVER_START), MULTIROTOR, "s.yaml")
    for segments, start, key in ((MULTIROTOR_SEGMENTS[:1], TRACK["start"], "track.segments[0]"),
                                 (MULTIROTOR_SEGMENTS[1:], TRACK["start"], "track.segments[0].yaw"),
                                 (FIXED_WING_SEGMENTS, HOVER_START, "track.start.type")):
        with pytest.raises(ScenarioError, match=key.replace("[", r"\[").replace("]", r"\]")):
            check_segments(dict_track(segments, start), FIXED_WING, "s.yaml")


def dict_track(segments, start):
    return parse_track(dict(TRACK, segments=segments, start=start))


def test_octo25_copied_beside_a_scenario_under_another_name_validates_and_flies(tmp_path):
    """A user's multirotor: octo25's folder copied as ``my_octo`` (its model renamed inside),
    flown from a scenario beside it: the same flight as the shipped octo25's, bit for bit."""
    dest = tmp_path / "my_octo"
    dest.mkdir()
    xml = (AIRCRAFT_DIR / "octo25" / "octo25.xml").read_text()
    (dest / "my_octo.xml").write_text(xml.replace('name="octo25"', 'name="my_octo"'))
    shutil.copy(AIRCRAFT_DIR / "octo25" / "navsim.yaml", dest / "navsim.yaml")
    segments = [{"type": "hover", "time_s": 2}, {"type": "goto", "north_m": 5, "east_m": 0}]
    mine = load_scenario(write_scenario(tmp_path, "./my_octo", segments, HOVER_START))
    assert mine.flight.aircraft_dir == str(tmp_path)
    shipped = dataclasses.replace(mine.flight, aircraft="octo25", aircraft_dir=None)
    a, b = fly(mine.flight), fly(shipped)
    assert a.n == b.n and np.array_equal(a.lat_rad, b.lat_rad) and np.array_equal(a.h_m, b.h_m)
    assert np.array_equal(a.rotor_rpm, b.rotor_rpm) and a.rotor_rpm.shape[1] == 16


def f450_folder(tmp_path: Path, **change) -> Path:
    """aircraft/f450's navsim.yaml (no model: it names the jsbsim package's F450) beside a
    scenario as ``quad``, changed by ``change``."""
    dest = tmp_path / "quad"
    dest.mkdir()
    data = yaml.safe_load((AIRCRAFT_DIR / "f450" / "navsim.yaml").read_text())
    (dest / "navsim.yaml").write_text(yaml.safe_dump(dict(data, **change)))
    return dest


def test_a_folder_naming_a_jsbsim_package_model_holds_navsim_yaml_only(tmp_path):
    f450_folder(tmp_path)
    assert main(["validate", str(write_scenario(tmp_path, "./quad", MULTIROTOR_SEGMENTS, HOVER_START))]) == 0


@pytest.mark.parametrize("change, code, words", [
    ({"jsbsim_model": "F405"}, 2, ["navsim.yaml: jsbsim_model", "'F405' is not a model of the jsbsim package",
                                   "F450"]),
    ({"rotors": "add"}, 2, ["navsim.yaml: rotors", "4 engines, the rotor table 5 rotors"]),
    ({"rotors": "twice"}, 2, ["navsim.yaml: rotors[3].command", "'fcs/cmdFR_ext_nd' as rotors[0] does"]),
    ({"jsbsim_model": "../F450"}, 2, ["navsim.yaml: jsbsim_model", "not a model's name"]),
    ({"rotors": "rename"}, 2, ["navsim.yaml: rotors[2].command", "no property 'fcs/cmdFX_ext_nd'"]),
])
def test_a_jsbsim_package_model_the_table_does_not_fit_is_refused(tmp_path, capsys, change, code, words):
    """A model name the jsbsim package lacks or a path for one, two rotors naming one command
    property (validation), a rotor table with more rotors than the model's engines or naming a command property the model lacks (at the flight's start):
    exit 2 naming navsim.yaml and the key."""
    rotors = yaml.safe_load((AIRCRAFT_DIR / "f450" / "navsim.yaml").read_text())["rotors"]
    if change.get("rotors") == "add":
        change = {"rotors": rotors + [dict(rotors[0], command="fcs/cmdX_ext_nd", rpm="propulsion/engine[4]/propeller-rpm")]}
    elif change.get("rotors") == "twice":
        change = {"rotors": rotors[:3] + [dict(rotors[3], command=rotors[0]["command"])]}
    elif change.get("rotors") == "rename":
        change = {"rotors": rotors[:2] + [dict(rotors[2], command="fcs/cmdFX_ext_nd")] + rotors[3:]}
    f450_folder(tmp_path, **change)
    err = refused(capsys, ["fly", str(write_scenario(tmp_path, "./quad", MULTIROTOR_SEGMENTS[:1], HOVER_START)),
                           "--out", str(tmp_path / "out")], code)
    for w in words:
        assert w in err, (w, err)
