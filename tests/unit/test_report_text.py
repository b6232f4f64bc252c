"""What a report page prints, read as a person reads it: the scenario as run is YAML without
escape artefacts that reads back to the same mapping, and the ground track's segment numbers
keep apart where segments meet or a circle closes on itself; a flight's record is thinned for
drawing without losing a spike; a text line is measured no narrower than Agg draws it."""

import numpy as np
import pytest
import yaml

from matplotlib.backends.backend_agg import RendererAgg
from matplotlib.font_manager import FontProperties

from navsim.flight.plots import PLOT_POINTS, drawn, label_points
from navsim.foundations.config import load_yaml
from navsim.report.scenario_page import scenario_yaml
from navsim.report.tables import PNG_DPI, _line_width_px


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


def test_a_thinned_record_keeps_its_spikes_ends_and_order():
    """50 000 samples of noise with one spike up and one down, one sample each: the drawn ones
    are at most PLOT_POINTS + 2, in order, and hold both spikes, the first and the last sample;
    a short record is drawn whole."""
    rng = np.random.default_rng(7)
    y = rng.normal(size=50_001)
    y[12_345], y[40_000] = 50.0, -50.0
    k = drawn(y)
    assert len(k) <= PLOT_POINTS + 2 and np.all(np.diff(k) > 0)
    assert {0, 12_345, 40_000, 50_000} <= set(k.tolist())
    assert y[k].max() == y.max() and y[k].min() == y.min()
    assert np.array_equal(drawn(y[:PLOT_POINTS]), np.arange(PLOT_POINTS))


@pytest.mark.parametrize("size,weight", [(8.5, "normal"), (7.5, "bold"), (6.5, "normal")])
def test_a_line_is_measured_no_narrower_than_agg_draws_it_and_at_most_5_pct_wider(size, weight):
    """The report's tables are laid out on the sum of their characters' widths; against Agg's
    own measure of the whole line (kerning included) on table cells of the P0 report (0-1.5 %
    wider) and a line of kerned pairs (AV, Ty, ...: 4 % wider)."""
    cells = ["BD/SINS/ADS ES-KF 16  stays within the BD's sigma", "final.pos_m",
             ">= 10 x BD/SINS/ADS ES-KF 16 (15.9 14.9 8.48)", "Consistency: sigmas that do not describe the errors:",
             "204 [196, 215]  200 [191, 210]  146 [140, 152]", "below: too pessimistic; (e/σ)² vel_D 0.566",
             "NIS velocity:ads", "AVWA Type LT Tt Vv"]
    renderer, prop = RendererAgg(1, 1, PNG_DPI), FontProperties(size=size, weight=weight)
    for text in cells:
        agg = renderer.get_text_width_height_descent(text, prop, ismath=False)[0]
        ours = _line_width_px(text, size, weight, "sans-serif", PNG_DPI)
        assert agg - 0.5 <= ours <= 1.05 * agg, text
