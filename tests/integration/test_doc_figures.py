"""The figures README.md and docs/ quote from navsim's commands, recomputed at this checkout.

Each test reads the figures from the page's own text (so a figure edited without its command
re-run fails here), runs the command the page gives beside it through the API (the numbers of
``navsim run`` / ``navsim compare`` without the report; runs and seeds as the page gives them)
and checks every figure to its printed precision: ``8.09`` is right for 8.085 to 8.095.
The commands cheaper than ~10 s run in the default suite, the others are marked ``slow``.
"""

import math
import re
import shlex
from decimal import Decimal
from pathlib import Path

import pytest

import navsim
from navsim.replay.metrics import replay_metrics
from navsim.replay.run import replay
from navsim.replay.ulog import load_ulog

ROOT = Path(__file__).resolve().parents[2]
#: a number as the pages print it: a Unicode minus or a sign, decimals, an exponent (not the
#: digits of a name such as ``p95`` or ``att_N2``)
NUMBER = r"(?<![\w.])[−+-]?\d+(?:\.\d+)?(?:e[−+-]?\d+)?"
#: ``value [lo, hi]``
WITH_INTERVAL = rf"({NUMBER}) \[({NUMBER}), ({NUMBER})\]"
#: the family error rate of compare's verdicts (Holm's step-down over the components)
FAMILY_ALPHA = 0.05
ES_KF = "BD/SINS/ADS ES-KF 16"


def number(text: str) -> float:
    return float(text.replace("−", "-"))


def agrees(text: str, value: float) -> bool:
    """Whether ``value`` prints as ``text`` at ``text``'s precision (half its last digit)."""
    exponent = Decimal(text.replace("−", "-").lstrip("+")).as_tuple().exponent
    return abs(number(text) - value) <= 0.5 * 10.0 ** exponent * (1 + 1e-9)


def check(texts, values, what: str) -> None:
    """Each quoted figure against the value its command gives now."""
    texts, values = list(texts), list(values)
    assert len(texts) == len(values), what
    wrong = [(t, v) for t, v in zip(texts, values) if not agrees(t, v)]
    assert not wrong, f"{what}: the page says {', '.join(t for t, _ in wrong)}; " \
                      f"its command gives {', '.join(f'{v:.6g}' for _, v in wrong)}"


def page(name: str) -> str:
    return (ROOT / name).read_text(encoding="utf-8")


def line_with(text: str, anchor: str) -> str:
    """The one line of ``text`` holding ``anchor``."""
    lines = [ln for ln in text.splitlines() if anchor in ln]
    assert len(lines) == 1, f"{len(lines)} lines hold {anchor!r}"
    return lines[0]


def figures(line: str, pattern: str) -> tuple:
    found = re.search(pattern, line)
    assert found, f"{pattern!r} not in {line!r}"
    return found.groups()


def command_args(line: str) -> tuple[Path, int | None, int | None]:
    """``navsim run FILE [--runs N] [--seed S] ...`` -> (file, runs, seed)."""
    words = shlex.split(line.split("#")[0])
    at = words.index("run")
    opt = lambda name: int(words[words.index(name) + 1]) if name in words else None
    return ROOT / words[at + 1], opt("--runs"), opt("--seed")


@pytest.fixture(scope="module")
def results(shipped_flight):
    """``get(command line)`` -> the Result of that ``navsim run``, each run once per module."""
    shipped_flight("p0_bd_sins_ads")            # the session's flight cache
    done = {}

    def get(line: str):
        key = command_args(line)
        if key not in done:
            path, runs, seed = key
            done[key] = navsim.run(navsim.load_scenario(path), runs, seed)
        return done[key]
    return get


def holm_significant(comparison) -> int:
    """The components Holm's step-down at 5 % finds different from 0 (whatever the verdicts'
    words)."""
    p = sorted(d.p_value for d in comparison.differences if math.isfinite(d.p_value))
    m = len(comparison.differences)
    for k, pk in enumerate(p):
        if pk > FAMILY_ALPHA / (m - k):
            return k
    return len(p)


