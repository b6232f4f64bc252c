import pytest

from navsim.experiment.scenario import load_scenario, parse_scenario
from navsim.flight.environment import parse_environment
from navsim.flight.track import available_tracks, load_track, nominal_duration_s, parse_track
from navsim.foundations.errors import ScenarioError

START = {"lat_deg": 37.0, "lon_deg": 118.0, "alt_m": 300, "speed_mps": 14}


def track(*segments, **start):
    return {"start": {**START, **start}, "segments": list(segments)}


def test_shipped_tracks_load_with_their_nominal_durations():
    assert {"p0", "p3", "p2_sea"} <= set(available_tracks())
    assert nominal_duration_s(load_track("p0")) == pytest.approx(500, abs=1)
    assert nominal_duration_s(load_track("p3")) == pytest.approx(3000, abs=1)
    p2 = load_track("p2_sea")
    assert p2.start.type == "launch" and p2.start.pitch_deg == 14.0


def test_segment_defaults_and_labels():
    t = parse_track(track({"type": "turn", "by_deg": -90}, {"type": "straight", "time_s": 5}))
    assert t.segments[0]["bank_deg"] == 20.0 and t.segments[0].label == "0:turn"
    assert t.segments[1]["time_s"] == 5.0


@pytest.mark.parametrize("segment, key, words", [
    ({"type": "straigt", "time_s": 5}, "track.segments[0].type", "did you mean 'straight'"),
    ({"type": "straight", "time": 5}, "track.segments[0].time", "did you mean 'time_s'"),
    ({"type": "straight"}, "track.segments[0]", "needs time_s or distance_m or until_s"),
    ({"type": "straight", "time_s": 5, "distance_m": 3}, "track.segments[0]", "only one of"),
    ({"type": "circle", "radius_m": -3, "laps": 1}, "track.segments[0].radius_m", "> 0.0"),
    ({"type": "climb", "to_m": "high"}, "track.segments[0].to_m", "expected a number"),
    ({"type": "climb"}, "track.segments[0].to_m", "is missing"),
    ({"type": "turn", "by_deg": 0}, "track.segments[0].by_deg", "non-zero"),
    ({"type": "turn", "by_deg": 30, "bank_deg": 80}, "track.segments[0].bank_deg", "<= 45"),
])
def test_malformed_segments_name_the_key(segment, key, words):
    with pytest.raises(ScenarioError) as info:
        parse_track(track(segment), "track", "f.yaml")
    text = str(info.value)
    assert text.startswith(f"f.yaml: {key}:"), text
    assert words in text


def test_malformed_start():
    with pytest.raises(ScenarioError, match=r"track.start.speed_mps: is missing"):
        parse_track({"start": {"lat_deg": 1, "lon_deg": 2, "alt_m": 3},
                     "segments": [{"type": "straight", "time_s": 1}]}, "track")
    with pytest.raises(ScenarioError, match=r"track.start.type: is 'rocket'"):
        parse_track(track({"type": "straight", "time_s": 1}, type="rocket"), "track")


def test_environment_wind_forms():
    env = parse_environment({"wind": {"speed_mps": 5, "from_deg": 270}})
    assert env.wind_n_mps == pytest.approx((0.0, 5.0, 0.0), abs=1e-12)  # from west -> blows east
    env = parse_environment({"wind": {"force": 3, "from_deg": 0}})
    assert env.wind_n_mps[0] == pytest.approx(-4.4)                    # force 3: 3.4-5.4 m/s
    env = parse_environment({"wind": {"north_mps": 1, "east_mps": -2}})
    assert env.wind_n_mps == (1.0, -2.0, 0.0)
    with pytest.raises(ScenarioError, match="environment.turbulence.severity"):
        parse_environment({"turbulence": {"severity": 9}})


def test_shipped_scenarios_validate(shipped_scenarios):
    for path in shipped_scenarios:
        s = load_scenario(path)
        assert s.flight.track.segments


def test_every_shipped_reference_says_what_kind_of_number_the_paper_published_and_why(shipped_scenarios):
    """Each paper here reports one flight or simulation: its checks are single runs, with the
    reason in the scenario (kind_note); a population check is a count over the runs."""
    refs = {path.stem: load_scenario(path).reference for path in shipped_scenarios}
    refs = {name: r for name, r in refs.items() if r is not None}
    assert len(refs) >= 10
    for name, ref in refs.items():
        assert ref.kind == "single_run" and len(ref.kind_note.split()) >= 6, name
        assert all(c.kind == "single_run" or c.metric == "diverged_runs" for c in ref.checks), name


def test_scenario_errors():
    with pytest.raises(ScenarioError, match=r"(?s)aircraft: 'survey1' .*did you mean 'survey10'"):
        parse_scenario({"aircraft": "survey1", "track": "p0"}, "s.yaml")
    with pytest.raises(ScenarioError, match=r"track: 'p9' is not a shipped track"):
        parse_scenario({"track": "p9"}, "s.yaml")
    with pytest.raises(ScenarioError, match=r"(?s)s.yaml: envronment: is not a known key.*environment"):
        parse_scenario({"track": "p0", "envronment": {}}, "s.yaml")
