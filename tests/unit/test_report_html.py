"""report.html without a browser: the run picker's data decode to each run's recorded errors and
sigmas within their quantisation, the worst runs are the worst, tables sort by numbers, text a
user wrote is escaped, and NaN records and diverged runs are drawn as gaps and listed."""

import dataclasses
import html as html_lib
import json
import os
import re
import subprocess
import sys
import time

import numpy as np
import pytest

import navsim
from navsim.api.results import _report_input
from navsim.foundations.outputs import temporary_name, write_atomic
from navsim.records.states import POS
from navsim.report import html, html_parts, picker
from navsim.report.render import ForkedWrite


@pytest.fixture(scope="module")
def p0(repo_root, shipped_flight, tmp_path_factory):
    """P0's scenario (its flight cached), 6 runs held in memory."""
    shipped_flight("p0_bd_sins_ads")
    return navsim.run(repo_root / "scenarios" / "p0_bd_sins_ads.yaml", runs=6, workers=1)


def test_the_picker_decodes_every_run_to_its_errors_and_sigmas(p0):
    """Every run's decoded position error and ±3σ equal the recorded ones within half a step
    of the run's 16-bit scale (its largest value / 32767), at the epochs drawn."""
    for h in p0.histories.values():
        tr = picker.run_traces(h)
        for r in range(len(h.diverged)):
            d = picker.decoded(tr, r)
            assert tr["idx"].size == 0 and np.array_equal(d["t"], h.t_s.astype(np.float32).astype(float))
            for j in range(3):
                err = h.pos_err_m[r, :, j].astype(float)
                step = tr["scales"][r * tr["channels"] + j]             # the run's own step
                assert np.nanmax(np.abs(d[f"e{j}"] - err)) <= 0.5 * step * (1 + 1e-6)
                assert step == pytest.approx(np.nanmax(np.abs(err)) / picker.FULL_SCALE, rel=1e-6)
                if h.sigma is None:
                    assert np.isnan(d[f"p{j}"]).all()
                    continue
                sig = h.sigma[r, :, POS][:, j].astype(float)
                step = tr["scales"][r * tr["channels"] + 3 + j]
                assert np.nanmax(np.abs(d[f"p{j}"] - 3 * sig)) <= 1.5 * step * (1 + 1e-6)
                assert np.array_equal(d[f"m{j}"], -d[f"p{j}"])


def test_long_records_are_thinned_per_run_and_nan_stays_a_gap():
    """Beyond PLOT_POINTS epochs each run keeps its own min/max samples (a spike stays drawn),
    a NaN decodes to NaN."""
    rng = np.random.default_rng(57)
    R, E = 3, 3 * picker.PLOT_POINTS
    err = rng.normal(0, 1, (R, E, 3)).astype(np.float32)
    err[1, 4000, 2] = 50.0                      # a spike
    err[2, 100:200, :] = np.nan
    h = type("H", (), {"pos_err_m": err, "sigma": None, "t_s": np.arange(E) * 0.1})()
    tr = picker.run_traces(h)
    assert tr["idx"].size and tr["idx"].size < R * E
    d1, d2 = picker.decoded(tr, 1), picker.decoded(tr, 2)
    assert np.nanmax(d1["e2"]) == pytest.approx(50.0, rel=1e-4)
    assert np.isnan(d2["e0"]).any() and np.isfinite(d2["e0"]).any()
    assert len(d1["t"]) < E and np.all(np.diff(d1["t"]) > 0)


def test_the_worst_runs_listed_are_the_worst(p0):
    """Each "worst by final position error" group lists runs in decreasing order of that error
    (recomputed from the records), then every run."""
    groups = picker.rankings(_report_input(p0))
    assert list(groups)[-1] == "every run" and len(groups["every run"]) == 6
    for name, options in groups.items():
        if "final position error" not in name:
            continue
        label = name.split(": worst")[0]
        err = p0.histories[label].pos_err_m.astype(float)
        final = np.linalg.norm(err[:, -1], axis=1)
        rows = [r for r, _ in options]
        assert rows == list(np.argsort(-final)[:len(rows)])
        assert all(f"{final[r]:.3g} m final" in text for (_, text), r in zip(options, rows))
    texts = [text for opts in groups.values() for _, text in opts]
    assert len(set(texts)) == len(texts)                 # an option's text is its value