def nees_change(comparison) -> list[float]:
    """A, B, B - A and its interval of the NEES average."""
    [d] = [d for d in comparison.differences if d.metric == "nees.average"]
    return [d.a, d.b, d.diff, *d.ci95]


# --- README.md and docs/intervals.md: navsim compare ------------------------------------------

COMPARE_RUNS = ("navsim run scenarios/p0_bd_sins_ads.yaml --out reports/p0",
                "navsim run examples/compare/p0_gnss_sigma_x1.1.yaml --runs 50 --out reports/p0_gnss_sigma_x1.1")
#: ``8.09 → 7.29: −0.796 [−0.868, −0.724] (−9.84 %)``
NEES_CHANGE = rf"({NUMBER}) (?:→|->) ({NUMBER}): {WITH_INTERVAL} \(({NUMBER}) %\)"


@pytest.fixture(scope="module")
def paired_50(results):
    a, b = (results(line) for line in COMPARE_RUNS)
    return a, b


@pytest.mark.parametrize("name", ["README.md", "docs/intervals.md"])
def test_the_compare_example_is_what_its_commands_give(name, paired_50):
    text = page(name)
    for line in COMPARE_RUNS:
        assert line in text, f"{name} no longer gives the command {line!r}"
    anchor = "# paired: NEES average" if name == "README.md" else "| paired | 50 |"
    quoted = figures(line_with(text, anchor), NEES_CHANGE)
    [c] = navsim.compare(*paired_50, [ES_KF])
    assert c.paired
    values = nees_change(c)
    check(quoted, values + [100 * values[2] / values[0]], f"{name}: the paired NEES average")


def test_the_paired_rows_other_figures(paired_50):
    row = line_with(page("docs/intervals.md"), "| paired | 50 |")
    [c] = navsim.compare(*paired_50, [ES_KF])
    by_name = {d.name: d for d in c.differences}
    vel_d = by_name["rms.vel_mps D"]
    quoted = figures(row, rf"RMS vertical velocity ({NUMBER}) % \[({NUMBER}), ({NUMBER})\]")
    check(quoted, [100 * x / vel_d.a for x in (vel_d.diff, *vel_d.ci95)], "paired RMS vertical velocity, %")
    count = figures(row, r"(\d+) components")
    assert int(count[0]) == len(c.differences)
    found = figures(row, r"(\d+) found different")
    assert int(found[0]) == holm_significant(c), "paired: the components found different (Holm, 5 %)"
    horizontal = by_name["rms.pos_m horizontal"]
    text = line_with(page("docs/intervals.md"), "(horizontal ")
    quoted = figures(text, rf"\(horizontal ({NUMBER}) % \[({NUMBER}), ({NUMBER})\] paired\)")
    check(quoted, [100 * x / horizontal.a for x in (horizontal.diff, *horizontal.ci95)], "horizontal RMS, %")


def test_the_unpaired_row_of_the_same_data(paired_50):
    text = page("docs/intervals.md")
    row = line_with(text, "| unpaired, the same data | 50 |")
    [c] = navsim.compare(*paired_50, [ES_KF], unpaired=True)
    [paired] = navsim.compare(*paired_50, [ES_KF])
    assert not c.paired
    quoted = figures(row, WITH_INTERVAL)
    check(quoted, nees_change(c)[2:], "unpaired at 50 runs: the NEES average's B - A")
    [d] = [d for d in c.differences if d.metric == "nees.average"]
    assert figures(row, r"~(\d+) runs would resolve")[0] == str(d.runs_needed)
    assert int(figures(row, r"(\d+) found different")[0]) == holm_significant(c)
    narrower = figures(line_with(text, "Pairing narrows"), rf"interval ({NUMBER}) times \(({NUMBER}) against ({NUMBER}) wide\)")
    width = lambda comparison: [x for x in comparison.differences if x.metric == "nees.average"][0].ci95
    w_paired, w_unpaired = (hi - lo for lo, hi in (width(paired), width(c)))
    check(narrower, [w_unpaired / w_paired, w_paired, w_unpaired], "how much pairing narrows the interval")


