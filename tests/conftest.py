import os
from pathlib import Path

import matplotlib
import numpy as np
import pytest
from matplotlib.figure import Figure

from pages import check_saved, saved_name

matplotlib.use("Agg")
# one cache of compiled kernels for every test, worker and subprocess of the suite (tests that
# point NAVSIM_CACHE at a folder of their own would otherwise compile the kernels again)
os.environ.setdefault("NUMBA_CACHE_DIR", str(Path(__file__).resolve().parents[1] / ".pytest_cache" / "numba"))

#: the checkout's output folder: tests write only under their tmp_path, never here
CHECKOUT_REPORTS = Path(__file__).resolve().parents[1] / "reports"
#: set to 1 (as .ci/run does) to fail a session that left files in :data:`CHECKOUT_REPORTS`
STRICT_ENV = "NAVSIM_REQUIRE_CLEAN_CHECKOUT"
_REPORTS_BEFORE = pytest.StashKey[set]()     # the listing when the session started
_REPORTS_NEW = pytest.StashKey[list]()       # what the session added


def _reports_listing() -> set:
    return {str(p.relative_to(CHECKOUT_REPORTS)) for p in CHECKOUT_REPORTS.rglob("*")} \
        if CHECKOUT_REPORTS.is_dir() else set()


def pytest_sessionstart(session):
    if not hasattr(session.config, "workerinput"):
        session.config.stash[_REPORTS_BEFORE] = _reports_listing()


def pytest_sessionfinish(session, exitstatus):
    """A test that left files or folders in the checkout's reports/ (a command run without
    ``--out`` in the repository): named in the summary; the session fails under
    ``NAVSIM_REQUIRE_CLEAN_CHECKOUT=1`` (CI)."""
    if hasattr(session.config, "workerinput") or _REPORTS_BEFORE not in session.config.stash:
        return
    new = sorted(_reports_listing() - session.config.stash[_REPORTS_BEFORE])
    session.config.stash[_REPORTS_NEW] = new
    if new and os.environ.get(STRICT_ENV) == "1":
        session.exitstatus = pytest.ExitCode.TESTS_FAILED


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    new = config.stash.get(_REPORTS_NEW, [])
    if new:
        terminalreporter.write_line(
            f"the tests wrote into the checkout's {CHECKOUT_REPORTS}: {', '.join(new[:10])}"
            + (f" and {len(new) - 10} more" if len(new) > 10 else "")
            + " (a command without --out; give it a folder under tmp_path)"
            + ("" if os.environ.get(STRICT_ENV) == "1" else f"; {STRICT_ENV}=1 fails the session"),
            red=True, bold=True)


def pytest_configure(config):
    """Compile the kernels once, in the controlling process before the workers start (each
    worker and each subprocess would otherwise compile them itself on a fresh clone): two runs
    of P0's chunk over 3 s of flight (the strapdown, Kalman and IMU kernels); a second of work
    when the cache is warm."""
    if hasattr(config, "workerinput") or config.option.collectonly:
        return
    from navsim.experiment.runner import _chunk_work
    from navsim.experiment.scenario import load_scenario
    from navsim.flight import fly, parse_track
    scenario = load_scenario(Path(__file__).resolve().parents[1] / "scenarios" / "p0_bd_sins_ads.yaml")
    truth = fly(parse_track({"start": {"lat_deg": 30.0, "lon_deg": 122.5, "alt_m": 150, "speed_mps": 15,
                                       "heading_deg": 0}, "segments": [{"type": "straight", "time_s": 3}]}))
    _chunk_work(truth, scenario, 1, range(2))


#: what the figures saved since the last test's end were found with: (file, problems)
_SAVED_PROBLEMS: list = []


@pytest.fixture(scope="session", autouse=True)
def _pages_checked_when_saved():
    """Every figure saved in this process (``Figure.savefig``; ``PdfPages.savefig`` calls it)
    is checked for text outside its page and overprinted tick labels (``tests/pages.py``) and
    its problems kept for :func:`pages_read_well` (the PNGs are rasterised from the PDF, whose
    pages are these figures). Not in a forked child nor in a subprocess (a CLI run as one)."""
    parent, original = os.getpid(), Figure.savefig

    def savefig(fig, fname, *args, **kwargs):
        out = original(fig, fname, *args, **kwargs)
        if os.getpid() == parent:
            found = check_saved(fig, fname, kwargs)
            if found:
                _SAVED_PROBLEMS.append((saved_name(fname), found))
        return out

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(Figure, "savefig", savefig)
        yield