def test_tables_sort_by_their_cells_numbers():
    assert html_parts.sort_key("2.35 [2.28, 2.42]") == 2.35
    assert html_parts.sort_key("-1,234.5 m") == -1234.5 and html_parts.sort_key("1e-3") == 1e-3
    assert np.isnan(html_parts.sort_key("pass")) and np.isnan(html_parts.sort_key("-"))
    t = html_parts.table(["what", "value"], [["b", "10 [9, 11]"], ["a", "9.5"], ["c", "-"]])
    data = t.source.data
    assert data["k1"] == [10.0, 9.5, -np.inf] and data["k0"] == ["b", "a", "c"]      # text column: text
    assert all("<%-" in c.formatter.template for c in t.columns)      # shown escaped


def page_strings(text: str) -> list[str]:
    """Every string of the page's document as BokehJS reads it (the JSON script element's text,
    HTML-unescaped, parsed)."""
    found = re.search(r'<script type="application/json" id="[^"]+">(.*?)</script>', text, re.S)
    out, todo = [], [json.loads(html_lib.unescape(found.group(1)))]
    while todo:
        x = todo.pop()
        if isinstance(x, str):
            out.append(x)
        elif isinstance(x, dict):
            todo += list(x.values())
        elif isinstance(x, list):
            todo += x
    return out


def test_text_a_user_wrote_is_escaped(p0):
    """A label with quotes and ``</script>``, a description and a name with tags: the file's
    scripts are not ended early, and in the document every text block holds them escaped (shown
    as written, never run); the labels go to titles, legends and options as plain text."""
    nasty = 'ES-KF "q" </script><script>window.pwned=1</script>'
    rename = lambda k: nasty if k.startswith("BD") else k
    hist = {rename(k): dataclasses.replace(h, label=rename(k)) for k, h in p0.histories.items()}
    metrics = dataclasses.replace(p0.metrics, estimators={rename(k): v for k, v in p0.metrics.estimators.items()})
    scenario = dataclasses.replace(p0.scenario, description="<script>window.pwned=2</script> & <b>bold</b>",
                                   name="p0 <i>x</i>")
    result = dataclasses.replace(p0, histories=hist, metrics=metrics, scenario=scenario)
    text = html.report_html(_report_input(result))
    assert "<script>window.pwned" not in text                 # no script of ours ended early
    strings = page_strings(text)
    blocks = [x for x in strings if x.startswith("<")]        # the text blocks' HTML
    assert any(html_lib.escape("<script>window.pwned=2</script> & <b>bold</b>") in b for b in blocks)
    assert not any("<script" in b or "<b>bold" in b or "<i>x" in b for b in blocks)
    assert any(html_lib.escape("p0 <i>x</i>") in b for b in blocks)
    assert nasty in strings                                   # a legend's label: plain text


def test_a_table_header_is_escaped_as_its_cells_are():
    """A column title is shown by the table as HTML: a sweep parameter or tune label with a tag
    stays text."""
    t = html_parts.table(['<img src=x onerror="window.pwned=3">', "b"], [["1", "2"]])
    assert t.columns[0].title == html_lib.escape('<img src=x onerror="window.pwned=3">')


def test_quantised_traces_keep_infinite_and_tiny_values_apart():
    """An infinite value is a gap, not a scale that zeroes the trace; a trace of tiny values
    keeps a usable scale (0 stays 0)."""
    q, scale = picker.quantised(np.array([[[1.0, 2.0, np.inf, -3.0, np.nan]], [[1e-45, 0.0, -1e-45, 0, 0]]]))
    assert list(q[0, 0]) == [10922, 21845, -32768, -32767, -32768] and scale[0, 0] == np.float32(3.0 / 32767)
    assert np.isfinite(scale).all() and scale[1, 0] > 0 and q[1, 0, 1] == 0