#: the other rows' commands, as docs/intervals.md gives them
RUNS_200 = ("navsim run scenarios/p0_bd_sins_ads.yaml --runs 200 --out reports/p0_200",
            "navsim run examples/compare/p0_gnss_sigma_x1.1.yaml --runs 200 --out reports/p0_gnss_sigma_x1.1_200")
SEED_2 = "navsim run scenarios/p0_bd_sins_ads.yaml --seed 2 --out reports/p0_seed2"


@pytest.mark.slow
def test_the_unpaired_row_at_200_runs(results):
    text = page("docs/intervals.md")
    assert all(line in text for line in RUNS_200) and "navsim compare reports/p0_200 reports/p0_gnss_sigma_x1.1_200 --unpaired" in text
    row = line_with(text, "| unpaired | 200 |")
    [c] = navsim.compare(*(results(line) for line in RUNS_200), [ES_KF], unpaired=True)
    values = nees_change(c)
    check(figures(row, NEES_CHANGE), values + [100 * values[2] / values[0]], "unpaired at 200 runs: the NEES average")
    [d] = [d for d in c.differences if d.metric == "nees.average"]
    assert figures(row, r"~(\d+) runs would resolve")[0] == str(d.runs_needed)
    assert int(figures(row, r"(\d+) found different")[0]) == holm_significant(c)


@pytest.mark.slow
def test_the_same_filter_at_two_seeds_is_found_the_same(results):
    text = page("docs/intervals.md")
    assert SEED_2 in text and "navsim compare reports/p0 reports/p0_seed2" in text
    row = line_with(text, "| the same filter, seeds 1 and 2 (unpaired) | 50 |")
    by_label = {c.a.estimator: c for c in navsim.compare(results(COMPARE_RUNS[0]), results(SEED_2))}
    quoted = re.findall(r"(\d+) of (\d+) found different \(([^)]+)\)", row)
    assert {label for *_, label in quoted} == set(by_label)
    for found, of, label in quoted:
        assert not by_label[label].paired
        assert (int(found), int(of)) == (holm_significant(by_label[label]), len(by_label[label].differences)), label


# --- docs/papers.md: the paper checks ----------------------------------------------------------

def paper_check_rows() -> list[str]:
    text = page("docs/papers.md")
    table = text.split("## Paper checks: pass or fail", 1)[1].split("```", 1)[0]
    return [ln for ln in table.splitlines() if re.match(r"\| `\w+` \(\d+\) \|", ln)]


def verdict_counts(checks: list[dict]) -> dict:
    counts = {"pass": sum(c["passed"] is True for c in checks), "fail": sum(c["passed"] is False for c in checks),
              "undecided": sum(bool(c.get("undecided")) for c in checks),
              "shown": sum(c["rule"] == "none" for c in checks)}
    counts["of"] = len(checks) - counts["shown"]
    return counts


def quoted_counts(cell: str) -> dict:
    passed, of = figures(cell, r"(\d+) of (\d+) pass")
    out = {"pass": int(passed), "of": int(of)}
    for word in ("fail", "undecided", "shown"):
        n = re.search(rf"(\d+) {word}", cell)
        out[word] = int(n.group(1)) if n else 0
    return out


def values_with_intervals(checks: list[dict]) -> list[tuple]:
    """Every (value, lo, hi) of our side of the checks."""
    out = []
    for c in checks:
        ours, ivs = c.get("ours"), c.get("ours_ci95")
        if ivs is None or ours is None:
            continue
        for v, iv in zip(ours if isinstance(ours, list) else [ours], ivs):
            if None not in iv:
                out.append((v, *iv))
    return out