@pytest.fixture(autouse=True)
def pages_read_well(_pages_checked_when_saved):
    """Fails the test that saved a figure with text outside its page or tick labels printed
    over each other (in its body or in a fixture it set up), naming the file and the texts."""
    yield                            # a module fixture's pages go to the first test using it
    found, _SAVED_PROBLEMS[:] = list(_SAVED_PROBLEMS), []
    if found:
        pytest.fail("pages that do not read well:\n" + "\n".join(
            f"{name}: {p}" for name, problems in found for p in problems), pytrace=False)


@pytest.fixture(scope="session")
def repo_root() -> Path:
    return Path(__file__).resolve().parents[1]


#: the scenarios shipped in scenarios/ (P0-P4): a test over them finds at least these many
SHIPPED_SCENARIOS = 17


@pytest.fixture(scope="session")
def shipped_scenarios(repo_root) -> list:
    """The paths of the shipped scenarios, sorted; at least :data:`SHIPPED_SCENARIOS` of them
    (a test looping over them must not pass on an empty folder)."""
    paths = sorted((repo_root / "scenarios").glob("*.yaml"))
    assert len(paths) >= SHIPPED_SCENARIOS, f"found {len(paths)} scenarios in {repo_root / 'scenarios'}"
    return paths


@pytest.fixture(scope="session")
def shipped_flight(repo_root, tmp_path_factory):
    """``get(name)`` -> (scenario, truth, truth path) of a shipped scenario; flights are cached
    in a per-session folder unless NAVSIM_CACHE is set."""
    from navsim.experiment.runner import cached_flight
    from navsim.experiment.scenario import load_scenario
    os.environ.setdefault("NAVSIM_CACHE", str(tmp_path_factory.mktemp("cache")))

    def get(name):
        scenario = load_scenario(repo_root / "scenarios" / f"{name}.yaml")
        truth, path, _ = cached_flight(scenario.flight)
        return scenario, truth, path
    return get


@pytest.fixture
def assert_scenario_error():
    """``check(data, key, words)``: parsing the scenario mapping ``data`` raises a ScenarioError
    that names ``bad.yaml``, the key path ``key`` and contains ``words``."""
    def check(data, key, words):
        from navsim.experiment.scenario import parse_scenario
        from navsim.foundations.errors import ScenarioError
        with pytest.raises(ScenarioError) as exc:
            parse_scenario(data, "bad.yaml")
        assert f"bad.yaml: {key}:" in str(exc.value) and words in str(exc.value), str(exc.value)
    return check


def _close_metrics(a, b, path=""):
    """Equal metric trees; numbers equal up to the rounding of sums taken in another order."""
    if isinstance(a, dict):
        assert list(a) == list(b), path
        for k in a:
            _close_metrics(a[k], b[k], f"{path}.{k}")
    elif isinstance(a, list) and a and isinstance(a[0], dict):
        assert len(a) == len(b), path
        for i, (x, y) in enumerate(zip(a, b)):
            _close_metrics(x, y, f"{path}[{i}]")
    elif isinstance(a, list) and a and isinstance(a[0], (list, str, tuple)):
        assert a == b, path
    elif isinstance(a, (list, float, int)) and not isinstance(a, bool):
        # None: an interval's open end (JSON null)
        assert np.allclose(np.asarray(a, float), np.asarray(b, float), rtol=1e-12, atol=0, equal_nan=True), (path, a, b)
    else:
        assert a == b, path


@pytest.fixture
def close_metrics():
    """``close_metrics(a, b)``: two metrics.json trees equal (numbers to 1e-12 relative)."""
    return _close_metrics


def _same_history(a, b, timed: bool = True):
    """Two EstimatorHistory equal in every field, bit for bit (NaN equal to NaN); ``timed=False``
    for two separate runs: the CPU seconds in ``cost`` differ."""
    for name, va in vars(a).items():
        vb = getattr(b, name)
        if isinstance(va, np.ndarray):
            assert va.dtype == vb.dtype and np.array_equal(va, vb, equal_nan=va.dtype.kind == "f"), name
        elif name == "nis":
            assert list(va) == list(vb) and all(np.array_equal(va[k], vb[k], equal_nan=True) for k in va)
        elif name == "cost" and not timed:
            assert {k: va[k] for k in ("runs", "epochs", "batches")} == {k: vb[k] for k in ("runs", "epochs", "batches")}
        else:
            assert va == vb, name


@pytest.fixture
def same_history():
    """``same_history(a, b, timed=True)``: two histories equal in every field (see above)."""
    return _same_history
