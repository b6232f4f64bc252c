"""What a report page prints, read as a person reads it: the scenario as run is YAML without
escape artefacts that reads back to the same mapping, and the ground track's segment numbers
keep apart where segments meet or a circle closes on itself."""

import numpy as np
import pytest
import yaml

from navsim.flight.plots import label_points
from navsim.foundations.config import load_yaml
from navsim.report.scenario_page import scenario_yaml


def test_every_shipped_scenario_reads_back_without_doubled_quotes(repo_root):
    for path in sorted((repo_root / "scenarios").glob("*.yaml")):
        raw = load_yaml(path)
        text = scenario_yaml(raw)
        assert yaml.safe_load(text) == raw, path.name
        assert "''" not in text and not [ln for ln in text.splitlines() if ln.strip() in ("'", '"')], path.name


@pytest.mark.parametrize("value", ["P0's track", "a: b's", "line one\nP0's line two\n", "'quoted'", "-"])
def test_awkward_strings_read_back(value):
    text = scenario_yaml({"description": value, "list": [value]})
    assert yaml.safe_load(text) == {"description": value, "list": [value]}
    assert "''" not in text


def test_segment_numbers_keep_apart_where_segments_meet_and_a_circle_closes():
    """A straight leg, a full circle back to its own entry, a short leg and a long one: the
    numbers at the segments' starts would stand on each other (2, 3 and 4 at one point)."""
    t = np.arange(0.0, 40.0, 0.1)
    east = np.where(t < 10, 20 * t, 200.0)
    north = np.zeros_like(t)
    circle = (t >= 10) & (t < 20)
    th = 2 * np.pi * (t[circle] - 10) / 10
    east[circle], north[circle] = 200 + 50 * np.sin(th), 50 - 50 * np.cos(th)
    leg = t >= 20
    north[leg] = -5 * (t[leg] - 20) ** 1.5
    spans = [(0, "straight", 0, 10), (1, "circle", 10, 20), (2, "short", 20, 21), (3, "long", 21, 40)]
    pts = np.array(label_points(east, north, t, spans))
    gap = min(np.linalg.norm(pts[i] - pts[j]) for i in range(4) for j in range(i + 1, 4))
    assert gap > 20.0, pts                       # 20 m on a track 450 m across: apart at any zoom that shows it
    start = np.array([east[0], north[0]])
    assert np.all(np.linalg.norm(pts - start, axis=1) > 20.0)