#: the columns of the table: their runs (None: the scenario's own)
CHECK_COLUMNS = {"at 20 runs": 20, "at its runs": None, "at 100 runs": 100}
#: the rows and columns whose command runs in under ~10 s (the others are slow)
CHEAP_CHECKS = {("p0_bd_sins_ads", "at its runs")}
PAPER_CHECK_SCENARIOS = [re.match(r"\| `(\w+)`", row).group(1) for row in paper_check_rows()]
#: what a single run's verdict quotes: one run's range, the paper's percentile, a share of runs
ONE_RUN = rf"one run \[({NUMBER}), ({NUMBER})\]"
PERCENTILE, SHARE = r"\(p(\d+(?:\.\d)?)\)", r"(\d+) % \[(\d+), (\d+)\] of runs meet it"


@pytest.mark.parametrize("name, column", [
    pytest.param(name, column, marks=() if (name, column) in CHEAP_CHECKS else pytest.mark.slow)
    for name in PAPER_CHECK_SCENARIOS for column in CHECK_COLUMNS])
def test_the_paper_checks_table(name, column, results):
    """A row's kinds, its verdicts at 20 runs, at the scenario's own runs and at 100 (``navsim
    run scenarios/<name>.yaml [--runs N]``, its seed); in the last column every ``value [lo,
    hi]`` quoted is one of the population checks' values with its interval, every ``one run
    [lo, hi]`` one of the single-run ranges, every ``(pN)`` a paper percentile and every share of
    runs meeting a bound one of the checks' (at 100 runs)."""
    [row] = [r for r in paper_check_rows() if r.startswith(f"| `{name}` (")]
    cells = [c.strip() for c in row.strip("|").split("|")]
    runs = CHECK_COLUMNS[column]
    result = results(f"navsim run scenarios/{name}.yaml" + (f" --runs {runs}" if runs else ""))
    if runs is None:
        assert int(figures(cells[0], r"\((\d+)\)")[0]) == result.record.runs
    checks = result.to_dict()["paper_checks"]
    assert ("single run" in cells[1]) == any(c["kind"] == "single_run" for c in checks)
    assert ("population" in cells[1]) == any(c["kind"] == "population" for c in checks)
    assert quoted_counts(cells[2 + list(CHECK_COLUMNS).index(column)]) == verdict_counts(checks), \
        f"{name}: the verdicts {column}"
    if runs != 100:
        return
    ours = values_with_intervals(checks)
    for quoted in re.findall(WITH_INTERVAL, cells[5]):
        assert any(all(agrees(t, v) for t, v in zip(quoted, triple)) for triple in ours), \
            f"{name}: {quoted[0]} [{quoted[1]}, {quoted[2]}] is none of the checks' " \
            f"{[tuple(round(x, 4) for x in t) for t in ours]}"
    ranges = [r for c in checks for r in c.get("run_range") or [] if None not in r]
    for quoted in re.findall(ONE_RUN, cells[5]):
        assert any(all(agrees(t, v) for t, v in zip(quoted, r)) for r in ranges), f"{name}: one run {quoted}"
    percentiles = {round(p) for c in checks for p in c.get("percentile") or []}
    for quoted in re.findall(PERCENTILE, cells[5]):
        assert round(float(quoted)) in percentiles, f"{name}: (p{quoted}) is none of {sorted(percentiles)}"
    shares = {(round(100 * c["share"]), *(round(100 * x) for x in c["share_ci95"])) for c in checks
              if c.get("share") is not None}
    for quoted in re.findall(SHARE, cells[5]):
        assert tuple(map(int, quoted)) in shares, f"{name}: {quoted} is none of the shares {shares}"


# --- docs/papers.md: P0's two-step table -------------------------------------------------------