def test_the_page_follows_report_formats(p0, tmp_path):
    """``report.formats`` without html writes no page; html alone writes only it; the default
    writes it beside the PDF."""
    for formats, expect in ((["pdf"], {"report.pdf"}), (["html"], {"report.html"}),
                            (["pdf", "png", "html"], {"report.pdf", "report.html"})):
        result = dataclasses.replace(p0, scenario=dataclasses.replace(p0.scenario, report={"formats": formats}))
        out = tmp_path / "-".join(formats)
        files = navsim.write_report(result, out)
        names = {f.name for f in files}
        assert {n for n in names if n.startswith("report.")} == expect and (out / "report.html").exists() == (
            "html" in formats)
        assert ("png" in formats) == any(n.endswith(".png") for n in names)


def test_a_forked_writer_whose_child_fails_writes_here_and_an_abandoned_one_leaves_nothing(tmp_path):
    """The child's failure is invisible (the parent writes the file itself); abandoning the
    child (the parent failed) ends it and removes its half-written file."""
    parent, path = os.getpid(), tmp_path / "page.html"

    def write():
        if os.getpid() != parent:
            raise RuntimeError("the child fails")
        write_atomic(path, lambda p: p.write_text("written here"))
    ForkedWrite(write, [path]).finish()
    assert path.read_text() == "written here"

    slow = tmp_path / "slow.html"

    def write_slowly():
        temporary_name(slow).write_text("half")
        time.sleep(30)
    job = ForkedWrite(write_slowly, [slow])
    time.sleep(0.5)
    t0 = time.perf_counter()
    assert job.end(abandon=True) is False
    assert time.perf_counter() - t0 < 5 and not slow.exists() and not temporary_name(slow).exists()


def test_the_picker_holds_attitude_and_velocity_while_the_page_stays_small(p0, monkeypatch):
    """Position always; attitude, then velocity, while the values held stay within
    MAX_VALUES; each held error decodes to its record (the attitude in degrees)."""
    h = p0.histories["BD/SINS/ADS ES-KF 16"]
    one = h.pos_err_m.size * 2                                     # errors and sigmas of one quantity
    sins = p0.histories["free SINS"].pos_err_m.size
    monkeypatch.setattr(picker, "MAX_VALUES", one + sins)
    assert picker.quantities(p0.histories) == ("pos",)
    monkeypatch.setattr(picker, "MAX_VALUES", 2 * (one + sins))
    assert picker.quantities(p0.histories) == ("pos", "att")
    monkeypatch.setattr(picker, "MAX_VALUES", 3 * (one + sins))
    keys = picker.quantities(p0.histories)
    assert keys == ("pos", "att", "vel")
    tr = picker.run_traces(h, keys)
    for q, (field, scale) in enumerate((("pos_err_m", 1.0), ("att_err_rad", 180 / np.pi), ("vel_err_mps", 1.0))):
        recorded = getattr(h, field)[2, :, 1].astype(float) * scale
        step = tr["scales"][2 * tr["channels"] + q * tr["per"] + 1]
        assert np.nanmax(np.abs(picker.decoded(tr, 2, q)["e1"] - recorded)) <= 0.5 * step * (1 + 1e-6)


def test_writing_a_report_leaves_bokeh_to_the_child_that_writes_the_page(p0, tmp_path):
    """The process writing a report never imports Bokeh (0.3-0.5 s and its memory): the forked
    child that writes report.html does."""
    navsim.write_report(p0, tmp_path / "p0")
    code = ("import sys, navsim; files = navsim.write_report(navsim.open_result(sys.argv[1])); "
            "print(any(f.name == 'report.html' for f in files), 'bokeh' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code, str(tmp_path / "p0")], capture_output=True, text=True,
                         check=True).stdout.split()
    assert out == ["True", "False"], out