@pytest.mark.slow
def test_p0_two_step_table(results):
    text = page("docs/papers.md")
    [command] = re.findall(r"`(navsim run scenarios/p0_two_step\.yaml[^`]*)` \(P0's sensors", text)
    metrics = results(command).metrics.estimators
    labels = {"ES-KF 16 (right model)": ES_KF, "two-step adaptive (right model)": "two-step adaptive (P0)",
              "ES-KF 16, BD R/10": "ES-KF 16, R/10", "two-step adaptive, BD R/10": "two-step adaptive, R/10"}
    for shown, label in labels.items():
        cells = [c.strip() for c in line_with(text, f"| {shown} |").strip("|").split("|")]
        m = metrics[label]
        check(cells[1].split(), m.rms.pos_m, f"{shown}: RMS position")
        check([cells[2], cells[3].rstrip(" %"), cells[4].rstrip(" s")],
              [m.nees.average, 100 * m.nees.fraction_inside, m.convergence_s], f"{shown}: NEES, in band, converged")


# --- docs/papers.md and docs/scenarios.md: the free-inertial replay ------------------------------

def test_the_free_inertial_replay_of_the_px4_log():
    line = "`navsim replay tests/data/px4_quad_real_69s.ulg.gz --estimator sins`"
    diff = replay_metrics(replay(load_ulog(ROOT / "tests/data/px4_quad_real_69s.ulg.gz"), "sins")).attitude_diff_deg
    for name in ("docs/papers.md", "docs/scenarios.md"):
        text = page(name)
        assert line in text or line.replace("`", "") in text.replace("`", ""), name
        quoted = figures(text, rf"RMS differences\s+({NUMBER})° roll, ({NUMBER})° pitch, ({NUMBER})° yaw")
        check(quoted, [diff.roll.rms, diff.pitch.rms, diff.yaw.rms], f"{name}: free inertial against PX4")


# --- docs/papers.md: the experiments' tables ---------------------------------------------------

def row_cells(text: str, label: str) -> list[list[str]]:
    """The numbers of each cell of the table row ``| label | ...``, the label's cell left out."""
    cells = line_with(text, f"| {label} |").strip().strip("|").split("|")[1:]
    return [re.findall(NUMBER, cell.replace("σ", "")) for cell in cells]


def section(text: str, command: str) -> str:
    """The page from the paragraph giving ``command`` to the next heading."""
    starts = [k for k in (m.start() for m in re.finditer(re.escape(f"`{command}`"), text))
              if not text[text.rfind("\n", 0, k) + 1:].startswith("|")]     # not a table's cell
    assert starts, f"the page no longer gives {command!r} outside a table"
    return text[starts[0]:text.find("\n#", starts[0])]


def check_table(text: str, command: str, rows: dict, result) -> None:
    """``rows``: row label -> (estimator, one function per cell of its metrics as
    ``metrics.json`` holds them, giving the cell's numbers; None: a cell not checked)."""
    part = section(text, command)
    for label, (estimator, cells) in rows.items():
        m = result.to_dict()["estimators"][estimator]
        for quoted, get in zip(row_cells(part, label), cells):
            if get is not None:
                check(quoted, get(m), f"{command}: {label}")


def window(name: str, field: str, stat: str):
    return lambda m: [m["windows"][name][field][stat]]


def fault_max(name: str):
    return lambda m: [max(abs(m["windows"][name]["height_m"]["max_pos"]), abs(m["windows"][name]["height_m"]["max_neg"]))]


P2_COMMAND = "navsim run scenarios/p2_sea_height.yaml --runs 100"
P2_CELLS = [window("low_leg", "height_m", "max_pos"), window("low_leg", "height_m", "max_neg"),
            window("low_leg", "height_m", "std"), fault_max("gps_fault")]


@pytest.mark.slow
def test_p2_table(results):
    rows = {"ours, standard KF (GPS height)": ("standard KF (GPS height)", P2_CELLS),
            "ours, P2 dynamic weights": ("dynamic weights (P2)", P2_CELLS),
            "ours, dynamic weights + 3σ gating + radar averaging": ("dynamic weights + gating", P2_CELLS)}
    check_table(page("docs/papers.md"), P2_COMMAND, rows, results(P2_COMMAND))


@pytest.mark.slow
def test_p1_emi_table(results):
    command = "navsim run scenarios/p1_emi_powerline.yaml"
    passes = [f"interference {k}" for k in (1, 2, 3)]
    cells = [window(p, "horizontal_m", "rms") for p in passes] + [
        lambda m: [100 * m["windows"][p]["nees"]["fraction_inside"] for p in passes]
        + [m["windows"][p]["nees"]["average"] for p in passes],
        lambda m: [100 * m["nees"]["fraction_inside"]]]
    rows = {"ES-KF 15": ("ES-KF 15", cells), "Sage–Husa (b = 0.95)": ("Sage-Husa", cells),
            "fuzzy adaptive": ("fuzzy adaptive", cells)}
    text = page("docs/papers.md")
    quoted_passes = row_cells(section(text, command), "Sage–Husa (b = 0.95)")[3]
    assert len(quoted_passes) == 6, quoted_passes        # 3 shares, 3 averages
    check_table(text, command, rows, results(command))


@pytest.mark.slow
def test_p1_federated_table(results):
    command = "navsim run scenarios/p1_federated.yaml --runs 20"
    cells = [window("baro step", "height_m", "rms"), window("baro step", "height_m", "max_pos"),
             window("after the step", "height_m", "rms"),
             lambda m: [m["nees"]["average"], 100 * m["nees"]["fraction_inside"]]]
    rows = {label: (label, cells) for label in ("centralized ES-KF 16", "federated, no reset",
                                                "federated, reset + isolation")}
    rows["federated, reset (β = 0.5, 0.5)"] = ("federated, reset", cells)
    check_table(page("docs/papers.md"), command, rows, results(command))


@pytest.mark.slow
@pytest.mark.parametrize("name, row, summary", [
    ("p4_static", "`p4_static` (360 s parked, heading 63°)", "| P4 (Wu et al.) | CPF-EKF static (360 s) |"),
    ("p4_circle", "`p4_circle` (1000 s, 17 laps, vibration)", "| P4 | CPF-EKF circle (1000 s) |")])
def test_p4_attitude_table(name, row, summary, results):
    """P4's table and its summary line: the CPF-EKF's p95 against the truth and about each run's
    mean, the CPF's (``navsim run scenarios/<name>.yaml``, its own 20 runs and seed)."""
    text = page("docs/papers.md")
    metrics = results(f"navsim run scenarios/{name}.yaml").to_dict()["estimators"]
    ekf, cpf = metrics["CPF-EKF"]["attitude"], metrics["CPF"]["attitude"]
    cells = row_cells(text, row)
    check(cells[0] + cells[1] + cells[3], ekf["p95_deg"] + ekf["p95_about_run_mean_deg"] + cpf["p95_deg"], row)
    ours = line_with(text, summary).strip("|").split("|")[3]
    check(re.findall(NUMBER, ours), ekf["p95_deg"] + ekf["p95_about_run_mean_deg"], summary)


@pytest.mark.slow
def test_p3_figures(results):
    """The summary line and the P3 section (``navsim run scenarios/p3_sins_gps.yaml``: 200 runs,
    seed 3)."""
    text = page("docs/papers.md")
    m = results("navsim run scenarios/p3_sins_gps.yaml").to_dict()["estimators"]["SINS/GPS 15-state"]
    ours = line_with(text, "| P3 (Wang et al.) |").strip("|").split("|")[3]
    check(re.findall(NUMBER, ours), m["p99"]["pos_m"] + m["rms"]["pos_m"] + m["p99"]["vel_mps"], "P3's summary line")
    quoted = figures(" ".join(section(text, "navsim run scenarios/p3_sins_gps.yaml").split()),
                     rf"within ({NUMBER}), ({NUMBER}) and ({NUMBER}) m \(RMS ({NUMBER}), ({NUMBER}), ({NUMBER}) m\) "
                     rf"and of the velocity errors within ({NUMBER}) m/s \(RMS ({NUMBER}) m/s\)")
    check(quoted, m["p99"]["pos_m"] + m["rms"]["pos_m"] + [max(m["p99"]["vel_mps"]), max(m["rms"]["vel_mps"])],
          "P3's section")
